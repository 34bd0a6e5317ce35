"""Perception trained on our own frames (dialfred_performer.perception) and the performer that sees
through it: labels become the right targets, training resumes to the same weights, the performer
keeps the network frozen and points at single pixels, and the agent reads RGB only."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from dialfred_performer.distributed import Ranks
from dialfred_performer.model import PerformerConfig, load_checkpoint, pointer_ce
from dialfred_performer.perception import (FIRST_OBJECT_CLASS, Perception, PerceptionNetConfig, cell_targets,
                                          load_perception, main as perception_main)
from dialfred_sim.tasks.demonstrations import DEPTH_STEP, label_classes
from dialfred_sim.protocol import Observation, env_observation

TINY = ['--c1', '8', '--c2', '8', '--c3', '16', '--decoder', '8']


@pytest.fixture(scope='module')
def prepared(tmp_path_factory):
    """A labelled, prepared slice of valid_unseen and a perception network trained on it briefly."""
    from dialfred_performer.prepare import PrepareConfig, prepare
    root = tmp_path_factory.mktemp('perception')
    folder = root / 'demos'
    prepare(PrepareConfig(split='valid_unseen', resolution=32, workers=1, limit=10, out=str(folder),
                          progress=False, labels=True))
    out = root / 'perception'
    assert perception_main(['--demonstrations', str(folder), '--out', str(out), '--frames', '96',
                            '--batch-size', '16', '--validate-every', '3', '--val-fraction', '0.3',
                            '--val-frames', '32', '--no-progress', *TINY]) == 0
    return folder, out


def test_cell_targets_are_each_cells_class_shares_depth_and_colour():
    classes = torch.zeros(1, 4, 4, dtype=torch.uint8)
    classes[0, :2, :2] = FIRST_OBJECT_CLASS                  # one whole cell of an object
    classes[0, 2, 2] = 1                                     # a quarter of a cell of floor
    depth = torch.full((1, 4, 4), 25, dtype=torch.uint8)     # 1 m
    rgb = torch.rand(1, 3, 4, 4)
    share, metres, colour, objects = cell_targets(classes, depth, rgb, len(label_classes()))
    assert share.shape == (1, len(label_classes()), 2, 2) and torch.allclose(share.sum(1), torch.ones(1, 2, 2))
    assert share[0, FIRST_OBJECT_CLASS, 0, 0] == 1 and share[0, 1, 1, 1] == 0.25 and share[0, 0, 1, 1] == 0.75
    assert torch.allclose(metres, torch.full((1, 2, 2), 25 * DEPTH_STEP))
    assert torch.allclose(colour, F.avg_pool2d(rgb, 2)) and objects[0, 0, 0] == 1 and objects[0, 1, 1] == 0


def test_the_pointer_loss_counts_every_cell_of_the_target():
    logits = torch.randn(5, 16)
    target = torch.randint(16, (5,))
    one_hot = F.one_hot(target, 16).bool()
    assert torch.allclose(pointer_ce(logits, one_hot), F.cross_entropy(logits, target), atol=1e-6)
    wider = one_hot.clone()
    wider[:, (target + 1) % 16] = True
    assert pointer_ce(logits, wider, 'sum') < pointer_ce(logits, one_hot, 'sum')


def test_perception_outputs_three_maps_at_their_resolutions():
    net = Perception(PerceptionNetConfig(resolution=32, c1=8, c2=8, c3=16, decoder=8))
    out = net(torch.rand(2, 3, 32, 32))
    assert out.coarse.shape == (2, 16, 4, 4) and out.fine.shape == (2, 8, 16, 16) and out.stem.shape == (2, 8, 32, 32)
    logits, metres, colour = net.heads(out.fine)
    assert logits.shape == (2, len(label_classes()), 16, 16) and (metres >= 0).all() and colour.shape == (2, 3, 16, 16)
    with pytest.raises(ValueError, match='multiple of 8'):
        Perception(PerceptionNetConfig(resolution=30))
    frames = torch.rand(2, 3, 32, 32)
    assert torch.equal(net.coarse(frames), net(frames).coarse)      # the encoder alone gives the same map


def test_training_writes_a_checkpoint_and_metrics_and_the_same_seed_gives_the_same_weights(prepared, tmp_path):
    folder, out = prepared
    net, extra = load_perception(out / 'perception.pt')
    rows = [json.loads(line) for line in (out / 'metrics.jsonl').read_text().splitlines()]
    assert [r['update'] for r in rows] == [3, 6] and 0 <= rows[-1]['val']['object_accuracy'] <= 1
    assert extra['command'].startswith('python -m dialfred_performer.perception')
    args = ['--demonstrations', str(folder), '--frames', '96', '--batch-size', '16', '--validate-every', '3',
            '--val-fraction', '0.3', '--val-frames', '32', '--no-progress', *TINY]
    assert perception_main([*args, '--out', str(tmp_path / 'a'), '--frames', '48']) == 0
    assert perception_main([*args, '--out', str(tmp_path / 'a'), '--resume', '--lr', '0.1']) == 2  # another config
    assert perception_main([*args, '--out', str(tmp_path / 'b')]) == 0
    first = torch.load(tmp_path / 'b' / 'last.pt', weights_only=True)['state_dict']
    again = torch.load(out / 'last.pt', weights_only=True)['state_dict']
    assert all(torch.equal(first[k], again[k]) for k in first)          # the same seed, the same weights


def test_bf16_training_keeps_fp32_weights_and_learns_and_an_unknown_precision_is_refused(prepared, tmp_path):
    """--precision bf16 autocasts the training steps only: the weights stay fp32, the run learns (its
    validation, in fp32, improves) and differs from the fp32 run; a precision it does not know is refused."""
    folder, out = prepared
    args = ['--demonstrations', str(folder), '--frames', '96', '--batch-size', '16', '--validate-every', '3',
            '--val-fraction', '0.3', '--val-frames', '32', '--no-progress', *TINY]
    assert perception_main([*args, '--out', str(tmp_path / 'bf16'), '--precision', 'bf16']) == 0
    bf16 = torch.load(tmp_path / 'bf16' / 'last.pt', weights_only=True)['state_dict']
    fp32 = torch.load(out / 'last.pt', weights_only=True)['state_dict']      # the same run in fp32 (the fixture)
    assert all(v.dtype == torch.float32 for v in bf16.values() if v.is_floating_point())
    assert any(not torch.equal(bf16[k], fp32[k]) for k in fp32)
    rows = [json.loads(line) for line in (tmp_path / 'bf16' / 'metrics.jsonl').read_text().splitlines()]
    assert rows[-1]['val']['loss'] < rows[0]['val']['loss'] or rows[-1]['val']['cell_accuracy'] > 0.3
    with pytest.raises(SystemExit) as refused:
        perception_main([*args, '--out', str(tmp_path / 'x'), '--precision', 'fp16'])
    assert refused.value.code == 2 and not (tmp_path / 'x').exists()


def test_a_damaged_perception_checkpoint_is_refused(tmp_path):
    from dialfred_performer.perception import PerceptionCheckpointError
    (tmp_path / 'p.pt').write_bytes(b'not a checkpoint')
    with pytest.raises(PerceptionCheckpointError, match='is not a perception checkpoint'):
        load_perception(tmp_path / 'p.pt')
    with pytest.raises(FileNotFoundError):
        load_perception(tmp_path / 'missing.pt')


def tiny_performer(prepared, out, *extra: str):
    """A perception performer trained for 3 updates on the prepared slice: (its last.pt, perception.pt)."""
    from dialfred_performer.train import main as train_main
    folder, perception = prepared
    assert train_main(['--demonstrations', str(folder), '--out', str(out), '--perception',
                       str(perception / 'perception.pt'), '--resolution', '32', '--max-updates', '3',
                       '--batch-size', '4', '--d-model', '32', '--heads', '2', '--layers', '1', '--ff', '32',
                       '--val-fraction', '0.3', '--no-progress', '--threads', '1', *extra]) == 0
    return out / 'last.pt', perception / 'perception.pt'


@pytest.fixture(scope='module')
def performer(prepared, tmp_path_factory):
    return tiny_performer(prepared, tmp_path_factory.mktemp('performer'))


@pytest.fixture(scope='module')
def reach_performer(prepared, tmp_path_factory):
    """With the reach input (the action head reads the predicted distance under the pointer); a high
    learning rate so that 3 updates move its layer away from zero."""
    return tiny_performer(prepared, tmp_path_factory.mktemp('reach'), '--reach-input', '--lr', '0.05',
                          '--warmup-updates', '1')


def test_the_performer_keeps_the_perception_network_as_trained_and_points_at_pixels(performer):
    checkpoint, perception = performer
    model, _, info = load_checkpoint(checkpoint)
    assert info['config'].visual == 'perception' and model.config.grid_size == 32
    net, _ = load_perception(perception)
    trained = net.state_dict()
    assert all(torch.equal(v, trained[k]) for k, v in model.visual.net.state_dict().items())
    assert not any(p.requires_grad for p in model.visual.net.parameters())
    frames = torch.rand(2, 3, 32, 32)
    emb, keys = model.encode_frames(frames)
    assert emb.shape == (2, 32) and keys.shape == (2, 32 * 32, model.config.pointer_key)
    assert torch.equal(model.visual.embedding(frames), emb)   # the questioner's path skips the decoder, same numbers
    model.train()
    assert not model.visual.net.training              # frozen means its norms never switch to training either


@pytest.mark.parametrize('which', ['performer', 'reach_performer'])
def test_the_agent_reads_rgb_only(which, request):
    """No label reaches the agent: with the simulator's depth and segmentation removed from every
    observation, it takes the same actions at the same pixels (with the reach input too: its
    distances are the network's)."""
    from dialfred_performer.agent import PerformerAgent
    from dialfred_sim.env import DialfredEnv
    from dialfred_sim.tasks import load_split
    checkpoint, _ = request.getfixturevalue(which)
    task = load_split('valid_unseen')[0]
    runs = []
    for strip in (False, True):
        env = DialfredEnv(resolution=32)
        agent = PerformerAgent.from_checkpoint(checkpoint)
        obs = env_observation(*env.reset(options={'task': task}))
        agent.reset(task)
        actions = []
        for _ in range(12):
            name, x, y = agent.act(Observation(rgb=obs.rgb) if strip else obs)
            actions.append((name, x, y))
            assert name == 'Stop' or x < 32 and y < 32
            if name == 'Stop':
                break
            raw, _, done, truncated, info = env.step({'action': name, 'pixel': (max(x, 0), max(y, 0))}
                                                     if x >= 0 else {'action': name})
            obs = env_observation(raw, info)
            if done or truncated:
                break
        env.close()
        runs.append(actions)
    assert runs[0] == runs[1]


def test_a_questioner_pretrained_against_the_perception_performer_sees_through_its_network(performer, tmp_path):
    """The questioner keeps a frozen copy of whichever frame encoder its performer has: pre-trained against
    a perception performer, its checkpoint rebuilds that encoder and gives the performer's frame embedding."""
    from dialfred_performer.preprocess import frame_tensor
    from dialfred_questioner.frames import build_first_frames
    from dialfred_questioner.model import QuestionerConfig
    from dialfred_questioner.policy import LearnedQuestioner
    from dialfred_questioner.pretrain import PretrainConfig, pretrain
    from dialfred_sim.tasks import load_split
    checkpoint, _ = performer
    build_first_frames('valid_unseen', 32, tmp_path / 'first.npz', workers=1, limit=8, progress=False)
    pretrain(PretrainConfig(split='valid_unseen', frames=str(tmp_path / 'first.npz'), performer=str(checkpoint),
                            out=str(tmp_path / 'q'), model=QuestionerConfig(embedding=16, hidden=32, image=32),
                            epochs=1, batch_size=4, val_fraction=0.3, limit=8, threads=1, progress=False))
    q = LearnedQuestioner.from_checkpoint(tmp_path / 'q' / 'best.pt')
    model, _, _ = load_checkpoint(checkpoint)
    assert type(q.visual) is type(model.visual)
    rgb = torch.randint(0, 255, (32, 32, 3), dtype=torch.uint8).numpy()
    _, record = q.decide(rgb, load_split('valid_unseen')[0].instruction, [], 0)
    with torch.no_grad():
        assert torch.allclose(record.image, model.encode_frames(frame_tensor(rgb, 32)[None])[0][0])


def test_the_reach_input_reads_the_network_s_distance_under_the_pointer(reach_performer):
    """With reach_input each pixel's key carries the network's predicted distance (view-axis depth
    along the pixel's ray), and the action head adds what the reach features say."""
    from dialfred_performer.model import REACH_METRES, reach_features
    from dialfred_performer.nn.enc_perceived import pixel_ray_lengths
    checkpoint, _ = reach_performer
    model, _, _ = load_checkpoint(checkpoint)
    assert model.config.reach_input
    frames = torch.rand(2, 3, 32, 32)
    emb, grid = model.encode_frames(frames)
    assert grid.shape == (2, 32 * 32, model.config.pointer_key + 1)
    with torch.no_grad():
        depth = model.visual.net.heads(model.visual.net(frames).fine)[1]
    metres = F.interpolate(depth[:, None], size=(32, 32), mode='nearest')[:, 0] * pixel_ray_lengths(32)
    assert torch.allclose(grid[..., -1], metres.flatten(1))
    assert torch.allclose(pixel_ray_lengths(2), torch.full((2, 2), 1.5 ** 0.5))   # 90 degrees: corners at +-0.5
    # the features: mass within reach, the expected and the best pixel's distance
    logits = torch.tensor([[0.0, 0.0, 9.0]])
    f = reach_features(logits, torch.tensor([[1.0, 3.0, REACH_METRES + 0.5]]))
    p = torch.softmax(logits, -1)[0]
    assert torch.allclose(f, torch.tensor([[(p[0] + 3 * p[1] + 2.0 * p[2]) / 2, p[0], 1.0]]))
    assert any(float(w.detach().abs().sum()) > 0 for w in model.reach_head.parameters())   # it was trained
    # training points at every frame without making its keys: the same logits as the keys give
    queries = torch.randn(2, model.config.pointer_key)
    with torch.no_grad():
        _, _, out = model.visual.perceive(frames)
        folded = model.visual.pointer_logits(out, queries)
    assert torch.allclose(folded, torch.einsum('nd,ncd->nc', queries, grid[..., :-1]), atol=1e-4)
    assert torch.allclose(model.visual.distances(out), grid[..., -1])


def test_the_reach_performer_acts_as_it_was_trained_step_by_step(reach_performer, prepared):
    """Teacher-forced training (`forward`, which points with keys made without gradient at every step),
    the whole-episode decode and the incremental decode_step give the same action and pointer logits."""
    from dialfred_performer.data import DemonstrationDataset, collate
    from dialfred_performer.model import camera_pitches
    checkpoint, _ = reach_performer
    model, vocab, _ = load_checkpoint(checkpoint)
    model.eval()
    ds = DemonstrationDataset(prepared[0], vocab, 32, model.config.max_tokens, seed=0, grid_size=32)
    batch = collate([ds[0]])
    with torch.no_grad():
        out = model(batch)
        T = batch['frames'].shape[1]
        emb, grid = model.encode_frames(batch['frames'][0])
        actions, pointer = model.decode(batch['lang_ids'], batch['lang_types'], batch['lang_steps'],
                                        batch['lang_valid'], emb[None], grid[None], batch['previous_actions'],
                                        batch['step_valid'])
    assert torch.allclose(out['action_logits'], actions, atol=1e-4)
    assert torch.allclose(out['pointer_logits'], pointer[batch['target_cells'] >= 0], atol=1e-4)
    cache = model.encoder.empty_cache()
    steps = batch['lang_steps'][0][batch['lang_valid'][0]]
    pitches = camera_pitches(batch['previous_actions'][0])
    for t in range(T):                                 # the agent's path: each QA's tokens from their step on
        known = int((steps <= t).sum())
        a, ptr, cache = model.decode_step(cache, batch['lang_ids'][0, :known], batch['lang_types'][0, :known],
                                          int((steps <= t - 1).sum()) if t else 0, emb[t], grid[t],
                                          int(batch['previous_actions'][0, t]), t, float(pitches[t]))
        if t == 0:
            assert torch.allclose(a, actions[0, 0], atol=1e-4) and torch.allclose(ptr, pointer[0, 0], atol=1e-4)
    assert torch.allclose(a, actions[0, T - 1], atol=1e-4)


def play_side_by_side(agent, other, check, at_cut=lambda: None, steps: int = 10, cut_at: int = 6,
                      keep_going: bool = False) -> int:
    """Play valid_unseen's first task with `agent`'s decisions, `other` deciding on the same frames:
    `check(t, agent's outputs, other's outputs)` at each step, the same decision asserted; at step
    `cut_at` both caches are dropped (as when the QAs outgrow max_tokens: the whole episode is read
    again), after `at_cut()`. With `keep_going`, Stop and MoveAhead are played as RotateLeft so the
    episode lasts. Returns the steps played."""
    from dialfred_sim.env import DialfredEnv
    from dialfred_sim.tasks import load_split
    task = load_split('valid_unseen')[0]
    env = DialfredEnv(resolution=32)
    obs = env_observation(*env.reset(options={'task': task}))
    agent.reset(task)
    other.reset(task)
    played = 0
    for t in range(steps):
        if t == cut_at:
            at_cut()
            agent.state.cache = other.state.cache = None
        check(t, agent._outputs(obs), other._outputs(obs))
        decision = agent.act(obs)
        assert decision == other.act(obs), t
        played = t + 1
        name, x, y = decision
        if keep_going and name in ('Stop', 'MoveAhead'):
            name = 'RotateLeft'
        elif name == 'Stop':
            break
        raw, _, done, truncated, info = env.step({'action': name, **({'pixel': (x, y)} if x >= 0 else {})})
        obs = env_observation(raw, info)
        if done or truncated:
            break
    env.close()
    return played


def test_the_agent_makes_pointer_keys_only_to_act_and_decides_as_with_them_at_every_step(performer):
    """A performer without the reach input makes a frame's keys only when it interacts (lazy_pointer):
    the same action logits bit for bit as an agent that makes them at every step, the same pointer when
    it acts, and the same decisions when the dialogue outgrows the cache (the keys of earlier steps
    are then made from their frames)."""
    from dialfred_performer.agent import PerformerAgent

    checkpoint, _ = performer
    lazy, eager = PerformerAgent.from_checkpoint(checkpoint), PerformerAgent.from_checkpoint(checkpoint, pointer_mode='keys')
    assert lazy.state.pointer_mode == 'lazy' and eager.state.pointer_mode == 'keys'
    unmade = []

    def check(t, a, b):
        assert torch.equal(a.action_logits, b.action_logits), t
        if a.pointer_logits is None:
            assert torch.equal(lazy.model.step_pointer(a)[1], b.pointer_logits), t
        else:
            assert torch.equal(a.pointer_logits, b.pointer_logits), t
    assert play_side_by_side(lazy, eager, check, lambda: unmade.append(sum(g is None for g in lazy.state.grids)),
                             keep_going=True) == 10
    assert unmade[0] >= 1 and all(g is not None for g in lazy.state.grids[:6])     # made on demand for the fallback


def test_a_performer_trained_through_the_frozen_network_in_bf16_perceives_in_bf16_where_the_cpu_does_it(
        prepared, reach_performer, tmp_path, monkeypatch):
    """--perception-precision bf16 runs the frozen network's convolutions in bfloat16 while training (the
    training loss within rounding of fp32's) and records it in the model's config; the checkpoint's agent
    (and a questioner's copy of its encoder) perceive in bfloat16 where the CPU does it natively, in fp32
    elsewhere. Every path through the network (whole, encoder then decoder, encoder alone) is in it."""
    from dialfred_performer import model as model_module
    from dialfred_performer.train import TrainConfig
    checkpoint, _ = tiny_performer(prepared, tmp_path / 'bf16', '--reach-input', '--lr', '0.05', '--warmup-updates',
                                   '1', '--perception-precision', 'bf16')
    rows = [json.loads(line) for name in (checkpoint, reach_performer[0])
            for line in (name.parent / 'metrics.jsonl').read_text().splitlines()[:1]]
    assert rows[0]['loss'] == pytest.approx(rows[1]['loss'], rel=0.02) and rows[0]['loss'] != rows[1]['loss']
    assert load_checkpoint(reach_performer[0])[0].config.frozen_arithmetic == 'fp32'
    for native, expected in ((True, 'bf16'), (False, 'fp32')):
        monkeypatch.setattr(model_module, 'native_bf16', lambda native=native: native)
        model, _, _ = load_checkpoint(checkpoint)
        assert model.config.frozen_arithmetic == 'bf16' and model.visual.precision == expected
    frames = torch.rand(2, 3, 32, 32, generator=torch.Generator().manual_seed(0))
    visual = model.visual
    emb, keys, out = visual.perceive(frames)
    coarse32, encoded32 = visual.embedding(frames), visual.encode(frames)
    visual.precision = 'bf16'
    emb16, keys16, out16 = visual.perceive(frames)
    assert out16.fine.dtype == torch.float32 and not torch.equal(out16.fine, out.fine)

    def relative_error(a, b):
        return ((a - b).norm() / b.norm()).item()
    # bfloat16 keeps 8 bits of mantissa (rounding ~0.4% per operation), so the error scales with the
    # maps' size: a few conv layers give ~1.5-2.5% (L2, relative) whatever the weights and frames; an
    # absolute bound would depend on how large the trained network's maps happen to be (up to ~5 here).
    assert relative_error(out16.fine, out.fine) < 0.05 and relative_error(emb16, emb) < 0.05
    encoded16 = visual.encode(frames)
    assert all(t.dtype == torch.float32 for t in encoded16)
    assert not torch.equal(encoded16[3], encoded32[3]) and relative_error(encoded16[3], encoded32[3]) < 0.05
    assert not torch.equal(visual.embedding(frames), coarse32)
    assert torch.allclose(visual.keys_of(encoded16), keys16, atol=1e-2)     # encoder then decoder: the same path
    with pytest.raises(ValueError, match='--perception-precision takes fp32, bf16 or auto'):
        TrainConfig(perception_precision='fp16')
    with pytest.raises(ValueError, match='--frozen-arithmetic is recorded from --perception-precision'):
        TrainConfig(model=dataclasses.replace(TrainConfig().model, frozen_arithmetic='bf16'))


def test_the_reach_agent_scores_pixels_without_keys_and_decides_as_with_them(reach_performer):
    """With the reach input the agent folds the pointer's query into the key layer (keyless_pointer): the
    same action and pointer logits up to rounding as an agent that makes every pixel's key, the same
    decisions, also when the dialogue outgrows the cache (the keys of earlier steps are then made)."""
    from dialfred_performer.agent import PerformerAgent

    checkpoint, _ = reach_performer
    keyless = PerformerAgent.from_checkpoint(checkpoint)
    keyed = PerformerAgent.from_checkpoint(checkpoint, pointer_mode='keys')
    assert keyless.state.pointer_mode == 'keyless' and keyed.state.pointer_mode == 'keys'

    def check(t, a, b):
        assert torch.allclose(a.action_logits, b.action_logits, atol=1e-5), t
        assert torch.allclose(a.pointer_logits, b.pointer_logits, atol=1e-4), t

    def at_cut():
        assert keyless.state.grids and all(g is None for g in keyless.state.grids)
    assert play_side_by_side(keyless, keyed, check, at_cut, keep_going=True) == 10          # the whole-episode steps were played too


def test_block_order_shows_every_item_once_with_each_batch_inside_its_block():
    from dialfred_performer.blocks import block_batches, block_of
    combos, tasks = 8, 7
    items = [t * combos + c for t in range(tasks) for c in range(combos) if (t, c) != (3, 5)]   # one item left out
    lengths = [3 + (i // combos) % 4 for i in items]
    batches, blocks = block_batches(items, lengths, combos, batch_size=4, seed=0, epoch=0, bucket=2, block_tasks=3)
    assert sorted(p for b in batches for p in b) == list(range(len(items)))
    assert [len(b.tasks) for b in blocks] == [3, 3, 1] and sorted(t for b in blocks for t in b.tasks) == list(range(tasks))
    for position, batch in enumerate(batches):
        block = blocks[block_of(blocks, position)]
        assert {items[p] // combos for p in batch} <= set(block.tasks), position
    assert blocks[0].first_batch == 0 and [block_of(blocks, b.first_batch) for b in blocks] == [0, 1, 2]
    again = block_batches(items, lengths, combos, 4, 0, 0, 2, 3)
    assert again == (batches, blocks) and block_batches(items, lengths, combos, 4, 0, 1, 2, 3) != again
    with pytest.raises(ValueError, match='block_tasks must be at least 1'):
        block_batches(items, lengths, combos, 4, 0, 0, 2, 0)
    # visits of 3 items: the epoch in 3 rounds, each task in one block a round, its items in none twice
    batches, blocks = block_batches(items, lengths, combos, 4, 0, 0, 2, 3, per_visit=3)
    assert sorted(p for b in batches for p in b) == list(range(len(items)))
    assert all(sum(t in b.tasks for b in blocks) == 3 for t in range(tasks))
    for position, batch in enumerate(batches):
        assert {items[p] // combos for p in batch} <= set(blocks[block_of(blocks, position)].tasks), position
    first_round = [b for b in blocks if b.first_batch < blocks[3].first_batch]      # 7 tasks in blocks of 3
    assert sorted(t for b in first_round for t in b.tasks) == list(range(tasks))



def test_blocks_of_one_batch_sorted_by_length_pad_as_little_as_buckets_and_show_every_item_once():
    """Blocks of 4 tasks x 2 items (one batch of 8 each): with task_bucket the round's tasks are sorted by
    length within groups of blocks, so a batch holds tasks of about one length; every item still shows once,
    two items of each task in each of its visits, the same plan for the same seed and epoch."""
    from dialfred_performer.blocks import block_batches, block_of
    combos, tasks = 8, 64
    steps = np.random.default_rng(5).integers(2, 40, tasks)
    items = [t * combos + c for t in range(tasks) for c in range(combos)]
    lengths = [int(steps[i // combos]) for i in items]

    def padding(plan):
        return sum(len(b) * max(lengths[p] for p in b) - sum(lengths[p] for p in b) for b in plan[0])

    plain = block_batches(items, lengths, combos, 8, 0, 0, 1, 4, per_visit=2)
    grouped = block_batches(items, lengths, combos, 8, 0, 0, 1, 4, per_visit=2, task_bucket=8)
    for batches, blocks in (plain, grouped):
        assert sorted(p for b in batches for p in b) == list(range(len(items)))
        assert all(len(b) == 8 for b in batches) and len(blocks) == len(batches) == tasks * combos // 8
        for position, batch in enumerate(batches):
            shown = [items[p] // combos for p in batch]
            assert set(shown) == set(blocks[block_of(blocks, position)].tasks)
            assert all(shown.count(t) == 2 for t in shown), position
    assert padding(grouped) * 3 < padding(plain)
    assert grouped == block_batches(items, lengths, combos, 8, 0, 0, 1, 4, per_visit=2, task_bucket=8)
    assert grouped != block_batches(items, lengths, combos, 8, 0, 1, 1, 4, per_visit=2, task_bucket=8)
    with pytest.raises(ValueError, match='task_bucket must be at least 1'):
        block_batches(items, lengths, combos, 8, 0, 0, 1, 4, task_bucket=0)


def test_the_frozen_network_on_channels_last_tensors_gives_the_same_output_up_to_rounding(reach_performer, prepared):
    from dialfred_performer.blocks import BlockFeatures
    from dialfred_performer.data import DemonstrationDataset
    from dialfred_performer.preprocess import frame_tensor
    checkpoint, _ = reach_performer
    model, vocab, _ = load_checkpoint(checkpoint)
    ds = DemonstrationDataset(prepared[0], vocab, 32, model.config.max_tokens, seed=0, grid_size=32)
    ids = BlockFeatures(model.visual, ds).frame_ids([0, 1])
    batch = frame_tensor(np.asarray(ds.demo.frames[ids]), ds.resolution)
    plain = model.visual.outputs(batch)
    last = model.visual.to_channels_last().outputs(batch)
    assert last.fine.is_contiguous(memory_format=torch.channels_last)
    for a, b in zip(plain, last):
        assert a.shape == b.shape and torch.allclose(a, b, atol=1e-4)


def test_perception_precision_auto_is_bf16_only_where_the_cpu_does_bfloat16(monkeypatch):
    from dialfred_performer import perception
    assert perception.PerceptionConfig(precision='fp32').arithmetic == 'fp32'
    assert perception.PerceptionConfig(precision='bf16').arithmetic == 'bf16'
    for native, expected in ((True, 'bf16'), (False, 'fp32')):
        monkeypatch.setattr(perception, 'native_bf16', lambda native=native: native)
        assert perception.PerceptionConfig(precision='auto').arithmetic == expected
    with pytest.raises(ValueError, match='fp32, bf16 or auto'):
        perception.PerceptionConfig(precision='fp16')

def test_a_block_s_gathered_features_give_the_numbers_of_perceiving_each_batch(reach_performer, prepared):
    """The frozen network run once on a block's frames, its output gathered per batch, gives the performer's
    outputs on frames perceived batch by batch; a frame outside the loaded block is refused."""
    from dialfred_performer.blocks import BlockFeatures
    from dialfred_performer.data import DemonstrationDataset, collate
    checkpoint, _ = reach_performer
    model, vocab, _ = load_checkpoint(checkpoint)
    model.eval()
    ds = DemonstrationDataset(prepared[0], vocab, 32, model.config.max_tokens, seed=0, grid_size=32)
    combos = len(ds.combinations)
    items = [0, combos + 3, 2 * combos + 1, 5]            # three tasks, two items of the first
    with_frames = collate([ds[i] for i in items])
    features = BlockFeatures(model.visual, ds, chunk=5)   # chunks that cut a task's frames
    features.load([0, 1, 2])
    ds.with_frames = False
    gathered = features.attach(collate([ds[i] for i in items]))
    assert 'frames' not in gathered and torch.equal(gathered['frame_ids'], with_frames['frame_ids'])
    assert features.frames_computed == len(features.ids) == sum(ds.steps_of(ds.task_indices[t]) for t in range(3))
    with torch.no_grad():
        a, b = model(with_frames), model(gathered)
    assert torch.allclose(a['action_logits'], b['action_logits'], atol=1e-5)
    assert torch.allclose(a['pointer_logits'], b['pointer_logits'], atol=1e-4)
    features.load([0, 1, 2])                               # the loaded block: nothing runs again
    assert features.frames_computed == len(features.ids)
    features.load([1])
    with pytest.raises(ValueError, match='outside the loaded block'):
        features.attach(collate([ds[0]]))


def test_a_block_run_resumed_inside_a_block_ends_with_the_weights_of_an_uninterrupted_one(prepared, tmp_path):
    from dialfred_performer.train import TrainConfig, Training, train
    folder, perception = prepared
    base = dict(demonstrations=str(folder), perception=str(perception / 'perception.pt'), block_tasks=3,
                model=PerformerConfig(resolution=32, d_model=32, heads=2, layers=1, ff=32, reach_input=True),
                max_updates=7, batch_size=4, bucket=2, val_fraction=0.3, validate_every=3, checkpoint_every=2,
                warmup_updates=1, log_every=1, threads=1, device='cpu', progress=False)
    whole = train(TrainConfig(out=str(tmp_path / 'whole'), **base))
    assert whole['finished'] and whole['updates'] == 7
    parts = TrainConfig(out=str(tmp_path / 'parts'), stop_after=4, **base)          # stops inside the second block
    assert not train(parts)['finished']
    assert train(dataclasses.replace(parts, resume=True, stop_after=0))['finished']
    a = load_checkpoint(tmp_path / 'whole' / 'last.pt')[0].state_dict()
    b = load_checkpoint(tmp_path / 'parts' / 'last.pt')[0].state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    rows = [json.loads(line) for line in (tmp_path / 'whole' / 'metrics.jsonl').read_text().splitlines()]
    assert [r['update'] for r in rows if r['kind'] == 'val'] == [3, 6, 7]         # along the way, and at the end
    # the network ran once per frame of each block, not once per item
    run = Training(TrainConfig(out=str(tmp_path / 'count'), **base), Ranks())
    items, batches, blocks = run.epoch_plan(0)
    ds = run.data.train
    shown = sum(ds.steps_of(ds.task_indices[items[p] // len(ds.combinations)]) for b in batches for p in b)
    for block in blocks:
        run.features.load(block.tasks)
    assert run.features.frames_computed * 4 < shown
    with pytest.raises(ValueError, match='--block-tasks .* needs --perception'):
        TrainConfig(demonstrations=str(folder), block_tasks=3)
    with pytest.raises(ValueError, match='--block-items needs --block-tasks'):
        TrainConfig(demonstrations=str(folder), block_items=2)


def test_perception_training_without_held_out_frames_says_so(prepared, tmp_path, capsys):
    folder, _ = prepared
    assert perception_main(['--demonstrations', str(folder), '--out', str(tmp_path / 'p'), '--frames', '16',
                            '--val-fraction', '0.001', '--no-progress', *TINY]) == 2    # no task hashes that low
    assert '0 held-out frames at --val-fraction 0.001' in capsys.readouterr().err


def test_the_reach_features_read_the_distance_from_the_agents_axis_at_the_dead_reckoned_pitch():
    """The simulator measures reach from the agent's vertical axis; the performer knows its pitch from
    its own looks (30 down at the start, 15 a look, held at the limits, where the simulator refuses)."""
    from dialfred_sim.protocol import ACTIONS
    from dialfred_performer.data import START
    from dialfred_performer.model import axis_factors, camera_pitches
    down, up, ahead = ACTIONS.index('LookDown'), ACTIONS.index('LookUp'), ACTIONS.index('MoveAhead')
    previous = torch.tensor([[START, down, down, down, ahead, up, up, up, up, up, up, up, up]])
    assert camera_pitches(previous).tolist() == [[30, 45, 60, 60, 60, 45, 30, 15, 0, -15, -30, -30, -30]]
    # A point on a pixel's ray at unit depth along the view axis, by hand: its distance from the axis
    # over its distance from the eye.
    t = math.tan(math.radians(45))
    c = (torch.arange(16) + 0.5) / 16 * 2 - 1
    u, v = (c * t)[None, :].expand(16, 16), (-c * t)[:, None].expand(16, 16)
    for pitch in (-30.0, 0.0, 30.0, 60.0):
        p = math.radians(pitch)
        forward = math.cos(p) + v * math.sin(p)
        expected = torch.sqrt(forward ** 2 + u ** 2) / torch.sqrt(1 + u ** 2 + v ** 2)
        assert torch.allclose(axis_factors(torch.tensor(pitch), 16 * 16), expected.flatten(), atol=1e-5)
    # A batch of pitches, each on its own row.
    batch = axis_factors(torch.tensor([[60.0, 0.0], [0.0, -30.0]]), 16 * 16)
    assert batch.shape == (2, 2, 256)
    assert torch.equal(batch[0, 1], batch[1, 0]) and torch.equal(batch[0, 0], axis_factors(torch.tensor(60.0), 256))
    # Looking down, the bottom row lies nearer the axis than the eye; looking level, the centre as near.
    assert float(axis_factors(torch.tensor(60.0), 16 * 16)[-1]) < 0.6
    assert float(axis_factors(torch.tensor(0.0), 2 * 2).max()) < 1.0
