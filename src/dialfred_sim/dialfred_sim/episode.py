"""The one episode loop: reset -> (ask -> hear)* -> act -> step, until the simulator ends the episode.

`play(agent, ...)` is a generator. It never talks to a simulator or an oracle itself: it yields what it
needs (`RESET`, `Ask(question)`, `Step(action, x, y)`) and is sent the reply (a `SimReply` for a reset or
a step, a `protocol.QA` for a question, or `Failed(error)` when a request got no usable reply). It
returns the episode's `EpisodeState` (how it ended, with its counts and dialogue). Whoever drives it
chooses the transport:

- `run(episode, serve)` drives it synchronously: `serve(request) -> reply`. `dialfred_oracle.in_process.EnvServer`
  serves requests from a `DialfredEnv` in this process and the oracle's rules: local evaluation workers
  and the RL rollouts. The performer node serves them with ROS service calls.
- the evaluation's `SimWorker` sends each request as an asynchronous ROS call and resumes the generator
  when the reply arrives (many episodes in flight from one executor).

The rules live here and nowhere else: the agent is reset after the simulator, with the task it is told
(a later task of a chained episode: an agent that is `protocol.Continuing` carries on instead);
before every action a dialogue agent may ask until it returns None, at most `max_questions` in a row
(the next one ends the episode with an error); an action the simulator refuses, or a request with no
reply, ends it with an error; otherwise it ends when the simulator says so (success, Stop, too many
failed actions, the step limit). Observers (`EpisodeObserver`) see each reset, QA, action and step, in
order: recorders, the live view, ROS feedback and the RL rewards hang there.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Generator, Iterable, Optional, Union

from .metrics import end_reason
from .protocol import MAX_QUESTIONS, QA, Continuing, Question


@dataclass(frozen=True)
class Reset:
    """Start the task's episode (the driver knows which task)."""


RESET = Reset()


@dataclass(frozen=True)
class Ask:
    """Ask the oracle `question` before action number `step` + 1."""

    question: Question
    step: int


@dataclass(frozen=True)
class Step:
    """Take `action` at pixel (x, y) (-1, -1 for actions without a target)."""

    action: str
    x: int
    y: int


@dataclass
class SimReply:
    """The simulator's reply to a reset or a step (what /sim/reset and /sim/step return).

    `observation` is what the agent is given (an observation message or the env's dict); `task`, after a
    reset, is the public view of the task the simulator reports; `ok` False: the request was refused
    (`error`), nothing changed."""

    observation: Any = None
    step_count: int = 0
    failed_actions: int = 0
    last_action_success: bool = True
    last_action_error: str = ''
    goal_conditions_met: int = 0
    goal_conditions_total: int = 0
    success: bool = False
    terminated: bool = False
    truncated: bool = False
    task: Any = None
    ok: bool = True
    error: str = ''
    raw: Any = None          # the transport's own reply (a service response), for observers


@dataclass(frozen=True)
class Failed:
    """A request that got no usable reply."""

    error: str


Request = Union[Reset, Ask, Step]
Reply = Union[SimReply, QA, Failed]


@dataclass
class EpisodeState:
    """An episode as it goes, and how it ended (`end_reason` is '' until it has)."""

    steps: int = 0
    failed_actions: int = 0
    goal_conditions_met: int = 0
    goal_conditions_total: int = 0
    questions: int = 0
    invalid_questions: int = 0
    dialogue: list[QA] = field(default_factory=list)
    asked_at: list[int] = field(default_factory=list)     # per QA of `dialogue`: the actions taken before it
    actions: list[tuple[str, int, int]] = field(default_factory=list)   # every action sent, with its pixel
    last_action: str = ''
    last_error: str = ''
    success: bool = False
    end_reason: str = ''
    error: str = ''


