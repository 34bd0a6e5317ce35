"""The navigation graph of the agent's moves: states (grid point, heading), MoveAhead and the two
rotations, on the floor that open doors leave free and only where the object in hand has room (the
rules of `actions.move_ahead` and `actions.rotate`). The camera's pitch is a fourth coordinate that
LookUp / LookDown change by 15 degrees without leaving the state.

`successors` is the one definition of a move that the expert's search and DialFRED's go-to goal
(`actions_to_pose`) both use; ALFRED's `Graph.get_shortest_path` measures a go-to the same way: the
shortest path over (x, z, rotation), then one look action per 15 degrees of pitch between the two poses.
"""

from __future__ import annotations

from collections import deque
from typing import Iterator, Optional

from ..actions import LOOK_STEP, Action
from ..world.scene import World

STEP = {0: (1, 0), 90: (0, 1), 180: (-1, 0), 270: (0, -1)}

State = tuple[int, int, int]             # grid point (i, j) and heading in degrees
Pose = tuple[int, int, int, float]       # ... and camera pitch in degrees (positive: down)


def successors(world: World, state: State, free: Optional[set] = None) -> Iterator[tuple[Action, State]]:
    """(action, next state) of every move that succeeds from `state` in `world` as it is now, in the
    order MoveAhead, RotateLeft, RotateRight. `free`: the world's free floor, when the caller has it."""
    i, j, r = state
    di, dj = STEP[r]
    held = world.objects[world.held] if world.held else None
    for act, nxt in ((Action.MoveAhead, (i + di, j + dj, r)), (Action.RotateLeft, (i, j, (r + 90) % 360)),
                     (Action.RotateRight, (i, j, (r - 90) % 360))):
        if act == Action.MoveAhead:
            if free is not None:
                if nxt[:2] not in free:
                    continue
            elif nxt[:2] not in world.layout.navigable or world.open_blocker(*nxt[:2]) is not None:
                continue
        if held is not None and world.carry_spot(held, *nxt)[0] is None:
            continue
        yield act, nxt


def look_actions(h_from: float, h_to: float) -> int:
    """LookUp / LookDown actions between two camera pitches."""
    return int(round(abs(h_to - h_from) / LOOK_STEP))


def actions_to_pose(world: World, goal: Pose, limit: int) -> Optional[int]:
    """The fewest actions (moves, rotations and looks) that take the agent of `world`, from where it
    stands now, to the pose `goal` = (i, j, heading, pitch); None when that takes more than `limit`.

    A breadth-first search no deeper than the budget the looks leave, so a check against DialFRED's
    goal (`limit` 4) visits a few dozen states at most."""
    a = world.agent
    looks = look_actions(a.horizon, goal[3])
    budget = limit - looks
    if budget < 0:
        return None
    target = (int(goal[0]), int(goal[1]), int(goal[2]) % 360)
    start = (a.i, a.j, a.rotation % 360)
    turns = 0 if start[2] == target[2] else (2 if (start[2] - target[2]) % 180 == 0 else 1)
    if abs(start[0] - target[0]) + abs(start[1] - target[1]) + turns > budget:
        return None          # no path can be this short (each move changes one coordinate by one)
    depth = {start: 0}
    queue = deque([start])
    while queue:
        s = queue.popleft()
        if s == target:
            return depth[s] + looks
        if depth[s] == budget:
            continue
        for _, nxt in successors(world, s):
            if nxt not in depth:
                depth[nxt] = depth[s] + 1
                queue.append(nxt)
    return None
