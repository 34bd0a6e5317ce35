"""Goal conditions of the task types and their check against the world (like ALFRED's
`goal_conditions_met`): which conditions hold now, success when all do, and the goal-condition
progress GC counts (`goal_progress`: only the conditions that did not hold at the task's start).

A go-to is judged by DialFRED's rule (its `GotoLocationAction` with `min_reach_distance` 5): the agent
must stand within `NEAR_ACTIONS` actions of the pose where the expert ended the task's steps (where its
last go-to led, unless the expert stepped on inside an interaction), counted over the navigation graph
(`navigation.actions_to_pose`). Every task whose steps include a go-to has that 'near' condition,
beside the conditions of its object actions. The rule used
before, kept as the named variant 'visible' (`GOAL_RULES`), asks instead for enough of the target in
view and within reach, and only of the Move and Pick & Move tasks (`rule_goal`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Optional, Sequence

import numpy as np

from ..actions import REACH
from .navigation import Pose, actions_to_pose
from ..world.camera import reach_lengths
from ..world.objects import COLD, HOT
from ..world.scene import World
from .schema import Condition, Primitive, Task
from .types import task_type as task_type_named

MIN_REACHABLE_PIXELS = 4     # at 128x128; scaled with the frame area
NEAR_ACTIONS = 4             # DialFRED: a go-to is done when fewer than min_reach_distance (5) actions remain
GOAL_RULES = ('dialfred', 'visible')   # how a go-to is judged: DialFRED's pose rule, or the target in view and reach
DEFAULT_GOAL_RULE = 'dialfred'


def pose_arg(pose) -> str:
    """A pose (i, j, heading, pitch) as a 'near' condition's argument: 'i|j|heading|pitch' (as ALFRED
    writes a go-to's location, 'loc|x|z|rotation|horizon', in grid units and degrees)."""
    i, j, rot, horizon = pose
    return f'{int(i)}|{int(j)}|{int(rot) % 360}|{int(round(horizon))}'


def parse_pose_arg(arg: str) -> Pose:
    """The pose of a 'near' condition's argument; ValueError for anything but four integers."""
    parts = arg.split('|')
    if len(parts) != 4:
        raise ValueError(f"a 'near' condition's pose is 'i|j|heading|pitch', got {arg!r}")
    i, j, rot, horizon = (int(p) for p in parts)
    return i, j, rot, float(horizon)


def check_goal_rule(rule: str) -> str:
    if rule not in GOAL_RULES:
        raise ValueError(f'unknown goal rule {rule!r}: expected one of {", ".join(GOAL_RULES)}')
    return rule


def reachable_mask(world: World, object_id: str, depth: np.ndarray, seg: np.ndarray,
                   reach: float = REACH) -> np.ndarray:
    """Pixels of `object_id` in the frame that lie within `reach` of the agent's vertical axis."""
    obj = world.objects.get(object_id)
    if obj is None:
        return np.zeros(seg.shape, bool)
    mask = seg == obj.body
    if not mask.any():
        return mask
    dist = depth * reach_lengths(seg.shape[1], seg.shape[0], world.agent.horizon)
    return mask & (dist <= reach)


def min_pixels(shape: tuple) -> int:
    """Pixels of an object that must show for it to count as in view, in a frame of `shape`."""
    return max(1, round(MIN_REACHABLE_PIXELS * shape[0] * shape[1] / (128 * 128)))


def is_reachable(world: World, object_id: str, depth: np.ndarray, seg: np.ndarray, margin: float = 0.0) -> bool:
    """Whether enough of `object_id` is in view and within reach to act on it."""
    return int(reachable_mask(world, object_id, depth, seg, REACH - margin).sum()) >= min_pixels(seg.shape)


def condition_met(world: World, c: Condition, frame: Optional[tuple] = None) -> bool:
    objects = world.objects
    if c.kind == 'near':
        # The agent's own pose: it does not matter what became of the landmark.
        return actions_to_pose(world, parse_pose_arg(c.arg), NEAR_ACTIONS) is not None
    if c.kind == 'sliced':
        # Slicing replaces the object by its pieces.
        return c.obj not in objects and any(o.sliced_from == c.obj for o in objects.values())
    obj = objects.get(c.obj)
    if obj is None:
        return False
    if c.kind == 'holding':
        return world.held == c.obj
    if c.kind == 'in':
        return not obj.held and any(r.type_name == c.arg for r in world.container_chain(obj))
    if c.kind == 'open':
        return obj.is_open
    if c.kind == 'closed':
        return not obj.is_open
    if c.kind == 'on':
        return obj.is_on
    if c.kind == 'off':
        return not obj.is_on
    if c.kind == 'clean':
        return not obj.is_dirty
    if c.kind == 'hot':
        return obj.temperature == HOT
    if c.kind == 'cold':
        return obj.temperature == COLD
    if c.kind == 'reachable':
        if frame is None:
            return False
        return is_reachable(world, c.obj, frame[1], frame[2])
    raise ValueError(f'unknown goal condition kind {c.kind!r}')


