"""Procedural household rooms: 120 layouts (30 per room type) numbered like ALFRED's floor plans.

A layout fixes the room's size, its furniture (type, pose, colour, size) and the pool of small object
types that episodes in it may scatter. Kitchens are FloorPlan1-30, living rooms FloorPlan201-230,
bedrooms FloorPlan301-330 and bathrooms FloorPlan401-430, as in AI2-THOR. Everything follows from
the floor plan number, so a layout is rebuilt identically on any machine.

World frame: the room spans x in [0, width], y in [0, depth], z up, walls on the four sides.
Furniture stands with its front (+x of its own frame) facing into the room.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ..protocol import BODY
from ..catalog import ROOM_TYPES, load_catalog
from .geometry import Part, ShapeSpec, Surface, fit_spec
from .shapes import shape_for

GRID = BODY.grid_step  # the agent's step, metres
AGENT_RADIUS = 0.2     # a grid point is free if a disc of this radius touches no furniture
MIN_NAVIGABLE = 30     # free grid points a layout must offer
WALL_HEIGHT = 2.6
COUNTER_HEIGHT = 0.9
COUNTER_DEPTH = 0.62
COUNTER_SLAB = 0.04      # the counter top's thickness

SCENE_RANGES = {'kitchen': range(1, 31), 'living_room': range(201, 231),
                'bedroom': range(301, 331), 'bathroom': range(401, 431)}

# Target extents (x = depth from its front, y = width, z = height) of furniture, before jitter.
FURNITURE_SIZE: dict[str, tuple[float, float, float]] = {
    'Fridge': (0.72, 0.85, 1.85), 'DiningTable': (0.9, 1.5, 0.76), 'CoffeeTable': (0.6, 1.1, 0.42),
    'SideTable': (0.45, 0.55, 0.66), 'Desk': (0.65, 1.4, 0.76), 'Shelf': (0.35, 0.9, 1.5),
    'Dresser': (0.55, 1.3, 0.95), 'Bed': (2.05, 1.5, 0.6), 'Sofa': (0.9, 2.1, 0.85),
    'ArmChair': (0.85, 0.85, 0.9), 'TVStand': (0.45, 1.3, 0.55), 'Television': (0.12, 1.05, 0.65),
    'GarbageCan': (0.35, 0.35, 0.5), 'Toilet': (0.7, 0.45, 0.8), 'Bathtub': (0.8, 1.7, 0.55),
    'BathtubBasin': (0.62, 1.5, 0.4), 'FloorLamp': (0.4, 0.4, 1.7), 'DeskLamp': (0.25, 0.25, 0.45),
    'Safe': (0.5, 0.5, 0.5), 'Ottoman': (0.5, 0.8, 0.42), 'HousePlant': (0.4, 0.4, 0.7),
    'LaundryHamper': (0.45, 0.5, 0.7), 'Chair': (0.5, 0.5, 0.9), 'Cart': (0.45, 0.7, 0.9),
    'Microwave': (0.38, 0.55, 0.32), 'CoffeeMachine': (0.3, 0.25, 0.38), 'Toaster': (0.2, 0.3, 0.2),
    'StoveBurner': (0.22, 0.22, 0.03), 'StoveKnob': (0.05, 0.05, 0.06), 'SinkBasin': (0.42, 0.55, 0.16),
    'Faucet': (0.16, 0.1, 0.28), 'Window': (0.06, 1.0, 1.1), 'Painting': (0.05, 0.8, 0.65),
    'Poster': (0.03, 0.55, 0.7), 'Mirror': (0.04, 0.7, 0.8), 'LightSwitch': (0.02, 0.08, 0.12),
    'TowelHolder': (0.1, 0.6, 0.06), 'HandTowelHolder': (0.1, 0.22, 0.25),
    'ToiletPaperHanger': (0.1, 0.2, 0.1), 'Cabinet': (0.55, 0.6, 0.8), 'Drawer': (0.55, 0.6, 0.2),
}

# Heights of the bottom of wall-mounted things.
WALL_MOUNT_Z = {'Window': 0.95, 'Painting': 1.25, 'Poster': 1.2, 'Mirror': 1.1, 'LightSwitch': 1.15,
                'TowelHolder': 1.05, 'HandTowelHolder': 0.95, 'ToiletPaperHanger': 0.65}

# Room recipes: (type, probability, (min count, max count), where). 'wall' stands against a wall,
# 'interior' stands free, 'mount' hangs on a wall, 'on:<Type>' stands on such a fixture's top.
RECIPES: dict[str, list[tuple[str, float, tuple[int, int], str]]] = {
    'kitchen': [
        ('Fridge', 1.0, (1, 1), 'wall'), ('GarbageCan', 1.0, (1, 1), 'wall'),
        ('DiningTable', 0.5, (1, 1), 'interior'), ('Shelf', 0.2, (1, 1), 'wall'),
        ('SideTable', 0.1, (1, 1), 'wall'), ('Chair', 0.5, (1, 2), 'interior'),
        ('Safe', 0.05, (1, 1), 'wall'), ('HousePlant', 0.3, (1, 1), 'wall'),
        ('Window', 0.85, (1, 1), 'mount'), ('LightSwitch', 1.0, (1, 1), 'mount'),
        ('Microwave', 1.0, (1, 1), 'on:CounterTop'), ('CoffeeMachine', 1.0, (1, 1), 'on:CounterTop'),
        ('Toaster', 1.0, (1, 1), 'on:CounterTop'),
    ],
    'living_room': [
        ('Sofa', 1.0, (1, 1), 'wall'), ('ArmChair', 0.8, (1, 2), 'wall'),
        ('CoffeeTable', 0.85, (1, 1), 'interior'), ('TVStand', 0.9, (1, 1), 'wall'),
        ('SideTable', 0.8, (1, 2), 'wall'), ('Shelf', 0.5, (1, 1), 'wall'),
        ('Dresser', 0.35, (1, 1), 'wall'), ('GarbageCan', 1.0, (1, 1), 'wall'),
        ('FloorLamp', 1.0, (1, 1), 'wall'), ('Ottoman', 0.15, (1, 1), 'interior'),
        ('DiningTable', 0.4, (1, 1), 'interior'), ('Safe', 0.1, (1, 1), 'wall'),
        ('HousePlant', 0.9, (1, 1), 'wall'), ('Cabinet', 0.15, (1, 2), 'wall'),
        ('Drawer', 0.25, (1, 2), 'wall'), ('Painting', 1.0, (1, 2), 'mount'),
        ('Window', 0.9, (1, 2), 'mount'), ('LightSwitch', 1.0, (1, 1), 'mount'),
        ('Television', 1.0, (1, 1), 'on:TVStand'),
    ],
    'bedroom': [
        ('Bed', 1.0, (1, 1), 'wall'), ('SideTable', 0.85, (1, 2), 'wall'), ('Desk', 0.65, (1, 1), 'wall'),
        ('Dresser', 0.8, (1, 1), 'wall'), ('Shelf', 0.65, (1, 1), 'wall'), ('GarbageCan', 1.0, (1, 1), 'wall'),
        ('LaundryHamper', 0.3, (1, 1), 'wall'), ('Safe', 0.17, (1, 1), 'wall'), ('Chair', 0.6, (1, 1), 'wall'),
        ('ArmChair', 0.2, (1, 1), 'wall'), ('Drawer', 0.6, (1, 2), 'wall'), ('Cabinet', 0.15, (1, 1), 'wall'),
        ('Mirror', 0.9, (1, 1), 'mount'), ('Window', 0.9, (1, 2), 'mount'), ('Poster', 0.2, (1, 1), 'mount'),
        ('Painting', 0.4, (1, 1), 'mount'), ('LightSwitch', 1.0, (1, 1), 'mount'),
        ('DeskLamp', 0.8, (1, 1), 'on:SideTable|Desk|Dresser'),
    ],
    'bathroom': [
        ('Toilet', 1.0, (1, 1), 'wall'), ('Bathtub', 0.7, (1, 1), 'wall'), ('GarbageCan', 1.0, (1, 1), 'wall'),
        ('Shelf', 0.3, (1, 1), 'wall'), ('Cart', 0.1, (1, 1), 'wall'), ('Dresser', 0.05, (1, 1), 'wall'),
        ('Mirror', 1.0, (1, 1), 'mount'), ('TowelHolder', 0.8, (1, 1), 'mount'),
        ('HandTowelHolder', 0.7, (1, 1), 'mount'), ('ToiletPaperHanger', 1.0, (1, 1), 'mount'),
        ('Window', 0.6, (1, 1), 'mount'), ('LightSwitch', 1.0, (1, 1), 'mount'),
        ('FloorLamp', 0.05, (1, 1), 'wall'),
    ],
}

# Room extents (short side, long side), metres: AI2-THOR's rooms are small, long and full, so the free
# floor a room of each type offers comes near theirs, and walks across it as long
# (./dialfred bench world_statistics).
ROOM_SIZE = {'kitchen': ((2.75, 3.25), (5.0, 6.25)), 'living_room': ((3.5, 4.5), (5.0, 7.0)),
             'bedroom': ((3.0, 3.5), (4.75, 6.0)), 'bathroom': ((2.0, 2.75), (3.0, 4.25))}

WALL_CABINET_P = 0.4   # base units of a kitchen's wall run with a cabinet above
ISLAND_P = 0.5         # kitchens with a free-standing counter (where one fits)
DESK_CHAIR_P = 0.8     # desks with a chair in front

MAX_SMALL_TYPES = {'kitchen': 30, 'living_room': 20, 'bedroom': 18, 'bathroom': 15}


@dataclass(frozen=True)
class Fixture:
    """A piece of furniture or appliance of a layout (not moved by episodes)."""

    object_id: str
    type_name: str
    spec: ShapeSpec
    position: tuple[float, float, float]   # world position of the object-frame origin
    yaw: float
    colour: str
    parent: Optional[str] = None            # the fixture it stands on (a microwave on a counter)
    controls: Optional[str] = None          # a faucet controls its sink basin, a knob its burner
    blocks_floor: bool = True


@dataclass(frozen=True)
class RoomLayout:
    """One floor plan: the room, its fixtures, the free grid and the small-object pool."""

    scene: str
    number: int
    room_type: str
    width: float
    depth: float
    wall_colour: str
    floor_colour: str
    fixtures: tuple[Fixture, ...]
    navigable: frozenset              # grid points (i, j) at (i * GRID, j * GRID) the agent may stand on
    small_object_types: tuple[str, ...]
    fixture_index: dict = field(default_factory=dict, compare=False, hash=False)

    def fixture(self, object_id: str) -> Fixture:
        return self.fixture_index[object_id]


def all_scenes() -> list[str]:
    """The 120 floor plan names, kitchens first."""
    return [f'FloorPlan{n}' for room in ROOM_TYPES for n in SCENE_RANGES[room]]


def scene_number(scene: str) -> int:
    """'FloorPlan207' -> 207; ValueError for anything that is not one of the 120 floor plans."""
    if not isinstance(scene, str) or not scene.startswith('FloorPlan'):
        raise ValueError(f'unknown scene {scene!r}: expected FloorPlan<N>, N in 1-30, 201-230, 301-330, 401-430')
    try:
        number = int(scene[len('FloorPlan'):])
    except ValueError:
        raise ValueError(f'unknown scene {scene!r}') from None
    if room_type_of(number) is None:
        raise ValueError(f'unknown scene {scene!r}: N must be in 1-30, 201-230, 301-330 or 401-430')
    return number


def room_type_of(number: int) -> Optional[str]:
    for room, numbers in SCENE_RANGES.items():
        if number in numbers:
            return room
    return None


# ----------------------------------------------------------------------------------------------
# Geometry helpers

_WALLS = ('south', 'east', 'north', 'west')


def _wall_frame(wall: str, width: float, depth: float):
    """Start point, unit direction along the wall, inward normal and the yaw facing inward."""
    if wall == 'south':
        return (0.0, 0.0), (1.0, 0.0), (0.0, 1.0), math.pi / 2, width
    if wall == 'east':
        return (width, 0.0), (0.0, 1.0), (-1.0, 0.0), math.pi, depth
    if wall == 'north':
        return (width, depth), (-1.0, 0.0), (0.0, -1.0), -math.pi / 2, width
    return (0.0, depth), (0.0, -1.0), (1.0, 0.0), 0.0, depth


def footprint(position, yaw: float, size) -> tuple[float, float, float, float]:
    """World axis-aligned rectangle (xmin, ymin, xmax, ymax) of a box of `size` at a yaw (any)."""
    c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
    hx = (size[0] * c + size[1] * s) / 2
    hy = (size[0] * s + size[1] * c) / 2
    return (position[0] - hx, position[1] - hy, position[0] + hx, position[1] + hy)


def _overlaps(a, b, margin: float = 0.0) -> bool:
    return not (a[2] + margin <= b[0] or b[2] + margin <= a[0] or a[3] + margin <= b[1] or b[3] + margin <= a[1])


def local_to_world(position, yaw: float, local) -> tuple[float, float, float]:
    """A point of an object frame (origin at `position`, turned by `yaw`) in the world frame."""
    c, s = math.cos(yaw), math.sin(yaw)
    return (position[0] + c * local[0] - s * local[1], position[1] + s * local[0] + c * local[1],
            position[2] + local[2])


def slab_spec(size) -> ShapeSpec:
    """A counter top: one slab whose top is a placement surface."""
    sx, sy, sz = size
    return ShapeSpec(parts=(Part('box', (sx / 2, sy / 2, sz / 2), (0.0, 0.0, sz / 2)),),
                     size=(sx, sy, sz),
                     surfaces=(Surface((0.0, 0.0, sz), (sx / 2 - 0.04, sy / 2 - 0.04), 0.6),))


CARCASS_T = 0.025      # board thickness of a chest's carcass


def carcass_spec(size, shelf: Optional[tuple[float, float]] = None, plinth: float = 0.06) -> ShapeSpec:
    """The frame of a chest whose front is drawers or doors (those are fixtures of their own): a top
    whose upper face is a placement surface, two sides, a back and a plinth; with `shelf` = (height,
    clearance), an open board at that height with a surface of its own (a side table's lower shelf)."""
    sx, sy, sz = size
    t = CARCASS_T
    parts = [Part('box', (sx / 2, sy / 2, t / 2), (0.0, 0.0, sz - t / 2)),
             Part('box', (sx / 2, t / 2, (sz - t) / 2), (0.0, sy / 2 - t / 2, (sz - t) / 2)),
             Part('box', (sx / 2, t / 2, (sz - t) / 2), (0.0, -sy / 2 + t / 2, (sz - t) / 2)),
             Part('box', (t / 2, sy / 2 - t, (sz - t) / 2), (-sx / 2 + t / 2, 0.0, (sz - t) / 2), colour='dark'),
             Part('box', (sx / 2 - 0.02, sy / 2 - t, plinth / 2), (-0.02, 0.0, plinth / 2), colour='dark')]
    surfaces = [Surface((0.0, 0.0, sz), (sx / 2 - 0.03, sy / 2 - 0.03), 0.6)]
    if shelf is not None:
        shelf_z, clearance = shelf
        parts.append(Part('box', (sx / 2 - t / 2, sy / 2 - t, t / 2), (t / 2, 0.0, shelf_z - t / 2), colour='light'))
        surfaces.append(Surface((0.02, 0.0, shelf_z), (sx / 2 - 0.06, sy / 2 - t - 0.03), clearance))
    return ShapeSpec(parts=tuple(parts), size=(sx, sy, sz), surfaces=tuple(surfaces))


def _room_shell_free(width: float, depth: float):
    """Grid points strictly inside the room, at least AGENT_RADIUS from every wall."""
    pts = []
    for i in range(1, int(round(width / GRID))):
        for j in range(1, int(round(depth / GRID))):
            x, y = i * GRID, j * GRID
            if AGENT_RADIUS <= x <= width - AGENT_RADIUS and AGENT_RADIUS <= y <= depth - AGENT_RADIUS:
                pts.append((i, j))
    return pts


def _disc_hits_rect(x: float, y: float, r: float, rect) -> bool:
    dx = max(rect[0] - x, 0.0, x - rect[2])
    dy = max(rect[1] - y, 0.0, y - rect[3])
    return dx * dx + dy * dy < r * r


def navigable_points(width: float, depth: float, rects) -> set:
    """Grid points where the agent's disc touches no furniture footprint, in the largest region."""
    free = {(i, j) for (i, j) in _room_shell_free(width, depth)
            if not any(_disc_hits_rect(i * GRID, j * GRID, AGENT_RADIUS, r) for r in rects)}
    best: set = set()
    seen: set = set()
    for start in sorted(free):
        if start in seen:
            continue
        comp, stack = set(), [start]
        seen.add(start)
        while stack:
            i, j = stack.pop()
            comp.add((i, j))
            for n in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)):
                if n in free and n not in seen:
                    seen.add(n)
                    stack.append(n)
        if len(comp) > len(best):
            best = comp
    return best


