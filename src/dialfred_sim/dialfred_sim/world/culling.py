"""Frustum culling for pybullet's TinyRenderer: the objects wholly outside a camera's view are left out
of its draw, and every image is the same, pixel for pixel, as a draw of everything.

TinyRenderer draws every triangle of every body, in view or not; leaving out the bodies outside the
view makes a 64 px frame about 1.3x faster (128 px: about 1.1x). Before each draw, `Culling.prepare` bounds each
object by a sphere about its body's origin (a radius from its shape: its parts in any pose of its
joint, `shape_radius`) and tests it against the view's six planes (taken from the view and projection
matrices, so any camera goes: the agent's, the oracle's close-ups). A body wholly outside is drawn
with its colour's alpha at 0, which TinyRenderer skips; a body shown again gets its colours back. The
test is conservative (a sphere that touches the frustum stays), so a culled body could not have
covered a pixel, and the images, depths and segmentation are those of a full draw
(tests/sim/test_culling.py; `./dialfred bench render_culling`).

The floor, walls and ceiling are never culled. A body made or removed (`forget`) shows every hidden
body again first, so no body keeps a stale alpha. DIALFRED_CULLING=0 in the environment turns the
culling off for every world a process makes (`World.culling.enabled` for one world).
"""

from __future__ import annotations

import functools
import math
from typing import Iterable, Optional

import numpy as np

from .geometry import ShapeSpec

MARGIN = 0.01       # metres added to every radius (the eye's shift, rounding)
CULLING_ENV = 'DIALFRED_CULLING'     # '0': every world made in this process draws everything (for comparison)


@functools.lru_cache(maxsize=None)
def shape_radius(spec: ShapeSpec) -> float:
    """The radius of a sphere about the object frame's origin that holds every part of `spec` in every
    pose of its joint and every turn of the body: a rigid part's farthest point is within |pos| + |half
    extents| of the origin; a hinged part stays within |pos - hinge| + |half extents| of a hinge point,
    and a sliding part moves at most its open value."""
    radius = 0.0
    art = spec.articulation
    for part in spec.parts:
        size = math.hypot(*part.half_extents)
        if part.moving and art is not None:
            origin = np.asarray(art.origin, dtype=float)
            if art.kind == 'revolute':
                reach = float(np.linalg.norm(origin)) + float(np.linalg.norm(np.asarray(part.pos) - origin)) + size
            else:
                reach = float(np.linalg.norm(part.pos)) + size + abs(float(art.open_value))
        else:
            reach = float(np.linalg.norm(part.pos)) + size
        radius = max(radius, reach)
    return radius + MARGIN


def frustum_planes(view: Iterable[float], projection: Iterable[float]) -> np.ndarray:
    """[6, 4]: the view's planes (a, b, c, d) with a x + b y + c z + d >= 0 inside and (a, b, c) of unit
    length, from pybullet's column-major 4 x 4 view and projection matrices."""
    v = np.asarray(list(view), dtype=np.float64).reshape(4, 4).T
    p = np.asarray(list(projection), dtype=np.float64).reshape(4, 4).T
    m = p @ v
    planes = np.stack([m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2]])
    return planes / np.linalg.norm(planes[:, :3], axis=1, keepdims=True)


class Culling:
    """What is hidden from the draw on one pybullet client, and the colours to give back."""

    def __init__(self, client):
        self.client = client
        self.enabled = True
        self._links: dict[int, list[tuple[int, list[float]]]] = {}     # body -> [(link, rgba)]
        self._radius: dict[int, float] = {}                            # body -> shape_radius
        self._fixed: dict[int, tuple] = {}                             # a fixture's body -> its origin
        self.hidden: set[int] = set()

    def _shapes(self, body: int) -> list[tuple[int, list[float]]]:
        links = self._links.get(body)
        if links is None:
            links = self._links[body] = [(int(d[1]), list(d[7])) for d in self.client.getVisualShapeData(body)]
        return links

    def _set(self, body: int, shown: bool) -> None:
        for link, colour in self._shapes(body):
            self.client.changeVisualShape(body, link, rgbaColor=colour if shown else [*colour[:3], 0.0])

    def _centre(self, obj) -> tuple:
        if not obj.fixture:                          # small objects move: where pybullet has the body now
            return self.client.getBasePositionAndOrientation(obj.body)[0]
        centre = self._fixed.get(obj.body)
        if centre is None:
            centre = self._fixed[obj.body] = self.client.getBasePositionAndOrientation(obj.body)[0]
        return centre

    def prepare(self, view, projection, objects) -> int:
        """Hide the bodies of `objects` (scene.WorldObject) wholly outside the view of `view` and
        `projection`, show the others; returns how many are hidden."""
        if not self.enabled:
            self.show_all()
            return 0
        objects = list(objects)
        if not objects:
            return 0
        radius = self._radius
        for obj in objects:
            if obj.body not in radius:
                radius[obj.body] = shape_radius(obj.spec)
        centres = np.array([self._centre(obj) for obj in objects], dtype=np.float64)
        radii = np.array([radius[obj.body] for obj in objects])
        planes = frustum_planes(view, projection)
        outside = ((centres @ planes[:, :3].T + planes[:, 3]) < -radii[:, None]).any(axis=1)
        hide = {obj.body for obj, out in zip(objects, outside) if out}
        for body in hide - self.hidden:
            self._set(body, False)
        for body in self.hidden - hide:
            self._set(body, True)
        self.hidden = hide
        return len(hide)

    def show_all(self) -> None:
        """Every hidden body drawn again."""
        for body in self.hidden:
            self._set(body, True)
        self.hidden = set()

    def forget(self, existing: Optional[set[int]] = None) -> None:
        """Bodies are about to be, or were just, made or removed: give the hidden ones that still exist
        (`existing`; None: all) their colours back and forget every body's shapes and places."""
        for body in self.hidden:
            if existing is None or body in existing:
                self._set(body, True)
        self.hidden = set()
        self._links, self._radius, self._fixed = {}, {}, {}
