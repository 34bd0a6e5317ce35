"""Primitive helpers every shape builder is made of, and the normalisation that finishes a shape.

Sizes are full extents and positions are centres, in the object frame of geometry.py. `_finish`
recentres a builder's parts on their closed bounding box and makes the ShapeSpec.
"""

from __future__ import annotations

import math
from typing import Iterable, Optional, Sequence

from ..geometry import Articulation, Part, ShapeSpec, Surface, Vec3

PI = math.pi

# ---------------------------------------------------------------------------------------------------
# Primitive helpers (sizes are full extents, positions are centres)


def _box(sx: float, sy: float, sz: float, x: float = 0.0, y: float = 0.0, z: float = 0.0,
         c: str = 'main', rpy: Vec3 = (0.0, 0.0, 0.0), m: bool = False) -> Part:
    return Part('box', (sx / 2, sy / 2, sz / 2), (x, y, z), rpy, c, m)


_AXIS_RPY = {'z': (0.0, 0.0, 0.0), 'x': (0.0, PI / 2, 0.0), 'y': (PI / 2, 0.0, 0.0)}


def _cyl(r: float, h: float, x: float = 0.0, y: float = 0.0, z: float = 0.0, c: str = 'main',
         axis: str = 'z', rpy: Optional[Vec3] = None, m: bool = False) -> Part:
    return Part('cylinder', (r, r, h / 2), (x, y, z), rpy or _AXIS_RPY[axis], c, m)


def _sph(r: float, x: float = 0.0, y: float = 0.0, z: float = 0.0, c: str = 'main',
         m: bool = False) -> Part:
    return Part('sphere', (r, r, r), (x, y, z), (0.0, 0.0, 0.0), c, m)


def _bar(p0: Sequence[float], p1: Sequence[float], w: float, t: float, c: str = 'main',
         m: bool = False, roll: float = 0.0) -> Part:
    """A box from point p0 to p1 (its length), w wide (local y) and t thick (local z)."""
    dx, dy, dz = (p1[i] - p0[i] for i in range(3))
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    rpy = (roll, -math.atan2(dz, math.hypot(dx, dy)), math.atan2(dy, dx))
    mid = tuple((p0[i] + p1[i]) / 2 for i in range(3))
    return _box(length, w, t, *mid, c=c, rpy=rpy, m=m)


def _rod(p0: Sequence[float], p1: Sequence[float], r: float, c: str = 'main',
         m: bool = False) -> Part:
    """A cylinder of radius r from point p0 to p1."""
    dx, dy, dz = (p1[i] - p0[i] for i in range(3))
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    rpy = (0.0, math.atan2(math.hypot(dx, dy), dz), math.atan2(dy, dx))
    mid = tuple((p0[i] + p1[i]) / 2 for i in range(3))
    return _cyl(r, length, *mid, c=c, rpy=rpy, m=m)


def _ring(r: float, wall: float, h: float, z0: float, n: int = 8, c: str = 'main',
          x: float = 0.0, y: float = 0.0, m: bool = False) -> list[Part]:
    """A polygonal tube (outer apothem r) standing on z0: the wall of a cup, pot or bin."""
    side = 2 * r * math.tan(PI / n)
    return [_box(wall, side, h, x + (r - wall / 2) * math.cos(2 * PI * k / n),
                 y + (r - wall / 2) * math.sin(2 * PI * k / n), z0 + h / 2, c,
                 (0.0, 0.0, 2 * PI * k / n), m) for k in range(n)]


def _loop(points: Sequence[Sequence[float]], w: float, t: float, c: str = 'main',
          closed: bool = True, m: bool = False) -> list[Part]:
    """Bars joining consecutive points (a handle, a frame, a racket head)."""
    pts = list(points) + ([points[0]] if closed else [])
    return [_bar(pts[i], pts[i + 1], w, t, c, m) for i in range(len(pts) - 1)]


def _frame(ox: float, oy: float, ix: float, iy: float, h: float, z0: float, c: str = 'main',
           x: float = 0.0, y: float = 0.0, m: bool = False) -> list[Part]:
    """Four boxes around a rectangular hole: outer ox*oy, hole ix*iy, height h from z0."""
    fx, fy = (ox - ix) / 2, (oy - iy) / 2
    z = z0 + h / 2
    return [_box(fx, oy, h, x + (ox - fx) / 2, y, z, c, m=m),
            _box(fx, oy, h, x - (ox - fx) / 2, y, z, c, m=m),
            _box(ix, fy, h, x, y + (oy - fy) / 2, z, c, m=m),
            _box(ix, fy, h, x, y - (oy - fy) / 2, z, c, m=m)]


