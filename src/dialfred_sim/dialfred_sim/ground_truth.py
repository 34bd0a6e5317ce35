"""The simulator's ground truth as plain data, for the oracle: objects, the agent, the task, looks.

`snapshot(env)` reads a `DialfredEnv` after reset (a task or free exploration) and returns a
`Snapshot` of frozen dataclasses, tuples and numpy arrays only, so that the oracle can be answered
from it anywhere (rebuilt from a ROS message, or from JSON with `snapshot_from_dict`).
`GroundTruthCache` computes it once per state of the world and numbers the states, so that a
client can ask "has anything changed since version v?" instead of fetching the world again. Nothing
here changes the world: appearance close-ups are extra camera images of the same scene. Importing
this module does not import pybullet (the oracle uses the dataclasses without a simulator).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Optional, Sequence

import numpy as np

from .world.camera import FOV_DEG
from .world.rooms import GRID

if TYPE_CHECKING:
    from .world.objects import WorldObject
    from .world.scene import World

MAX_APPEARANCE_PIXELS = 400     # evenly subsampled from the object's mask
MIN_APPEARANCE_PIXELS = 20      # fewer pixels of it in view: take a close-up instead
CLOSEUP_SIZE = 64               # close-up images are this many pixels square
CLOSEUP_FOV_DEG = 60.0
CLOSEUP_DISTANCES = (0.45, 0.6, 0.35)      # metres from the object's centre, tried in this order
NEAR_DISTANCES = (0.25, 0.15)              # for objects shut in a fridge, cabinet, drawer, ...
MIN_SEEN_PIXELS = MIN_APPEARANCE_PIXELS    # an object is in view when at least this many pixels show it


@dataclass(frozen=True)
class ObjectFact:
    """What the simulator knows about one object (positions in metres, world frame)."""

    object_id: str
    type_name: str
    noun: str
    position: tuple[float, float, float]   # centre of its bounding box
    parent_id: str                         # the receptacle it is in/on; '' when none (or held)
    parent_type: str
    parent_noun: str
    preposition: str                       # 'in' or 'on' its parent ('' without one)
    colour: str                            # its palette colour variant
    material: str
    pickupable: bool
    is_open: bool
    is_on: bool
    is_dirty: bool
    is_sliced: bool
    temperature: str
    held: bool
    # The middle of what the agent sees of it (seen_positions: the world point of its visible pixel
    # with the median bearing); None when fewer than MIN_SEEN_PIXELS show. For a bed or a counter it
    # is where the agent sees it, which may lie in another direction than its centre.
    seen_position: Optional[tuple[float, float, float]] = None

    @property
    def where(self) -> tuple[float, float, float]:
        """Where a person would say it is: the part the agent sees when in view, else its centre."""
        return self.seen_position if self.seen_position is not None else self.position


@dataclass(frozen=True)
class Appearance:
    """RGB samples of an object's rendered mask: (N, 3) uint8, N <= MAX_APPEARANCE_PIXELS.

    from_current_view: taken from the agent's current frame (else from a close-up render).
    N is 0 when no camera position showed the object."""

    object_id: str
    pixels: np.ndarray
    from_current_view: bool


@dataclass(frozen=True)
class Snapshot:
    """Everything the oracle needs about one moment of an episode.

    agent and expert_end: (x m, y m, rotation deg (0 = facing +x, counter-clockwise), horizon deg).
    task_objects: noun -> id of the task's own instance of it ({} without a task)."""

    agent: tuple[float, float, float, float]
    expert_end: Optional[tuple[float, float, float, float]]
    task_id: str
    task_type: str
    instruction: str
    task_objects: dict[str, str]
    objects: dict[str, ObjectFact]
    appearances: dict[str, Appearance] = field(default_factory=dict)


# ---------------------------------------------------------------------- facts

