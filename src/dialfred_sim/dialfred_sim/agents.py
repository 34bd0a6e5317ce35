"""Agents that the evaluation drives through the simulator (no ROS).

An agent is told the task at the start of an episode (`reset(task, seed)`) and then, given the latest
observation, names its next action (`act(observation) -> (action, x, y)`, ALFRED's action names, the
target pixel in the simulator's frame; -1, -1 for actions without a target). The observation is
whatever the driver has (the launcher passes the dialfred_msgs/Observation message); the two agents
here do not look at it. The task an agent is told is its public view (`tasks.PublicTask`: the
instruction and the nouns it names, with the task's id, room and split); the expert's plan, the goal
and the type stay with the simulator, the checker and the oracle. Only a built-in reference agent
marked `privileged` (the expert) is given the whole `Task`, and its results say so. The performer is an
agent too: `make_agent` is where an agent gets its name, and any class of yours works as
'package.module:ClassName'.

An agent that talks (`protocol.DialogueAgent`) also has `ask(observation) -> Question | None`, called
before every `act`: a question goes to the oracle and its answer comes back through `hear(qa)`, then
`ask` is called again, until it returns None and the agent acts. `dialfred_questioner` gives any agent
a questioner this way. The protocol itself (actions, questions, the Agent protocols) is `protocol`.
"""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np

from .protocol import ACTIONS, Agent, Decision, is_privileged, scale_pixel


def public_view(task: Any) -> Any:
    """The public view of `task` (a Task's `public()`; a PublicTask as it is)."""
    return task.public() if hasattr(task, 'public') else task


def task_nouns(task: Any) -> list[str]:
    """The objects a question may name: the nouns of the task's instruction, without repeats."""
    return list(dict.fromkeys(n for n in task.object_nouns if n))


def task_view(agent: Any, task: Any) -> Any:
    """What `agent` is told of `task`: the whole Task for a privileged reference agent, else its
    public view."""
    return task if is_privileged(agent) else public_view(task)


class ExpertAgent:
    """Replays the task's expert actions in order, then Stop (if the episode is still running).

    Privileged: it reads the expert's plan from the whole Task, so it is a reference (the
    benchmark's upper bound and a check of the world), not an agent, and results mark it."""

    name = 'expert'
    privileged = True

    def __init__(self, resolution: int = 128):
        self.resolution = resolution      # the simulator's frame size; pixels are scaled to it
        self._plan: list[Decision] = []
        self._next = 0

    def reset(self, task: Any, seed: int = 0) -> None:
        if not hasattr(task, 'expert_actions'):
            raise TypeError(f'the expert replays the task\'s plan: it needs the whole Task, got {type(task).__name__}')
        self._plan = [(a.action, *scale_pixel(a.x, a.y, task.resolution, self.resolution))
                      for a in task.expert_actions]
        self._next = 0

    def act(self, observation: Any = None) -> Decision:
        if self._next >= len(self._plan):
            return ('Stop', -1, -1)
        decision = self._plan[self._next]
        self._next += 1
        return decision


class RandomAgent:
    """Uniform over the 13 actions, with a uniform random pixel; seeded per episode."""

    name = 'random'
    privileged = False

    def __init__(self, resolution: int = 128):
        self.resolution = resolution
        self._rng = np.random.default_rng(0)

    def reset(self, task: Any, seed: int = 0) -> None:
        self._rng = np.random.default_rng(seed)

    def action_probabilities(self, observation: Any = None) -> np.ndarray:
        """Uniform over ACTIONS: the random agent is always unsure (see the confusion questioner)."""
        return np.full(len(ACTIONS), 1.0 / len(ACTIONS))

    def act(self, observation: Any = None) -> Decision:
        action = ACTIONS[int(self._rng.integers(len(ACTIONS)))]
        x, y = (int(v) for v in self._rng.integers(self.resolution, size=2))
        return (action, x, y)


AGENTS = {'expert': ExpertAgent, 'random': RandomAgent}


def load_class(spec: str, kind: str = 'agent', methods: tuple[str, ...] = ('reset', 'act')) -> type:
    """The class named by 'package.module:ClassName' (a module on the Python path), checked to have
    `methods`; ValueError saying what is wrong otherwise."""
    module_name, _, class_name = spec.partition(':')
    if not module_name or not class_name:
        raise ValueError(f'{kind} {spec!r} is neither a known name nor of the form package.module:ClassName')
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:           # a broken module of the user's: say which and why
        raise ValueError(f'cannot import {module_name!r} for {kind} {spec!r}: {exc!r}') from None
    cls = getattr(module, class_name, None)
    if not isinstance(cls, type):
        raise ValueError(f'{module_name!r} has no class {class_name!r} (for {kind} {spec!r})')
    missing = [m for m in methods if not callable(getattr(cls, m, None))]
    if missing:
        raise ValueError(f'{kind} class {spec!r} lacks {", ".join(missing)}')
    return cls


def make_agent(name: str, resolution: int = 128) -> Agent:
    """A new agent (one per worker: agents keep per-episode state): 'expert', 'random', or your own
    class as 'package.module:ClassName', constructed as ClassName(resolution=...)."""
    if name in AGENTS:
        return AGENTS[name](resolution=resolution)
    if ':' not in name:
        raise ValueError(f'unknown agent {name!r}; known: {", ".join(AGENTS)}, or package.module:ClassName')
    cls = load_class(name)
    if is_privileged(cls):
        raise ValueError(f'agent {name!r} says it is privileged: only the built-in reference agents '
                         f'({", ".join(k for k, c in AGENTS.items() if c.privileged)}) may see a task\'s solution')
    return cls(resolution=resolution)