# ----------------------------------------------------------------------------------------------
# Layout generation

class _Builder:
    """Places fixtures one by one, keeping floor rectangles and wall spans free of overlaps."""

    def __init__(self, rng: np.random.Generator, room_type: str, width: float, depth: float):
        self.rng, self.room_type, self.width, self.depth = rng, room_type, width, depth
        self.fixtures: list[Fixture] = []
        self.rects: list[tuple] = []             # floor footprints
        self.mounts: dict[str, list] = {w: [] for w in _WALLS}  # (start, end, zlo, zhi) along walls
        self.counts: dict[str, int] = {}
        self.catalog = load_catalog()

    def new_id(self, type_name: str) -> str:
        n = self.counts.get(type_name, 0)
        self.counts[type_name] = n + 1
        return f'{type_name}_{n}'

    def colour(self, type_name: str) -> str:
        colours = self.catalog[type_name].colours
        return colours[int(self.rng.integers(len(colours)))]

    def jitter(self, size, amount: float = 0.1):
        f = 1.0 + self.rng.uniform(-amount, amount, size=3)
        return (size[0] * f[0], size[1] * f[1], size[2] * f[2])

    def spec(self, type_name: str, size) -> ShapeSpec:
        base = shape_for(type_name, self.catalog[type_name].dims)
        return fit_spec(base, size)

    def add(self, type_name, spec, position, yaw, *, parent=None, controls=None, blocks=True,
            colour=None, object_id=None) -> Fixture:
        fx = Fixture(object_id or self.new_id(type_name), type_name, spec, tuple(position), yaw,
                     colour or self.colour(type_name), parent, controls, blocks)
        self.fixtures.append(fx)
        if blocks:
            self.rects.append(footprint(position, yaw, spec.size))
        return fx

    def free_rect(self, rect, margin: float = 0.05) -> bool:
        if rect[0] < -1e-6 or rect[1] < -1e-6 or rect[2] > self.width + 1e-6 or rect[3] > self.depth + 1e-6:
            return False
        return not any(_overlaps(rect, r, margin) for r in self.rects)

    def wall_slot(self, size, tries: int = 40):
        """A free spot against a random wall for a footprint of `size`; None if none found."""
        for _ in range(tries):
            wall = _WALLS[int(self.rng.integers(4))]
            start, along, normal, yaw, length = _wall_frame(wall, self.width, self.depth)
            if size[1] + 0.1 > length:
                continue
            s = float(self.rng.uniform(size[1] / 2 + 0.05, length - size[1] / 2 - 0.05))
            s = round(s / 0.05) * 0.05
            d = size[0] / 2 + 0.02
            pos = (start[0] + along[0] * s + normal[0] * d, start[1] + along[1] * s + normal[1] * d, 0.0)
            if self.free_rect(footprint(pos, yaw, size)):
                return wall, s, pos, yaw
        return None

    def interior_slot(self, size, tries: int = 60, clearance: float = 0.55):
        for _ in range(tries):
            yaw = float(self.rng.choice([0.0, math.pi / 2]))
            rect0 = footprint((0, 0, 0), yaw, size)
            hx, hy = rect0[2], rect0[3]
            lo_x, hi_x = hx + clearance, self.width - hx - clearance
            lo_y, hi_y = hy + clearance, self.depth - hy - clearance
            if lo_x > hi_x or lo_y > hi_y:
                return None
            pos = (round(float(self.rng.uniform(lo_x, hi_x)) / 0.05) * 0.05,
                   round(float(self.rng.uniform(lo_y, hi_y)) / 0.05) * 0.05, 0.0)
            if self.free_rect(footprint(pos, yaw, size), margin=clearance):
                return pos, yaw
        return None

    def mount_slot(self, size, z0: float, tries: int = 40):
        for _ in range(tries):
            wall = _WALLS[int(self.rng.integers(4))]
            start, along, normal, yaw, length = _wall_frame(wall, self.width, self.depth)
            if size[1] + 0.2 > length:
                continue
            s = round(float(self.rng.uniform(size[1] / 2 + 0.1, length - size[1] / 2 - 0.1)) / 0.05) * 0.05
            span = (s - size[1] / 2, s + size[1] / 2, z0, z0 + size[2])
            if any(not (span[1] <= m[0] or m[1] <= span[0] or span[3] <= m[2] or m[3] <= span[2])
                   for m in self.mounts[wall]):
                continue
            # Do not hang things where tall furniture stands against this wall.
            d = size[0] / 2 + 0.005
            pos = (start[0] + along[0] * s + normal[0] * d, start[1] + along[1] * s + normal[1] * d, z0)
            probe = footprint(pos, yaw, (0.3, size[1], 0))
            if any(_overlaps(probe, footprint(f.position, f.yaw, f.spec.size)) and
                   f.spec.size[2] + f.position[2] > z0 for f in self.fixtures if f.blocks_floor):
                continue
            self.mounts[wall].append(span)
            return pos, yaw
        return None

    # Chests ------------------------------------------------------------------------------------

    def chest(self, type_name: str, size, pos, yaw: float, rows, cols: int = 1, unit: str = 'Drawer',
              shelf: Optional[tuple[float, float]] = None) -> Fixture:
        """A chest standing at `pos` facing `yaw`: its carcass (a `type_name` fixture whose top is a
        surface) and, under the top, `rows` (unit heights, top down) of `cols` units (drawers or
        cabinets) filling its front, each an openable fixture of its own. The footprint blocks the floor."""
        depth, width, height = size
        t = CARCASS_T
        colour = self.colour(type_name)
        self.rects.append(footprint(pos, yaw, size))
        host = self.add(type_name, carcass_spec(size, shelf), pos, yaw, blocks=False, colour=colour)
        unit_w = (width - 2 * t) / cols
        z = height - t
        for h in rows:
            z -= h
            for c in range(cols):
                y_mid = -(width - 2 * t) / 2 + (c + 0.5) * unit_w
                spot = local_to_world(pos, yaw, (t / 2 + 0.0025, y_mid, z + 0.002))
                self.add(unit, self.spec(unit, (depth - t - 0.005, unit_w - 0.004, h - 0.004)), spot, yaw,
                         blocks=False, colour=colour)
        return host

    # Counter runs -----------------------------------------------------------------------------

    def counter_run(self, units: list[str], unit_width: float, island: bool = False) -> bool:
        """A run of base units with a counter top: 'cabinet', 'drawers', 'sink', 'stove'; against a
        wall, or free-standing with room to walk round it (`island`). Kitchen runs against a wall get
        wall cabinets above some of their units."""
        run_len = unit_width * len(units)
        size = (COUNTER_DEPTH, run_len, COUNTER_HEIGHT)
        if island:
            slot = self.interior_slot(size, clearance=0.6)
            if slot is None:
                return False
            pos, yaw = slot
        else:
            slot = self.wall_slot(size, tries=80)
            if slot is None:
                return False
            wall, s, pos, yaw = slot
        self.rects.append(footprint(pos, yaw, size))
        segments = self._base_units(pos, yaw, units, unit_width)
        counters = [self.add('CounterTop', slab_spec((COUNTER_DEPTH, b - a, COUNTER_SLAB)),
                             local_to_world(pos, yaw, (0.0, -(a + b) / 2, COUNTER_HEIGHT - COUNTER_SLAB)), yaw,
                             blocks=False) for a, b in segments]
        for k, unit in enumerate(units):
            if unit == 'stove':
                y_mid = -run_len / 2 + k * unit_width + unit_width / 2
                host = next(c for (a, b), c in zip(segments, counters) if a <= y_mid <= b)
                self._burners(pos, yaw, y_mid, host)
        if self.room_type == 'kitchen' and not island:
            for k, unit in enumerate(units):
                if unit in ('cabinet', 'drawers') and self.rng.random() < WALL_CABINET_P:
                    y_mid = -run_len / 2 + k * unit_width + unit_width / 2
                    self.add('Cabinet', self.spec('Cabinet', (0.34, unit_width - 0.02, 0.55)),
                             local_to_world(pos, yaw, (-COUNTER_DEPTH / 2 + 0.17, -y_mid, 1.5)), yaw, blocks=False)
        return True

    def _base_units(self, pos, yaw: float, units: list[str], unit_width: float) -> list[tuple[float, float]]:
        """The units under a counter run at `pos` facing `yaw`, left to right along the run; returns the
        stretches (along the run's own y, +y to its left) the counter top covers: all but the sinks."""
        run_len = unit_width * len(units)
        base_h = COUNTER_HEIGHT - COUNTER_SLAB
        segments: list[tuple[float, float]] = []
        seg_start = -run_len / 2
        for k, unit in enumerate(units):
            y_lo = -run_len / 2 + k * unit_width
            y_mid = y_lo + unit_width / 2
            centre = local_to_world(pos, yaw, (0.0, -y_mid, 0.0))
            if unit == 'sink':
                if y_lo > seg_start + 1e-6:        # the counter top has a hole here
                    segments.append((seg_start, y_lo))
                seg_start = y_lo + unit_width
                self._sink(pos, yaw, y_mid, centre, unit_width)
            elif unit == 'drawers':
                dh = 0.2
                self.add('Cabinet', self.spec('Cabinet', (COUNTER_DEPTH - 0.04, unit_width - 0.02, base_h - dh - 0.02)),
                         (centre[0], centre[1], 0.0), yaw, blocks=False)
                self.add('Drawer', self.spec('Drawer', (COUNTER_DEPTH - 0.04, unit_width - 0.02, dh)),
                         (centre[0], centre[1], base_h - dh), yaw, blocks=False)
            else:
                self.add('Cabinet', self.spec('Cabinet', (COUNTER_DEPTH - 0.04, unit_width - 0.02, base_h)),
                         (centre[0], centre[1], 0.0), yaw, blocks=False)
        if seg_start < run_len / 2 - 1e-6:
            segments.append((seg_start, run_len / 2))
        return segments

    def _sink(self, pos, yaw: float, y_mid: float, centre, unit_width: float) -> None:
        """A sink unit: the basin, a rim of counter round it (so the hole is no gap to the floor), the
        faucet that controls it and the cabinet under it."""
        bsize = (FURNITURE_SIZE['SinkBasin'][0], unit_width - 0.08, FURNITURE_SIZE['SinkBasin'][2])
        basin = self.add('SinkBasin', self.spec('SinkBasin', bsize),
                         local_to_world(pos, yaw, (0.02, -y_mid, COUNTER_HEIGHT - bsize[2])), yaw,
                         blocks=False, colour='silver')
        rim = ShapeSpec(parts=(Part('box', (0.06, unit_width / 2, COUNTER_SLAB / 2),
                                    (-COUNTER_DEPTH / 2 + 0.06, 0.0, COUNTER_SLAB / 2)),),
                        size=slab_spec((COUNTER_DEPTH, unit_width, COUNTER_SLAB)).size)
        self.add('CounterTop', rim, (centre[0], centre[1], COUNTER_HEIGHT - COUNTER_SLAB), yaw, blocks=False,
                 colour='gray')
        self.add('Faucet', self.spec('Faucet', FURNITURE_SIZE['Faucet']),
                 local_to_world(pos, yaw, (-COUNTER_DEPTH / 2 + 0.1, -y_mid, COUNTER_HEIGHT)), yaw,
                 controls=basin.object_id, blocks=False, colour='silver', parent=None)
        self.add('Cabinet', self.spec('Cabinet', (COUNTER_DEPTH - 0.04, unit_width - 0.02,
                                                  COUNTER_HEIGHT - bsize[2] - 0.04)),
                 (centre[0], centre[1], 0.0), yaw, blocks=False)

    def _burners(self, pos, yaw: float, y_mid: float, host: Fixture) -> None:
        """A stove unit's four burners on the counter top `host`, each with its knob on the front."""
        for dx, dy in ((0.05, -0.14), (0.05, 0.14), (-0.18, -0.14), (-0.18, 0.14)):
            burner = self.add('StoveBurner', self.spec('StoveBurner', FURNITURE_SIZE['StoveBurner']),
                              local_to_world(pos, yaw, (dx, -y_mid + dy, COUNTER_HEIGHT)), yaw,
                              parent=host.object_id, blocks=False)
            self.add('StoveKnob', self.spec('StoveKnob', FURNITURE_SIZE['StoveKnob']),
                     local_to_world(pos, yaw, (COUNTER_DEPTH / 2 + 0.025, -y_mid + dy * 0.8 - dx * 0.25,
                                               COUNTER_HEIGHT - 0.1)),
                     yaw, controls=burner.object_id, blocks=False)