def conditions_met(world: World, goal: Sequence[Condition], frame: Optional[tuple] = None) -> list[bool]:
    """Per condition, whether it holds now. `frame` = (rgb, depth, segmentation) of the current view
    (only 'reachable' looks at it)."""
    return [condition_met(world, c, frame) for c in goal]


def under_rule(task: Task, rule: str) -> Task:
    """`task` as the goal rule `rule` judges it (GOAL_RULES): its goal, and its end, the first moment
    that goal holds on the expert's path (hence the expert's length for PWSR). The same task when it
    already follows `rule`. Under 'visible', a task whose target never showed enough on the expert's
    path ends with the path (and the expert fails it). ValueError for an unknown rule, or a task not
    under DialFRED's rule asked for another (split files keep DialFRED's)."""
    if check_goal_rule(rule) == task.goal_rule:
        return task
    if task.goal_rule != 'dialfred':
        raise ValueError(f'task {task.task_id} follows the {task.goal_rule!r} rule; only a task under '
                         "DialFRED's rule converts")
    end = task.visible_end if task.visible_end is not None else task.end
    return replace(task, goal=rule_goal(task.task_type, task.goal, rule), end=end, visible_end=None, goal_rule=rule)


def needs_frame(goal: Sequence[Condition]) -> bool:
    """Whether checking `goal` needs the current frame (a 'reachable' condition)."""
    return any(c.kind == 'reachable' for c in goal)


def rule_goal(task_type: str, goal: Sequence[Condition], rule: str) -> list[Condition]:
    """The goal of a task of `task_type` under goal rule `rule`, from its goal under DialFRED's
    (`goal_for`): under 'visible', a type that `shows_target` (Move, Pick & Move) wants its target in
    view and within reach where DialFRED wants the expert's pose, and the other types drop their pose
    condition."""
    if check_goal_rule(rule) == 'dialfred':
        return list(goal)
    out = []
    for c in goal:
        if c.kind != 'near':
            out.append(c)
        elif task_type_named(task_type).shows_target:
            out.append(Condition('reachable', c.obj))
    return out


def goal_progress(met_now: Sequence[bool], met_at_start: Sequence[bool]) -> tuple[int, int]:
    """(achieved, to_achieve): of the goal conditions that did not hold when the task started
    (`met_at_start`), how many there are and how many hold now (`met_now`).

    This is what GC counts. A condition that already held at the start (the apple in hand in a
    Heat task, the microwave closed) is left out of both: doing nothing scores 0, and undoing such
    a condition on the way (putting the apple into the microwave) does not lower GC. Success still
    needs every condition, those that held at the start included. ALFRED instead counts every
    condition of the goal; its tasks start from scratch, where hardly any holds (docs/dataset.md).
    """
    if len(met_now) != len(met_at_start):
        raise ValueError(f'{len(met_now)} conditions now but {len(met_at_start)} at the start')
    open_at_start = [now for now, before in zip(met_now, met_at_start) if not before]
    return int(sum(open_at_start)), len(open_at_start)


# ---------------------------------------------------------------------- goals of the task types

def goal_for(task_type: str, prims: Sequence[Primitive], world_types: dict[str, str],
             poses: Sequence[Pose]) -> list[Condition]:
    """The goal conditions of a task of `task_type` made of `prims`, under DialFRED's rule: those of
    its object actions, and, when it has a go-to, being near the pose the expert ended the task at.

    `world_types` maps object ids to type names (receptacles are matched by type, as ALFRED does;
    the object acted on is the very instance, which appearance questions tell apart); `poses` are
    the episode's expert poses (the pose before each action, and at the end)."""
    conds = task_type_named(task_type).goal(prims, world_types)
    gotos = [p for p in prims if p.kind == 'goto']
    if gotos:
        # Neither ALFRED's expert nor ours walks inside an interaction, so the pose where the task's
        # steps end is the go-to's end pose, give or take the looks of the actions after it
        # (Task.expert_end_pose, which the direction answers point to).
        conds.append(Condition('near', gotos[-1].target, pose_arg(poses[prims[-1].end])))
    return conds
