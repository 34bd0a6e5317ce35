"""The performer model (dialfred_performer.model and nn/, no ROS).

Claims: the outputs have one action distribution and one pointer heatmap per step; the decision at
step t does not change when a later frame, a later action or a QA asked later changes (perturbation);
a tiny training run overfits three expert episodes (learning happens); a checkpoint rebuilds the same
model, and a missing, corrupt or mismatched one is refused with a clear message.
"""

from __future__ import annotations

import dataclasses

import pytest
import torch

from dialfred_performer.data import DemonstrationDataset, collate, generate_dialogues, vocabulary_texts
from dialfred_performer.model import (CheckpointError, Performer, PerformerConfig, load_checkpoint, performer_loss,
                                      save_checkpoint)
from dialfred_performer.nn.heads import cell_centre_pixel, pixel_cell
from dialfred_performer.preprocess import Vocabulary
from dialfred_sim.protocol import ACTIONS
from dialfred_sim.tasks.demonstrations import build_demonstrations

torch.set_num_threads(1)
RES = 64
SMALL = PerformerConfig(resolution=RES, d_model=64, heads=4, layers=2, ff=128, dropout=0.0, max_steps=64)


@pytest.fixture(scope='module')
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp('performer_demo')
    build_demonstrations('valid_unseen', RES, out, workers=1, limit=3, progress=False)
    generate_dialogues(out)
    vocab = Vocabulary.build(vocabulary_texts(out))
    return out, vocab, DemonstrationDataset(out, vocab, RES)


def model_for(vocab, config=SMALL, seed=0):
    torch.manual_seed(seed)
    return Performer(config, len(vocab)).eval()


def test_one_action_distribution_and_one_heatmap_per_step(demo):
    _, vocab, ds = demo
    batch = collate([ds[7], ds[15], ds[23]])        # each task with all three question types
    B, T = batch['actions'].shape
    with torch.no_grad():
        out = model_for(vocab)(batch)
    G = RES // 8
    assert out['action_logits'].shape == (B, T, len(ACTIONS)) == (3, T, 13)
    K = int((batch['target_cells'] >= 0).sum())
    assert K > 0 and out['pointer_logits'].shape == (K, G * G) == batch['target_masks'].shape    # at target steps
    assert torch.isfinite(out['action_logits']).all() and torch.isfinite(out['pointer_logits']).all()
    assert pixel_cell(*cell_centre_pixel(27, G, RES), G, RES) == 27 and pixel_cell(-1, -1, G, RES) == -1


def every_step(model, batch) -> dict:
    """Action and pointer logits at every step [B, T, ...] (the agent's path: encode_frames, decode)."""
    frames = batch['frames']
    B, T = frames.shape[:2]
    emb, grid = model.encode_frames(frames.reshape(B * T, *frames.shape[2:]))
    action, pointer = model.decode(batch['lang_ids'], batch['lang_types'], batch['lang_steps'], batch['lang_valid'],
                                   emb.view(B, T, -1), grid.view(B, T, grid.shape[1], -1), batch['previous_actions'],
                                   batch['step_valid'])
    return {'action_logits': action, 'pointer_logits': pointer}


def test_the_decision_at_a_step_never_sees_a_later_frame_action_or_qa(demo):
    _, vocab, ds = demo
    model = model_for(vocab)
    batch = collate([ds[7]])                          # all three types
    T = batch['actions'].shape[1]
    t = 1
    assert T > t + 2
    later_qa = batch['lang_steps'][0] > t
    if not later_qa.any():                            # make sure some QA is asked after step t
        batch['lang_steps'][0, -3:] = t + 1
        later_qa = batch['lang_steps'][0] > t
    with torch.no_grad():
        ref = every_step(model, batch)
        changed = {k: v.clone() if torch.is_tensor(v) else v for k, v in batch.items()}
        changed['frames'][0, t + 1:] = torch.rand_like(changed['frames'][0, t + 1:])
        changed['previous_actions'][0, t + 1:] = (changed['previous_actions'][0, t + 1:] + 3) % len(ACTIONS)
        changed['lang_ids'][0, later_qa] = 1                        # <unk>
        changed['lang_types'][0, later_qa] = 1
        out = every_step(model, changed)
    for key in ('action_logits', 'pointer_logits'):
        assert torch.allclose(out[key][0, :t + 1], ref[key][0, :t + 1], atol=1e-5), key
        assert not torch.allclose(out[key][0, t + 1:], ref[key][0, t + 1:], atol=1e-5), key   # it does see them later
    with torch.no_grad():                              # and an earlier frame does change step t
        earlier = {k: v.clone() if torch.is_tensor(v) else v for k, v in batch.items()}
        earlier['frames'][0, 0] = torch.rand_like(earlier['frames'][0, 0])
        assert not torch.allclose(model(earlier)['action_logits'][0, t], ref['action_logits'][0, t], atol=1e-5)