def _chairs_at(b: _Builder, host: Fixture, spots) -> int:
    """Chairs facing `host` at `spots` (x, y in its frame: their seat centres), where the floor is free."""
    placed = 0
    for lx, ly in spots:
        size = b.jitter(FURNITURE_SIZE['Chair'], 0.05)
        pos = local_to_world(host.position, host.yaw, (lx, ly, 0.0))
        yaw = host.yaw + (math.pi if lx > 0 else 0.0)      # its front (the seat) towards the host
        if b.free_rect(footprint(pos, yaw, size), margin=0.02):
            b.add('Chair', b.spec('Chair', size), pos, yaw)
            placed += 1
    return placed


def _dining_chairs(b: _Builder, table: Fixture) -> None:
    """Two to four chairs along a dining table's long sides."""
    dx = table.spec.size[0] / 2 + 0.22
    dy = min(0.4, table.spec.size[1] / 4)
    spots = [(sx * dx, sy * dy) for sx in (1, -1) for sy in (1, -1)]
    b.rng.shuffle(spots)
    _chairs_at(b, table, spots[:int(b.rng.integers(2, 5))])


def _chest_plan(type_name: str, size) -> Optional[dict]:
    """How a chest of `type_name` is built (Builder.chest): a dresser is rows of drawers, a side table
    one drawer over an open shelf, a TV stand two cupboards; None for other furniture."""
    depth, width, height = size
    usable = height - CARCASS_T - 0.06
    if type_name == 'Dresser':
        rows = 3 if height > 0.75 else 2
        return {'rows': [usable / rows] * rows, 'cols': 2 if width >= 1.4 else 1}
    if type_name == 'SideTable':
        dh = 0.15
        return {'rows': [dh], 'shelf': (0.12, height - CARCASS_T - dh - 0.12 - 0.01)}
    if type_name == 'TVStand':
        return {'rows': [usable], 'cols': 2, 'unit': 'Cabinet'}
    return None


