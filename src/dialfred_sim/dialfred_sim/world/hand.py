"""Where the agent carries the object it holds.

An object in hand rides ahead of the agent, low and to the right (`HAND`), so that it hides little
of the view. Near a wall or a tall piece of furniture that spot can lie inside it (a bread carried
0.17 m through the wall when the agent faces the wall from its nearest grid point). The hand then
draws the object back towards the body, in steps of a tenth of the way, to the first spot where it
is inside the room and clear of every fixture at its height; the box it checks takes in whatever
rides on the object (World.carried_size: a spatula reaching past a plate's rim). Where even the body's own spot is
taken (a baseball bat, longer than the agent is wide, facing a wall), there is no room to hold it:
the move, turn or pickup that would need it fails (see actions.py).

Pure geometry on the layout (no pybullet). Open doors and small objects are not obstacles here.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from .rooms import footprint, local_to_world, room_layout

HAND = (0.42, -0.16, 0.95)   # metres ahead, to the left (negative: right) and above the floor
HAND_STEPS = 10              # the hand draws back in this many steps, down to the body's centre
EPS = 1e-6


@dataclass(frozen=True)
class Solids:
    """The room's walls and its fixtures as boxes (xmin, ymin, xmax, ymax, zmin, zmax)."""

    width: float
    depth: float
    boxes: np.ndarray            # (n, 6)
    names: tuple[str, ...]       # the fixture of each box

    def first_hit(self, rect: Sequence[float], zmin: float, zmax: float) -> Optional[str]:
        """What a box of floor outline `rect` from height zmin to zmax would pass into: 'the wall',
        a fixture's id, or None if nothing."""
        if rect[0] < -EPS or rect[1] < -EPS or rect[2] > self.width + EPS or rect[3] > self.depth + EPS:
            return 'the wall'
        if not len(self.boxes):
            return None
        b = self.boxes
        hit = ((rect[0] < b[:, 2] - EPS) & (b[:, 0] < rect[2] - EPS) & (rect[1] < b[:, 3] - EPS)
               & (b[:, 1] < rect[3] - EPS) & (zmin < b[:, 5] - EPS) & (b[:, 4] < zmax - EPS))
        k = np.flatnonzero(hit)
        return self.names[int(k[0])] if len(k) else None


@functools.lru_cache(maxsize=256)
def solids_of(scene: str) -> Solids:
    """The walls and fixtures of floor plan `scene`, as the hand sees them."""
    layout = room_layout(scene)
    rows, names = [], []
    for fx in layout.fixtures:
        rect = footprint(fx.position, fx.yaw, fx.spec.size)
        rows.append((*rect, fx.position[2], fx.position[2] + fx.spec.size[2]))
        names.append(fx.object_id)
    return Solids(layout.width, layout.depth, np.array(rows, float).reshape(-1, 6), tuple(names))


def hand_spot(k: int, x: float, y: float, rotation: float) -> tuple[float, float, float]:
    """The k-th spot of the hand (k = HAND_STEPS: the full reach; 0: above the body's centre) for an
    agent at (x, y) facing `rotation` degrees."""
    f = k / HAND_STEPS
    return local_to_world((x, y, 0.0), math.radians(rotation), (HAND[0] * f, HAND[1] * f, HAND[2]))


def carry_spot(solids: Solids, x: float, y: float, rotation: float, size: Sequence[float]
               ) -> tuple[Optional[tuple[float, float, float]], str]:
    """(spot, '') where an object of `size` (turned with the agent) is carried by an agent at (x, y)
    facing `rotation`: the farthest reach that is clear. (None, what it would hit) when none is."""
    yaw = math.radians(rotation)
    hit = ''
    for k in range(HAND_STEPS, -1, -1):
        spot = hand_spot(k, x, y, rotation)
        hit = solids.first_hit(footprint(spot, yaw, size), spot[2], spot[2] + size[2]) or ''
        if not hit:
            return spot, ''
    return None, hit
