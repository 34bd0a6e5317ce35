"""The expert: shortest-path navigation on the 0.25 m grid and pixel-targeted interactions.

The expert acts on a `World` directly, rendering only when it must look (to choose a pose from which
its targets are in view and within reach, and to pick the pixel of an interaction). Every action goes
through the same `actions.execute` an agent's does, so what the expert records replays exactly.

A go-to is ALFRED's planner's (`Graph.navigate_to_goal` in ALFRED's `gen/graph/graph_obj.py`): the
camera tilts to 45 degrees down first (unless it is there), the agent walks the shortest path to the
designated pose, and the camera then looks to the designated pitch. So the walk is the shortest, and the
looks are ALFRED's, not the fewest.

As ALFRED's expert, it never walks inside an interaction: a go-to ends where the whole of what follows
can be done with at most a look up or down (the contents of a closed container included, once it is
open), and a put lands where the agent can see and reach what it put (AI2-THOR places a put object only
at spots in the agent's view and reach). Where that cannot be, the expert fails and the generator draws
another episode, as ALFRED discards the trajectories its expert cannot finish.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Optional, Sequence

import numpy as np

from ..actions import LOOK_STEP, REACH, Action, execute, interact
from ..world.rooms import GRID
from ..world.camera import CAMERA_HEIGHT, HORIZON_MAX, HORIZON_MIN
from ..world.scene import World
from .goals import is_reachable, reachable_mask
from .navigation import successors
from .schema import ExpertAction, Primitive

KIND_TO_ACTION = {'pickup': Action.Pickup, 'put': Action.Put, 'open': Action.Open, 'close': Action.Close,
                  'toggle_on': Action.ToggleOn, 'toggle_off': Action.ToggleOff, 'slice': Action.Slice}
TILT = 45.0           # degrees down: ALFRED's planner walks every go-to with the camera at this pitch
MARGIN = 0.08          # the expert keeps its targets this far inside the reach limit
MAX_POSE_RENDERS = 40  # candidate poses looked at per navigation goal
PREVIEW = 64           # pixels of the cheap first look at a candidate pose
PULL_BACK = 0.5        # metres: a designated pose keeps the eye at least this far from its target's centre
PUT_TRIES = 8          # pixels of a receptacle tried for where a put lands in view ...
PUT_STRIDE = 7         # ... taking every this-many-th in order of nearness to its middle


class ExpertFailed(RuntimeError):
    """The expert could not carry out a step (no pose sees the target, no room to put, ...)."""


Pose = tuple[int, int, int, float]


class Expert:
    """Plays primitives on `world`, recording low-level actions, primitives and poses."""

    def __init__(self, world: World):
        self.world = world
        self.actions: list[ExpertAction] = []
        self.primitives: list[Primitive] = []
        self.poses: list[Pose] = []

    # ------------------------------------------------------------------ bookkeeping

    def pose(self) -> Pose:
        a = self.world.agent
        return (a.i, a.j, a.rotation, a.horizon)

    def _set_pose(self, pose: Pose) -> None:
        a = self.world.agent
        a.i, a.j, a.rotation, a.horizon = pose
        self.world.update_held_pose()

    def _nav(self, act: Action) -> None:
        self.poses.append(self.pose())
        result = execute(self.world, act, (-1, -1), None, None)
        if not result.success:
            raise ExpertFailed(f'{act.name} failed: {result.error}')
        self.actions.append(ExpertAction(act.name))

    def finish(self) -> None:
        self.poses.append(self.pose())

    # ------------------------------------------------------------------ navigation

    def _bfs(self) -> dict:
        """Shortest action paths from the current (i, j, rotation) to every reachable one: over the
        floor that open doors leave free, and with the object in hand, only where there is room to
        carry it (the same rules as actions.move_ahead and rotate)."""
        start = self.pose()[:3]
        parent = {start: None}
        queue = deque([start])
        free = self.world.free_floor()
        while queue:
            s = queue.popleft()
            for act, nxt in successors(self.world, s, free):
                if nxt not in parent:
                    parent[nxt] = (s, act)
                    queue.append(nxt)
        return parent

    def _clear_to_open(self, focus: Sequence[str], i: int, j: int) -> bool:
        """Whether every closed openable in `focus` (the expert goes to it to open it) can open
        without its door or drawer hitting an agent on (i, j)."""
        objects = self.world.objects
        return not any(objects[f].otype.openable and not objects[f].is_open and objects[f].spec.articulation
                       is not None and self.world.would_hit_agent(objects[f], i, j) for f in focus)

    @staticmethod
    def _path(parent: dict, goal) -> list[Action]:
        path = []
        while parent[goal] is not None:
            goal, act = parent[goal]
            path.append(act)
        return path[::-1]

    def _sees(self, focus: Sequence[str], preview: bool = False) -> bool:
        size = PREVIEW if preview else None
        _, depth, seg = self.world.render(size, size)
        return all(is_reachable(self.world, f, depth, seg, MARGIN) for f in focus)

    def _ready_inside(self, focus: Sequence[str], inside: Sequence[str], put: Optional[str]) -> bool:
        """Whether, once the closed openables of `focus` stand open (opened for the look and closed
        again), `inside` is in view and within reach, and the held `put` would land in view and within
        reach if put into `focus[0]`."""
        if not inside and put is None:
            return True
        closed = [self.world.objects[f] for f in focus
                  if self.world.objects[f].otype.openable and not self.world.objects[f].is_open]
        try:
            for obj in closed:
                self.world.set_open(obj, True)
            if inside and not (self._sees(inside, preview=True) and self._sees(inside)):
                return False
            if put is not None:
                _, depth, seg = self.world.render()
                return self._put_pixel(put, focus[0], depth, seg, strict=True) is not None
            return True
        finally:
            for obj in closed:
                self.world.set_open(obj, False)

    def _aabb(self, object_id: str) -> tuple[np.ndarray, np.ndarray]:
        obj = self.world.objects[object_id]
        c = self.world.client
        lo, hi = (np.array(v) for v in c.getAABB(obj.body, -1))
        for link in range(c.getNumJoints(obj.body)):
            a, b = c.getAABB(obj.body, link)
            lo, hi = np.minimum(lo, a), np.maximum(hi, b)
        return lo, hi

    def find_pose(self, focus: Sequence[str], inside: Sequence[str] = (),
                  put: Optional[str] = None) -> tuple[Pose, list[Action]]:
        """The designated pose for `focus` (ALFRED's rule for where its planner's go-to ends) and the
        shortest walk to it (moves and turns; `goto` adds the looks). `inside`: objects in a closed
        container of `focus` that must be in view and within reach too, once it is open; `put`: the held
        object, which a put into `focus[0]` (opened if closed) must land in view and within reach.

        The pose depends on the world, never on where the agent stands: the free grid point nearest the
        first target's centre (L1 distance, as ALFRED's `get_obj_coords`), but not so near that the eye
        is within `PULL_BACK` of it; facing the target along the axis it lies most along; the camera
        pitched at the target's base, rounded to the look step. Every target must be in view and within
        reach there (checked by rendering), and a closed door or drawer in `focus` must have room to
        open; where the designated pitch does not see them, a pitch a step or two off is tried, each
        step costing as much as a grid step further away."""
        here = self.pose()
        parent = self._bfs()
        lo0, hi0 = self._aabb(focus[0])
        centre = (lo0 + hi0) / 2
        boxes = [self._aabb(f) for f in focus]
        candidates = []
        for (i, j, r) in parent:
            dx, dy = centre[0] - i * GRID, centre[1] - j * GRID
            facing = (0 if dx >= 0 else 180) if abs(dx) > abs(dy) else (90 if dy >= 0 else 270)
            if r != facing:
                continue
            eye = np.array([i * GRID, j * GRID, CAMERA_HEIGHT])
            if np.linalg.norm(eye - centre) < PULL_BACK:
                continue
            # Every target's nearest point must be within reach of the agent's axis, or no view of it can be.
            if any(np.linalg.norm(eye[:2] - np.clip(eye[:2], lo[:2], hi[:2])) > REACH - MARGIN for lo, hi in boxes):
                continue
            if not self._clear_to_open(focus, i, j):
                continue
            pitch = math.degrees(math.atan2(CAMERA_HEIGHT - lo0[2], max(abs(dx), abs(dy))))
            h0 = min(max(round(pitch / LOOK_STEP) * LOOK_STEP, HORIZON_MIN), HORIZON_MAX)
            steps = (abs(dx) + abs(dy)) / GRID
            for dh in (0, LOOK_STEP, -LOOK_STEP, 2 * LOOK_STEP, -2 * LOOK_STEP):
                h = h0 + dh
                if HORIZON_MIN <= h <= HORIZON_MAX:
                    candidates.append((steps + abs(dh) / LOOK_STEP, i, j, (i, j, r, float(h))))
        candidates.sort()
        try:
            for *_, pose in candidates[:MAX_POSE_RENDERS]:
                self._set_pose(pose)
                # A cheap low-resolution look first; the full frame decides.
                if self._sees(focus, preview=True) and self._sees(focus) and self._ready_inside(focus, inside, put):
                    return pose, self._path(parent, pose[:3])
        finally:
            self._set_pose(here)
        raise ExpertFailed(f'no pose in {self.world.layout.scene} sees {", ".join(focus)} within reach')

    @staticmethod
    def _look_actions(h_from: float, h_to: float) -> list[Action]:
        n = round((h_to - h_from) / LOOK_STEP)
        return [Action.LookDown] * n if n > 0 else [Action.LookUp] * (-n)

    def goto(self, landmark: str, focus: Sequence[str], inside: Sequence[str] = (), put: Optional[str] = None) -> None:
        """Walk to where `focus` can be acted on (see find_pose for `inside` and `put`) as ALFRED's
        planner does: tilt to `TILT`, walk, look to the designated pitch. A `goto landmark` primitive
        if the agent was not at that pose already."""
        start = len(self.actions)
        here = self.pose()
        pose, walk = self.find_pose(list(dict.fromkeys(focus)), list(inside), put)
        if pose == here:
            return
        actions = self._look_actions(here[3], TILT) + walk + self._look_actions(TILT, pose[3])
        for act in actions:
            self._nav(act)
        if len(self.actions) > start:
            self.primitives.append(Primitive('goto', landmark, start, len(self.actions)))

    # ------------------------------------------------------------------ interaction

    def _pixels(self, object_id: str, depth: np.ndarray, seg: np.ndarray) -> list[tuple[int, int]]:
        """The pixels of `object_id` within reach, nearest the middle of all its pixels first."""
        near = reachable_mask(self.world, object_id, depth, seg, REACH - MARGIN)
        ys, xs = np.nonzero(near)
        if len(xs) == 0:
            return []
        whole_y, whole_x = np.nonzero(seg == self.world.objects[object_id].body)
        order = np.argsort((xs - whole_x.mean()) ** 2 + (ys - whole_y.mean()) ** 2, kind='stable')
        return [(int(xs[k]), int(ys[k])) for k in order]

    def _pixel(self, object_id: str, depth: np.ndarray, seg: np.ndarray) -> Optional[tuple[int, int]]:
        pixels = self._pixels(object_id, depth, seg)
        return pixels[0] if pixels else None

    def _put_pixel(self, oid: str, rid: str, depth: np.ndarray, seg: np.ndarray,
                   strict: bool = False) -> Optional[tuple[int, int]]:
        """The pixel of receptacle `rid` to put the held `oid` at: the first (in `_pixels`' order, every
        PUT_STRIDE-th) from which `oid` would land where the agent sees and reaches it; else the first
        pixel (None if `strict`). Each try places `oid` as the put would, looks, and takes it back into
        the hand."""
        pixels = self._pixels(rid, depth, seg)
        if not pixels:
            return None
        fallback = None if strict else pixels[0]
        w = self.world
        obj, receptacle = w.objects[oid], w.objects[rid]
        kept = (obj.surface, obj.local, obj.local_yaw)
        for px, py in pixels[::PUT_STRIDE][:PUT_TRIES]:
            point, _ = w.pixel_point(px, py, depth)
            if not w.place(obj, receptacle, near=point):
                return fallback             # nowhere to put it: the put itself will say so
            try:
                if self._sees([oid], preview=True) and self._sees([oid]):
                    return px, py
            finally:
                w.hold(obj)
                obj.surface, obj.local, obj.local_yaw = kept
        return fallback

    def act(self, kind: str, target: str, receptacle: str = '') -> None:
        """One interaction primitive (plus the look up/down it needs to see its target)."""
        start = len(self.actions)
        clicked = receptacle if kind == 'put' else target
        _, depth, seg = self.world.render()
        pixel = self._put_pixel(target, receptacle, depth, seg) if kind == 'put' else self._pixel(clicked, depth, seg)
        if pixel is None:
            here = self.pose()
            for dh in (LOOK_STEP, -LOOK_STEP, 2 * LOOK_STEP, -2 * LOOK_STEP):
                h = here[3] + dh
                if not HORIZON_MIN <= h <= HORIZON_MAX:
                    continue
                self._set_pose((*here[:3], h))
                _, depth, seg = self.world.render()
                pixel = self._pixel(clicked, depth, seg)
                self._set_pose(here)
                if pixel is not None:
                    for a in self._look_actions(here[3], h):
                        self._nav(a)
                    break
            if pixel is None:   # no walking inside an interaction (see the module's docstring)
                raise ExpertFailed(f'{kind}: {clicked} is not in reach from where the go-to ended')
        action = KIND_TO_ACTION[kind]
        point, _ = self.world.pixel_point(pixel[0], pixel[1], depth)
        self.poses.append(self.pose())
        result = execute(self.world, action, pixel, depth, seg)
        if not result.success:
            raise ExpertFailed(f'{action.name} {clicked}: {result.error}')
        self.actions.append(ExpertAction(action.name, pixel[0], pixel[1], result.target or clicked,
                                         tuple(float(v) for v in point)))
        self.primitives.append(Primitive(kind, target, start, len(self.actions), receptacle))


def replay(world: World, actions: Sequence[ExpertAction]) -> None:
    """Apply recorded expert actions to `world` without rendering (rebuilds a task's initial state).

    Raises RuntimeError if an action does not succeed, which means the world has drifted from the
    one the expert acted in."""
    for k, a in enumerate(actions):
        act = Action[a.action]
        if act.is_interaction:
            obj = world.objects.get(a.target)
            if obj is None:
                raise RuntimeError(f'replay step {k}: {a.target} does not exist')
            result = interact(world, act, obj, a.point)
        else:
            result = execute(world, act, (-1, -1), None, None)
        if not result.success:
            raise RuntimeError(f'replay step {k} ({a.action} {a.target}): {result.error}')