class EpisodeObserver:
    """Sees an episode as it is played; every method is optional. The hooks are named on_* so that one
    object can be an agent (reset / ask / hear / act) and an observer at once."""

    def on_started(self, state: EpisodeState, reply: SimReply) -> None:
        """The simulator started the episode (before the agent is told the task)."""

    def on_question(self, state: EpisodeState, qa: QA, step: int) -> None:
        """The oracle answered (before the agent hears it); `step`: actions taken so far."""

    def on_action(self, state: EpisodeState, action: str, x: int, y: int) -> None:
        """The agent decided (before the simulator is asked to act)."""

    def on_stepped(self, state: EpisodeState, reply: SimReply, action: str, x: int, y: int) -> None:
        """The simulator took the action (`reply.ok`), before the episode's end is checked."""

    def on_ended(self, state: EpisodeState) -> None:
        """The episode ended: `state.end_reason` says how."""


def play(agent, *, seed: int, told: Any = None, asks: bool = True, max_questions: int = MAX_QUESTIONS,
         asker: str = 'agent', observers: Iterable[EpisodeObserver] = (), carry_on: bool = False
         ) -> Generator[Request, Reply, EpisodeState]:
    """One episode of `agent` (protocol.Agent; with `asks`, a protocol.DialogueAgent): yields requests,
    is sent their replies, returns the final EpisodeState.

    seed: the agent's episode seed. told: the task the agent is told (default: the reset reply's
    `task`). asker: who is named when too many questions end the episode ('agent', 'questioner').
    carry_on: the task follows another of a chained episode in the same world; an agent that is
    protocol.Continuing is told it with `carry_on(task, seed)` instead of `reset`."""
    observers = list(observers)
    state = EpisodeState()

    def end(reason: str, reply: Optional[SimReply] = None, success: bool = False, error: str = '') -> EpisodeState:
        state.end_reason, state.success = reason, bool(success)
        state.steps = int(reply.step_count) if reply is not None else 0
        state.failed_actions = int(reply.failed_actions) if reply is not None else 0
        state.error = '' if success else (error or state.last_error)
        for o in observers:
            o.on_ended(state)
        return state

    reply = yield RESET
    if isinstance(reply, Failed) or not reply.ok:
        return end('error', error=reply.error)
    state.goal_conditions_total = int(reply.goal_conditions_total)
    for o in observers:
        o.on_started(state, reply)
    task = told if told is not None else reply.task
    if carry_on and isinstance(agent, Continuing):
        agent.carry_on(task, seed)
    else:
        agent.reset(task, seed)
    current = reply
    while True:
        in_a_row = 0
        while asks:
            question = agent.ask(current.observation)
            if question is None:
                break
            if in_a_row >= max_questions:
                return end('error', current, error=f'the {asker} asked more than {max_questions} questions without acting')
            in_a_row += 1
            qa = yield Ask(question, int(current.step_count))
            if isinstance(qa, Failed):
                return end('error', error=qa.error)
            state.questions += 1
            state.invalid_questions += not qa.valid
            state.dialogue.append(qa)
            state.asked_at.append(int(current.step_count))
            for o in observers:
                o.on_question(state, qa, int(current.step_count))
            agent.hear(qa)
        name, x, y = agent.act(current.observation)
        x, y = int(x), int(y)
        state.last_action = name
        state.actions.append((name, x, y))
        for o in observers:
            o.on_action(state, name, x, y)
        reply = yield Step(name, x, y)
        if isinstance(reply, Failed):
            return end('error', error=reply.error)
        if not reply.ok:
            return end('error', reply, error=reply.error)
        state.goal_conditions_met = int(reply.goal_conditions_met)
        state.goal_conditions_total = int(reply.goal_conditions_total)
        state.steps, state.failed_actions = int(reply.step_count), int(reply.failed_actions)
        for o in observers:
            o.on_stepped(state, reply, name, x, y)
        if not reply.last_action_success:
            state.last_error = reply.last_action_error
        if reply.terminated or reply.truncated:
            return end(end_reason(bool(reply.success), name, int(reply.failed_actions), bool(reply.truncated)),
                       reply, success=bool(reply.success))
        current = reply


def run(episode: Generator[Request, Reply, EpisodeState], serve: Callable[[Request], Reply]) -> EpisodeState:
    """Drive `episode` to its end, each request answered by `serve(request)`."""
    try:
        request = next(episode)
        while True:
            request = episode.send(serve(request))
    except StopIteration as stop:
        return stop.value