def _place_on(b: _Builder, type_name: str, host_types: list[str]) -> bool:
    """Stand an appliance on the top surface of a fixture of one of `host_types`."""
    hosts = [f for f in b.fixtures if f.type_name in host_types and f.spec.surfaces]
    b.rng.shuffle(hosts)
    size = b.jitter(FURNITURE_SIZE[type_name], 0.06)
    for host in hosts:
        top = max(host.spec.surfaces, key=lambda s: s.center[2])
        if top.inside or size[1] / 2 > top.half_size[1] or size[0] / 2 > top.half_size[0] + 0.05:
            continue
        taken = [f for f in b.fixtures if f.parent == host.object_id]
        for _ in range(12):
            ly = float(b.rng.uniform(-top.half_size[1] + size[1] / 2, top.half_size[1] - size[1] / 2))
            lx = top.center[0] - max(0.0, top.half_size[0] - size[0] / 2)  # pushed to the back
            pos = local_to_world(host.position, host.yaw, (lx, top.center[1] + ly, top.center[2]))
            rect = footprint(pos, host.yaw, size)
            if any(_overlaps(rect, footprint(t.position, t.yaw, t.spec.size), 0.03) for t in taken):
                continue
            b.add(type_name, b.spec(type_name, size), pos, host.yaw, parent=host.object_id, blocks=False)
            return True
    return False


