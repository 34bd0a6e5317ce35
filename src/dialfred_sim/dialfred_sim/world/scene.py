"""The live world of one episode: pybullet bodies, object states, the agent and its camera.

`World` owns one pybullet client. `World.build(layout, rng)` lays out a floor plan and scatters its
small objects; afterwards every object's state lives in `World.objects` (the ground truth the task
checker and the oracle read) and its body in pybullet (what the camera sees).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Optional

import numpy as np

from .bodies import ShapeCache, build_body, set_articulation
from .catalog import ObjectType, load_catalog
from .geometry import ShapeSpec
from .hand import carry_spot, hand_spot, solids_of
from .open_parts import blocks, footprints, moving_part_boxes
from .palette import rgba
from .rooms import GRID, WALL_HEIGHT, RoomLayout, local_to_world
from .shapes import shape_for

CAMERA_HEIGHT = 1.5          # metres above the floor
FOV_DEG = 90.0               # AI2-THOR's default field of view
NEAR, FAR = 0.05, 12.0       # clipping planes, metres
HORIZON_MIN, HORIZON_MAX = -30.0, 60.0   # look up / down limits (positive = down), as in AI2-THOR
SMALL_OBJECT_COPIES = (0.6, 0.15, 0.1, 0.15)   # chances of 1, 2, 3, 4 instances of each small type a room has
START_HORIZON = 30.0         # ALFRED starts every episode looking 30 degrees down
LIGHT_DIRECTION = (0.3, 0.5, 1.0)
EYE_SHIFT = 0.0007           # metres the drawn eye sits behind the true one (see World.view_matrix)

COLD, ROOM, HOT = 'cold', 'room', 'hot'
OPENING_SWEEP = (0.25, 0.5, 0.75, 1.0)   # fractions of a door's swing checked against the agent
SLICES_PER_OBJECT = {'Bread': 5}
DEFAULT_SLICES = 4


def _host_order(hosts: list, rng: np.random.Generator) -> list:
    """The order in which a small object tries its hosts: receptacle types in random order, and within
    a type its instances in random order, so that a type of many units (a dresser's drawers, a kitchen's
    cabinets) is as likely a first choice as one table."""
    by_type: dict = {}
    for host in hosts:
        by_type.setdefault(host.type_name, []).append(host)
    types = sorted(by_type)
    return [by_type[t][k] for t in (types[i] for i in rng.permutation(len(types)))
            for k in rng.permutation(len(by_type[t]))]


@dataclass
class WorldObject:
    """One object instance and its state (fixtures and small objects alike)."""

    object_id: str
    otype: ObjectType
    colour: str
    spec: ShapeSpec
    body: int
    position: tuple[float, float, float]
    yaw: float
    fixture: bool                                # part of the floor plan, never moves
    parent: Optional[str] = None                 # receptacle it is in/on
    surface: int = 0                             # index of the parent's surface it rests on
    local: tuple[float, float, float] = (0.0, 0.0, 0.0)   # position in the parent's frame
    local_yaw: float = 0.0
    contents: list[str] = field(default_factory=list)
    controls: Optional[str] = None
    is_open: bool = False
    is_on: bool = False
    is_dirty: bool = False
    is_sliced: bool = False
    temperature: str = ROOM
    held: bool = False
    sliced_from: Optional[str] = None            # a slice remembers the object it was cut from

    @property
    def type_name(self) -> str:
        return self.otype.name


@dataclass(frozen=True)
class ObjectState:
    """Ground truth about one object, as the oracle and the task checker read it."""

    object_id: str
    type_name: str
    noun: str
    position: tuple[float, float, float]
    parent: Optional[str]
    parent_type: Optional[str]
    colour: str
    material: str
    pickupable: bool
    receptacle: bool
    is_open: bool
    is_on: bool
    is_dirty: bool
    is_sliced: bool
    temperature: str
    held: bool
    contents: tuple[str, ...]


@dataclass
class AgentPose:
    """The agent on the 0.25 m grid: point (i, j), yaw in {0, 90, 180, 270}, camera pitch."""

    i: int
    j: int
    rotation: int = 0
    horizon: float = START_HORIZON

    @property
    def x(self) -> float:
        return self.i * GRID

    @property
    def y(self) -> float:
        return self.j * GRID

    def forward_cell(self) -> tuple[int, int]:
        di, dj = {0: (1, 0), 90: (0, 1), 180: (-1, 0), 270: (0, -1)}[self.rotation % 360]
        return self.i + di, self.j + dj


def _quat(client, yaw: float):
    return client.getQuaternionFromEuler((0.0, 0.0, yaw))


class World:
    """The pybullet scene of one episode plus the ground-truth state of every object."""

    def __init__(self, client, width: int = 128, height: int = 128):
        self.client = client
        self.width, self.height = width, height
        self.cache = ShapeCache(client)
        self.layout: Optional[RoomLayout] = None
        self.objects: dict[str, WorldObject] = {}
        self.body_to_object: dict[int, str] = {}
        self.structure_bodies: dict[int, str] = {}   # floor, walls, ceiling
        self.agent = AgentPose(0, 0)
        self.held: Optional[str] = None
        self._projection = client.computeProjectionMatrixFOV(FOV_DEG, width / height, NEAR, FAR)
        self._counts: dict[str, int] = {}
        self._fixture_bodies: dict[str, int] = {}      # the current room's furniture, kept for its next episode
        self._carry_cache: dict[tuple, tuple] = {}     # carry_spot per (size, pose), for this room
        self._outline_cache: dict[tuple, list] = {}    # open_part_outlines per (object, pose, fraction)
        # ground_truth.closeup_pixels per (object, what every body's pose and joints are); emptied
        # whenever a body is made or removed (see bodies_changed)
        self.closeup_cache: dict[tuple, object] = {}

    def bodies_changed(self) -> None:
        """A body was made or removed: renders made before may not repeat bit for bit (pybullet's
        draw order), so cached close-ups are dropped."""
        self.closeup_cache = {}

    # ------------------------------------------------------------------ building

    def build(self, layout: RoomLayout, rng: np.random.Generator, dirty_probability: float = 0.25) -> None:
        """Lay out `layout` from scratch and scatter its small objects using `rng`."""
        c = self.client
        # Bodies go one by one rather than by resetSimulation(): pybullet 3.2.7 never frees the
        # visual shapes a reset drops (about 1 MB per room), while the shape cache lets every room
        # reuse the shapes made before. The same room again keeps its walls and furniture (and
        # pybullet leaks a little for every body made and removed). Removing in descending id
        # order makes pybullet hand the freed ids out again in ascending order, so a room gets
        # the same body ids (segmentation values) whatever was built before.
        reuse = self.layout is layout and bool(self._fixture_bodies)
        self.bodies_changed()
        kept = set(self.structure_bodies) | set(self._fixture_bodies.values()) if reuse else set()
        for body in sorted(set(self.body_to_object) | set(self.structure_bodies), reverse=True):
            if body not in kept:
                c.removeBody(body)
        self.layout = layout
        self.objects, self.body_to_object = {}, {}
        self.held = None
        self._carry_cache, self._outline_cache = {}, {}
        self._counts = {}
        if not reuse:
            self.structure_bodies, self._fixture_bodies = {}, {}
            self._build_structure(layout)
        catalog = load_catalog()
        for fx in layout.fixtures:
            otype = catalog[fx.type_name]
            if reuse:
                body = self._fixture_bodies[fx.object_id]
                if fx.spec.articulation is not None:
                    set_articulation(c, body, fx.spec, 0.0)     # doors and drawers start closed
            else:
                body = build_body(c, fx.spec, fx.colour, fx.position, fx.yaw, self.cache)
                self._fixture_bodies[fx.object_id] = body
            obj = WorldObject(fx.object_id, otype, fx.colour, fx.spec, body, fx.position, fx.yaw, True,
                              parent=fx.parent, controls=fx.controls)
            self._register(obj)
            self._counts[fx.type_name] = self._counts.get(fx.type_name, 0) + 1
        for fx in layout.fixtures:
            if fx.parent:
                self.objects[fx.parent].contents.append(fx.object_id)
        self._scatter(layout, rng, dirty_probability)
        start = sorted(layout.navigable)[int(rng.integers(len(layout.navigable)))]
        self.agent = AgentPose(start[0], start[1], int(rng.integers(4)) * 90, START_HORIZON)

    def _build_structure(self, layout: RoomLayout) -> None:
        c = self.client
        w, d, t = layout.width, layout.depth, 0.1
        boxes = [
            ('Floor', (w / 2 + t, d / 2 + t, t / 2), (w / 2, d / 2, -t / 2), layout.floor_colour),
            ('Ceiling', (w / 2 + t, d / 2 + t, t / 2), (w / 2, d / 2, WALL_HEIGHT + t / 2), 'white'),
            ('Wall', (w / 2 + t, t / 2, WALL_HEIGHT / 2), (w / 2, -t / 2, WALL_HEIGHT / 2), layout.wall_colour),
            ('Wall', (w / 2 + t, t / 2, WALL_HEIGHT / 2), (w / 2, d + t / 2, WALL_HEIGHT / 2), layout.wall_colour),
            ('Wall', (t / 2, d / 2 + t, WALL_HEIGHT / 2), (-t / 2, d / 2, WALL_HEIGHT / 2), layout.wall_colour),
            ('Wall', (t / 2, d / 2 + t, WALL_HEIGHT / 2), (w + t / 2, d / 2, WALL_HEIGHT / 2), layout.wall_colour),
        ]
        for name, half, pos, colour in boxes:
            vis = self.cache.visual('box', half, rgba(colour))
            body = c.createMultiBody(baseMass=0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=vis,
                                     basePosition=pos)
            self.structure_bodies[body] = name

    def _register(self, obj: WorldObject) -> None:
        self.objects[obj.object_id] = obj
        self.body_to_object[obj.body] = obj.object_id

    def new_object_id(self, type_name: str) -> str:
        n = self._counts.get(type_name, 0)
        self._counts[type_name] = n + 1
        return f'{type_name}_{n}'

    def spawn(self, type_name: str, colour: str, position=(0.0, 0.0, -5.0), yaw: float = 0.0) -> WorldObject:
        """Create a small object's body (parked below the floor until placed)."""
        otype = load_catalog()[type_name]
        spec = shape_for(type_name, otype.dims)
        body = build_body(self.client, spec, colour, position, yaw, self.cache)
        self.bodies_changed()
        obj = WorldObject(self.new_object_id(type_name), otype, colour, spec, body, tuple(position), yaw, False)
        self._register(obj)
        return obj

    def remove(self, object_id: str) -> None:
        obj = self.objects.pop(object_id)
        self.body_to_object.pop(obj.body, None)
        self.client.removeBody(obj.body)
        self.bodies_changed()
        if obj.parent and object_id in self.objects.get(obj.parent, obj).contents:
            self.objects[obj.parent].contents.remove(object_id)
        if self.held == object_id:
            self.held = None

    def _scatter(self, layout: RoomLayout, rng: np.random.Generator, dirty_probability: float) -> None:
        """Place the layout's small objects: 1-4 instances per type (SMALL_OBJECT_COPIES), in distinct colours."""
        receptacles = [o for o in self.objects.values() if o.otype.receptacle and o.spec.surfaces]
        for type_name in layout.small_object_types:
            otype = load_catalog()[type_name]
            hosts = [r for r in receptacles if r.type_name in otype.typical_receptacles]
            if not hosts:
                continue
            count = 1 + int(rng.choice(len(SMALL_OBJECT_COPIES), p=SMALL_OBJECT_COPIES))
            colours = list(rng.permutation(otype.colours))[:count]
            for colour in colours:
                obj = self.spawn(type_name, str(colour))
                if not any(self.place(obj, host, rng=rng) for host in _host_order(hosts, rng)):
                    self.remove(obj.object_id)
                    continue
                if otype.cleanable and rng.random() < dirty_probability:
                    obj.is_dirty = True
                if obj.otype.movable_receptacle:
                    receptacles.append(obj)
                root = self.container_chain(obj)
                if any(r.type_name == 'Fridge' for r in root):
                    obj.temperature = COLD

    # ------------------------------------------------------------------ geometry of placement

    def surface_offset(self, receptacle: WorldObject) -> tuple[float, float, float]:
        """How far an open drawer has slid its contents out (object frame)."""
        art = receptacle.spec.articulation
        if art is not None and art.kind == 'prismatic' and receptacle.is_open:
            return (art.axis[0] * art.open_value, art.axis[1] * art.open_value, art.axis[2] * art.open_value)
        return (0.0, 0.0, 0.0)

    def _free_spots(self, receptacle: WorldObject, obj: WorldObject, surface_index: int):
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
            for spot in self._free_spots(receptacle, obj, k):
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
        self._update_pose(obj)
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

    def _update_pose(self, obj: WorldObject) -> None:
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
                self._update_pose(child)

    def set_open(self, obj: WorldObject, is_open: bool) -> None:
        obj.is_open = is_open
        set_articulation(self.client, obj.body, obj.spec, 1.0 if is_open else 0.0)
        if obj.spec.articulation is not None and obj.spec.articulation.kind == 'prismatic':
            for cid in obj.contents:   # a drawer carries its contents when it slides
                child = self.objects[cid]
                if not child.fixture:
                    self._update_pose(child)

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

    # ------------------------------------------------------------------ queries

    def container_chain(self, obj: WorldObject) -> list[WorldObject]:
        """The receptacles holding `obj`, innermost first."""
        chain, cur = [], obj
        while cur.parent is not None and cur.parent in self.objects:
            cur = self.objects[cur.parent]
            chain.append(cur)
        return chain

    def enclosed_by_closed(self, obj: WorldObject) -> Optional[WorldObject]:
        """The closed openable container `obj` sits inside, if any."""
        for r in self.container_chain(obj):
            if r.otype.openable and not r.is_open and r.spec.surfaces and any(s.inside for s in r.spec.surfaces):
                return r
        return None

    def descendants(self, obj: WorldObject) -> Iterable[WorldObject]:
        for cid in obj.contents:
            child = self.objects[cid]
            yield child
            yield from self.descendants(child)

    def object_state(self, object_id: str) -> ObjectState:
        o = self.objects[object_id]
        parent = self.objects.get(o.parent) if o.parent else None
        return ObjectState(o.object_id, o.type_name, o.otype.noun, tuple(o.position), o.parent,
                           parent.type_name if parent else None, o.colour, o.otype.material,
                           o.otype.pickupable, o.otype.receptacle, o.is_open, o.is_on, o.is_dirty,
                           o.is_sliced, o.temperature, o.held, tuple(o.contents))

    def object_states(self) -> list[ObjectState]:
        """Ground truth of every object in the scene, in a stable order."""
        return [self.object_state(k) for k in sorted(self.objects)]

    def instance_table(self) -> tuple[list[int], list[str]]:
        """Body ids and the names they stand for in the segmentation (objects and structure)."""
        ids = sorted(list(self.body_to_object) + list(self.structure_bodies))
        names = [self.body_to_object.get(b) or self.structure_bodies[b] for b in ids]
        return ids, names

    # ------------------------------------------------------------------ camera

    def camera(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Eye position and unit view direction of the agent's camera."""
        yaw = math.radians(self.agent.rotation)
        pitch = math.radians(-self.agent.horizon)
        eye = (self.agent.x, self.agent.y, CAMERA_HEIGHT)
        direction = (math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), math.sin(pitch))
        return eye, direction

    def view_matrix(self):
        """The camera drawn from EYE_SHIFT behind the eye, along its view (render() measures depth
        from the true eye). TinyRenderer divides by each vertex's view depth without clipping, so a
        box corner lying exactly in the camera's plane (with grid poses and whole-centimetre furniture:
        a 0.9 m counter top ending 0.6 m behind an eye 1.5 m up pitched 45 degrees) blackens its faces
        with NaN depth or drops them; the shift keeps every such corner off that plane."""
        eye, d = self.camera()
        eye = tuple(eye[k] - EYE_SHIFT * d[k] for k in range(3))
        target = (eye[0] + d[0], eye[1] + d[1], eye[2] + d[2])
        return self.client.computeViewMatrix(eye, target, (0.0, 0.0, 1.0))

    def render(self, width: Optional[int] = None, height: Optional[int] = None):
        """(rgb uint8 HxWx3, depth float32 HxW metres along the view axis, segmentation int32 HxW).

        A smaller `width` x `height` (same aspect) gives a cheap preview, as the expert uses."""
        w, h = width or self.width, height or self.height
        rgba_px, z, seg = self._camera_image(w, h, self.view_matrix())
        rgb = np.ascontiguousarray(np.asarray(rgba_px, dtype=np.uint8).reshape(h, w, 4)[:, :, :3])
        z = z.reshape(h, w)
        depth = (FAR * NEAR / (FAR - (FAR - NEAR) * z) - EYE_SHIFT).astype(np.float32)
        seg = np.asarray(seg, dtype=np.int32).reshape(h, w)
        return rgb, depth, seg

    def _camera_image(self, w: int, h: int, view):
        _, _, rgba_px, zbuf, seg = self.client.getCameraImage(
            w, h, view, self._projection,
            renderer=self.client.ER_TINY_RENDERER, shadow=0, lightDirection=LIGHT_DIRECTION)
        return rgba_px, np.asarray(zbuf, dtype=np.float32), seg

    def pixel_point(self, px: int, py: int, depth: np.ndarray) -> tuple[tuple[float, float, float], float]:
        """The world point seen at pixel (px, py) and its distance from the eye."""
        eye, fwd = self.camera()
        yaw = math.radians(self.agent.rotation)
        right = (math.sin(yaw), -math.cos(yaw), 0.0)
        up = (right[1] * fwd[2] - right[2] * fwd[1], right[2] * fwd[0] - right[0] * fwd[2],
              right[0] * fwd[1] - right[1] * fwd[0])   # right x forward: the camera's up
        t = math.tan(math.radians(FOV_DEG) / 2)
        u = ((px + 0.5) / self.width * 2 - 1) * t * (self.width / self.height)
        v = (1 - (py + 0.5) / self.height * 2) * t
        ray = tuple(fwd[k] + u * right[k] + v * up[k] for k in range(3))
        z = float(depth[py, px])
        point = tuple(eye[k] + z * ray[k] for k in range(3))
        return point, z * math.sqrt(sum(r * r for r in ray))


def _to_local(position, yaw: float, point) -> tuple[float, float, float]:
    """A world point in the frame of an object at `position` turned by `yaw`."""
    dx, dy = point[0] - position[0], point[1] - position[1]
    c, s = math.cos(yaw), math.sin(yaw)
    return (c * dx + s * dy, -s * dx + c * dy, point[2] - position[2])
