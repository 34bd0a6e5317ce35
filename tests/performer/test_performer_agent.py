"""PerformerAgent (dialfred_performer.agent, no ROS) in the real simulator.

Claims: an (untrained) performer plays steps of a valid_unseen task at 64 px without error, from a
protocol.Observation or a bare frame; its pixels lie in the frame; its action
probabilities sum to 1 and are the distribution `act` chooses from; a QA heard changes its input.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from dialfred_performer.agent import PerformerAgent
from dialfred_performer.model import Performer, PerformerConfig
from dialfred_performer.preprocess import Vocabulary, type_of_question
from dialfred_sim.protocol import ACTIONS, QA, Observation, Question
from dialfred_sim.env import DialfredEnv

torch.set_num_threads(1)
RES = 64


def test_the_agent_plays_steps_of_a_real_task():
    env = DialfredEnv(resolution=RES)
    obs, _ = env.reset(options={'task_id': 'valid_unseen/000000'})
    task = env.task.public()
    vocab = Vocabulary.build([task.instruction, 'the key chain is in front of you'])
    torch.manual_seed(0)
    agent = PerformerAgent(Performer(PerformerConfig(resolution=RES, d_model=64, heads=4, layers=2, ff=128), len(vocab)),
                           vocab)
    agent.reset(task, seed=1)
    before = agent.language_input()
    agent.hear(QA(Question('location', 'key chain'), True, 'The key chain is in front of you.'))
    assert len(agent.language_input()) > len(before)
    for k in range(6):
        view = [obs['rgb'], Observation(rgb=obs['rgb'], depth=obs['depth'])][k % 2]
        p = agent.action_probabilities(view)
        assert p.shape == (len(ACTIONS),) and abs(p.sum() - 1) < 1e-5
        action, x, y = agent.act(view)
        assert action == ACTIONS[int(np.argmax(p))]
        assert (x, y) == (-1, -1) or (0 <= x < RES and 0 <= y < RES)
        obs, _, terminated, truncated, _ = env.step({'action': action, 'pixel': (x, y)})
        if terminated or truncated:
            break
    assert agent.step == k + 1
    env.close()


@pytest.mark.slow   # a benchmark script end to end; the incremental step equals the whole episode's: below
def test_the_decision_benchmark_prints_ms_per_step_at_steps_1_20_60():
    script = Path(__file__).resolve().parents[2] / 'benchmarks' / 'performer_decision.py'
    proc = subprocess.run([sys.executable, str(script), '--repeats', '1', '--last-step', '60'], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    report = json.loads(proc.stdout[proc.stdout.index('{'):])
    assert report['threads'] == 1
    for path in ('incremental', 'incremental_keys_every_step', 'whole_episode'):
        assert set(report[path]['ms_per_step_median']) == {'step_1', 'step_20', 'step_60'}


def _twin_agents(max_tokens: int = 256, stream: bool = False, fresh: bool = False):
    from types import SimpleNamespace as NS
    vocab = Vocabulary.build(['put the red apple in the fridge', 'the apple is to your left in the fridge .',
                              'you should turn around', 'it is red and made of plastic'])
    torch.manual_seed(3)
    model = Performer(PerformerConfig(resolution=RES, d_model=32, heads=2, layers=2, ff=64, max_tokens=max_tokens,
                                      stream_answers=stream, fresh_directions=fresh), len(vocab))
    task = NS(instruction='put the red apple in the fridge', object_nouns=['apple', 'fridge'])
    return PerformerAgent(model, vocab, incremental=True), PerformerAgent(model, vocab, incremental=False), task


def _play_twins(incremental, full, task, frames, qas_at):
    incremental.reset(task, 0)
    full.reset(task, 0)
    logits = []
    for t, frame in enumerate(frames):
        if t in qas_at:
            # the confusion questioner's look before a QA arrives must not be committed
            assert np.allclose(incremental.action_probabilities(frame), full.action_probabilities(frame), atol=1e-5)
            for qa in qas_at[t]:
                incremental.hear(qa)
                full.hear(qa)
        a = incremental._outputs(frame)
        b = full._outputs(frame)
        assert torch.allclose(a.action_logits, b.action_logits, atol=1e-4), t
        assert torch.allclose(a.pointer_logits, b.pointer_logits, atol=1e-4), t
        logits.append(a.action_logits)
        assert incremental.act(frame) == full.act(frame)
    return logits


def test_incremental_decisions_equal_reading_the_whole_episode_again():
    incremental, full, task = _twin_agents()
    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 256, (RES, RES, 3), dtype=np.uint8) for _ in range(14)]
    loc = QA(Question('location', 'apple'), True, 'The apple is to your left in the fridge.')
    app = QA(Question('appearance', 'apple'), True, 'It is red and made of plastic.')
    dirn = QA(Question('direction'), True, 'You should turn around.')
    _play_twins(incremental, full, task, frames, {0: [loc, app], 5: [dirn], 9: [loc]})
    assert incremental.state.cache is not None and incremental.state.cache[0].keys.shape[1] > 3 * 14


def test_when_qas_outgrow_max_tokens_the_agent_falls_back_to_the_whole_episode():
    incremental, full, task = _twin_agents(max_tokens=40)
    rng = np.random.default_rng(1)
    frames = [rng.integers(0, 256, (RES, RES, 3), dtype=np.uint8) for _ in range(8)]
    loc = QA(Question('location', 'apple'), True, 'The apple is to your left in the fridge.')
    _play_twins(incremental, full, task, frames, {0: [loc], 2: [loc], 4: [loc, loc]})
    assert incremental.state.cache is None     # the oldest QAs were dropped, positions moved


def test_a_pointer_mode_the_model_cannot_play_is_refused():
    incremental, _, _ = _twin_agents()
    assert incremental.state.pointer_mode == 'keys'          # a cnn encoder makes every frame's keys
    with pytest.raises(ValueError, match="pointer mode 'lazy'"):
        PerformerAgent(incremental.model, incremental.vocab, pointer_mode='lazy')


def _stream_qas():
    loc = QA(Question('location', 'apple'), True, 'The apple is to your left in the fridge.')
    ahead = QA(Question('location', 'apple'), True, 'The apple is in front of you in the fridge.')
    dirn = QA(Question('direction'), True, 'You should turn around.')
    left = QA(Question('direction'), True, 'You should turn left.')
    # repeats (step 3, 7), a newer answer superseding an older one (4, 6, 9), two answers at one step (9)
    return {0: [loc, dirn], 3: [dirn], 4: [left], 6: [ahead, dirn], 7: [dirn], 9: [loc, left, dirn]}


def test_an_answer_stream_decides_the_same_incrementally_and_over_the_whole_episode():
    """With the stream encoding (repeats add nothing, a newer answer hides the older one of its (type,
    noun), positions restart), the incremental step equals reading the whole episode again, and the
    cache is kept however long the stream grows (its positions never outgrow the table)."""
    incremental, full, task = _twin_agents(max_tokens=40, stream=True)
    rng = np.random.default_rng(2)
    frames = [rng.integers(0, 256, (RES, RES, 3), dtype=np.uint8) for _ in range(12)]
    _play_twins(incremental, full, task, frames, _stream_qas())
    lang = incremental.language_input()
    assert len(lang) > 40 and incremental.state.cache is not None
    assert max(lang.positions) < 40
    from dialfred_performer.preprocess import NEVER
    superseded = {(s, u) for s, u in zip(lang.steps, lang.until) if u != NEVER}
    assert superseded == {(0, 4), (0, 6), (4, 6), (6, 9), (9, 9)}    # (asked at, superseded at); repeats left out


def test_fresh_directions_are_heard_at_their_own_step_only_and_decide_the_same_incrementally():
    """fresh_directions: a direction answer is seen at the step it is heard at only (a repeat at a later step is
    heard again, one at the same step is not); the location's stream is as before; the incremental step still
    equals reading the whole episode again."""
    from dialfred_performer.preprocess import NEVER
    incremental, full, task = _twin_agents(max_tokens=40, stream=True, fresh=True)
    rng = np.random.default_rng(5)
    frames = [rng.integers(0, 256, (RES, RES, 3), dtype=np.uint8) for _ in range(12)]
    qas = _stream_qas()
    qas[9].append(qas[9][-1])                                        # asked twice at one step: heard once
    _play_twins(incremental, full, task, frames, qas)
    lang = incremental.language_input()
    direction = type_of_question()['direction']
    spans = sorted({(s, u) for t, s, u in zip(lang.types, lang.steps, lang.until) if t == direction})
    assert spans == [(0, 1), (3, 4), (4, 5), (6, 7), (7, 8), (9, 9), (9, 10)]   # 9: turn left, then around
    location = {(s, u) for t, s, u in zip(lang.types, lang.steps, lang.until) if t == type_of_question()['location']}
    assert location == {(0, 6), (6, 9), (9, NEVER)}
    with pytest.raises(ValueError, match='stream_answers'):
        PerformerConfig(fresh_directions=True)


def test_an_answer_stream_is_read_at_each_step_as_training_reads_the_episode():
    """The agent's step over an answer stream gives the logits of training's forward over the same episode
    (the batch path: data.collate's positions and until)."""
    from dialfred_performer.data import START, collate
    incremental, _, task = _twin_agents(stream=True)
    rng = np.random.default_rng(4)
    frames = [rng.integers(0, 256, (RES, RES, 3), dtype=np.uint8) for _ in range(11)]
    incremental.reset(task, 0)
    qas_at, logits, actions = _stream_qas(), [], []
    for t, frame in enumerate(frames):
        for qa in qas_at.get(t, []):
            incremental.hear(qa)
        logits.append(incremental._outputs(frame).action_logits)
        action, _, _ = incremental.act(frame)
        actions.append(ACTIONS.index(action))
    lang = incremental.language_input()
    model = incremental.model
    item = {'task_id': 't', 'actions': torch.tensor(actions), 'frame_ids': torch.arange(len(frames)),
            'previous_actions': torch.tensor([START, *actions[:-1]]), 'target_cells': torch.full((len(frames),), -1),
            'target_masks': torch.zeros(0, model.config.grid_size ** 2, dtype=torch.bool),
            'lang_ids': torch.tensor(lang.ids), 'lang_types': torch.tensor(lang.types),
            'lang_steps': torch.tensor(lang.steps), 'lang_positions': torch.tensor(lang.positions),
            'lang_until': torch.tensor(lang.until), 'action_valid': torch.ones(len(frames), dtype=torch.bool),
            'frames': torch.stack([model.frame_input(f)[0] for f in frames])}
    with torch.no_grad():
        out = model(collate([item]))['action_logits'][0]
    assert torch.allclose(out, torch.stack(logits), atol=1e-4)
