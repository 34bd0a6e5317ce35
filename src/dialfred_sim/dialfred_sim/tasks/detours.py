"""Detours: a task's expert demonstration with a few wrong moves in the middle of one of its go-tos, and the
expert's way back from where they led (no ROS).

An expert never strays, so a performer trained on its demonstrations alone has never seen a frame off the
expert's path, nor an answer heard there ("You should turn around."), nor what to do next. A detour shows
both: at a step of a go-to the agent takes `wrong` moves (MoveAhead, RotateLeft, RotateRight, drawn from
the task's seed), then the expert's shortest way back to the pose that go-to ends at (its breadth-first
search over the free floor, then the looks to the go-to's pitch), then the rest of the expert's own
actions, which from that pose do what they did. The wrong moves are not targets of the imitation (the
record's `targets`); every other action is. DAgger's idea, with the expert's planner in place of its
queries.

    detour_plan(task, rng)  -> (step, wrong moves) or None when the task has no go-to to stray from
    way_back(world, pose)   -> the expert's moves from the agent's pose to `pose`, or None

`demonstrations.build_demonstrations(..., detours=True)` plays every task so (a task without a go-to as
the expert played it), each task's frames in `len(expert actions) + 1 + DETOUR_ROWS` rows.

Guided walks: an expert walks the shortest way, which a direction answer ("You should turn left.": where
the expert's end lies, as the crow flies) does not say: in the expert's demonstrations a third of the
steps told to turn left walk straight on. A performer that imitates them learns to walk past the answer.
A guided walk shows the other behaviour: from the first action of the task's last go-to (the one that
ends where the task's expert ends, where the direction answers point) the agent does what a direction
`advise(env)` says at each step (a move or a turn, or Stop when there), taking the expert's shortest way
for a few moves where a move it is told to make is blocked; then the expert's way to the go-to's end pose
and the rest of the expert's actions. It gives up on the directions (and walks the expert's way) where it
comes back to a pose it stood on, or where the rows left would not hold the way back.

    guided_plan(task)                  -> (step, rejoin step) or None
    GuidedWalk(goal, advise).next(env, rows) -> the next action, or None when the walk is over

`build_demonstrations(..., guide='package.module:Class')` plays every task so (`advise` is a `Class()`).
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from .expert import Expert
from .navigation import successors

WRONG_MOVES = ('MoveAhead', 'RotateLeft', 'RotateRight')
WRONG_P = (0.5, 0.25, 0.25)          # a wrong move is a step ahead half the time, else a turn
DETOUR_MOVES = (2, 6)                # how many wrong moves, drawn from this range (inclusive)
# Rows a detour may add to a task's frames: its wrong moves, and a way back at most that many steps
# plus two turns and the looks of the go-to's pitch. A longer way back is cut short (the task is then
# played as the expert played it).
DETOUR_ROWS = 2 * DETOUR_MOVES[1] + 8


def detour_plan(task, rng: np.random.Generator) -> Optional[tuple[int, list[str]]]:
    """(the step of the task at which to stray, the wrong moves): a step inside one of the task's go-tos
    (a walking action of it, not its first), and DETOUR_MOVES wrong moves; None when the task has no go-to
    with such a step. Drawn from `rng` alone."""
    steps = []
    for p in task.primitives:
        if p.kind != 'goto':
            continue
        for k in range(max(p.start, task.start) + 1, p.end):
            if task.episode.actions[k].action in WRONG_MOVES:
                steps.append(k - task.start)
    if not steps:
        return None
    at = steps[int(rng.integers(len(steps)))]
    n = int(rng.integers(DETOUR_MOVES[0], DETOUR_MOVES[1] + 1))
    wrong = [WRONG_MOVES[int(i)] for i in rng.choice(len(WRONG_MOVES), size=n, p=WRONG_P)]
    return at, wrong


def rejoin_step(task, at: int) -> int:
    """The step of the task at which the go-to holding step `at` ends (where a detour from `at` rejoins the
    expert's actions)."""
    for p in task.primitives:
        if p.kind == 'goto' and p.start <= task.start + at < p.end:
            return p.end - task.start
    raise ValueError(f'step {at} of {task.task_id} is in none of its go-tos')


def way_back(world, pose: tuple) -> Optional[list[str]]:
    """The expert's moves from the agent's pose in `world` to `pose` (i, j, rotation, horizon): its
    shortest walk (the expert's breadth-first search over the free floor, with what it carries), then
    the looks to the pose's pitch; None when `pose` cannot be reached. Changes nothing in `world`."""
    expert = Expert(world)
    parent = expert._bfs()
    goal = tuple(pose[:3])
    if goal not in parent:
        return None
    walk = [a.name for a in Expert._path(parent, goal)]
    looks = [a.name for a in Expert._look_actions(world.agent.horizon, pose[3])]
    return walk + looks



GUIDE_SIDESTEP = 3                   # a blocked move the directions ask for: this many of the expert's moves


def guided_plan(task) -> Optional[tuple[int, int]]:
    """(the step of the task at which a guided walk starts, the step at which its go-to ends): the first
    action of the task's last go-to, where that go-to ends on the grid point where the task's expert ends
    (the direction answers point there); None otherwise (no go-to, or one that walks on after it)."""
    gotos = [p for p in task.primitives if p.kind == 'goto' and p.end > task.start]
    if not gotos:
        return None
    last = gotos[-1]
    if tuple(task.episode.poses[last.end][:2]) != tuple(task.expert_end_pose[:2]):
        return None
    return max(last.start, task.start) - task.start, last.end - task.start


class GuidedWalk:
    """The agent walking where `advise(env)` says (an action name: MoveAhead, RotateLeft, RotateRight, or
    Stop for "here"), towards `goal` (i, j, rotation, horizon: the go-to's end pose); see the module."""

    def __init__(self, goal: tuple, advise):
        self.goal, self.advise = tuple(goal), advise
        self.stood: set[tuple] = set()
        self.sidestep: list[str] = []
        self.walked = 0                  # actions taken on the walk (told, or a sidestep's)

    def next(self, env, rows: int) -> Optional[str]:
        """The walk's next action from where `env`'s agent stands, with `rows` actions left for the walk and the
        expert's way from its end to the goal; None when the walk is over (told "here", back on a pose it stood
        on, or the rows would not hold another action and the way back)."""
        world = env.world
        a = world.agent
        pose = (a.i, a.j, a.rotation)
        back = way_back(world, self.goal)
        if back is None or len(back) + 2 > rows:
            return None
        if self.sidestep:
            self.walked += 1
            return self.sidestep.pop(0)
        if pose in self.stood:
            return None
        self.stood.add(pose)
        told = self.advise(env)
        if told == 'Stop':
            return None
        if told not in {act.name for act, _ in successors(world, pose)}:
            if not back:
                return None
            self.sidestep = back[:GUIDE_SIDESTEP]
            told = self.sidestep.pop(0)
        self.walked += 1
        return told