def _small_object_pool(rng: np.random.Generator, room_type: str, receptacle_types: set) -> tuple[str, ...]:
    catalog = load_catalog()
    pool = []
    for t in sorted(catalog.values(), key=lambda t: t.name):
        if not t.pickupable or t.parent_type or room_type not in t.room_types or t.dims is None:
            continue
        if not set(t.typical_receptacles) & receptacle_types:
            continue
        p = t.scene_counts.get(room_type, 0) / 30.0
        if rng.random() < max(p, 0.15):
            pool.append(t.name)
    rng.shuffle(pool)
    return tuple(sorted(pool[:MAX_SMALL_TYPES[room_type]]))


def _kitchen_counters(b: _Builder) -> bool:
    n_units = int(b.rng.integers(6, 10))
    units = ['cabinet'] * n_units
    sink_at = int(b.rng.integers(1, n_units - 1))
    units[sink_at] = 'sink'
    stove_choices = [k for k in range(n_units) if abs(k - sink_at) > 1]
    units[int(b.rng.choice(stove_choices))] = 'stove'
    for k in range(n_units):
        if units[k] == 'cabinet' and b.rng.random() < 0.4:
            units[k] = 'drawers'
    # Split long runs over two walls.
    if n_units >= 7 and b.rng.random() < 0.6:
        cut = n_units // 2
        first, second = units[:cut], units[cut:]
        return b.counter_run(first, 0.6) and b.counter_run(second, 0.6)
    return b.counter_run(units, 0.6)


