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
from dialfred_performer.preprocess import Vocabulary
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


def _twin_agents(max_tokens: int = 256):
    from types import SimpleNamespace as NS
    vocab = Vocabulary.build(['put the red apple in the fridge', 'the apple is to your left in the fridge .',
                              'you should turn around', 'it is red and made of plastic'])
    torch.manual_seed(3)
    model = Performer(PerformerConfig(resolution=RES, d_model=32, heads=2, layers=2, ff=64, max_tokens=max_tokens),
                      len(vocab))
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