def object_fact(world: World, obj: WorldObject,
                seen_position: Optional[tuple[float, float, float]] = None) -> ObjectFact:
    """The ground truth of one object of `world`: the world's own ObjectState, flattened for the wire
    (empty strings for "none") and with the parent's noun and preposition that answers need;
    `seen_position` as `seen_positions` found it (None: not in view)."""
    state = world.object_state(obj.object_id)
    parent = world.objects.get(state.parent) if state.parent else None
    x, y, z = state.position    # the bottom centre of its footprint; a fact gives its box's centre
    return ObjectFact(
        object_id=state.object_id, type_name=state.type_name, noun=state.noun,
        position=(float(x), float(y), float(z) + obj.spec.size[2] / 2),
        parent_id=state.parent or '', parent_type=state.parent_type or '',
        parent_noun=parent.otype.noun if parent else '',
        preposition=parent.otype.preposition if parent else '',
        colour=state.colour, material=state.material, pickupable=state.pickupable,
        is_open=state.is_open, is_on=state.is_on, is_dirty=state.is_dirty, is_sliced=state.is_sliced,
        temperature=state.temperature, held=state.held, seen_position=seen_position)


def seen_positions(world: World, depth: np.ndarray, segmentation: np.ndarray,
                   min_pixels: int = MIN_SEEN_PIXELS) -> dict[str, tuple[float, float, float]]:
    """object id -> the middle of what the agent sees of it: among its pixels in a frame of the
    agent's camera (`depth` in metres along the view axis and `segmentation` by body, as
    World.render gives them), the world point (World.pixel_point's) of the one whose bearing from
    the agent is the median of theirs (the lower middle for an even count). For every object with
    at least `min_pixels` pixels. Where one 45-degree direction bin holds more than half of an
    object's pixels, this point lies in it; a mean point can be pulled out of it by perspective."""
    h, w = segmentation.shape
    bodies = {obj.body: oid for oid, obj in world.objects.items()}
    labels = segmentation.ravel().astype(np.int64)
    shown = np.flatnonzero(labels >= 0)
    if not len(shown):
        return {}
    labels = labels[shown]
    t = math.tan(math.radians(FOV_DEG) / 2)
    u = (((shown % w) + 0.5) / w * 2 - 1) * t * (w / h)
    v = (1 - ((shown // w) + 0.5) / h * 2) * t
    z = depth.ravel()[shown].astype(np.float64)
    eye, fwd = world.camera()
    yaw = math.radians(world.agent.rotation)
    right = (math.sin(yaw), -math.cos(yaw), 0.0)
    up = (right[1] * fwd[2] - right[2] * fwd[1], right[2] * fwd[0] - right[0] * fwd[2],
          right[0] * fwd[1] - right[1] * fwd[0])
    points = [eye[i] + z * (fwd[i] + u * right[i] + v * up[i]) for i in range(3)]
    # Bearings relative to the heading: what is in view lies ahead, so no wrap-around.
    ahead = (points[0] - eye[0]) * math.cos(yaw) + (points[1] - eye[1]) * math.sin(yaw)
    left = -(points[0] - eye[0]) * math.sin(yaw) + (points[1] - eye[1]) * math.cos(yaw)
    order = np.lexsort((np.arctan2(left, ahead), labels))       # by body, then by bearing
    counts = np.bincount(labels)
    starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
    out = {}
    for body in np.flatnonzero(counts >= min_pixels):
        oid = bodies.get(int(body))
        if oid is None:
            continue
        k = order[starts[body] + (counts[body] - 1) // 2]
        out[oid] = (float(points[0][k]), float(points[1][k]), float(points[2][k]))
    return out


def _with_slices(world: World, object_id: str) -> list[str]:
    """[object_id] while it exists; once sliced, the slices cut from it (sorted); else []."""
    if object_id in world.objects:
        return [object_id]
    return sorted(o.object_id for o in world.objects.values() if o.sliced_from == object_id)


def task_object_ids(env) -> list[str]:
    """Ids of the objects the current task acts on (targets and receptacles), in primitive order; a
    target that has been sliced is replaced by its slices (what is left of it in the world)."""
    task = getattr(env, 'task', None)
    if task is None:
        return []
    ids = [q for p in task.primitives for q in (p.target, p.receptacle) if q]
    return list(dict.fromkeys(s for q in dict.fromkeys(ids) for s in _with_slices(env.world, q)))


def _task_objects(env) -> dict[str, str]:
    """noun -> object id; where two task objects share a noun, the one acted on (not walked to) wins.
    A sliced target counts as its slices ('apple slice' -> the first of them)."""
    task = getattr(env, 'task', None)
    if task is None:
        return {}
    objects = env.world.objects
    out: dict[str, str] = {}
    ranked = [(p.kind == 'goto', q) for p in task.primitives for q in (p.target, p.receptacle) if q]
    for _, oid in sorted(ranked, key=lambda r: r[0]):   # stable: acted-on first, primitive order
        for q in _with_slices(env.world, oid):
            out.setdefault(objects[q].otype.noun, q)
    return out


def snapshot(env, appearance_of: Sequence[str] = ()) -> Snapshot:
    """The ground truth of `env` (a DialfredEnv after reset) now, with the appearance of each
    object id in `appearance_of` (ids not in the scene are skipped). Changes nothing in `env`."""
    if env.frames() is None:
        raise RuntimeError('snapshot() before reset()')
    world = env.world
    a = world.agent
    task = env.task
    expert_end = None
    if task is not None:
        i, j, rot, hor = task.expert_end_pose
        expert_end = (i * GRID, j * GRID, float(rot), float(hor))
    view = _PartView(world)    # rendered once, if any of them is in view
    appearances = {oid: _appearance(env, oid, MIN_APPEARANCE_PIXELS, view) for oid in dict.fromkeys(appearance_of)
                   if oid in world.objects}
    _, depth, segmentation = env.frames()
    seen = seen_positions(world, depth, segmentation)
    return Snapshot(
        agent=(float(a.x), float(a.y), float(a.rotation), float(a.horizon)),
        expert_end=expert_end,
        task_id=task.task_id if task is not None else '',
        task_type=task.task_type if task is not None else '',
        instruction=task.instruction if task is not None else '',
        task_objects=_task_objects(env),
        objects={oid: object_fact(world, world.objects[oid], seen.get(oid)) for oid in sorted(world.objects)},
        appearances=appearances)


class GroundTruthCache:
    """The ground truth of one DialfredEnv, computed once per state of its world, states numbered.

    The env renders a new frame on every reset, step and teleport (and the world changes only
    then), so a frame object not seen before starts a new state: `version()` then moves on by one
    from `first_version`, and the snapshot and appearances are computed afresh, each on first use.
    A snapshot from here equals `snapshot(env, ids)` of the same moment. Changes made to the world
    directly, without a new frame, are not noticed (tests re-render after such edits)."""

    def __init__(self, env, first_version: int = 1):
        self.env = env
        self._frame = None                  # the frame of the cached state (held: its id stays unique)
        self._version = first_version - 1
        self._snapshot: Optional[Snapshot] = None
        self._appearances: dict[str, Appearance] = {}
        self._view: Optional[_PartView] = None

    def _sync(self) -> None:
        frame = self.env.frames()
        if frame is None:
            raise RuntimeError('snapshot() before reset()')
        if frame is not self._frame:
            self._frame, self._version = frame, self._version + 1
            self._snapshot, self._appearances, self._view = None, {}, _PartView(self.env.world)

    def version(self) -> int:
        """The number of the world's current state."""
        self._sync()
        return self._version

    def snapshot(self, appearance_of: Sequence[str] = ()) -> Snapshot:
        """`snapshot(env, appearance_of)`, from the cache while the state is unchanged."""
        self._sync()
        if self._snapshot is None:
            self._snapshot = snapshot(self.env)
        looks = self.appearances(appearance_of)
        return replace(self._snapshot, appearances=looks) if looks else self._snapshot

    def appearances(self, object_ids: Sequence[str]) -> dict[str, Appearance]:
        """The appearance of each id in `object_ids` that is in the scene, rendered once per state."""
        self._sync()
        world = self.env.world
        out = {}
        for oid in dict.fromkeys(object_ids):
            if oid not in world.objects:
                continue
            if oid not in self._appearances:
                self._appearances[oid] = _appearance(self.env, oid, MIN_APPEARANCE_PIXELS, self._view)
            out[oid] = self._appearances[oid]
        return out


# ---------------------------------------------------------------------- appearance

def _sample(rgb: np.ndarray, mask: np.ndarray, limit: int = MAX_APPEARANCE_PIXELS) -> np.ndarray:
    """Up to `limit` RGB values of the masked pixels, evenly spread over the mask (row-major)."""
    px = rgb[mask]
    if len(px) > limit:
        px = px[np.linspace(0, len(px) - 1, limit).round().astype(int)]
    return np.ascontiguousarray(px, dtype=np.uint8).reshape(-1, 3)


def _body_part_ids(obj: WorldObject) -> np.ndarray:
    """Segmentation values (with link index) of the parts of `obj` painted in its colour variant.

    Link layout of bodies.build_body: rigid parts are links 0..n-1 in spec order, then the hinge
    link (no visual), then the moving parts; pybullet encodes body + ((link + 1) << 24)."""
    rigid = [p for p in obj.spec.parts if not p.moving]
    moving = [p for p in obj.spec.parts if p.moving]
    links = [k for k, p in enumerate(rigid) if p.colour == 'main']
    links += [len(rigid) + 1 + k for k, p in enumerate(moving) if p.colour == 'main']
    return np.array([obj.body + ((link + 1) << 24) for link in links], dtype=np.int64)


class _PartView:
    """The agent's current view again, with a segmentation that tells the parts of bodies apart;
    rendered on first use (the same image as the frame: rendering is deterministic)."""

    def __init__(self, world: World):
        self.world = world
        self._image: Optional[tuple[np.ndarray, np.ndarray]] = None

    def image(self) -> tuple[np.ndarray, np.ndarray]:
        if self._image is None:
            w = self.world
            c = w.client
            _, _, px, _, seg = w.draw(w.width, w.height, w.view_matrix(), w.projection,
                                      flags=c.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX)
            rgb = np.asarray(px, dtype=np.uint8).reshape(w.height, w.width, 4)[:, :, :3]
            self._image = rgb, np.asarray(seg, dtype=np.int64).reshape(w.height, w.width)
        return self._image


def appearance(env, object_id: str, min_pixels: int = MIN_APPEARANCE_PIXELS) -> Appearance:
    """Pixels of `object_id`'s body: the parts painted in its colour variant, leaving out details
    of fixed colour (a knife's blade, a window's glass, a television's screen) as a person naming
    its colour would. From the agent's current frame when at least `min_pixels` of them show, else
    from a close-up render around the object; 0 pixels if no close-up shows them either.
    KeyError for an unknown id. Changes nothing in the world."""
    return _appearance(env, object_id, min_pixels, _PartView(env.world))


def _appearance(env, object_id: str, min_pixels: int, view: _PartView) -> Appearance:
    world = env.world
    obj = world.objects[object_id]
    if env.frames() is not None and int((env.frames()[2] == obj.body).sum()) >= min_pixels:
        rgb, seg = view.image()
        mask = np.isin(seg, _body_part_ids(obj))
        if int(mask.sum()) >= min_pixels:
            return Appearance(object_id, _sample(rgb, mask), True)
    closeup = closeup_pixels(world, obj, min_pixels)
    return Appearance(object_id, closeup if closeup is not None else np.zeros((0, 3), np.uint8), False)


def _eye_directions(yaw: float) -> list[tuple[float, float, float]]:
    """Unit vectors from the object towards candidate eyes: its front, sides and back from 35 deg
    above, then from above, then level with it (object frame turned by `yaw`)."""
    out = []
    for elevation in (35.0, 70.0, 5.0):
        e = math.radians(elevation)
        for azimuth in (0, 90, -90, 45, -45, 180, 135, -135):
            az = yaw + math.radians(azimuth)
            out.append((math.cos(e) * math.cos(az), math.cos(e) * math.sin(az), math.sin(e)))
    return out


def _render_closeup(world: World, eye, target, near: float) -> tuple[np.ndarray, np.ndarray]:
    """(rgb, segmentation with link indices) of a CLOSEUP_SIZE square image from `eye` at `target`."""
    c = world.client
    view = c.computeViewMatrix(list(eye), list(target), [0.0, 0.0, 1.0])
    proj = c.computeProjectionMatrixFOV(CLOSEUP_FOV_DEG, 1.0, near, 5.0)
    n = CLOSEUP_SIZE
    _, _, px, _, seg = world.draw(n, n, view, proj, flags=c.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX)
    rgb = np.asarray(px, dtype=np.uint8).reshape(n, n, 4)[:, :, :3]
    return rgb, np.asarray(seg, dtype=np.int64).reshape(n, n)


def render_state(world: World) -> tuple:
    """What a render of `world` depends on besides the camera: every body's pose and joint positions
    (no body's colours change after it is made; a body made or removed empties the close-up cache)."""
    c = world.client
    out = []
    for body in sorted(world.body_to_object):
        pos, orn = c.getBasePositionAndOrientation(body)
        joints = c.getNumJoints(body)
        out.append((body, pos, orn, tuple(s[0] for s in c.getJointStates(body, range(joints))) if joints else ()))
    return tuple(out)


def closeup_pixels(world: World, obj: WorldObject, min_pixels: int = MIN_APPEARANCE_PIXELS) -> Optional[np.ndarray]:
    """Samples of `obj`'s body (see `appearance`) from the first close-up camera around it that
    shows >= `min_pixels` of it (None if none does). Objects shut inside a container are tried from
    very close first. Remembered per world state (`render_state`): asking again while nothing has
    moved (the oracle at step 0 and mid-episode, several annotators) renders nothing."""
    key = (obj.object_id, min_pixels, render_state(world))
    if key not in world.closeup_cache:
        world.closeup_cache[key] = _search_closeup(world, obj, min_pixels)
    found = world.closeup_cache[key]
    return None if found is None else found.copy()


def _search_closeup(world: World, obj: WorldObject, min_pixels: int) -> Optional[np.ndarray]:
    x, y, z = obj.position
    centre = (x, y, z + obj.spec.size[2] / 2)
    extent = max(obj.spec.size)
    # A big fixture needs the camera farther away than its half size; small things 0.35-0.6 m.
    scale = max(1.0, extent / 0.6)
    far = [(d * scale, 0.02) for d in CLOSEUP_DISTANCES]
    near = [(d + extent / 2, 0.01) for d in NEAR_DISTANCES]
    shut_in = world.enclosed_by_closed(obj) is not None
    parts = _body_part_ids(obj)
    for distance, near_plane in (near + far if shut_in else far + near):
        for dx, dy, dz in _eye_directions(obj.yaw):
            eye = (centre[0] + distance * dx, centre[1] + distance * dy, centre[2] + distance * dz)
            rgb, seg = _render_closeup(world, eye, centre, near_plane)
            mask = np.isin(seg, parts)
            if int(mask.sum()) >= min_pixels:
                return _sample(rgb, mask)
    return None


# ---------------------------------------------------------------------- JSON

def snapshot_to_dict(s: Snapshot) -> dict[str, Any]:
    """A JSON-able dict of `s` (pixels as lists of [r, g, b])."""
    return {
        'agent': list(s.agent),
        'expert_end': list(s.expert_end) if s.expert_end is not None else None,
        'task_id': s.task_id, 'task_type': s.task_type, 'instruction': s.instruction,
        'task_objects': dict(s.task_objects),
        'objects': {oid: {**f.__dict__, 'position': list(f.position),
                          'seen_position': list(f.seen_position) if f.seen_position is not None else None}
                    for oid, f in s.objects.items()},
        'appearances': {oid: {'object_id': a.object_id, 'pixels': np.asarray(a.pixels).tolist(),
                              'from_current_view': a.from_current_view} for oid, a in s.appearances.items()},
    }


def snapshot_from_dict(d: dict[str, Any]) -> Snapshot:
    """The Snapshot that `snapshot_to_dict` wrote."""
    def point(v):
        return tuple(float(x) for x in v) if v is not None else None
    objects = {oid: ObjectFact(**{**f, 'position': point(f['position']),
                                  'seen_position': point(f.get('seen_position'))})
               for oid, f in d['objects'].items()}
    appearances = {oid: Appearance(a['object_id'], np.asarray(a['pixels'], dtype=np.uint8).reshape(-1, 3),
                                   bool(a['from_current_view'])) for oid, a in d.get('appearances', {}).items()}
    end = d.get('expert_end')
    return Snapshot(
        agent=tuple(float(v) for v in d['agent']),
        expert_end=tuple(float(v) for v in end) if end is not None else None,
        task_id=d.get('task_id', ''), task_type=d.get('task_type', ''), instruction=d.get('instruction', ''),
        task_objects=dict(d.get('task_objects', {})), objects=objects, appearances=appearances)
