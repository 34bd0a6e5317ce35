"""Where a world's objects rest and how they move: the free spots on a receptacle's surfaces, placing,
holding and carrying, contents riding along with what holds them, and the floor that open doors and
drawers take from the agent.

`Placement` is a part of `scene.World`, which inherits it: its methods read and write the world's
objects, agent, layout and pybullet client, and the carry and outline caches World empties per room.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from .bodies import set_articulation
from .hand import carry_spot, hand_spot, solids_of
from .objects import WorldObject
from .open_parts import blocks, footprints, moving_part_boxes
from .rooms import GRID, local_to_world

OPENING_SWEEP = (0.25, 0.5, 0.75, 1.0)   # fractions of a door's swing checked against the agent


class Placement:
    """Resting, holding and carrying objects, and the floor open parts take (a part of World)."""

    def surface_offset(self, receptacle: WorldObject) -> tuple[float, float, float]:
        """How far an open drawer has slid its contents out (object frame)."""
        art = receptacle.spec.articulation
        if art is not None and art.kind == 'prismatic' and receptacle.is_open:
            return (art.axis[0] * art.open_value, art.axis[1] * art.open_value, art.axis[2] * art.open_value)
        return (0.0, 0.0, 0.0)

    def free_spots(self, receptacle: WorldObject, obj: WorldObject, surface_index: int):
        """Candidate resting points (local x, y) on a surface where `obj` fits, and their count."""
        surf = receptacle.spec.surfaces[surface_index]
        hx, hy = obj.spec.size[0] / 2, obj.spec.size[1] / 2
        if obj.spec.size[2] > surf.clearance + 1e-6:
            return []
        if hx > surf.half_size[0] + 1e-6 or hy > surf.half_size[1] + 1e-6:
            # Long things may overhang open-top surfaces a little (a knife on a plate), and as much
            # as they like where ALFRED's allow-list names them (a pan on a stove burner).
            named = obj.type_name in receptacle.otype.accepts
            if surf.inside or not named and (hx > surf.half_size[0] * 1.6 + 0.02 or hy > surf.half_size[1] * 1.6 + 0.02):
                return []
        taken = []
        for cid in receptacle.contents:
            other = self.objects[cid]
            if other.fixture or other.surface != surface_index or cid == obj.object_id:
                continue
            ox, oy = other.spec.size[0] / 2, other.spec.size[1] / 2
            taken.append((other.local[0] - ox, other.local[1] - oy, other.local[0] + ox, other.local[1] + oy))
        # Fixtures standing on this receptacle (a microwave on a counter) take room too.
        for cid in receptacle.contents:
            other = self.objects[cid]
            if other.fixture:
                rel = _to_local(receptacle.position, receptacle.yaw, other.position)
                ox, oy = other.spec.size[0] / 2, other.spec.size[1] / 2
                taken.append((rel[0] - ox, rel[1] - oy, rel[0] + ox, rel[1] + oy))
        ax = max(surf.half_size[0] - hx, 0.0)
        ay = max(surf.half_size[1] - hy, 0.0)
        xs = np.arange(-ax, ax + 1e-9, 0.04) if ax > 0 else np.array([0.0])
        ys = np.arange(-ay, ay + 1e-9, 0.04) if ay > 0 else np.array([0.0])
        # The grid, x-major, and for each point whether its rectangle (1 cm apart) overlaps a taken
        # one: the same float64 operations as the point-by-point loop this replaced, so the same
        # spots to the last bit (tests/sim/test_scene_spots.py keeps the loop as the reference).
        cx = (surf.center[0] + xs)[:, None].repeat(len(ys), axis=1).ravel()
        cy = np.tile(surf.center[1] + ys, len(xs))
        free = np.ones(len(cx), dtype=bool)
        for t0, t1, t2, t3 in taken:
            free &= ~((cx - hx < t2 + 0.01) & (t0 < cx + hx + 0.01) & (cy - hy < t3 + 0.01) & (t1 < cy + hy + 0.01))
        return list(zip(cx[free].tolist(), cy[free].tolist()))

    def place(self, obj: WorldObject, receptacle: WorldObject, rng: Optional[np.random.Generator] = None,
              near: Optional[tuple[float, float, float]] = None) -> bool:
        """Rest `obj` at a free spot on/in `receptacle` (nearest to `near`, or drawn with `rng`).

        Returns False, changing nothing, if no spot on any of its surfaces fits the object.
        """
        candidates = []
        for k in range(len(receptacle.spec.surfaces)):
            for spot in self.free_spots(receptacle, obj, k):
                candidates.append((k, spot))
        if not candidates:
            return False
        if near is not None:
            off = self.surface_offset(receptacle)
            rel = _to_local(receptacle.position, receptacle.yaw, near)

            def dist(c):
                k, (x, y) = c
                surf = receptacle.spec.surfaces[k]
                return (x + off[0] - rel[0]) ** 2 + (y + off[1] - rel[1]) ** 2 + \
                       (surf.center[2] + off[2] - rel[2]) ** 2
            k, (x, y) = min(candidates, key=dist)
        elif rng is not None:
            k, (x, y) = candidates[int(rng.integers(len(candidates)))]
        else:
            k, (x, y) = candidates[0]
        self._detach(obj)
        obj.parent, obj.surface = receptacle.object_id, k
        obj.local = (x, y, receptacle.spec.surfaces[k].center[2])
        obj.local_yaw = 0.0
        receptacle.contents.append(obj.object_id)
        self.update_pose(obj)
        return True

    def _detach(self, obj: WorldObject) -> None:
        if obj.parent is not None:
            parent = self.objects.get(obj.parent)
            if parent is not None and obj.object_id in parent.contents:
                parent.contents.remove(obj.object_id)
        obj.parent = None
        if obj.held:
            obj.held = False
            self.held = None

    def hold(self, obj: WorldObject) -> None:
        """Put `obj` (and whatever it carries) in the agent's hand."""
        self._detach(obj)
        obj.held = True
        self.held = obj.object_id
        self.update_held_pose()

    def carry_spot(self, obj: WorldObject, i: int, j: int, rotation: int) -> tuple[Optional[tuple], str]:
        """(spot, '') where the agent on (i, j) facing `rotation` would carry `obj` (and what it
        carries), clear of the walls and fixtures; (None, what it would hit) if there is no room (hand.py)."""
        size = self.carried_size(obj)
        key = (size, i, j, rotation % 360)
        if key not in self._carry_cache:
            self._carry_cache[key] = carry_spot(solids_of(self.layout.scene), i * GRID, j * GRID, rotation, size)
        return self._carry_cache[key]

    def carried_size(self, obj: WorldObject) -> tuple[float, float, float]:
        """The box the hand carries with `obj`, centred on it and turned with it: its own size, widened
        to take in whatever on or in it reaches past its sides (a spatula on a plate), and as tall as
        it plus the tallest thing it carries."""
        hx, hy = obj.spec.size[0] / 2, obj.spec.size[1] / 2
        c, s = math.cos(obj.yaw), math.sin(obj.yaw)
        for d in self.descendants(obj):
            dx, dy = d.position[0] - obj.position[0], d.position[1] - obj.position[1]
            turn = d.yaw - obj.yaw
            ct, st = abs(math.cos(turn)), abs(math.sin(turn))
            ex = ct * d.spec.size[0] / 2 + st * d.spec.size[1] / 2
            ey = st * d.spec.size[0] / 2 + ct * d.spec.size[1] / 2
            hx = max(hx, abs(c * dx + s * dy) + ex)
            hy = max(hy, abs(-s * dx + c * dy) + ey)
        height = obj.spec.size[2] + max((o.spec.size[2] for o in self.descendants(obj)), default=0.0)
        return (2 * hx, 2 * hy, height)

    def update_held_pose(self) -> None:
        if self.held is None:
            return
        obj = self.objects[self.held]
        a = self.agent
        spot, _ = self.carry_spot(obj, a.i, a.j, a.rotation)
        if spot is None:     # only where a pose was set directly (teleport, the expert's look-ahead)
            spot = hand_spot(0, a.x, a.y, a.rotation)
        obj.position, obj.yaw = spot, math.radians(a.rotation)
        self._move_body(obj)

    def update_pose(self, obj: WorldObject) -> None:
        parent = self.objects[obj.parent]
        off = self.surface_offset(parent)
        local = (obj.local[0] + off[0], obj.local[1] + off[1], obj.local[2] + off[2])
        obj.position = local_to_world(parent.position, parent.yaw, local)
        obj.yaw = parent.yaw + obj.local_yaw
        self._move_body(obj)

    def _move_body(self, obj: WorldObject) -> None:
        self.client.resetBasePositionAndOrientation(obj.body, obj.position, _quat(self.client, obj.yaw))
        for cid in obj.contents:
            child = self.objects[cid]
            if not child.fixture:
                self.update_pose(child)

    def set_open(self, obj: WorldObject, is_open: bool) -> None:
        obj.is_open = is_open
        set_articulation(self.client, obj.body, obj.spec, 1.0 if is_open else 0.0)
        if obj.spec.articulation is not None and obj.spec.articulation.kind == 'prismatic':
            for cid in obj.contents:   # a drawer carries its contents when it slides
                child = self.objects[cid]
                if not child.fixture:
                    self.update_pose(child)

    # ------------------------------------------------------------------ floor taken by open doors

    def open_part_outlines(self, obj: WorldObject, fraction: float = 1.0) -> list:
        """Floor outlines of `obj`'s door, lid or drawer opened to `fraction`, where they reach the
        agent's height (see open_parts)."""
        key = (obj.object_id, obj.position, obj.yaw, fraction)
        if key not in self._outline_cache:
            self._outline_cache[key] = footprints(moving_part_boxes(obj.spec, obj.position, obj.yaw, fraction))
        return self._outline_cache[key]

    def open_blocker(self, i: int, j: int) -> Optional[str]:
        """The open object whose door or drawer stands where an agent on grid point (i, j) would."""
        for obj in self.objects.values():
            if obj.is_open and obj.spec.articulation is not None and \
                    blocks(i * GRID, j * GRID, self.open_part_outlines(obj)):
                return obj.object_id
        return None

    def free_floor(self) -> set:
        """Grid points the agent may stand on now: the layout's free floor less what open doors take."""
        free = set(self.layout.navigable)
        for obj in self.objects.values():
            if obj.is_open and obj.spec.articulation is not None:
                outlines = self.open_part_outlines(obj)
                if outlines:
                    free -= {(i, j) for i, j in free if blocks(i * GRID, j * GRID, outlines)}
        return free

    def would_hit_agent(self, obj: WorldObject, i: Optional[int] = None, j: Optional[int] = None) -> bool:
        """Whether opening `obj` would swing or slide its moving part into an agent on (i, j) (the
        agent's own point by default), anywhere on its way open."""
        i = self.agent.i if i is None else i
        j = self.agent.j if j is None else j
        return any(blocks(i * GRID, j * GRID, self.open_part_outlines(obj, f)) for f in OPENING_SWEEP)


def _to_local(position, yaw: float, point) -> tuple[float, float, float]:
    """A world point in the frame of an object at `position` turned by `yaw`."""
    dx, dy = point[0] - position[0], point[1] - position[1]
    c, s = math.cos(yaw), math.sin(yaw)
    return (c * dx + s * dy, -s * dx + c * dy, point[2] - position[2])


def _quat(client, yaw: float):
    return client.getQuaternionFromEuler((0.0, 0.0, yaw))
