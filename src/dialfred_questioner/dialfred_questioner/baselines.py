"""Questioners that need no training, and how a questioner joins an agent (no ROS).

A questioner decides what to ask the oracle and when: `ask(observation, step)` is called before each of
the agent's actions (`step` = actions taken so far in the episode) and returns a `Question` or None;
the oracle's reply comes back through `hear(qa)`. The paper's baselines that need no model:

- `RandomQuestioner` ("random"): the paper's baseline 3, "Random QA": at the beginning of the task a
  question type is drawn, 25% each for location, appearance and direction and 25% for no question;
  for the drawn type it asks about every relevant object: a location or appearance question per
  object of the instruction, or one direction question. (Paper, Baselines, item 3.)
- `AllQuestioner` ("all"): at the beginning, a location and an appearance question about every object
  of the instruction, then one direction question. This is the "instruction + all QAs" setting of
  Table 3. The performer keeps the valid answers.
- `ModelConfusionQuestioner` ("confusion"): before any action about which the performer is unsure
  (its two most likely actions differ by less than epsilon = 0.5 in probability), one random
  question. This is the paper's "random MC" baseline; it needs a performer that exposes
  `action_probabilities(observation)`.

`with_questioner(agent, questioner)` makes any performer agent a `dialfred_sim.protocol.DialogueAgent`.
The learned questioner (LSTM seq2seq, actor-critic fine-tuning) is `policy.LearnedQuestioner`; every
questioner by name, these and the learned ones, comes from `questioners.make_questioner`.
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

from dialfred_sim.agents import public_view, task_nouns, task_view
from dialfred_sim.protocol import (QA, Agent, ConfusionSource, Continuing, Decision, Listener, heard_by,
                                  PerformerAware, Question, Questioner, every_question, is_privileged, names_object,
                                  question_types, top2_gap)


def random_question(rng: np.random.Generator, nouns: list[str]) -> Question:
    """A uniform question type; for location and appearance, a uniform noun of `nouns` (only
    direction questions when there is none)."""
    types = question_types() if nouns else tuple(t for t in question_types() if not names_object(t))
    qtype = types[int(rng.integers(len(types)))]
    return Question(qtype, nouns[int(rng.integers(len(nouns)))] if names_object(qtype) else '')


def random_qa_choices() -> tuple[Optional[str], ...]:
    """What RandomQuestioner draws at the beginning of a task, each as likely (1/4 with the paper's types);
    None = no question."""
    return (*question_types(), None)


def questions_of_type(question_type: Optional[str], nouns: list[str]) -> list[Question]:
    """Every question of `question_type` about a task whose instruction names `nouns`: one location or
    appearance question per noun (none without nouns), one direction question, or none for None."""
    if question_type is None:
        return []
    if not names_object(question_type):
        return [Question(question_type)]
    return [Question(question_type, n) for n in nouns]


class AtTheStart:
    """A questioner that asks its queue of questions (made by `reset`) before the first action, one a
    call, and nothing later."""

    _queue: list[Question]

    def ask(self, observation: Any, step: int) -> Optional[Question]:
        if step > 0 or not self._queue:
            return None
        return self._queue.pop(0)

    def hear(self, qa: QA) -> None:
        pass


class RandomQuestioner(AtTheStart):
    """The paper's "Random QA": at the beginning, a type drawn from location / appearance / direction /
    no question (1/4 each), then every question of that type (`questions_of_type`); nothing later.
    The draw comes from the episode's seed, in a stream apart from the performer's."""

    name = 'random'

    def __init__(self):
        self.drawn: Optional[str] = None       # the type drawn for the episode (None: no question)
        self._queue: list[Question] = []

    def reset(self, task: Any, seed: int) -> None:
        # A stream apart from the performer's, which is seeded with `seed` itself.
        rng = np.random.default_rng([seed, 1])
        choices = random_qa_choices()
        self.drawn = choices[int(rng.integers(len(choices)))]
        self._queue = questions_of_type(self.drawn, task_nouns(task))


class AllQuestioner(AtTheStart):
    """At the beginning: location and appearance of every object of the instruction, then direction."""

    name = 'all'

    def __init__(self):
        self._queue: list[Question] = []

    def reset(self, task: Any, seed: int) -> None:
        self._queue = every_question(task_nouns(task))


class ModelConfusionQuestioner:
    """Asks when the performer is unsure: before an action whose two most likely choices differ by less
    than `epsilon` in probability (the paper's model-confusion criterion, epsilon = 0.5 there), one
    random question as `random_question` draws it. At most one question per action.

    The performer must expose `action_probabilities(observation)`: its probabilities over
    `dialfred_sim.agents.ACTIONS` for the action it is about to choose."""

    name = 'confusion'

    def __init__(self, epsilon: float = 0.5):
        if not 0.0 <= epsilon <= 1.0:
            raise ValueError(f'epsilon must be in [0, 1], got {epsilon}')
        self.epsilon = epsilon
        self.performer: Optional[Agent] = None
        self._rng = np.random.default_rng(0)
        self._nouns: list[str] = []
        self._asked_at = -1

    needs_gap = True

    def attach(self, performer: Agent) -> None:
        if not isinstance(performer, ConfusionSource):
            raise ValueError(f'the confusion questioner needs a performer with action_probabilities(); '
                             f'{performer.name!r} has none')
        self.performer = performer

    def reset(self, task: Any, seed: int) -> None:
        self._rng = np.random.default_rng([seed, 2])
        self._nouns = task_nouns(task)
        self._asked_at = -1

    def confused(self, observation: Any) -> bool:
        return top2_gap(self.performer.action_probabilities(observation)) < self.epsilon

    def ask(self, observation: Any, step: int) -> Optional[Question]:
        if self.performer is None:
            raise RuntimeError('attach() the performer before asking')
        if self._asked_at == step:
            return None
        return self.ask_given_gap(observation, step, top2_gap(self.performer.action_probabilities(observation)))

    def ask_given_gap(self, observation: Any, step: int, gap: Optional[float]) -> Optional[Question]:
        """The same decision from the performer's top-2 gap as the performer reports it (the
        questioner node gets it in the /questioner/ask request instead of calling the performer)."""
        if gap is None:
            raise ValueError('the confusion questioner needs the performer\'s top-2 gap')
        if self._asked_at == step or gap >= self.epsilon:
            return None
        self._asked_at = step
        return random_question(self._rng, self._nouns)

    def hear(self, qa: QA) -> None:
        pass


class ScheduleQuestioner:
    """Before action 0 and every `gap`-th action after it: every question of `types` (one per noun for a
    type that names an object, else one), one a call, in the registry's order; nothing in between.
    Named `every:TYPES` (gap 1) or `every-N:TYPES` (`schedule_questioner`)."""

    def __init__(self, types: tuple[str, ...], gap: int = 1):
        unknown = [t for t in types if t not in question_types()]
        if not types or unknown:
            raise ValueError(f'a schedule asks some of the question types {question_types()}, got {types}')
        if gap < 1:
            raise ValueError(f'a schedule asks every N >= 1 actions, got {gap}')
        self.types, self.gap = tuple(t for t in question_types() if t in types), gap
        self.name = f'every{"" if gap == 1 else f"-{gap}"}:{"+".join(self.types)}'
        self._nouns: list[str] = []
        self._queue: list[Question] = []
        self._filled_at = -1

    def reset(self, task: Any, seed: int) -> None:
        self._nouns = task_nouns(task)
        self._queue, self._filled_at = [], -1

    def ask(self, observation: Any, step: int) -> Optional[Question]:
        if step % self.gap or (step == self._filled_at and not self._queue):
            return None
        if step != self._filled_at:
            self._filled_at = step
            self._queue = [q for t in self.types for q in questions_of_type(t, self._nouns)]
        return self._queue.pop(0) if self._queue else None

    def hear(self, qa: QA) -> None:
        pass


SCHEDULE_PREFIX = 'every'


def schedule_questioner(name: str) -> Optional[ScheduleQuestioner]:
    """The ScheduleQuestioner a name like 'every:direction', 'every-2:location+appearance' or 'every:all'
    means; None for a name of another kind; ValueError for a malformed one."""
    head, sep, tail = name.partition(':')
    if not sep or not (head == SCHEDULE_PREFIX or head.startswith(SCHEDULE_PREFIX + '-')):
        return None
    gap_text = head[len(SCHEDULE_PREFIX) + 1:] or '1'
    if not gap_text.isdigit():
        raise ValueError(f'{name!r}: a schedule is every:TYPES or every-N:TYPES with N a whole number')
    types = question_types() if tail == 'all' else tuple(t for t in tail.split('+') if t)
    return ScheduleQuestioner(types, int(gap_text))


# The questioners of this module by name (questioners.make_questioner makes them).
QUESTIONERS = {'random': RandomQuestioner, 'all': AllQuestioner, 'confusion': ModelConfusionQuestioner}


class QuestioningAgent:
    """A performer agent with a questioner: asks what the questioner asks, hands every QA to the
    performer (if it listens: a `hear` method) and keeps the episode's dialogue in `dialogue`."""

    def __init__(self, performer: Agent, questioner: Questioner):
        self.performer, self.questioner = performer, questioner
        if isinstance(questioner, PerformerAware):     # a questioner that watches the performer (model confusion)
            questioner.attach(performer)
        self.name = f'{performer.name}+{questioner.name}'
        self.privileged = is_privileged(performer)
        self.dialogue: list[QA] = []
        self._steps = 0

    def reset(self, task: Any, seed: int) -> None:
        self.performer.reset(task_view(self.performer, task), seed)
        self.reset_questioner(task, seed)
        self.dialogue = []
        self._steps = 0

    def carry_on(self, task: Any, seed: int) -> None:
        """The next task of a chained episode: a performer that is protocol.Continuing carries on, any
        other is reset; the questioner always starts the task anew."""
        if isinstance(self.performer, Continuing):
            self.performer.carry_on(task_view(self.performer, task), seed)
        else:
            self.performer.reset(task_view(self.performer, task), seed)
        self.reset_questioner(task, seed)
        self.dialogue = []
        self._steps = 0

    def reset_questioner(self, task: Any, seed: int) -> None:
        """The questioner's part of `reset` (dialfred_bringup.silent runs the questioner alone so)."""
        self.questioner.reset(public_view(task), seed)     # a questioner is never privileged

    def ask(self, observation: Any) -> Optional[Question]:
        return self.questioner.ask(observation, self._steps)

    def hear(self, qa: QA) -> None:
        self.dialogue.append(qa)
        self.questioner.hear(qa)
        if isinstance(self.performer, Listener):
            self.performer.hear(qa)

    def understood(self, qa: QA) -> str:
        """What the performer took from `qa` (protocol.heard_by), '' if it reads no fields."""
        return heard_by(self.performer, qa)

    def act(self, observation: Any) -> Decision:
        self._steps += 1
        return self.performer.act(observation)


def with_questioner(agent: Agent, questioner: Optional[Questioner]) -> Agent:
    """`agent` asking what `questioner` asks (the agent itself when there is no questioner)."""
    return agent if questioner is None else QuestioningAgent(agent, questioner)
