"""The questioners that need no training and how a questioner joins an agent (no ROS).

Claims (the paper's baselines): the random questioner ("Random QA") draws at the beginning of a task
location, appearance, direction or no question with 25% each and asks every question of the drawn
type (one per object of the instruction, or one direction question); the all-questions questioner asks the
location and appearance of every object of the instruction and then for directions; the agent hands
every answer to its performer and keeps the dialogue.
"""

from __future__ import annotations

from collections import Counter
from types import SimpleNamespace

import numpy as np
import pytest

from dialfred_questioner.baselines import AllQuestioner, QuestioningAgent, RandomQuestioner, task_nouns, with_questioner
from dialfred_questioner.questioners import make_questioner
from dialfred_sim.agents import ExpertAgent
from dialfred_sim.protocol import QA, PAPER_QUESTION_TYPES, DialogueAgent, Question
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


def test_the_random_questioner_asks_only_at_the_beginning_every_question_of_the_drawn_type():
    for seed in range(40):
        questioner = RandomQuestioner()
        asked = questions_of(questioner, task(), seed=seed)
        assert all(step == 0 for step, _ in asked)
        expected = {'location': [Question('location', 'fridge'), Question('location', 'apple')],
                    'appearance': [Question('appearance', 'fridge'), Question('appearance', 'apple')],
                    'direction': [Question('direction', '')], None: []}[questioner.drawn]
        assert [q for _, q in asked] == expected


def asked_type(t, seed):
    """The type of the questions the random questioner asks in an episode (None: it asks nothing)."""
    asked = {q.question_type for _, q in questions_of(RandomQuestioner(), t, seed=seed)}
    assert len(asked) <= 1
    return asked.pop() if asked else None


def test_the_random_questioner_draws_each_type_and_no_question_a_quarter_of_the_time_per_seed():
    t = task(('fridge', 'apple'))
    drawn = [asked_type(t, s) for s in range(4000)]
    shares = Counter(drawn)
    assert set(shares) == {*PAPER_QUESTION_TYPES, None}
    assert all(abs(shares[k] / 4000 - 0.25) < 0.03 for k in shares), shares
    assert drawn[:50] == [asked_type(t, s) for s in range(50)]          # the same seed, the same draw


def test_a_drawn_location_type_asks_where_every_noun_of_the_instruction_is():
    t = task(('fridge', 'apple', 'apple', 'knife'))
    seed = next(s for s in range(100) if asked_type(t, s) == 'location')
    assert [q for _, q in questions_of(RandomQuestioner(), t, seed=seed)] == [
        Question('location', 'fridge'), Question('location', 'apple'), Question('location', 'knife')]


def test_without_an_object_in_the_instruction_only_a_drawn_direction_asks_anything():
    for seed in range(20):
        questioner = RandomQuestioner()
        asked = questions_of(questioner, task(()), seed=seed)
        assert asked == ([(0, Question('direction', ''))] if questioner.drawn == 'direction' else [])


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
        asked = questions_of(RandomQuestioner(), t, seed=k, steps=2)
        assert all(step == 0 for step, _ in asked)
        assert all(q.object_noun in t.object_nouns or q.question_type == 'direction' for _, q in asked)


class Performer(ExpertAgent):
    """An expert whose confidence the test sets."""

    def __init__(self, probabilities):
        super().__init__(128)
        self.probabilities = probabilities

    def action_probabilities(self, observation):
        return self.probabilities


def test_the_confusion_questioner_asks_once_before_each_action_the_performer_is_unsure_of():
    from dialfred_questioner.baselines import ModelConfusionQuestioner
    unsure = np.array([0.4, 0.3] + [0.3 / 11] * 11)          # top two 0.1 apart: confused at epsilon 0.5
    sure = np.array([0.9, 0.05] + [0.05 / 11] * 11)
    performer = Performer(unsure)
    agent = with_questioner(performer, ModelConfusionQuestioner())
    assert agent.name == 'expert+confusion'
    agent.reset(task(), seed=5)
    q = agent.ask(None)
    assert q is not None and (q.object_noun in ('fridge', 'apple') or q.question_type == 'direction')
    agent.hear(QA(q, True, 'said'))
    assert agent.ask(None) is None                           # one question per action
    agent.act(None)
    performer.probabilities = sure
    assert agent.ask(None) is None                           # sure: no question
    agent.act(None)
    performer.probabilities = unsure
    assert agent.ask(None) is not None
    # Seeded: the same episode seed gives the same questions.
    def first_question(seed):
        a = with_questioner(Performer(unsure), ModelConfusionQuestioner())
        a.reset(task(), seed)
        return a.ask(None)
    assert [first_question(s) for s in range(20)] == [first_question(s) for s in range(20)]
    assert len({first_question(s) for s in range(40)}) > 2


def test_the_confusion_questioner_needs_a_performer_that_shows_its_probabilities():
    from dialfred_questioner.baselines import ModelConfusionQuestioner
    with pytest.raises(ValueError, match="needs a performer with action_probabilities"):
        with_questioner(ExpertAgent(), ModelConfusionQuestioner())
    with pytest.raises(ValueError, match='epsilon'):
        ModelConfusionQuestioner(epsilon=1.5)
    from dialfred_sim.agents import RandomAgent
    uniform = RandomAgent().action_probabilities(None)
    assert uniform.shape == (13,) and np.isclose(uniform.sum(), 1.0)   # the random agent is always unsure


def _asked_at(questioner, task, steps):
    questioner.reset(task, 0)
    out = []
    for step in range(steps):
        now = []
        while (q := questioner.ask(None, step)) is not None:
            now.append(q)
            assert len(now) < 20
        out.append(now)
    return out


def test_a_schedule_asks_its_types_before_every_nth_action_and_nothing_between():
    task = SimpleNamespace(instruction='Put the apple in the fridge.', object_nouns=('apple', 'fridge'))
    every = _asked_at(make_questioner('every:direction'), task, 4)
    assert every == [[Question('direction')]] * 4
    second = _asked_at(make_questioner('every-2:direction+location'), task, 5)
    assert second[1] == second[3] == []
    assert second[0] == second[2] == second[4] == [Question('location', 'apple'), Question('location', 'fridge'),
                                                   Question('direction')]
    everything = make_questioner('every-3:all')
    assert everything.name == 'every-3:location+appearance+direction'
    assert len(_asked_at(everything, task, 1)[0]) == 5


@pytest.mark.parametrize('name, said', [('every:colour', 'some of the question types'),
                                        ('every-x:direction', 'whole number'), ('every-0:direction', 'N >= 1'),
                                        ('every:', 'some of the question types')])
def test_a_malformed_schedule_is_refused_with_what_it_should_be(name, said):
    with pytest.raises(ValueError, match=said):
        make_questioner(name)
