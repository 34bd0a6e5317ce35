"""The live world of one episode: pybullet bodies, object states, the agent and its camera.

`World` owns one pybullet client. `World.build(layout, rng)` lays out a floor plan and scatters its
small objects; afterwards every object's state lives in `World.objects` (the ground truth the task
checker and the oracle read) and its body in pybullet (what the camera sees).
"""

from __future__ import annotations

import os
from typing import Iterable, Optional

import numpy as np

from .bodies import ShapeCache, build_body, set_articulation
from .camera import FAR, FOV_DEG, NEAR, START_HORIZON, AgentView
from ..catalog import load_catalog
from .culling import CULLING_ENV, Culling
from .objects import COLD, AgentPose, ObjectState, WorldObject
from ..palette import rgba
from .placement import Placement
from .rooms import WALL_HEIGHT, RoomLayout
from .shapes import shape_for

SMALL_OBJECT_COPIES = (0.6, 0.15, 0.1, 0.15)   # chances of 1, 2, 3, 4 instances of each small type a room has
# How likely a closed receptacle type is to be a small object's first choice of host, against an open one:
# matched to the share of ALFRED's first targets that start shut away (11.0%, docs/dataset.md) on train's
# first 3,000 tasks (./dialfred bench world_statistics --file PATH).
CLOSED_HOST_WEIGHT = 0.4

SLICES_PER_OBJECT = {'Bread': 5}
DEFAULT_SLICES = 4


def _encloses(host) -> bool:
    """Whether `host` shuts what it holds away (a cabinet, drawer, fridge, microwave or safe)."""
    return bool(host.otype.openable and host.spec.surfaces and any(s.inside for s in host.spec.surfaces))


def _host_order(hosts: list, rng: np.random.Generator) -> list:
    """The order in which a small object tries its hosts: receptacle types in random order, those that
    shut their contents away CLOSED_HOST_WEIGHT times as likely to come first as the open ones, and
    within a type its instances in random order, so that a type of many units (a dresser's drawers, a
    kitchen's cabinets) is as likely a first choice as one table."""
    by_type: dict = {}
    for host in hosts:
        by_type.setdefault(host.type_name, []).append(host)
    types = sorted(by_type)
    weights = np.array([CLOSED_HOST_WEIGHT if _encloses(by_type[t][0]) else 1.0 for t in types])
    keys = rng.random(len(types)) ** (1.0 / weights)        # a weighted order without replacement
    return [by_type[types[i]][k] for i in np.argsort(-keys, kind='stable')
            for k in rng.permutation(len(by_type[types[i]]))]


class World(Placement, AgentView):
    """The pybullet scene of one episode plus the ground-truth state of every object. Where objects rest
    and move is `placement.Placement`; the agent's camera is `camera.AgentView`."""

    def __init__(self, client, width: int = 128, height: int = 128):
        self.client = client
        self.width, self.height = width, height
        self.cache = ShapeCache(client)
        self.culling = Culling(client)                 # what the camera's draws leave out (culling.py)
        self.culling.enabled = os.environ.get(CULLING_ENV, '1') != '0'
        self.layout: Optional[RoomLayout] = None
        self.objects: dict[str, WorldObject] = {}
        self.body_to_object: dict[int, str] = {}
        self.structure_bodies: dict[int, str] = {}   # floor, walls, ceiling
        self.agent = AgentPose(0, 0)
        self.held: Optional[str] = None
        # the camera's projection (pybullet's column-major 4 x 4, AI2-THOR's field of view and clipping planes)
        self.projection = client.computeProjectionMatrixFOV(FOV_DEG, width / height, NEAR, FAR)
        self._counts: dict[str, int] = {}
        self._fixture_bodies: dict[str, int] = {}      # the current room's furniture, kept for its next episode
        self._carry_cache: dict[tuple, tuple] = {}     # carry_spot per (size, pose), for this room
        self._outline_cache: dict[tuple, list] = {}    # open_part_outlines per (object, pose, fraction)
        # ground_truth.closeup_pixels per (object, what every body's pose and joints are); emptied
        # whenever a body is made or removed (see bodies_changed)
        self.closeup_cache: dict[tuple, object] = {}

    def bodies_changed(self) -> None:
        """A body was made or removed (or is about to be): renders made before may not repeat bit for
        bit (pybullet's draw order), so cached close-ups are dropped, and the culling shows its hidden
        bodies again and forgets their shapes."""
        self.closeup_cache = {}
        self.culling.forget(set(self.body_to_object) | set(self.structure_bodies))

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