def _legs(sx: float, sy: float, h: float, t: float, c: str = 'dark', z0: float = 0.0,
          round_legs: bool = False) -> list[Part]:
    """Four legs whose outer faces span sx*sy."""
    out = []
    for kx in (-1, 1):
        for ky in (-1, 1):
            px, py = kx * (sx - t) / 2, ky * (sy - t) / 2
            out.append(_cyl(t / 2, h, px, py, z0 + h / 2, c) if round_legs
                       else _box(t, t, h, px, py, z0 + h / 2, c))
    return out


def _surf(x: float, y: float, z: float, hx: float, hy: float, clearance: float,
          inside: bool = False) -> Surface:
    return Surface((x, y, z), (max(hx, 0.01), max(hy, 0.01)), clearance, inside)


# ---------------------------------------------------------------------------------------------------
# Normalisation: recentre on the closed bounding box


def _rot(rpy: Vec3) -> list[list[float]]:
    """R = Rz(yaw) Ry(pitch) Rx(roll), pybullet's Euler convention."""
    cr, sr = math.cos(rpy[0]), math.sin(rpy[0])
    cp, sp = math.cos(rpy[1]), math.sin(rpy[1])
    cy, sy = math.cos(rpy[2]), math.sin(rpy[2])
    return [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr]]


def part_bounds(part: Part) -> tuple[Vec3, Vec3]:
    """Axis-aligned (min, max) corners of a part in the object frame (closed pose)."""
    if part.shape == 'sphere':
        r = part.half_extents[0]
        return (tuple(p - r for p in part.pos), tuple(p + r for p in part.pos))  # type: ignore
    rot = _rot(part.rpy)
    he = part.half_extents
    ext = [sum(abs(rot[i][j]) * he[j] for j in range(3)) for i in range(3)]
    return (tuple(part.pos[i] - ext[i] for i in range(3)),  # type: ignore
            tuple(part.pos[i] + ext[i] for i in range(3)))


def _shift(v: Sequence[float], d: Sequence[float]) -> Vec3:
    return (v[0] + d[0], v[1] + d[1], v[2] + d[2])


def _finish(parts: Iterable[Part], articulation: Optional[Articulation] = None,
            surfaces: Iterable[Surface] = ()) -> ShapeSpec:
    parts = list(parts)
    lo = [min(part_bounds(p)[0][i] for p in parts) for i in range(3)]
    hi = [max(part_bounds(p)[1][i] for p in parts) for i in range(3)]
    d = (-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2])
    parts = tuple(Part(p.shape, p.half_extents, _shift(p.pos, d), p.rpy, p.colour, p.moving)
                  for p in parts)
    if articulation is not None:
        articulation = Articulation(articulation.kind, articulation.axis,
                                    _shift(articulation.origin, d), articulation.open_value)
    surfaces = tuple(Surface(_shift(s.center, d), s.half_size, s.clearance, s.inside)
                     for s in surfaces)
    size = tuple(round(hi[i] - lo[i], 4) for i in range(3))
    return ShapeSpec(parts, size, articulation, surfaces)  # type: ignore[arg-type]


def _hinge_z(x: float, y: float, door_towards_plus_y: bool, angle: float = 1.9) -> Articulation:
    """Vertical door hinge at (x, y): the door lies along +y (or -y) from it and swings to +x."""
    axis = (0.0, 0.0, -1.0 if door_towards_plus_y else 1.0)
    return Articulation('revolute', axis, (x, y, 0.0), angle)


def _hinge_lid(x: float, z: float, angle: float = 1.9) -> Articulation:
    """Horizontal hinge along y at the back edge (x, z) of a lid lying along +x: lifts upwards."""
    return Articulation('revolute', (0.0, -1.0, 0.0), (x, 0.0, z), angle)


def surface_offset(spec: ShapeSpec, surface: Surface, fraction: float) -> Vec3:
    """Displacement of `surface` when the object is opened to `fraction` (0..1).

    Only the inside surfaces of a prismatic articulation (a drawer's floor) move; others stay put.
    """
    art = spec.articulation
    if art is None or art.kind != 'prismatic' or not surface.inside:
        return (0.0, 0.0, 0.0)
    k = min(max(fraction, 0.0), 1.0) * art.open_value
    return (art.axis[0] * k, art.axis[1] * k, art.axis[2] * k)
