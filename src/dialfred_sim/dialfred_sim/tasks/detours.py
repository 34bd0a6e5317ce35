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
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from .expert import Expert

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

