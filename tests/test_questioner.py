"""The questioners that need no training and how a questioner joins an agent (no ROS).

Claims (the paper's baselines): the random questioner asks one question at the beginning of a task,
of a uniformly drawn type, about an object of the instruction; the all-questions questioner asks the
location and appearance of every object of the instruction and then for directions; the agent hands
every answer to its performer and keeps the dialogue.
"""

from __future__ import annotations

from collections import Counter
from types import SimpleNamespace

import pytest

from dialfred_questioner.baselines import (AllQuestioner, QuestioningAgent, RandomQuestioner, make_questioner,
                                           task_nouns, with_questioner)
from dialfred_sim.agents import QA, QUESTION_TYPES, DialogueAgent, ExpertAgent, Question
from dialfred_sim.tasks import ExpertAction, load_split


def task(nouns=('fridge', 'apple', 'apple'), actions=(ExpertAction('MoveAhead'),)):
    return SimpleNamespace(object_nouns=list(nouns), expert_actions=list(actions), resolution=128)


def questions_of(questioner, t, seed=0, steps=3):
    questioner.reset(t, seed)
    asked = []
    for step in range(steps):
        while (q := questioner.ask(None, step)) is not None:
            asked.append((step, q))
            questioner.hear(QA(q, True, 'an answer'))
    return asked


def test_the_random_questioner_asks_one_question_at_the_beginning_only():
    asked = questions_of(RandomQuestioner(), task(), seed=3)
    assert len(asked) == 1 and asked[0][0] == 0
    q = asked[0][1]
    assert q.question_type in QUESTION_TYPES
    assert q.object_noun == '' if q.question_type == 'direction' else q.object_noun in ('fridge', 'apple')


def test_the_random_questioner_draws_types_and_nouns_uniformly_and_repeats_itself_per_seed():
    t = task(('fridge', 'apple'))
    drawn = [questions_of(RandomQuestioner(), t, seed=s)[0][1] for s in range(3000)]
    types = Counter(q.question_type for q in drawn)
    assert all(abs(types[k] / 3000 - 1 / 3) < 0.04 for k in QUESTION_TYPES), types
    nouns = Counter(q.object_noun for q in drawn if q.question_type != 'direction')
    assert abs(nouns['fridge'] / sum(nouns.values()) - 0.5) < 0.05, nouns
    assert drawn[:50] == [questions_of(RandomQuestioner(), t, seed=s)[0][1] for s in range(50)]


def test_without_an_object_in_the_instruction_only_directions_are_asked():
    assert questions_of(RandomQuestioner(), task(()), seed=1) == [(0, Question('direction', ''))]


def test_the_all_questions_questioner_asks_about_every_object_then_for_directions():
    asked = [q for _, q in questions_of(AllQuestioner(), task())]
    assert asked == [Question('location', 'fridge'), Question('appearance', 'fridge'),
                     Question('location', 'apple'), Question('appearance', 'apple'), Question('direction', '')]
    assert task_nouns(task()) == ['fridge', 'apple']


def test_a_questioning_agent_hands_every_answer_to_a_performer_that_listens():
    class ListeningPerformer(ExpertAgent):
        def __init__(self):
            super().__init__(128)
            self.heard = []

        def hear(self, qa):
            self.heard.append(qa)

    performer = ListeningPerformer()
    agent = with_questioner(performer, AllQuestioner())
    assert isinstance(agent, DialogueAgent) and agent.name == 'expert+all'
    agent.reset(task(('apple',)), seed=0)
    replies = []
    while (q := agent.ask(None)) is not None:
        replies.append(QA(q, q.question_type != 'appearance', 'said', '' if q.question_type != 'appearance' else 'no'))
        agent.hear(replies[-1])
    assert performer.heard == agent.dialogue == replies and len(replies) == 3
    assert agent.act(None) == ('MoveAhead', -1, -1)
    assert agent.ask(None) is None                      # after the first action: no more questions
    agent.reset(task(('apple',)), seed=0)               # a new episode starts a new dialogue
    assert agent.dialogue == [] and agent.ask(None) == Question('location', 'apple')


def test_no_questioner_leaves_the_agent_as_it_is_and_an_unknown_one_is_named():
    expert = ExpertAgent()
    assert with_questioner(expert, None) is expert and not isinstance(expert, DialogueAgent)
    with pytest.raises(ValueError, match="unknown questioner 'lstm'; known: random, all"):
        make_questioner('lstm')
    assert isinstance(QuestioningAgent(expert, make_questioner('random')), DialogueAgent)


def test_the_random_questioner_asks_about_the_shipped_tasks_nouns():
    tasks = load_split('valid_unseen')[:40]
    for k, t in enumerate(tasks):
        (step, q), = questions_of(RandomQuestioner(), t, seed=k, steps=2)
        assert step == 0 and (q.object_noun in t.object_nouns or q.question_type == 'direction')