def test_padding_does_not_change_an_episode(demo):
    _, vocab, ds = demo
    model = model_for(vocab)
    short = min(range(0, 24, 8), key=lambda i: len(ds[i]['actions']))
    long = max(range(0, 24, 8), key=lambda i: len(ds[i]['actions']) + len(ds[i]['lang_ids']))
    with torch.no_grad():
        alone = model(collate([ds[short]]))
        padded = model(collate([ds[short], ds[long + 7]]))
    n = len(ds[short]['actions'])
    assert torch.allclose(alone['action_logits'][0], padded['action_logits'][0, :n], atol=1e-5)


def test_a_tiny_training_run_overfits_three_episodes(demo):
    _, vocab, ds = demo
    torch.manual_seed(0)
    model = Performer(SMALL, len(vocab))
    batch = collate([ds[i] for i in (0, 8, 16, 7, 15, 23)])     # 3 tasks, without and with QAs
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    first = None
    for _ in range(60):
        loss, parts = performer_loss(model(batch), batch)
        first = first if first is not None else parts
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert first['action'] > 1.5 and parts['action'] < 0.05 and parts['pointer'] < 0.05, (first, parts)
    model.eval()
    with torch.no_grad():
        out = model(batch)
    valid = batch['step_valid']
    assert (out['action_logits'].argmax(-1)[valid] == batch['actions'][valid]).all()
    has = batch['target_cells'] >= 0
    assert has.any() and (out['pointer_logits'].argmax(-1) == batch['target_cells'][has]).all()
    assert torch.allclose(every_step(model, batch)['pointer_logits'][has], out['pointer_logits'], atol=1e-5)


def test_checkpoint_round_trip_carries_config_vocab_commit_and_command(demo, tmp_path):
    _, vocab, ds = demo
    model = model_for(vocab, seed=3)
    path = tmp_path / 'performer.pt'
    save_checkpoint(path, model, vocab, command='python -m dialfred_performer.train --tiny')
    loaded, loaded_vocab, info = load_checkpoint(path)
    assert loaded_vocab == vocab and info['config'] == SMALL and info['command'].endswith('--tiny')
    assert info['git_commit'] and info['git_commit'] != ''
    batch = collate([ds[7]])
    with torch.no_grad():
        assert torch.equal(loaded(batch)['action_logits'], model(batch)['action_logits'])


def test_a_missing_corrupt_or_mismatched_checkpoint_is_refused_clearly(demo, tmp_path):
    _, vocab, _ = demo
    model = model_for(vocab)
    with pytest.raises(FileNotFoundError, match='no performer checkpoint'):
        load_checkpoint(tmp_path / 'nothing.pt')
    bad = tmp_path / 'corrupt.pt'
    bad.write_bytes(b'not a checkpoint at all')
    with pytest.raises(CheckpointError, match='not a readable checkpoint'):
        load_checkpoint(bad)
    good = tmp_path / 'good.pt'
    save_checkpoint(good, model, vocab, command='test')
    state = torch.load(good, weights_only=True)

    def broken(name, change):
        s = {**state, 'state_dict': dict(state['state_dict']), 'config': dict(state['config'])}
        change(s)
        p = tmp_path / f'{name}.pt'
        torch.save(s, p)
        return p

    with pytest.raises(CheckpointError, match=r"missing \['vocab'\]"):
        load_checkpoint(broken('novocab', lambda s: s.pop('vocab')))
    with pytest.raises(CheckpointError, match='missing weights'):
        load_checkpoint(broken('noweight', lambda s: s['state_dict'].pop('action_head.linear.weight')))
    with pytest.raises(CheckpointError, match='unexpected weights'):
        load_checkpoint(broken('extra', lambda s: s['state_dict'].update(stray=torch.zeros(1))))
    with pytest.raises(CheckpointError, match='shape mismatch'):
        load_checkpoint(broken('wider', lambda s: s['config'].update(d_model=32, ff=64)))
    with pytest.raises(CheckpointError, match='shape mismatch'):
        load_checkpoint(broken('vocab', lambda s: s.update(vocab=s['vocab'] + ['zebra'])))
    with pytest.raises(CheckpointError, match='not in PerformerConfig'):
        load_checkpoint(broken('field', lambda s: s['config'].update(colour='red')))
    with pytest.raises(CheckpointError, match='format'):
        load_checkpoint(broken('format', lambda s: s.update(format='something-else/9')))
    assert dataclasses.asdict(load_checkpoint(good)[2]['config']) == dataclasses.asdict(SMALL)
