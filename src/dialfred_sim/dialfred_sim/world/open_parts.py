"""Where the moving part of an opened object stands: a fridge or cabinet door swung out into the
room, a drawer pulled out of its counter. Layouts keep the agent clear of furniture as it stands
closed (`rooms.navigable_points`); these parts take floor from the agent only while they are open.

The agent's body is a vertical cylinder of `AGENT_RADIUS` from the floor to `AGENT_HEIGHT`. A
moving part blocks a grid point when its footprint comes closer to the point than the radius and
its height range overlaps the body's. Pure geometry on the shape specs (no pybullet).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .geometry import ShapeSpec
from .rooms import AGENT_RADIUS
from .shapes.primitives import part_bounds

AGENT_HEIGHT = 1.6   # metres: the camera (eye) is at 1.5 m, the top of the head a little above it


def _corners(lo: Sequence[float], hi: Sequence[float]) -> np.ndarray:
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def _axis_rotation(axis: Sequence[float], angle: float) -> np.ndarray:
    """Rodrigues' rotation matrix about the unit vector `axis`."""
    k = np.asarray(axis, float)
    k = k / np.linalg.norm(k)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * kx @ kx


def moving_part_boxes(spec: ShapeSpec, position: Sequence[float], yaw: float,
                      fraction: float = 1.0) -> list[np.ndarray]:
    """World corners (8x3 each) of the moving parts of `spec` standing at `position`, turned by
    `yaw`, opened to `fraction` (0 closed, 1 fully open). [] for a shape without moving parts."""
    art = spec.articulation
    parts = [p for p in spec.parts if p.moving]
    if art is None or not parts:
        return []
    value = fraction * art.open_value
    origin = np.asarray(art.origin, float)
    if art.kind == 'revolute':
        rot = _axis_rotation(art.axis, value)
        joint = lambda pts: (pts - origin) @ rot.T + origin
    else:
        shift = np.asarray(art.axis, float) * value
        joint = lambda pts: pts + shift
    c, s = math.cos(yaw), math.sin(yaw)
    to_world = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    at = np.asarray(position, float)
    return [joint(_corners(*part_bounds(p))) @ to_world.T + at for p in parts]


def _convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise hull of 2-D points (Andrew's monotone chain)."""
    pts = sorted(set(map(tuple, np.round(points, 9))))
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _distance_to_polygon(point: Sequence[float], hull: np.ndarray) -> float:
    """Distance from a 2-D point to a convex polygon (0 inside it)."""
    p = np.asarray(point, float)
    n = len(hull)
    if n == 1:
        return float(np.linalg.norm(p - hull[0]))
    inside = n >= 3
    best = math.inf
    for k in range(n):
        a, b = hull[k], hull[(k + 1) % n]
        ab = b - a
        t = 0.0 if not ab.any() else min(max(float(np.dot(p - a, ab) / np.dot(ab, ab)), 0.0), 1.0)
        best = min(best, float(np.linalg.norm(p - (a + t * ab))))
        if ab[0] * (p[1] - a[1]) - ab[1] * (p[0] - a[0]) < 0:
            inside = False
    return 0.0 if inside else best


def footprints(boxes: Sequence[np.ndarray], height: float = AGENT_HEIGHT) -> list[np.ndarray]:
    """The floor outlines (convex polygons) of those `boxes` that reach down below `height`."""
    return [_convex_hull(b[:, :2]) for b in boxes if b[:, 2].min() < height and b[:, 2].max() > 0.0]


def clearance(x: float, y: float, outlines: Sequence[np.ndarray]) -> float:
    """Distance from the floor point (x, y) to the nearest of `outlines` (inf if there is none)."""
    return min((_distance_to_polygon((x, y), h) for h in outlines), default=math.inf)


def blocks(x: float, y: float, outlines: Sequence[np.ndarray], radius: float = AGENT_RADIUS) -> bool:
    """Whether an agent standing at (x, y) would overlap one of `outlines`."""
    return clearance(x, y, outlines) < radius
