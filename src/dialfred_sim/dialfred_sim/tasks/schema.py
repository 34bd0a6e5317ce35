"""The task schema: episodes of an expert, the DialFRED tasks cut from them, and their goals.

An `Episode` is one ALFRED-style household job (e.g. heat an apple and put it on the table) played by
the expert: its room and seed, the set-up that makes the job possible, the expert's low-level actions
and the primitives (go to, pick up, put, open, ...) they form. A `Task` is a run of consecutive
primitives of an episode with one of the DialFRED task types (`types`); its initial state is the world as the
expert left it at the task's first action.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

PRIMITIVE_KINDS = ('goto', 'pickup', 'put', 'open', 'close', 'toggle_on', 'toggle_off', 'slice')


@dataclass(frozen=True)
class ExpertAction:
    """One low-level expert action. Interactions carry their target pixel (in a frame of the task's
    resolution), the object id the pixel hit and the world point under it (to replay it without
    rendering when a task's initial state is rebuilt)."""

    action: str
    x: int = -1
    y: int = -1
    target: str = ''
    point: Optional[tuple[float, float, float]] = None

    def to_json(self) -> list:
        if self.target:
            return [self.action, self.x, self.y, self.target, list(self.point or ())]
        return [self.action]

    @classmethod
    def from_json(cls, row: list) -> 'ExpertAction':
        if len(row) == 1:
            return cls(row[0])
        return cls(row[0], int(row[1]), int(row[2]), row[3], tuple(row[4]) if row[4] else None)


@dataclass(frozen=True)
class Primitive:
    """A step of the expert: `kind` on `target` (for put: `target` is the object, `receptacle` where
    it goes), made of the episode's actions [start, end)."""

    kind: str
    target: str
    start: int
    end: int
    receptacle: str = ''

    def to_json(self) -> list:
        return [self.kind, self.target, self.start, self.end, self.receptacle]

    @classmethod
    def from_json(cls, row: list) -> 'Primitive':
        return cls(row[0], row[1], int(row[2]), int(row[3]), row[4])


@dataclass(frozen=True)
class Condition:
    """One goal condition: `kind` about object `obj` (and receptacle type `arg` for 'in').

    kinds: holding, in, open, closed, on, off, sliced, clean, hot, cold, near (the agent within
    DialFRED's 4 actions of the pose `arg`, 'i|j|heading|pitch'; `obj` is where the go-to led),
    reachable (`obj` in view and within reach: the 'visible' goal rule)."""

    kind: str
    obj: str
    arg: str = ''

    def to_json(self) -> list:
        return [self.kind, self.obj, self.arg]

    @classmethod
    def from_json(cls, row: list) -> 'Condition':
        return cls(row[0], row[1], row[2])


@dataclass
class Episode:
    """An expert demonstration of one ALFRED-style job in one room."""

    episode_id: str
    split: str
    scene: str
    seed: int
    alfred_type: str
    setup: dict                    # changes applied after the scene is built (see generator.apply_setup)
    actions: list[ExpertAction]
    primitives: list[Primitive]
    poses: list[tuple[int, int, int, float]] = field(default_factory=list)   # agent pose before each action, and at the end
    resolution: int = 128


@dataclass(frozen=True)
class PublicTask:
    """What an agent is told about its task, as a DialFRED agent is: the main-action instruction and
    the nouns of the objects it names (what questions may be about), with the task's id, room and
    split. The type, goal, step-by-step instructions and the expert's plan, length and end pose stay
    with the simulator, the checker and the oracle (`Task`)."""

    task_id: str
    scene: str
    split: str
    instruction: str
    object_nouns: tuple[str, ...]


@dataclass
class Task:
    """One DialFRED task: a run of an episode's primitives with a type, goal and instructions.

    Privileged: it holds the expert's solution. Agents get `public()`."""

    task_id: str
    task_type: str
    episode: Episode
    start: int                     # first expert action (index into episode.actions)
    end: int                       # one past the last
    goal: list[Condition]
    instruction: str               # the main-action instruction
    step_instructions: list[str]
    object_nouns: list[str]
    primitives: list[Primitive]
    target_visible_at_start: bool = True
    has_distractor: bool = False
    visible_end: Optional[int] = None   # `end` under the 'visible' goal rule, where it differs (goals.rule_goal)
    goal_rule: str = 'dialfred'         # the rule `goal` and `end` follow (goals.under_rule makes the other)

    @property
    def split(self) -> str:
        return self.episode.split

    def public(self) -> PublicTask:
        """The view of this task that agents get."""
        return PublicTask(self.task_id, self.scene, self.split, self.instruction, tuple(self.object_nouns))

    @property
    def scene(self) -> str:
        return self.episode.scene

    @property
    def resolution(self) -> int:
        return self.episode.resolution

    @property
    def expert_actions(self) -> list[ExpertAction]:
        return self.episode.actions[self.start:self.end]

    @property
    def expert_length(self) -> int:
        return self.end - self.start

    @property
    def start_pose(self) -> tuple[int, int, int, float]:
        return self.episode.poses[self.start]

    @property
    def expert_end_pose(self) -> tuple[int, int, int, float]:
        """Where the expert's steps of this task end (the pose its last go-to led to, for a task that
        ends with one), whatever the goal rule: the pose the oracle's direction answers point to."""
        return self.episode.poses[self.primitives[-1].end]
