"""Pre-training of the learned questioner (dialfred_questioner.pretrain, no ROS) on the shipped
(SYNTHETIC) valid_unseen dialogues and a few rendered first frames.

Claims: every annotation of a rendered task becomes an example (a noun outside the catalogue or a
task without frames is skipped and counted); a tiny run writes last.pt, best.pt and a metrics line
per epoch and its loss falls; a run stopped after one epoch and resumed ends with the weights of an
uninterrupted run; a changed config is refused on resume.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from dialfred_oracle.annotator import load_dialogues
from dialfred_questioner.data import catalog_nouns, pretraining_examples
from dialfred_questioner.model import QuestionerConfig
from dialfred_questioner.pretrain import PretrainConfig, pretrain
from dialfred_questioner.frames import FirstFrames, build_first_frames
from dialfred_sim.protocol import env_observation
from helpers import tiny_checkpoint

TASKS = 16


@pytest.fixture(scope='module')
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp('qpre')
    build_first_frames('valid_unseen', 64, root / 'first.npz', workers=1, limit=TASKS, progress=False)
    return root / 'first.npz', tiny_checkpoint(root / 'performer.pt', favour='RotateLeft')   # plays to the step limit


def config(setup, out, **changes) -> PretrainConfig:
    demo, performer = setup
    base = dict(split='valid_unseen', frames=str(demo), performer=str(performer), out=str(out),
                model=QuestionerConfig(embedding=16, hidden=32, image=32, dropout=0.0), epochs=3, batch_size=8,
                lr=3e-3, val_fraction=0.2, limit=TASKS, threads=1, progress=False)
    return PretrainConfig(**{**base, **changes})


def test_each_annotation_of_a_rendered_task_is_an_example(setup):
    first = FirstFrames(setup[0])
    assert first.frames.shape == (TASKS, 64, 64, 3) and first.resolution == 64
    rows = load_dialogues('valid_unseen')[:TASKS + 4]
    examples, skipped = pretraining_examples(rows, first.index, catalog_nouns())
    assert len(examples) + skipped == sum(len(r.annotations) for r in rows)
    assert skipped >= 4 * 2                          # the 4 tasks without frames
    assert {e.task_id for e in examples} <= set(first.task_ids)


def test_a_tiny_run_learns_and_a_resumed_run_ends_with_the_same_weights(setup, tmp_path):
    report = pretrain(config(setup, tmp_path / 'full'))
    lines = [json.loads(l) for l in (tmp_path / 'full' / 'metrics.jsonl').read_text().splitlines()]
    assert [l['epoch'] for l in lines] == [1, 2, 3] and lines[-1]['train_loss'] < lines[0]['train_loss']
    assert report['examples']['train'] > 0 and report['examples']['val'] > 0
    assert (tmp_path / 'full' / 'best.pt').is_file()
    pretrain(config(setup, tmp_path / 'split', epochs=1))
    pretrain(config(setup, tmp_path / 'split', resume=True))
    a = torch.load(tmp_path / 'full' / 'last.pt', weights_only=True)['state_dict']
    b = torch.load(tmp_path / 'split' / 'last.pt', weights_only=True)['state_dict']
    assert all(torch.equal(a[k], b[k]) for k in a)
    with pytest.raises(ValueError, match='batch_size'):
        pretrain(config(setup, tmp_path / 'split', resume=True, batch_size=4))


def test_a_pretrained_checkpoint_asks_in_a_rollout_and_as_a_questioner(setup, tmp_path):
    from dialfred_performer.agent import PerformerAgent
    from dialfred_questioner.policy import LearnedQuestioner, batch_records
    from dialfred_questioner.rollout import Timing, play_rollout
    from dialfred_sim.env import DialfredEnv
    pretrain(config(setup, tmp_path / 'q', epochs=1))
    policy = LearnedQuestioner.from_checkpoint(tmp_path / 'q' / 'best.pt', greedy=False, seed=3)
    env = DialfredEnv(resolution=64, max_steps=6)
    performer = PerformerAgent.from_checkpoint(setup[1])
    ep = play_rollout(env, performer, policy, 'valid_unseen/000001', 0, Timing('anytime', gap=2))
    assert len(ep.decisions) == 3 and all(d.record is not None for d in ep.decisions)
    records = [d.record for d in ep.decisions]
    b = batch_records(records)
    assert b['steps'].tolist() == [0, 2, 4]
    asked = [d for d in ep.decisions if d.question is not None]
    assert len(ep.dialogue) == len(asked) and ep.asked_at == [d.step for d in asked]
    # the same inputs give the same greedy question as a Questioner
    greedy = LearnedQuestioner.from_checkpoint(tmp_path / 'q' / 'best.pt')
    obs = env_observation(*env.reset(options={'task_id': 'valid_unseen/000001'}))
    greedy.reset(env.task.public(), 0)
    assert greedy.ask(obs, 0) == greedy.decide(obs.rgb, env.task.public().instruction, [], 0)[0]
    env.close()
    with pytest.raises(FileNotFoundError):
        LearnedQuestioner.from_checkpoint(tmp_path / 'missing.pt')
    (tmp_path / 'bad.pt').write_bytes(b'not a checkpoint')
    with pytest.raises(ValueError, match='not a questioner checkpoint'):
        LearnedQuestioner.from_checkpoint(tmp_path / 'bad.pt')


def test_first_frames_copied_out_of_demonstrations_are_the_rendered_ones(setup, tmp_path):
    from dialfred_sim.tasks.demonstrations import build_demonstrations
    from dialfred_questioner.frames import main
    build_demonstrations('valid_unseen', 64, tmp_path / 'demos', workers=1, limit=6, progress=False)
    copied = build_first_frames('valid_unseen', 64, tmp_path / 'copied.npz', limit=6, progress=False,
                                demonstrations=tmp_path / 'demos')
    rendered = FirstFrames(setup[0])
    first = FirstFrames(copied)
    assert first.task_ids == rendered.task_ids[:6]
    assert np.array_equal(first.frames, rendered.frames[:6])
    # more tasks than the build has, or another resolution: a clear error, no file
    with pytest.raises(ValueError, match='lacks 2 of the tasks'):
        build_first_frames('valid_unseen', 64, tmp_path / 'more.npz', limit=8, demonstrations=tmp_path / 'demos')
    with pytest.raises(ValueError, match='rendered at 64'):
        build_first_frames('valid_unseen', 32, tmp_path / 'small.npz', limit=6, demonstrations=tmp_path / 'demos')
    assert main(['valid_unseen', '--limit', '6', '--demonstrations', str(tmp_path / 'nothing'),
                 '--out', str(tmp_path / 'x.npz')]) == 2
    assert not (tmp_path / 'more.npz').exists() and not (tmp_path / 'x.npz').exists()


def test_a_questioner_can_keep_its_frame_encoder_in_its_performers_checkpoint(setup, tmp_path):
    """share_visual drops the questioner's copy of the frozen encoder and names the performer checkpoint
    that holds it: the questioner decides the same, and a replaced or missing performer file is refused
    with the reason."""
    from dialfred_questioner.policy import LearnedQuestioner, SharedVisualError, share_visual
    pretrain(config(setup, tmp_path / 'q', epochs=1))
    full = tmp_path / 'q' / 'best.pt'
    performer = tmp_path / 'perf' / 'et.pt'
    performer.parent.mkdir()
    performer.write_bytes(setup[1].read_bytes())
    shared = tmp_path / 'ship' / 'q.pt'
    source = share_visual(full, shared, performer)
    assert source['performer'] == '../perf/et.pt' and shared.stat().st_size < full.stat().st_size
    assert 'visual' not in torch.load(shared, weights_only=True)
    rgb = np.random.default_rng(1).integers(0, 255, (64, 64, 3), dtype=np.uint8)
    instruction = load_dialogues('valid_unseen')[0].instruction
    a, b = LearnedQuestioner.from_checkpoint(full), LearnedQuestioner.from_checkpoint(shared)
    (qa, ra), (qb, rb) = a.decide(rgb, instruction, [], 0), b.decide(rgb, instruction, [], 0)
    assert qa == qb and torch.equal(ra.image, rb.image)
    state = torch.load(performer, weights_only=True)
    name = next(k for k in state['state_dict'] if k.startswith('visual.'))
    state['state_dict'][name] = state['state_dict'][name] + 1.0
    torch.save(state, performer)                          # another performer in its place
    with pytest.raises(SharedVisualError, match='another frame encoder'):
        LearnedQuestioner.from_checkpoint(shared)
    with pytest.raises(SharedVisualError, match='is not the one in'):
        share_visual(full, tmp_path / 'ship' / 'r.pt', performer)
    performer.unlink()
    with pytest.raises(SharedVisualError, match='cannot be read'):
        LearnedQuestioner.from_checkpoint(shared)
