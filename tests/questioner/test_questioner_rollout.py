"""In-process rollouts of a questioner with the frozen shipped performer (dialfred_questioner.rollout).

Claims: `begin` gives one chance, `anytime` with gap 1 a chance before every action; the decisions'
rewards add up to the paper's return (success - 0.01 x steps - 0.05 x questions - 0.1 x invalid);
the answers are the in-process oracle's (the node's rules), an invalid question is marked so; the same
seed gives the same episode.
"""

from __future__ import annotations

import pytest
import torch

from dialfred_performer.agent import PerformerAgent
from dialfred_performer.model import SHIPPED_CHECKPOINT
from dialfred_questioner.rl import Rewards
from dialfred_questioner.rollout import Timing, play_rollout
from dialfred_sim.protocol import Question
from dialfred_sim.env import DialfredEnv

torch.set_num_threads(1)


@pytest.fixture(scope='module')
def world():
    env = DialfredEnv(resolution=64, max_steps=30)
    yield env, PerformerAgent.from_checkpoint(SHIPPED_CHECKPOINT)
    env.close()


def ask_location(rgb, task, dialogue, step):
    return Question('location', task.object_nouns[0]), ('loc', step)


def ask_nonsense(rgb, task, dialogue, step):
    return Question('appearance', 'spaceship'), None


def paper_return(ep, rw=Rewards()):
    return (rw.success * ep.success + rw.step * ep.steps + rw.question * ep.questions
            + rw.invalid * ep.invalid_questions)


@pytest.mark.parametrize('task_id', ['valid_unseen/000054', 'valid_unseen/000000'])
def test_timings_rewards_and_determinism(world, task_id):
    env, performer = world
    begin = play_rollout(env, performer, ask_location, task_id, 0, Timing('begin'))
    assert len(begin.decisions) == 1 and begin.decisions[0].step == 0 and begin.questions == 1
    assert begin.dialogue[0].valid and begin.dialogue[0].answer
    assert sum(begin.rewards) == pytest.approx(paper_return(begin))
    every = play_rollout(env, performer, ask_location, task_id, 0, Timing('anytime', gap=1))
    assert [d.step for d in every.decisions] == list(range(every.steps))
    assert [d.record for d in every.decisions] == [('loc', s) for s in range(every.steps)]
    assert sum(every.rewards) == pytest.approx(paper_return(every))
    again = play_rollout(env, performer, ask_location, task_id, 0, Timing('anytime', gap=1))
    assert again.steps == every.steps and again.dialogue == every.dialogue and again.rewards == every.rewards


def test_an_invalid_question_costs_the_invalid_penalty(world):
    env, performer = world
    ep = play_rollout(env, performer, ask_nonsense, 'valid_unseen/000054', 0, Timing('begin'))
    assert ep.invalid_questions == 1 and not ep.dialogue[0].valid
    assert sum(ep.rewards) == pytest.approx(paper_return(ep))


def test_bad_timings_are_refused():
    with pytest.raises(ValueError, match='timing'):
        Timing('sometimes')
    with pytest.raises(ValueError, match='gap'):
        Timing('anytime', gap=0)