def _bathroom_counter(b: _Builder) -> bool:
    n = 3 if b.rng.random() < 0.5 else 2
    units = ['cabinet'] * n
    units[(n - 1) * int(b.rng.integers(2))] = 'sink'        # at one end: the counter top stays whole
    for k in range(n):
        if units[k] == 'cabinet' and b.rng.random() < 0.35:
            units[k] = 'drawers'
    return b.counter_run(units, 0.6)


def _try_layout(number: int, attempt: int) -> Optional[RoomLayout]:
    room_type = room_type_of(number)
    rng = np.random.default_rng([number, attempt, 20221122])
    (wlo, whi), (dlo, dhi) = ROOM_SIZE[room_type]
    width = round(float(rng.uniform(wlo, whi)) / GRID) * GRID
    depth = round(float(rng.uniform(dlo, dhi)) / GRID) * GRID
    if rng.random() < 0.5:              # the long side along x or along y
        width, depth = depth, width
    b = _Builder(rng, room_type, width, depth)
    if room_type == 'kitchen' and not _kitchen_counters(b):
        return None
    if room_type == 'kitchen' and rng.random() < ISLAND_P:
        units = ['drawers' if rng.random() < 0.4 else 'cabinet' for _ in range(int(rng.integers(2, 4)))]
        b.counter_run(units, 0.6, island=True)      # a kitchen without room for one has none
    if room_type == 'bathroom' and not _bathroom_counter(b):
        return None
    for type_name, prob, (lo, hi), where in RECIPES[room_type]:
        if rng.random() >= prob:
            continue
        for _ in range(int(rng.integers(lo, hi + 1))):
            size = b.jitter(FURNITURE_SIZE[type_name], 0.08)
            if where == 'wall':
                slot = b.wall_slot(size)
                if slot is None:
                    continue
                _, _, pos, yaw = slot
                plan = _chest_plan(type_name, size)
                if plan is not None:
                    b.chest(type_name, size, pos, yaw, **plan)
                    continue
                host = b.add(type_name, b.spec(type_name, size), pos, yaw)
                if type_name == 'Desk' and rng.random() < DESK_CHAIR_P:
                    _chairs_at(b, host, [(size[0] / 2 + 0.28, 0.0)])
                if type_name == 'Bathtub':  # the basin is the receptacle inside the tub
                    b.add('BathtubBasin', b.spec('BathtubBasin', (size[0] - 0.16, size[1] - 0.18, 0.06)),
                          (pos[0], pos[1], 0.08), yaw, blocks=False, colour='white')
            elif where == 'interior':
                slot = b.interior_slot(size)
                if slot is None:
                    continue
                pos, yaw = slot
                host = b.add(type_name, b.spec(type_name, size), pos, yaw)
                if type_name == 'DiningTable':
                    _dining_chairs(b, host)
            elif where == 'mount':
                slot = b.mount_slot(size, WALL_MOUNT_Z[type_name])
                if slot is None:
                    continue
                pos, yaw = slot
                b.add(type_name, b.spec(type_name, size), pos, yaw, blocks=False)
            else:
                _place_on(b, type_name, where[3:].split('|'))
    nav = navigable_points(width, depth, b.rects)
    if len(nav) < max(MIN_NAVIGABLE, 0.3 * len(_room_shell_free(width, depth))):
        return None
    # Every fixture one can use must be reachable: a free grid point within 1.0 m of its front.
    for f in b.fixtures:
        t = b.catalog[f.type_name]
        if not (t.receptacle or t.openable or t.toggleable):
            continue
        front = local_to_world(f.position, f.yaw, (f.spec.size[0] / 2 + 0.3, 0.0, 0.0))
        if not any(math.hypot(i * GRID - front[0], j * GRID - front[1]) <= 1.0 for i, j in nav):
            return None
    receptacle_types = {f.type_name for f in b.fixtures if b.catalog[f.type_name].receptacle}
    pool = _small_object_pool(rng, room_type, receptacle_types)
    walls = ('white', 'beige', 'tan', 'khaki', 'gray')
    floors = ('brown', 'tan', 'gray', 'beige', 'maroon')
    return RoomLayout(scene=f'FloorPlan{number}', number=number, room_type=room_type, width=width,
                      depth=depth, wall_colour=walls[int(rng.integers(len(walls)))],
                      floor_colour=floors[int(rng.integers(len(floors)))], fixtures=tuple(b.fixtures),
                      navigable=frozenset(nav), small_object_types=pool,
                      fixture_index={f.object_id: f for f in b.fixtures})


@functools.lru_cache(maxsize=None)
def room_layout(scene: str) -> RoomLayout:
    """The layout of floor plan `scene` ('FloorPlan7'); the same on every call and every machine."""
    number = scene_number(scene)
    for attempt in range(200):
        layout = _try_layout(number, attempt)
        if layout is not None:
            return layout
    raise RuntimeError(f'could not lay out {scene} in 200 attempts')
