"""The swap control: every answer replaced by the oracle's answer to the same question in another task.

An answer is worth something to a performer only if the performer reads it. With the answers of
another task, a performer that reads them is misled and does worse than with its own; one that plays
the same either way has learnt nothing from what it was told, whatever the world.

The other task (the partner) is fixed by the split, never by the run: task i of the n tasks is paired
with task (i + n // 2) mod n, or the first after it (wrapping round) that comes from another episode
and names at least one object. The question is the same type, about the partner's object at the same
place in its instruction's nouns (the asked noun's place among the asking task's nouns; the first if
it is not among them), answered in the partner's start state, where All QAs asks. The partner's
answers come from an env of the swap's own (one reset per partner, kept), by the oracle's own rules
(`local.answer_now`), so they are the answers that task's agent would have got.

A question that is invalid on its own task stays invalid; an invalid answer of the partner becomes a
valid "I don't know." (the question itself was fine).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Optional, Sequence

from dialfred_sim.agents import task_nouns
from dialfred_sim.env import DialfredEnv
from dialfred_sim.protocol import names_object

from .answers import WITHHELD, Answer, parse_question_type
from .in_process import answer_now


class AnswerSwap:
    """The partner's answers for the tasks of one split. `tasks`: every task of the split in order (a
    run of its first N tasks pairs them as a whole run does); `resolution`: the camera the runs play at
    (an appearance answer reads the frame when the object shows in it)."""

    def __init__(self, tasks: Sequence[Any], resolution: int, goal_rule: Optional[str] = None):
        if not tasks:
            raise ValueError('the swap needs the tasks of a split')
        self.tasks = list(tasks)
        self.index = {t.task_id: k for k, t in enumerate(self.tasks)}
        self.resolution, self.goal_rule = int(resolution), goal_rule
        self._env = None
        self._answers: dict[tuple, Answer] = {}

    def partner(self, task_id: str) -> Any:
        """The task whose answers `task_id` gets (KeyError for a task not of this split)."""
        i, n = self.index[task_id], len(self.tasks)
        own = self.tasks[i]
        for step in range(n):
            other = self.tasks[(i + n // 2 + step) % n]
            if other.task_id != own.task_id and _episode_of(other) != _episode_of(own) and task_nouns(other):
                return other
        raise ValueError(f'no task of another episode naming an object to pair {task_id} with')

    def apply(self, ans: Answer, task_id: str, object_noun: str) -> Answer:
        """`ans` (the oracle's answer to a question about task `task_id`) replaced by the partner's answer
        to the same question; an invalid `ans` as it is."""
        if not ans.valid:
            return ans
        qtype = parse_question_type(ans.question_type)
        task = self.tasks[self.index[task_id]]
        partner = self.partner(task_id)
        noun = ''
        if names_object(qtype):
            own, theirs = task_nouns(task), task_nouns(partner)
            place = own.index(object_noun) if object_noun in own else 0
            noun = theirs[min(place, len(theirs) - 1)]
        theirs_ans = self._partner_answer(partner, qtype, noun)
        text = theirs_ans.text if theirs_ans.valid else WITHHELD
        return replace(ans, text=text, reason='')

    def _partner_answer(self, partner: Any, qtype: str, noun: str) -> Answer:
        key = (partner.task_id, qtype, noun)
        if key not in self._answers:
            env = self._reset_to(partner)
            self._answers[key] = answer_now(env, qtype, noun)
        return self._answers[key]

    def _reset_to(self, task: Any):
        if self._env is None:
            extra = {'goal_rule': self.goal_rule} if self.goal_rule else {}
            self._env = DialfredEnv(resolution=self.resolution, **extra)
        if self._env.task is None or self._env.task.task_id != task.task_id:
            self._env.reset(options={'task': task})
        return self._env

    def close(self) -> None:
        if self._env is not None:
            self._env.close()
            self._env = None


def _episode_of(task: Any) -> Any:
    episode = getattr(task, 'episode', None)
    return getattr(episode, 'episode_id', None) or task.task_id
