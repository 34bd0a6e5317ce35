"""Composed box/cylinder/sphere shapes for every ALFRED object type.

`shape_for(type_name, dims)` returns a ShapeSpec in the object frame of geometry.py (origin at the
bottom centre of the footprint, +x front, +y left, +z up). `dims` are the catalogue's approx_size_m
numbers as given: for pickupables the oriented box edges sorted largest first, for fixed objects
(length, width, height) of the axis-aligned box; each type's layout below says which edge goes
where (the long side of furniture runs along y, its front facing +x). The numbers scale the shape;
proportions that the catalogue gets wrong for our purpose are fixed by the builder (a CounterTop's
0.02 m is its slab only, so the counter gets a base and a 0.9 m height). After building, every shape
is recentred so its closed bounding box sits on the origin; ShapeSpec.size is that box.

Colours: 'main' is the instance's colour variant and is given to the largest visible part; 'dark'
and 'light' shade it; palette names stay fixed (silver blades, black handles).

Receptacles get Surfaces; `inside=True` where the object encloses them. For a prismatic articulation
(Drawer) the inside surfaces ride on the moving drawer: see `surface_offset`. Hanging holders
(TowelHolder, HandTowelHolder, ToiletPaperHanger) get a thin surface on their bar, ring or spindle;
what hangs there needs a pose of its own.
"""

from __future__ import annotations

import functools
import math
from typing import Callable, Iterable, Optional, Sequence

from .geometry import Articulation, Part, ShapeSpec, Surface, Vec3

PI = math.pi
_MIN_EDGE = 0.004

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


# ---------------------------------------------------------------------------------------------------
# Food. Builders take the object-frame extents (x, y, z) the catalogue suggests.


def _apple(X, Y, Z):
    r = min(X, Y, Z) / 2
    return _finish([_sph(r, z=r),
                    _cyl(0.07 * r, 0.5 * r, z=2.15 * r, c='brown'),
                    _box(0.6 * r, 0.3 * r, 0.05 * r, 0.3 * r, 0, 2.1 * r, 'green', (0.0, -0.4, 0.3))])


def _tomato(X, Y, Z):
    r = min(X, Y) / 2
    calyx = [_box(1.0 * r, 0.16 * r, 0.05 * r, 0, 0, 1.97 * r, 'green', (0.0, 0.0, a))
             for a in (0.0, PI / 3, 2 * PI / 3)]
    return _finish([_sph(r, z=r), *calyx, _cyl(0.08 * r, 0.25 * r, z=2.05 * r, c='green')])


def _potato(X, Y, Z):
    r = 0.46 * min(Y, Z)
    half = max(X / 2 - r, 0.0)
    return _finish([_cyl(r, 2 * half, z=r, axis='x'), _sph(r, x=-half, z=r),
                    _sph(0.9 * r, x=half, y=0.05 * r, z=0.95 * r),
                    _sph(0.6 * r, x=-0.2 * half, y=0.35 * r, z=1.3 * r)])


def _lettuce(X, Y, Z):
    r = 0.45 * min(Y, Z)
    dx = max(X / 2 - r, 0.0)
    leaves = [_box(0.01, 1.1 * r, 1.1 * r, (dx + 0.75 * r) * math.cos(a), 0.75 * r * math.sin(a), 1.2 * r,
                   'main', (0.0, 0.6, a)) for a in (2 * PI * k / 5 + 0.4 for k in range(5))]
    return _finish([_sph(r, x=-0.3 * dx, z=r), _sph(0.85 * r, x=0.5 * dx, y=0.1 * r, z=0.95 * r),
                    _sph(0.6 * r, x=0.1 * dx, y=-0.2 * r, z=1.5 * r, c='light'), *leaves])


def _bread(X, Y, Z):
    rr = 0.4 * min(Y, Z)
    cuts = [_box(0.02, 0.7 * Y, 0.006, dx * X, 0, Z - 0.001, 'light', (0.0, 0.0, 0.5))
            for dx in (-0.25, 0.0, 0.25)]
    return _finish([_box(X, Y, Z - rr, z=(Z - rr) / 2), _box(X, Y - 2 * rr, rr, z=Z - rr / 2),
                    _cyl(rr, X, y=Y / 2 - rr, z=Z - rr, axis='x'),
                    _cyl(rr, X, y=-(Y / 2 - rr), z=Z - rr, axis='x'), *cuts])


def _slice_disc(r, t, flesh, seeds):
    """A round slice: skin-coloured disc with a flesh face and a few seeds on top."""
    parts = [_cyl(r, t, z=t / 2), _cyl(0.86 * r, 0.002, z=t + 0.001, c=flesh)]
    for k in range(seeds):
        a = 2 * PI * k / max(seeds, 1)
        parts.append(_box(0.25 * r, 0.1 * r, 0.003, 0.4 * r * math.cos(a), 0.4 * r * math.sin(a),
                          t + 0.002, 'brown' if flesh == 'beige' else 'yellow', (0.0, 0.0, a)))
    return _finish(parts)


def _apple_sliced(X, Y, Z):
    return _slice_disc(X / 2, Z, 'beige', 3)


def _tomato_sliced(X, Y, Z):
    return _slice_disc(X / 2, Z, 'light', 4)


def _potato_sliced(X, Y, Z):
    r, t = Y / 2, Z
    body = [_box(X - Y, Y, t, z=t / 2), _cyl(r, t, x=(X - Y) / 2, z=t / 2),
            _cyl(r, t, x=-(X - Y) / 2, z=t / 2)]
    r2 = 0.82 * r
    face = [_box(X - Y, 2 * r2, 0.002, z=t + 0.001, c='khaki'),
            _cyl(r2, 0.002, x=(X - Y) / 2, z=t + 0.001, c='khaki'),
            _cyl(r2, 0.002, x=-(X - Y) / 2, z=t + 0.001, c='khaki')]
    return _finish(body + face)


def _lettuce_sliced(X, Y, Z):
    return _finish([_box(X, Y, 0.006, 0.01 * k, 0.005 * k, 0.004 + 0.007 * k,
                         'main' if k != 1 else 'light', (0.15 * (k - 1), 0.1, 0.7 * k))
                    for k in range(3)])


def _bread_sliced(X, Y, Z):
    s, t, c = Y, Z, 0.012
    crust = [_box(0.6 * s, s, t, -0.2 * s, 0, t / 2), _cyl(s / 2, t, x=0.1 * s, z=t / 2)]
    crumb = [_box(0.6 * s - c, s - 2 * c, 0.002, -0.2 * s + c / 2, 0, t + 0.001, 'beige'),
             _cyl(s / 2 - c, 0.002, x=0.1 * s, z=t + 0.001, c='beige')]
    return _finish(crust + crumb)


def _egg(X, Y, Z):
    r = min(Y, Z) / 2
    return _finish([_sph(r, x=-0.3 * r, z=r), _sph(0.88 * r, x=0.2 * r, z=r),
                    _sph(0.7 * r, x=0.58 * r, z=r)])


# ---------------------------------------------------------------------------------------------------
# Kitchenware


def _vessel(r, h, wall, floor, n, c='main', inner='dark'):
    """An open round container: base disc, polygonal wall, darker inside floor."""
    return ([_cyl(r, floor, z=floor / 2, c=c)] + _ring(r, wall, h - floor, floor, n, c)
            + [_cyl(r - wall, 0.002, z=floor + 0.001, c=inner)])


def _bowl(X, Y, Z):
    R = min(X, Y) / 2
    floor_z = 0.45 * Z
    parts = [_cyl(0.45 * R, 0.12 * Z, z=0.06 * Z),
             _cyl(0.72 * R, floor_z - 0.1 * Z, z=0.1 * Z + (floor_z - 0.1 * Z) / 2),
             _cyl(R - 0.01, 0.004, z=floor_z, c='dark'),
             *_ring(R, 0.01, Z - 0.35 * Z, 0.35 * Z, 10)]
    return _finish(parts, surfaces=[_surf(0, 0, floor_z + 0.002, 0.55 * R, 0.55 * R, 0.6 * Z, True)])


def _cup(X, Y, Z):
    r = min(X, Y) / 2
    return _finish(_vessel(r, Z, 0.006, 0.012, 10),
                   surfaces=[_surf(0, 0, 0.014, 0.5 * r, 0.5 * r, Z - 0.02, True)])


def _mug(X, Y, Z):
    r = min(Y, 0.8 * X) / 2
    hx = r + 0.022
    handle = _loop([(0, r - 0.004, 0.8 * Z), (0, hx, 0.75 * Z), (0, hx, 0.3 * Z),
                    (0, r - 0.004, 0.25 * Z)], 0.012, 0.012, closed=False)
    return _finish(_vessel(r, Z, 0.006, 0.012, 10) + handle,
                   surfaces=[_surf(0, 0, 0.014, 0.5 * r, 0.5 * r, Z - 0.02, True)])


def _pot(X, Y, Z):
    R = min(Y, X) / 2
    ear = max(X / 2 - R, 0.03)
    handles = []
    for s in (-1, 1):
        handles += _loop([(s * (R - 0.01), -0.045, 0.8 * Z), (s * (R + ear), -0.045, 0.8 * Z),
                          (s * (R + ear), 0.045, 0.8 * Z), (s * (R - 0.01), 0.045, 0.8 * Z)],
                         0.014, 0.014, 'black', closed=False)
    return _finish(_vessel(R, Z, 0.008, 0.012, 12) + handles,
                   surfaces=[_surf(0, 0, 0.014, 0.6 * R, 0.6 * R, Z - 0.02, True)])


def _pan(X, Y, Z):
    R = Y / 2
    h = max(Z, 0.04)
    handle = [_bar((R - 0.01, 0, 0.6 * h), (X - R, 0, 0.6 * h + 0.03), 0.026, 0.012, 'black')]
    return _finish(_vessel(R, h, 0.006, 0.01, 12) + handle,
                   surfaces=[_surf(0, 0, 0.012, 0.6 * R, 0.6 * R, 0.15, True)])


def _plate(X, Y, Z):
    R = min(X, Y) / 2
    t = max(Z, 0.014)
    return _finish([_cyl(0.5 * R, 0.35 * t, z=0.175 * t, c='dark'), _cyl(R, 0.65 * t, z=0.675 * t),
                    _cyl(0.66 * R, 0.002, z=t + 0.001, c='light')],
                   surfaces=[_surf(0, 0, t, 0.6 * R, 0.6 * R, 0.3)])


def _kettle(X, Y, Z):
    r = 0.42 * min(X, Y)
    body = 0.62 * Z
    top = 0.75 * Z
    lid_r = 0.5 * r
    handle = _loop([(-0.75 * r, 0, top - 0.01), (-0.6 * r, 0, Z), (0.45 * r, 0, Z), (0.6 * r, 0, top - 0.01)],
                   0.02, 0.018, 'black', closed=False)
    parts = [_cyl(r, body, z=body / 2), _cyl(0.8 * r, top - body, z=(top + body) / 2),
             _rod((0.6 * r, 0, 0.25 * Z), (1.55 * r, 0, 0.72 * Z), 0.016), *handle,
             _cyl(lid_r, 0.012, z=top + 0.006, c='dark', m=True),
             _cyl(0.012, 0.025, z=top + 0.02, c='black', m=True)]
    return _finish(parts, _hinge_lid(-lid_r, top, 1.2))


def _glassbottle(X, Y, Z):
    r = 0.45 * min(X, Y)
    body = 0.5 * Z
    neck0 = body + 0.75 * r
    return _finish([_cyl(r, body, z=body / 2), _sph(r, z=body),
                    _cyl(0.3 * r, Z - neck0, z=(Z + neck0) / 2),
                    _cyl(0.38 * r, 0.04 * Z, z=Z - 0.02 * Z)])


def _wine_bottle(X, Y, Z):
    r = 0.48 * min(X, Y)
    body = 0.58 * Z
    neck0 = body + 0.7 * r
    return _finish([_cyl(r, body, z=body / 2), _sph(r, z=body),
                    _cyl(0.3 * r, Z - neck0, z=(Z + neck0) / 2),
                    _cyl(0.34 * r, 0.13 * Z, z=Z - 0.065 * Z, c='gold'),
                    _cyl(r + 0.002, 0.22 * Z, z=0.3 * Z, c='beige')])


def _soap_bottle(X, Y, Z):
    bx, by, bz = 0.9 * X, Y, 0.68 * Z
    return _finish([_box(bx, by, bz, z=bz / 2), _box(bx + 0.002, by * 0.8, 0.3 * bz, z=0.45 * bz,
                                                     c='light'),
                    _cyl(0.18 * by, 0.06 * Z, z=bz + 0.03 * Z, c='white'),
                    _cyl(0.01, 0.2 * Z, z=bz + 0.1 * Z, c='white'),
                    _box(0.4 * X, 0.02, 0.05 * Z, 0.15 * X, 0, bz + 0.2 * Z, 'white'),
                    _cyl(0.007, 0.03, x=0.35 * X, z=bz + 0.18 * Z, c='white')])


def _spray_bottle(X, Y, Z):
    r = 0.3 * X
    bz = 0.62 * Z
    return _finish([_cyl(r, bz, z=bz / 2), _cyl(0.45 * r, 0.1 * Z, z=bz + 0.05 * Z, c='white'),
                    _box(0.7 * X, 0.03, 0.12 * Z, 0.15 * X, 0, bz + 0.16 * Z, 'white'),
                    _box(0.012, 0.014, 0.15 * Z, 0.22 * X, 0, bz + 0.03 * Z, 'white',
                         (0.0, -0.3, 0.0)),
                    _cyl(0.008, 0.02, x=0.5 * X, z=bz + 0.18 * Z, c='black', axis='x')])


def _vase(X, Y, Z):
    r = 0.45 * min(X, Y)
    return _finish([_sph(r, z=r), _cyl(0.42 * r, Z - 1.6 * r, z=(Z + 1.6 * r) / 2),
                    _cyl(0.6 * r, 0.05 * Z, z=Z - 0.025 * Z)])


def _shaker(X, Y, Z, square):
    r = 0.45 * min(X, Y)
    bz = 0.72 * Z
    body = _box(2 * r, 2 * r, bz, z=bz / 2) if square else _cyl(r, bz, z=bz / 2)
    cap = 'black' if square else 'silver'
    cap_r = 0.7 * r if square else 0.9 * r
    holes = [_cyl(0.004, 0.002, x=dx * r, y=dy * r, z=Z + 0.001, c='white' if square else 'black')
             for dx, dy in ((-0.3, 0), (0.3, 0), (0, 0.3), (0, -0.3))]
    return _finish([body, _cyl(cap_r, Z - bz, z=(Z + bz) / 2, c=cap), *holes])


def _candle(X, Y, Z):
    r = 0.5 * min(X, Y)
    return _finish([_cyl(1.8 * r, 0.01, z=0.005, c='silver'), _cyl(r, Z, z=0.01 + Z / 2),
                    _cyl(0.003, 0.015, z=Z + 0.0175, c='black')])


def _roll(r, h, core_colour='tan'):
    return [_cyl(r, h, z=h / 2), _cyl(0.38 * r, 0.002, z=h + 0.001, c=core_colour),
            _cyl(0.28 * r, 0.003, z=h + 0.0015, c='black')]


def _toilet_paper(X, Y, Z):
    return _finish(_roll(X / 2, max(Y, 0.8 * X)))


def _paper_towel_roll(X, Y, Z):
    return _finish(_roll(0.5 * max(X, Y), Z))


def _paper_towel(X, Y, Z):
    r = 0.45 * min(X, Y)
    return _finish([_cyl(0.55 * min(X, Y), 0.012, z=0.006, c='silver'),
                    _cyl(0.008, Z, z=Z / 2, c='silver'),
                    *[Part(p.shape, p.half_extents, (p.pos[0], p.pos[1], p.pos[2] + 0.014), p.rpy,
                           p.colour) for p in _roll(r, Z - 0.03)]])


def _toilet_paper_roll(X, Y, Z):
    r = min(X, Y) / 2
    return _finish([_cyl(r, Z, z=Z / 2), _cyl(0.8 * r, 0.003, z=Z + 0.0015, c='black')])


# ---------------------------------------------------------------------------------------------------
# Cutlery and utensils, lying flat along x (handle towards -x)


def _knife(X, Y, Z):
    hl, w = 0.36 * X, 0.45 * Y
    bl, bw = X - hl - 0.02, Y
    d = bw / math.sqrt(2)
    by = bw / 2 - w / 2
    return _finish([_box(hl, w, max(Z, 0.012), -X / 2 + hl / 2, 0, max(Z, 0.012) / 2),
                    _box(0.02, w, 0.8 * max(Z, 0.012), -X / 2 + hl + 0.01, 0, 0.4 * max(Z, 0.012), 'silver'),
                    _box(bl - bw / 2, bw, 0.003, X / 2 - bl / 2 - bw / 4, by, 0.0015, 'silver'),
                    _box(d, d, 0.003, X / 2 - bw / 2, by, 0.0015, 'silver', (0.0, 0.0, PI / 4))])


def _butter_knife(X, Y, Z):
    hl = 0.45 * X
    return _finish([_box(hl, Y, Z, -X / 2 + hl / 2, 0, Z / 2),
                    _box(X - hl - Y / 2, 0.8 * Y, 0.003, (hl - Y / 2) / 2, 0, 0.0015, 'silver'),
                    _cyl(0.4 * Y, 0.003, x=X / 2 - 0.4 * Y, z=0.0015, c='silver')])


def _fork(X, Y, Z):
    hl = 0.62 * X
    tl = 0.22 * X
    tines = [_box(tl, 0.14 * Y, 0.003, X / 2 - tl / 2, (k - 1.5) * 0.26 * Y, 0.006)
             for k in range(4)]
    return _finish([_box(hl, 0.35 * Y, 0.005, -X / 2 + hl / 2, 0, 0.0025),
                    _box(X - hl - tl + 0.004, Y, 0.004, X / 2 - tl - (X - hl - tl) / 2, 0, 0.005),
                    *tines])


def _spoon(X, Y, Z):
    r = Y / 2
    hl = X - 3.4 * r
    return _finish([_box(hl, 0.3 * Y, 0.005, -X / 2 + hl / 2, 0, 0.0025),
                    _cyl(r, 0.008, x=X / 2 - r, z=0.004), _cyl(0.85 * r, 0.008, x=X / 2 - 2.2 * r, z=0.004),
                    _cyl(0.8 * r, 0.002, x=X / 2 - r, z=0.009, c='light')])


def _spatula(X, Y, Z):
    hl, head = 0.55 * X, 0.35 * X
    slots = [_box(0.7 * head, 0.012, 0.002, X / 2 - head / 2, dy * Y, 0.0045, 'black')
             for dy in (-0.22, 0.0, 0.22)]
    return _finish([_box(hl, 0.3 * Y, 0.014, -X / 2 + hl / 2, 0, 0.018),
                    _bar((-X / 2 + hl, 0, 0.018), (X / 2 - head, 0, 0.004), 0.2 * Y, 0.006, 'silver'),
                    _box(head, Y, 0.004, X / 2 - head / 2, 0, 0.002, 'silver'), *slots])


def _ladle(X, Y, Z):
    r = 0.45 * Y
    cx = X / 2 - r
    rim = r * 1.5
    return _finish([_sph(r, x=cx, z=r), _cyl(0.84 * r, 0.003, x=cx, z=rim, c='dark'),
                    _bar((cx - 0.8 * r, 0, rim), (-X / 2, 0, rim + 0.06), 0.015, 0.005)])


def _pen(X, Y, Z, pencil):
    r = max(Y, Z) / 2
    if pencil:
        return _finish([_cyl(r, 0.8 * X, x=-0.05 * X, z=r, axis='x'),
                        _cyl(r * 1.02, 0.05 * X, x=-0.475 * X, z=r, axis='x', c='silver'),
                        _cyl(r, 0.04 * X, x=-0.52 * X, z=r, axis='x', c='pink'),
                        _cyl(0.7 * r, 0.08 * X, x=0.39 * X, z=r, axis='x', c='tan'),
                        _cyl(0.3 * r, 0.03 * X, x=0.44 * X, z=r, axis='x', c='black')])
    return _finish([_cyl(r, 0.7 * X, x=0.1 * X, z=r, axis='x'),
                    _cyl(r * 1.1, 0.3 * X, x=-0.35 * X, z=r * 1.1, axis='x', c='dark'),
                    _box(0.22 * X, 0.3 * r, 0.4 * r, -0.32 * X, 0, 2.3 * r, 'silver'),
                    _cyl(0.5 * r, 0.06 * X, x=0.47 * X, z=r, axis='x', c='silver')])


# ---------------------------------------------------------------------------------------------------
# Small household objects


def _alarm_clock(X, Y, Z):
    r = 0.42 * min(Y, Z)
    cz = 0.02 + r
    fx = X / 2
    hands = [_bar((fx + 0.003, 0, cz), (fx + 0.003, 0.45 * r, cz + 0.2 * r), 0.012, 0.004, 'black'),
             _bar((fx + 0.003, 0, cz), (fx + 0.003, -0.1 * r, cz + 0.7 * r), 0.01, 0.004, 'black')]
    bells = [_sph(0.3 * r, 0, s * 0.55 * r, cz + 0.95 * r, 'silver') for s in (-1, 1)]
    feet = [_cyl(0.012, 0.03, 0, s * 0.55 * r, 0.015, 'black') for s in (-1, 1)]
    return _finish([_cyl(r, X, z=cz, axis='x'), _cyl(0.85 * r, 0.004, x=fx, z=cz, axis='x', c='white'),
                    *hands, *bells, *feet])


def _basketball(X, Y, Z):
    R = min(X, Y, Z) / 2
    return _finish([_sph(R, z=R), _cyl(R * 1.005, 0.005, z=R, axis='x', c='black'),
                    _cyl(R * 1.005, 0.005, z=R, axis='y', c='black'),
                    _cyl(R * 1.005, 0.005, z=R, c='black')])


def _baseball_bat(X, Y, Z):
    r = min(Y, Z) / 2
    return _finish([_cyl(r, 0.42 * X, x=0.29 * X, z=r, axis='x'),
                    _rod((-0.2 * X, 0, r), (0.08 * X, 0, r), 0.6 * r),
                    _cyl(0.38 * r, 0.28 * X, x=-0.34 * X, z=r, axis='x', c='black'),
                    _cyl(0.6 * r, 0.02, x=-0.49 * X, z=r, axis='x', c='black')])


def _book(X, Y, Z):
    t = 0.004
    return _finish([_box(X, Y, t, z=t / 2),
                    _box(X - 0.012, Y - 0.008, Z - 2 * t, 0.0, -0.004, Z / 2, 'white'),
                    _box(X + 0.002, 0.008, Z + 0.001, 0, Y / 2 - 0.0035, Z / 2, 'dark'),
                    _box(X, Y, t, z=Z - t / 2, m=True),
                    _box(0.3 * X, 0.5 * Y, 0.001, 0.15 * X, -0.05 * Y, Z + 0.0005, 'light', m=True)],
                   Articulation('revolute', (-1.0, 0.0, 0.0), (0.0, Y / 2, Z - t), 2.4))


def _boots(X, Y, Z):
    w = 0.42 * Y
    parts = []
    for s in (-1, 1):
        y = s * (Y / 2 - w / 2)
        parts += [_box(X, w, 0.02, 0, y, 0.01, 'black'),
                  _box(0.7 * X, w * 0.95, 0.09, 0.15 * X, y, 0.065),
                  _cyl(0.45 * w, 0.09, x=X / 2 - 0.45 * w, y=y, z=0.065),
                  _box(0.45 * X, w * 0.95, Z - 0.02, -0.27 * X, y, Z / 2 + 0.01),
                  _box(0.45 * X, w * 0.8, 0.003, -0.27 * X, y, Z + 0.0115, 'black')]
    return _finish(parts)


def _cloth(X, Y, Z):
    t = max(Z / 3, 0.004)
    return _finish([_box(X, 0.8 * Y, t, z=t / 2), _box(0.8 * X, 0.7 * Y, t, 0.05 * X, 0.1 * Y, 1.5 * t,
                                                       'light', (0.0, 0.0, 0.3)),
                    _box(0.6 * X, 0.5 * Y, t, -0.1 * X, -0.05 * Y, 2.5 * t, 'main', (0.05, 0.0, -0.4))])


def _cd(X, Y, Z):
    R = min(X, Y) / 2
    return _finish([_cyl(R, 0.0015, z=0.00075), _cyl(0.32 * R, 0.001, z=0.002, c='white'),
                    _cyl(0.1 * R, 0.002, z=0.0025, c='black')])


def _cell_phone(X, Y, Z):
    t = max(Z, 0.008)
    return _finish([_box(X, Y, t, z=t / 2), _box(0.86 * X, 0.88 * Y, 0.001, z=t + 0.0005, c='navy'),
                    _cyl(0.003, 0.001, x=0.46 * X, z=t + 0.0005, c='gray')])


def _credit_card(X, Y, Z):
    t = 0.0015
    return _finish([_box(X, Y, t, z=t / 2), _box(0.012, 0.01, 0.0004, -0.25 * X, 0.1 * Y, t, 'gold'),
                    _box(0.6 * X, 0.08 * Y, 0.0004, 0.05 * X, -0.2 * Y, t, 'white')])


def _dish_sponge(X, Y, Z):
    return _finish([_box(X, Y, 0.65 * Z, z=0.325 * Z), _box(X, Y, 0.35 * Z, z=0.825 * Z, c='dark')])


def _key_chain(X, Y, Z):
    ring = _loop([(0.015 * math.cos(a), 0.015 * math.sin(a), 0.002)
                  for a in (2 * PI * k / 6 for k in range(6))], 0.003, 0.003, 'silver')
    keys = []
    for a in (-0.35, 0.35):
        c, s = math.cos(a), math.sin(a)
        keys += [_cyl(0.011, 0.003, x=0.026 * c, y=0.026 * s, z=0.0045),
                 _box(0.045, 0.008, 0.002, 0.058 * c, 0.058 * s, 0.0045, rpy=(0.0, 0.0, a))]
    fob = _box(0.03, 0.02, 0.006, -0.03, 0, 0.004, 'dark')
    return _finish(ring + keys + [fob])


def _newspaper(X, Y, Z):
    t = max(Z, 0.01)
    lines = [_box(0.5 * X, 0.012, 0.0005, -0.12 * X, dy * Y, t + 0.00025, 'dark')
             for dy in (-0.32, -0.16, 0.0)]
    return _finish([_box(X, Y, t, z=t / 2),
                    _box(0.25 * X, 0.8 * Y, 0.0005, 0.32 * X, 0, t + 0.00025, 'black'),
                    _box(0.25 * X, 0.35 * Y, 0.0005, 0.02 * X, 0.25 * Y, t + 0.00026, 'gray'), *lines])


def _pillow(X, Y, Z):
    r = Z / 2
    return _finish([_box(X, Y - 2 * r, Z, z=r), _cyl(r, X, y=Y / 2 - r, z=r, axis='x'),
                    _cyl(r, X, y=-(Y / 2 - r), z=r, axis='x')])


def _remote(X, Y, Z):
    t = max(Z, 0.015)
    buttons = [_box(0.018, 0.012, 0.003, dx * X, dy * Y, t + 0.001, 'dark')
               for dx in (-0.15, 0.0, 0.15) for dy in (-0.22, 0.22)]
    return _finish([_box(X, Y, t, z=t / 2), _cyl(0.008, 0.003, x=0.4 * X, z=t + 0.001, c='red'),
                    _cyl(0.018, 0.003, x=0.22 * X, z=t + 0.001, c='light'), *buttons])


def _soap_bar(X, Y, Z):
    r = Y / 2
    return _finish([_box(X - Y, Y, Z, z=Z / 2), _cyl(r, Z, x=(X - Y) / 2, z=Z / 2),
                    _cyl(r, Z, x=-(X - Y) / 2, z=Z / 2),
                    _box(0.4 * X, 0.4 * Y, 0.002, z=Z + 0.001, c='light')])


def _statue(X, Y, Z):
    pz = 0.12 * Z
    torso = 0.42 * Z
    r = 0.16 * min(X, Y) + 0.01
    return _finish([_box(0.8 * X, 0.8 * Y, pz, z=pz / 2, c='black'),
                    _cyl(r, 0.45 * Z - r, z=pz + (0.45 * Z - r) / 2),
                    _cyl(1.2 * r, torso - r, z=pz + 0.45 * Z + (torso - r) / 2 - r),
                    _sph(0.9 * r, z=Z - 0.9 * r),
                    _rod((0, 1.1 * r, pz + 0.75 * Z - r), (0.2 * X, 0.45 * Y, pz + 0.5 * Z), 0.35 * r),
                    _rod((0, -1.1 * r, pz + 0.75 * Z - r), (0.0, -0.4 * Y, Z * 0.97), 0.35 * r)])


def _teddy_bear(X, Y, Z):
    H = Z
    parts = [_sph(0.28 * H, z=0.3 * H), _sph(0.2 * H, x=0.02 * H, z=0.72 * H),
             _sph(0.08 * H, x=0.21 * H, z=0.68 * H, c='light')]
    for s in (-1, 1):
        parts += [_sph(0.07 * H, y=s * 0.15 * H, z=0.88 * H),
                  _rod((0.05 * H, s * 0.24 * H, 0.46 * H), (0.22 * H, s * 0.33 * H, 0.28 * H), 0.08 * H),
                  _rod((0.05 * H, s * 0.15 * H, 0.1 * H), (0.4 * H, s * 0.2 * H, 0.09 * H), 0.09 * H),
                  _box(0.01, 0.025 * H, 0.025 * H, 0.2 * H, s * 0.07 * H, 0.78 * H, 'black')]
    return _finish(parts)


def _tissue_box(X, Y, Z):
    return _finish([_box(X, Y, Z, z=Z / 2), _box(0.5 * X, 0.25 * Y, 0.002, z=Z + 0.001, c='dark'),
                    _box(0.2 * X, 0.004, 0.5 * Z, 0, 0, Z + 0.2 * Z, 'white', (0.3, 0.0, 0.0)),
                    _box(0.2 * X, 0.004, 0.4 * Z, 0.04 * X, 0, Z + 0.15 * Z, 'white', (-0.4, 0.0, 0.2))])


def _watch(X, Y, Z):
    R = 0.45 * X
    strap = _loop([(R * math.cos(a), 0, R + R * math.sin(a)) for a in
                   (2 * PI * k / 8 for k in range(8))], min(Y, 0.022), 0.004)
    return _finish(strap + [_cyl(0.6 * min(Y, 0.03), 0.01, z=2 * R + 0.004, c='silver'),
                            _cyl(0.5 * min(Y, 0.03), 0.002, z=2 * R + 0.01, c='white')])


def _watering_can(X, Y, Z):
    r = 0.42 * Y
    cx = -X / 2 + r
    bz = 0.8 * Z
    return _finish([_cyl(r, bz, x=cx, z=bz / 2),
                    _rod((cx + 0.7 * r, 0, 0.2 * Z), (X / 2 - 0.015, 0, 0.9 * Z), 0.013),
                    _cyl(0.025, 0.015, x=X / 2 - 0.01, z=0.92 * Z, c='dark', rpy=(0.0, 0.9, 0.0)),
                    _cyl(0.6 * r, 0.002, x=cx + 0.2 * r, z=bz + 0.001, c='dark'),
                    *_loop([(cx - 0.9 * r, 0, 0.6 * Z), (cx - 0.9 * r, 0, Z), (cx + 0.3 * r, 0, Z),
                            (cx + 0.4 * r, 0, bz)], 0.016, 0.016, closed=False)])


def _scrub_brush(X, Y, Z):
    r = 0.45 * min(X, Y)
    hz = 0.28 * Z
    return _finish([_cyl(r, hz, z=hz / 2), _cyl(1.05 * r, 0.015, z=hz, c='dark'),
                    _cyl(0.012, Z - hz, z=(Z + hz) / 2, c='white'),
                    _cyl(0.02, 0.04, z=Z - 0.02, c='white')])


def _plunger(X, Y, Z):
    r = 0.5 * min(X, Y)
    return _finish([_cyl(r, 0.05, z=0.025), _sph(0.85 * r, z=0.05),
                    _cyl(0.014, Z - 0.05, z=0.05 + (Z - 0.05) / 2, c='tan')])


def _hanging_towel(X, Y, Z, stripes):
    t = 0.012
    r = 0.025
    parts = [_box(t, Y, Z - r, x=r - t / 2, z=(Z - r) / 2),
             _box(t, Y, 0.7 * (Z - r), x=-(r - t / 2), z=Z - r - 0.35 * (Z - r)),
             _cyl(r, Y, z=Z - r, axis='y')]
    parts += [_box(0.002, Y, 0.035, r + 0.001, 0, h * Z, 'light') for h in stripes]
    return _finish(parts)


def _towel(X, Y, Z):
    return _hanging_towel(X, Y, Z, (0.12, 0.2))


def _hand_towel(X, Y, Z):
    return _hanging_towel(X, Y, Z, (0.15,))


# ---------------------------------------------------------------------------------------------------
# Openable furniture and appliances (front +x; doors hinge on the object's right, -y)


def _shell(D, W, H, t, x=0.0, z0=0.0, c='main', back_t=None) -> list[Part]:
    """Back, sides, bottom and top of a box open at its front (+x); outer size D*W*H."""
    bt = back_t or t
    return [_box(bt, W, H, x - D / 2 + bt / 2, 0, z0 + H / 2, c),
            _box(D, t, H, x, W / 2 - t / 2, z0 + H / 2, c),
            _box(D, t, H, x, -W / 2 + t / 2, z0 + H / 2, c),
            _box(D, W - 2 * t, t, x, 0, z0 + t / 2, c),
            _box(D, W - 2 * t, t, x, 0, z0 + H - t / 2, c)]


def _fridge(X, Y, Z):
    d, t, plinth = 0.06, 0.04, 0.08
    D = X - d
    cx = -d / 2
    xf = X / 2 - d
    inner_d, inner_w = D - t, Y - 2 * t
    floor = plinth + t
    top = Z - t
    levels = [floor + (top - floor) * k / 3 for k in range(3)]
    parts = _shell(D, Y, Z - plinth, t, cx, plinth) + [
        _box(D - 0.02, Y - 0.04, plinth, cx - 0.01, 0, plinth / 2, 'black'),
        _box(0.005, inner_w, top - floor, -X / 2 + t + 0.0025, 0, (top + floor) / 2, 'white'),
        _box(inner_d, 0.005, top - floor, cx + t / 2, inner_w / 2 - 0.0025, (top + floor) / 2, 'white'),
        _box(inner_d, 0.005, top - floor, cx + t / 2, -inner_w / 2 + 0.0025, (top + floor) / 2, 'white'),
        _box(inner_d, inner_w, 0.004, cx + t / 2, 0, floor + 0.002, 'white')]
    parts += [_box(inner_d - 0.03, inner_w, 0.012, cx + t / 2 - 0.015, 0, z - 0.006, 'silver')
              for z in levels[1:]]
    parts += [_box(d, Y, Z - plinth, xf + d / 2, 0, plinth + (Z - plinth) / 2, m=True),
              _box(0.004, Y - 0.02, 0.01, X / 2 + 0.002, 0, 0.68 * Z, 'dark', m=True),
              _box(0.03, 0.03, 0.35 * Z, X / 2 + 0.015, Y / 2 - 0.08, 0.5 * Z, 'silver', m=True),
              _box(0.03, 0.03, 0.18 * Z, X / 2 + 0.015, Y / 2 - 0.08, 0.8 * Z, 'silver', m=True)]
    surfaces = []
    for k, z in enumerate(levels):
        z_next = levels[k + 1] - 0.012 if k + 1 < len(levels) else top
        zs = z + (0.004 if k == 0 else 0.0)
        surfaces.append(_surf(cx + t / 2 - 0.015, 0, zs, inner_d / 2 - 0.04, inner_w / 2 - 0.04,
                              z_next - zs, True))
    return _finish(parts, _hinge_z(X / 2, -Y / 2, True, 1.9), surfaces)


def _cabinet(X, Y, Z):
    d, t = 0.02, 0.018
    D = X - d
    cx = -d / 2
    inner_d = D - t
    mid = Z / 2
    parts = _shell(D, Y, Z, t, cx) + [
        _box(0.004, Y - 2 * t, Z - 2 * t, -X / 2 + t + 0.002, 0, Z / 2, 'light'),
        _box(inner_d - 0.01, Y - 2 * t, 0.015, cx + t / 2 - 0.005, 0, mid, 'light'),
        _box(d, Y, Z, X / 2 - d / 2, 0, Z / 2, m=True),
        _box(0.003, Y - 0.08, Z - 0.08, X / 2 + 0.0015, 0, Z / 2, 'dark', m=True),
        _box(0.003, Y - 0.1, Z - 0.1, X / 2 + 0.003, 0, Z / 2, m=True),
        _box(0.02, 0.015, 0.12, X / 2 + 0.01, Y / 2 - 0.05, 0.5 * Z, 'silver', m=True)]
    surfaces = [_surf(cx + t / 2, 0, t, inner_d / 2 - 0.02, Y / 2 - t - 0.02, mid - 0.0075 - t, True),
                _surf(cx + t / 2, 0, mid + 0.0075, inner_d / 2 - 0.02, Y / 2 - t - 0.02,
                      Z - t - mid - 0.0075, True)]
    return _finish(parts, _hinge_z(X / 2, -Y / 2, True, 1.9), surfaces)


def _microwave(X, Y, Z):
    d, t = 0.03, 0.02
    D = X - d
    cx = -d / 2
    panel = 0.24 * Y
    cav_w = Y - panel
    cav_cy = -panel / 2
    parts = [
        _box(t, Y, Z, -X / 2 + t / 2, 0, Z / 2),
        _box(D, Y, t, cx, 0, t / 2), _box(D, Y, t, cx, 0, Z - t / 2),
        _box(D, t, Z, cx, -Y / 2 + t / 2, Z / 2),
        _box(D, panel, Z - 2 * t, cx, Y / 2 - panel / 2, Z / 2),
        _box(0.004, panel - 0.02, Z - 0.04, X / 2 + 0.002 - d, Y / 2 - panel / 2, Z / 2, 'black'),
        _cyl(0.02, 0.01, x=X / 2 - d + 0.008, y=Y / 2 - panel / 2, z=0.6 * Z, c='silver', axis='x'),
        _cyl(0.02, 0.01, x=X / 2 - d + 0.008, y=Y / 2 - panel / 2, z=0.3 * Z, c='silver', axis='x'),
        _box(D - t, cav_w - t, 0.004, cx + t / 2, cav_cy + t / 2, t + 0.002, 'silver'),
        _box(0.004, cav_w - t, Z - 2 * t, -X / 2 + t + 0.002, cav_cy + t / 2, Z / 2, 'silver'),
        _box(d, cav_w, Z, X / 2 - d / 2, cav_cy, Z / 2, m=True),
        _box(0.003, 0.72 * cav_w, 0.62 * Z, X / 2 + 0.0015, cav_cy - 0.04 * cav_w, Z / 2, 'black',
             m=True),
        _box(0.02, 0.02, 0.5 * Z, X / 2 + 0.01, cav_cy + cav_w / 2 - 0.05, Z / 2, 'silver', m=True)]
    surfaces = [_surf(cx + t / 2, cav_cy + t / 2, t + 0.004, (D - t) / 2 - 0.03, cav_w / 2 - t - 0.02,
                      Z - 2 * t - 0.004, True)]
    return _finish(parts, _hinge_z(X / 2, -Y / 2, True, 1.9), surfaces)


def _safe(X, Y, Z):
    d, t = 0.06, 0.05
    D = X - d
    cx = -d / 2
    parts = _shell(D, Y, Z, t, cx) + [
        _box(0.004, Y - 2 * t, Z - 2 * t, -X / 2 + t + 0.002, 0, Z / 2, 'dark'),
        _box(D - t, Y - 2 * t, 0.004, cx + t / 2, 0, t + 0.002, 'dark'),
        _box(d, Y, Z, X / 2 - d / 2, 0, Z / 2, m=True),
        _cyl(0.06, 0.02, x=X / 2 + 0.01, y=0.05 * Y, z=0.58 * Z, c='silver', axis='x', m=True),
        _box(0.012, 0.01, 0.09, X / 2 + 0.024, 0.05 * Y, 0.58 * Z, 'black', m=True),
        _box(0.03, 0.025, 0.2 * Z, X / 2 + 0.015, Y / 2 - 0.07, 0.5 * Z, 'silver', m=True)]
    surfaces = [_surf(cx + t / 2, 0, t + 0.004, (D - t) / 2 - 0.03, Y / 2 - t - 0.03, Z - 2 * t - 0.004,
                      True)]
    return _finish(parts, _hinge_z(X / 2, -Y / 2, True, 1.9), surfaces)


def _drawer(X, Y, Z):
    t, f = 0.015, 0.02
    D = X - f
    cx = -f / 2
    # the drawer box sits inside the housing; its front closes the housing's front
    bx0, bx1 = -X / 2 + t + 0.005, X / 2 - f
    bw, bh = Y - 2 * t - 0.01, Z - 2 * t - 0.01
    bcx = (bx0 + bx1) / 2
    bd = bx1 - bx0
    parts = _shell(D, Y, Z, t, cx) + [
        _box(f, Y, Z, X / 2 - f / 2, 0, Z / 2, m=True),
        _box(0.02, 0.12, 0.02, X / 2 + 0.01, 0, 0.55 * Z, 'silver', m=True),
        _box(bd, bw, 0.01, bcx, 0, t + 0.005 + 0.005, 'light', m=True),
        _box(bd, 0.01, bh, bcx, bw / 2 - 0.005, t + 0.005 + bh / 2, 'light', m=True),
        _box(bd, 0.01, bh, bcx, -bw / 2 + 0.005, t + 0.005 + bh / 2, 'light', m=True),
        _box(0.01, bw, bh, bx0 + 0.005, 0, t + 0.005 + bh / 2, 'light', m=True)]
    floor_z = t + 0.015
    surfaces = [_surf(bcx, 0, floor_z, bd / 2 - 0.025, bw / 2 - 0.025, Z - t - floor_z, True)]
    return _finish(parts, Articulation('prismatic', (1.0, 0.0, 0.0), (X / 2, 0.0, 0.0), 0.8 * bd),
                   surfaces)


def _box_container(X, Y, Z):
    t = 0.008
    h = Z - t
    parts = [_box(X, Y, t, z=t / 2), *_frame(X, Y, X - 2 * t, Y - 2 * t, h - t, t),
             _box(X, Y, t, z=h + t / 2, m=True),
             _box(X, 0.06, 0.001, 0, 0, h + t + 0.0005, 'light', m=True)]
    surfaces = [_surf(0, 0, t, X / 2 - 2 * t, Y / 2 - 2 * t, h - 2 * t, True)]
    return _finish(parts, _hinge_lid(-X / 2, h, 1.9), surfaces)


def _laptop(X, Y, Z):
    base, lid = 0.02, 0.012
    parts = [_box(X, Y, base, z=base / 2),
             _box(0.45 * X, 0.88 * Y, 0.001, -0.1 * X, 0, base + 0.0005, 'black'),
             _box(0.18 * X, 0.3 * Y, 0.001, 0.32 * X, 0, base + 0.0005, 'dark'),
             _box(X, Y, lid, z=base + 0.001 + lid / 2, m=True),
             _box(0.86 * X, 0.9 * Y, 0.001, 0.02 * X, 0, base + 0.0011, 'navy', m=True),
             _box(0.2 * X, 0.2 * X, 0.001, 0.0, 0, base + 0.001 + lid + 0.0005, 'light', m=True)]
    return _finish(parts, _hinge_lid(-X / 2, base + 0.001, 1.85))


def _toilet(X, Y, Z):
    H = min(Z, 0.8)
    tank_d = 0.2
    r = min(0.42 * Y, 0.3)
    bx = -X / 2 + tank_d + r - 0.02
    bowl_top = 0.4
    seat = 0.025
    tank_z0 = bowl_top - 0.05
    base_h = bowl_top - 0.12
    parts = [_box(tank_d, 0.85 * Y, H - tank_z0 - 0.025, -X / 2 + tank_d / 2, 0, (H - 0.025 + tank_z0) / 2),
             _box(tank_d + 0.02, 0.88 * Y, 0.025, -X / 2 + tank_d / 2 + 0.005, 0, H - 0.0125),
             _box(0.02, 0.05, 0.015, -X / 2 + tank_d + 0.01, 0.3 * Y, H - 0.08, 'silver'),
             _box(bx + X / 2 - 0.02, 0.5 * Y, base_h, (bx - X / 2 + 0.02) / 2, 0, base_h / 2),
             _box(0.15, 0.6 * Y, tank_z0 - base_h + 0.01, -X / 2 + 0.095, 0, (tank_z0 + base_h) / 2),
             _cyl(r, 0.12, x=bx, z=bowl_top - 0.06),
             _cyl(0.7 * r, 0.002, x=bx, z=bowl_top + 0.001, c='teal'),
             *_ring(r, 0.05, seat, bowl_top, 10, 'light', x=bx),
             _cyl(r, 0.02, x=bx, z=bowl_top + seat + 0.01, m=True)]
    surfaces = [_surf(-X / 2 + tank_d / 2 + 0.005, 0, H, tank_d / 2 - 0.02, 0.4 * Y, 0.4)]
    return _finish(parts, _hinge_lid(bx - r, bowl_top + seat, 1.4), surfaces)


def _blinds(X, Y, Z):
    H = max(Z, 1.3)
    rail = 0.05
    drop = H - rail
    slats = [_box(0.003, Y - 0.02, 0.006, 0.012, 0, drop * (k + 0.5) / 7, 'light', m=True)
             for k in range(7)]
    parts = [_box(0.05, Y + 0.02, rail, 0, 0, H - rail / 2, 'white'),
             _box(0.01, Y - 0.02, drop, 0.005, 0, drop / 2, m=True),
             _box(0.022, Y, 0.02, 0.011, 0, 0.01, 'dark', m=True), *slats]
    return _finish(parts, Articulation('prismatic', (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 0.75 * drop))


def _shower_curtain(X, Y, Z):
    W = max(Y, X, 1.2)
    travel = 0.75 * W
    n = 8
    pleats = [_box(0.02, W / n + 0.01, Z - 0.1, 0.015 * (1 if k % 2 else -1),
                   -W / 2 + W * (k + 0.5) / n, (Z - 0.1) / 2, 'main' if k % 2 else 'dark', m=True)
              for k in range(n)]
    rod = _cyl(0.012, W + travel, y=travel / 2, z=Z - 0.03, c='silver', axis='y')
    return _finish([rod, *pleats], Articulation('prismatic', (0.0, 1.0, 0.0), (0.0, 0.0, 0.0), travel))


def _shower_door(X, Y, Z):
    jamb = 0.04
    g = 0.012
    hinge_y = -Y / 2 + jamb
    w = Y - jamb
    cy = hinge_y + w / 2
    parts = [_box(0.05, jamb, Z, 0, -Y / 2 + jamb / 2, Z / 2, 'silver'),
             _box(g, w - 0.03, Z - 0.06, 0, cy, Z / 2, m=True),
             _box(0.025, w, 0.03, 0, cy, Z - 0.015, 'silver', m=True),
             _box(0.025, w, 0.03, 0, cy, 0.015, 'silver', m=True),
             _box(0.025, 0.03, Z, 0, Y / 2 - 0.015, Z / 2, 'silver', m=True),
             _box(0.03, 0.02, 0.3, 0.025, Y / 2 - 0.08, 0.5 * Z, 'silver', m=True)]
    return _finish(parts, _hinge_z(0.0125, hinge_y, True, 1.4))


# ---------------------------------------------------------------------------------------------------
# Tables, seats, beds, storage (long side along y, front +x)


def _top_surface(X, Y, Z, margin=0.04, clearance=0.6):
    return _surf(0, 0, Z, X / 2 - margin, Y / 2 - margin, clearance)


def _table(X, Y, Z, top_t, leg, inset, shelf=False):
    parts = [_box(X, Y, top_t, z=Z - top_t / 2),
             *_frame(X - 2 * inset, Y - 2 * inset, X - 2 * inset - 0.04, Y - 2 * inset - 0.04,
                     0.08, Z - top_t - 0.08, 'dark'),
             *_legs(X - 2 * inset, Y - 2 * inset, Z - top_t, leg)]
    if shelf:
        parts.append(_box(X - 2 * inset - 0.02, Y - 2 * inset - 0.02, 0.02, z=0.12, c='dark'))
    return _finish(parts, surfaces=[_top_surface(X, Y, Z)])


def _dining_table(X, Y, Z):
    return _table(X, Y, Z, 0.04, 0.07, 0.06)


def _coffee_table(X, Y, Z):
    return _table(X, Y, Z, 0.04, 0.05, 0.04, shelf=True)


def _side_table(X, Y, Z):
    legs_h = 0.1
    body_h = Z - legs_h - 0.03
    fx = X / 2
    parts = [_box(X + 0.02, Y + 0.02, 0.03, z=Z - 0.015),
             _box(X, Y, body_h, z=legs_h + body_h / 2),
             _box(0.004, Y - 0.04, 0.3 * body_h, fx + 0.002, 0, legs_h + 0.8 * body_h, 'light'),
             _cyl(0.012, 0.02, x=fx + 0.01, z=legs_h + 0.8 * body_h, c='silver', axis='x'),
             _box(0.004, Y - 0.06, 0.5 * body_h, fx + 0.002, 0, legs_h + 0.32 * body_h, 'black'),
             *_legs(X - 0.02, Y - 0.02, legs_h, 0.04, 'dark')]
    return _finish(parts, surfaces=[_top_surface(X + 0.02, Y + 0.02, Z)])


def _desk(X, Y, Z):
    top_t = 0.035
    ped_w = min(0.42, 0.3 * Y)
    py = -Y / 2 + ped_w / 2 + 0.01
    h = Z - top_t
    parts = [_box(X, Y, top_t, z=Z - top_t / 2),
             _box(X - 0.04, ped_w, h, -0.01, py, h / 2),
             _box(0.02, Y - ped_w - 0.08, 0.4, -X / 2 + 0.06, ped_w / 2, Z - top_t - 0.2, 'dark'),
             *[_box(0.05, 0.05, h, sx * (X / 2 - 0.05), Y / 2 - 0.05, h / 2, 'dark') for sx in (-1, 1)]]
    for k in range(3):
        zc = h * (k + 0.5) / 3
        parts += [_box(0.004, ped_w - 0.03, h / 3 - 0.02, X / 2 - 0.03 + 0.002, py, zc, 'light'),
                  _box(0.02, 0.1, 0.015, X / 2 - 0.02, py, zc + 0.05, 'silver')]
    return _finish(parts, surfaces=[_top_surface(X, Y, Z)])


def _dresser(X, Y, Z):
    plinth, top_t = 0.08, 0.03
    h = Z - plinth - top_t
    parts = [_box(X, Y + 0.02, top_t, z=Z - top_t / 2),
             _box(X - 0.02, Y, h, -0.01, 0, plinth + h / 2, 'dark'),
             _box(X - 0.06, Y - 0.06, plinth, -0.02, 0, plinth / 2, 'dark')]
    for row in range(3):
        zc = plinth + h * (row + 0.5) / 3
        for col in (-1, 1):
            yc = col * Y / 4
            parts += [_box(0.02, Y / 2 - 0.03, h / 3 - 0.025, X / 2 - 0.01, yc, zc),
                      _cyl(0.015, 0.025, x=X / 2 + 0.012, y=yc, z=zc, c='silver', axis='x')]
    return _finish(parts, surfaces=[_top_surface(X, Y + 0.02, Z)])


def _tv_stand(X, Y, Z):
    t = 0.04
    parts = [_box(X, Y, t, z=Z - t / 2), _box(X, t, Z - t, 0, Y / 2 - t / 2, (Z - t) / 2),
             _box(X, t, Z - t, 0, -Y / 2 + t / 2, (Z - t) / 2),
             _box(X - 0.04, Y - 2 * t, 0.06, -0.02, 0, 0.03, 'dark'),
             _box(X, Y - 2 * t, t, 0, 0, 0.06 + t / 2),
             _box(0.02, Y - 2 * t, Z - t - 0.06 - t, -X / 2 + 0.01, 0, (Z + 0.06) / 2, 'dark'),
             _box(X - 0.02, Y - 2 * t, 0.03, 0.01, 0, (Z + 0.06) / 2)]
    mid = (Z + 0.06) / 2 + 0.015
    surfaces = [_top_surface(X, Y, Z),
                _surf(0.01, 0, mid, X / 2 - 0.05, Y / 2 - t - 0.04, Z - t - mid)]
    return _finish(parts, surfaces=surfaces)


def _shelf(X, Y, Z):
    gap = max(Z, 0.25)
    t = 0.02
    levels = 3
    H = levels * gap + t
    parts = [_box(X, t, H, 0, Y / 2 - t / 2, H / 2), _box(X, t, H, 0, -Y / 2 + t / 2, H / 2),
             _box(0.01, Y - 2 * t, H - 2 * t, -X / 2 + 0.005, 0, H / 2, 'dark')]
    surfaces = []
    for k in range(levels + 1):
        z = k * gap
        parts.append(_box(X, Y - 2 * t, t, 0, 0, z + t / 2))
        surfaces.append(_surf(0.005, 0, z + t, X / 2 - 0.03, Y / 2 - t - 0.02,
                              gap - t if k < levels else 0.4))
    return _finish(parts, surfaces=surfaces)


def _cart(X, Y, Z):
    levels = (0.12, 0.48, Z - 0.03)
    parts = [_cyl(0.015, Z - 0.06, x=sx * (X / 2 - 0.03), y=sy * (Y / 2 - 0.03), z=0.06 + (Z - 0.06) / 2,
                  c='silver') for sx in (-1, 1) for sy in (-1, 1)]
    parts += [_cyl(0.03, 0.02, x=sx * (X / 2 - 0.03), y=sy * (Y / 2 - 0.03), z=0.03, c='black', axis='y')
              for sx in (-1, 1) for sy in (-1, 1)]
    surfaces = []
    for k, z in enumerate(levels):
        parts.append(_box(X, Y, 0.025, z=z))
        parts += _frame(X, Y, X - 0.02, Y - 0.02, 0.03, z + 0.0125, 'dark')
        surfaces.append(_surf(0, 0, z + 0.0125, X / 2 - 0.06, Y / 2 - 0.06,
                              (levels[k + 1] - z - 0.03) if k + 1 < len(levels) else 0.5))
    parts.append(_rod((-X / 2 + 0.03, -Y / 2 - 0.06, Z + 0.1), (-X / 2 + 0.03, Y / 2 + 0.06, Z + 0.1),
                      0.012, 'silver'))
    parts += [_rod((-X / 2 + 0.03, s * (Y / 2 + 0.06), Z + 0.1), (-X / 2 + 0.03, s * (Y / 2 - 0.03), Z),
                   0.01, 'silver') for s in (-1, 1)]
    return _finish(parts, surfaces=surfaces)


def _counter_top(X, Y, Z):
    H = Z if Z > 0.5 else 0.9
    slab = 0.04
    kick = 0.1
    base_h = H - slab - kick
    n = max(1, round(Y / 0.6))
    parts = [_box(X + 0.03, Y, slab, 0.015, 0, H - slab / 2),
             _box(X - 0.02, Y, base_h, -0.01, 0, kick + base_h / 2),
             _box(X - 0.08, Y, kick, -0.04, 0, kick / 2, 'black'),
             _box(0.004, Y, 0.012, X / 2 - 0.018, 0, H - slab - 0.15, 'dark')]
    for k in range(n):
        yc = -Y / 2 + Y * (k + 0.5) / n
        if k:
            parts.append(_box(0.004, 0.012, base_h, X / 2 - 0.018, -Y / 2 + Y * k / n, kick + base_h / 2,
                              'dark'))
        parts.append(_box(0.02, 0.12, 0.015, X / 2 - 0.01, yc, H - slab - 0.075, 'silver'))
    return _finish(parts, surfaces=[_surf(0.015, 0, H, X / 2 - 0.02, Y / 2 - 0.03, 0.6)])


def _seat(X, Y, Z, n_cushions, arm_w, back_d, seat_h):
    legs_h = 0.08
    base_top = seat_h - 0.12
    parts = [_box(X - 0.02, Y - 0.02, base_top - legs_h - 0.01, z=(base_top + legs_h + 0.01) / 2, c='dark'),
             _box(back_d, Y, Z - legs_h, -X / 2 + back_d / 2, 0, (Z + legs_h) / 2),
             *_legs(X - 0.04, Y - 0.04, legs_h, 0.05, 'black')]
    for s in (-1, 1):
        parts.append(_box(X, arm_w, 0.62 * Z - legs_h, 0, s * (Y / 2 - arm_w / 2), (0.62 * Z + legs_h) / 2))
    inner_w = Y - 2 * arm_w
    cw = inner_w / n_cushions
    sx = (X - back_d) / 2
    cx = -X / 2 + back_d + sx
    for k in range(n_cushions):
        yc = -inner_w / 2 + cw * (k + 0.5)
        parts.append(_box(X - back_d, cw - 0.01, seat_h - base_top, cx, yc, (seat_h + base_top) / 2))
        parts.append(_box(0.12, cw - 0.02, 0.5 * (Z - seat_h), -X / 2 + back_d + 0.06, yc,
                          seat_h + 0.25 * (Z - seat_h), 'light'))
    surfaces = [_surf(cx + 0.06, 0, seat_h, sx - 0.1, inner_w / 2 - 0.03, 0.5)]
    return _finish(parts, surfaces=surfaces)


def _sofa(X, Y, Z):
    return _seat(X, Y, Z, max(2, min(3, round(Y / 0.7))), 0.2, 0.22, 0.45)


def _arm_chair(X, Y, Z):
    return _seat(X, Y, Z, 1, 0.18, 0.2, 0.45)


def _chair(X, Y, Z):
    seat_h = 0.46
    return _finish([_box(X, Y, 0.05, z=seat_h - 0.025),
                    *_legs(X, Y, seat_h - 0.05, 0.04, 'dark'),
                    *[_box(0.04, 0.04, Z - seat_h, -X / 2 + 0.02, s * (Y / 2 - 0.02), (Z + seat_h) / 2,
                           'dark') for s in (-1, 1)],
                    _box(0.03, Y - 0.04, 0.28, -X / 2 + 0.02, 0, Z - 0.16)])


def _ottoman(X, Y, Z):
    legs_h = 0.06
    body = Z - legs_h
    return _finish([_box(X, Y, body - 0.06, z=legs_h + (body - 0.06) / 2),
                    _box(X + 0.01, Y + 0.01, 0.06, z=Z - 0.03, c='light'),
                    *_legs(X - 0.04, Y - 0.04, legs_h, 0.04, 'brown')],
                   surfaces=[_top_surface(X, Y, Z, 0.05, 0.5)])


def _footstool(X, Y, Z):
    legs_h = 0.08
    r = min(X, Y) / 2
    return _finish([_cyl(r, Z - legs_h, z=legs_h + (Z - legs_h) / 2),
                    _cyl(0.98 * r, 0.004, z=Z + 0.002, c='light'),
                    *_legs(1.2 * r, 1.2 * r, legs_h, 0.03, 'brown', round_legs=True)])


def _bed(X, Y, Z):
    frame_h, matt = 0.3, 0.22
    top = frame_h + matt
    bx = 0.68 * X
    parts = [_box(X, Y, frame_h - 0.06, z=0.06 + (frame_h - 0.06) / 2, c='brown'),
             *_legs(X - 0.04, Y - 0.04, 0.06, 0.06, 'brown'),
             _box(0.06, Y + 0.02, Z, -X / 2 + 0.03, 0, Z / 2, 'brown'),
             _box(X - 0.08, Y - 0.04, matt, 0.03, 0, frame_h + matt / 2, 'white'),
             _box(bx, Y, 0.03, X / 2 - bx / 2, 0, top + 0.015),
             _box(bx, 0.01, matt + 0.03, X / 2 - bx / 2, Y / 2 + 0.005, frame_h + (matt + 0.03) / 2),
             _box(bx, 0.01, matt + 0.03, X / 2 - bx / 2, -Y / 2 - 0.005, frame_h + (matt + 0.03) / 2),
             _box(0.01, Y + 0.02, matt + 0.03, X / 2 + 0.005, 0, frame_h + (matt + 0.03) / 2)]
    parts += [_box(0.3, 0.4 * Y, 0.1, -X / 2 + 0.25, s * 0.23 * Y, top + 0.05, 'white', (0.0, -0.25, 0.0))
              for s in (-1, 1)]
    return _finish(parts, surfaces=[_surf(X / 2 - bx / 2, 0, top + 0.03, bx / 2 - 0.06, 0.42 * Y, 1.0)])


def _laundry_hamper(X, Y, Z):
    t = 0.015
    parts = [_box(X, Y, 0.02, z=0.01), *_frame(X, Y, X - 2 * t, Y - 2 * t, Z - 0.02, 0.02),
             _box(X - 2 * t, Y - 2 * t, 0.003, z=0.022, c='dark')]
    for z in (0.3 * Z, 0.6 * Z):
        parts += _frame(X + 0.006, Y + 0.006, X - t, Y - t, 0.03, z, 'dark')
    parts += _frame(X + 0.01, Y + 0.01, X - t, Y - t, 0.03, Z - 0.029, 'dark')
    return _finish(parts, surfaces=[_surf(0, 0, 0.024, X / 2 - 0.05, Y / 2 - 0.05, Z - 0.05, True)])


def _laundry_hamper_lid(X, Y, Z):
    return _finish([_box(X, Y, 0.025, z=0.0125), _box(0.04, 0.15, 0.03, z=0.04, c='dark')])


def _garbage_can(X, Y, Z):
    r = min(X, Y) / 2
    parts = [_cyl(r, 0.02, z=0.01), *_ring(r, 0.01, Z - 0.02, 0.02, 10),
             _cyl(r - 0.012, 0.003, z=0.0215, c='black'),
             *_ring(r + 0.006, 0.011, 0.03, Z - 0.029, 10, 'dark'),
             _box(0.06, 0.12, 0.02, r + 0.02, 0, 0.02, 'silver')]
    return _finish(parts, surfaces=[_surf(0, 0, 0.023, 0.6 * r, 0.6 * r, Z - 0.05, True)])


# ---------------------------------------------------------------------------------------------------
# Kitchen and bathroom fixtures


def _coffee_machine(X, Y, Z):
    w = 0.7 * Y
    tower = 0.42 * X
    head_h = 0.14 * Z
    parts = [_box(X, w, 0.04, z=0.02), _box(tower, w, Z, -X / 2 + tower / 2, 0, Z / 2),
             _box(X - tower, w, head_h, tower / 2, 0, Z - head_h / 2),
             _box(0.5 * (X - tower), 0.6 * w, 0.01, -X / 2 + tower + 0.3 * (X - tower), 0, 0.045, 'silver'),
             _cyl(0.015, 0.04, x=-X / 2 + tower + 0.3 * (X - tower), z=Z - head_h - 0.02, c='silver'),
             _box(0.004, 0.5 * w, 0.08, tower - X / 2 + 0.002, 0, 0.6 * Z, 'black'),
             _cyl(0.012, 0.006, x=X / 2 + 0.003, y=0.25 * w, z=Z - head_h / 2, c='red', axis='x')]
    sx = -X / 2 + tower + 0.3 * (X - tower)
    return _finish(parts, surfaces=[_surf(sx, 0, 0.05, 0.2 * (X - tower), 0.25 * w,
                                          Z - head_h - 0.05 - 0.04)])


def _toaster(X, Y, Z):
    r = X / 2
    h = Z - 0.01
    slots = [_box(0.025, 0.65 * (Y - X) + 0.06, 0.002, dx * X, 0, Z + 0.001, 'black') for dx in (-0.2, 0.2)]
    return _finish([_box(X, Y - X, h, z=0.01 + h / 2), _cyl(r, h, y=(Y - X) / 2, z=0.01 + h / 2),
                    _cyl(r, h, y=-(Y - X) / 2, z=0.01 + h / 2),
                    *_legs(X - 0.03, Y - 0.03, 0.01, 0.02, 'black'),
                    _box(0.02, 0.03, 0.015, X / 2 + 0.01, 0.3 * Y, 0.7 * Z, 'black'), *slots],
                   surfaces=[_surf(0, 0, Z, 0.3 * X, 0.3 * Y, 0.25)])


def _stove_burner(X, Y, Z):
    R = min(X, Y) / 2
    t = 0.012
    parts = [_cyl(0.9 * R, 0.006, z=0.003, c='dark'), *_ring(R, t, t, 0.006, 8),
             _box(2 * R - t, t, t, 0, 0, 0.006 + t / 2, rpy=(0.0, 0.0, PI / 4)),
             _box(2 * R - t, t, t, 0, 0, 0.006 + t / 2, rpy=(0.0, 0.0, -PI / 4)),
             _cyl(0.28 * R, 0.01, z=0.0095, c='gray'), _cyl(0.12 * R, 0.003, z=0.016, c='black')]
    return _finish(parts, surfaces=[_surf(0, 0, 0.006 + t, 0.6 * R, 0.6 * R, 0.5)])


def _stove_knob(X, Y, Z):
    r = 0.5 * min(Y, Z)
    return _finish([_cyl(r, 0.006, x=-X / 2 + 0.003, z=r, c='silver', axis='x'),
                    _cyl(0.65 * r, 0.6 * X, x=-X / 2 + 0.006 + 0.3 * X, z=r, axis='x'),
                    _box(X - 0.006, 0.3 * r, 1.4 * r, 0.003, 0, r),
                    _box(0.004, 0.1 * r, 0.5 * r, X / 2, 0, 1.45 * r, 'white')])


def _faucet(X, Y, Z):
    bx = -X / 2 + 0.03
    parts = [_box(0.06, 0.5 * Y, 0.02, bx, 0, 0.01, 'silver'),
             _cyl(0.018, Z - 0.02, x=bx, z=Z / 2, c='silver'),
             _rod((bx, 0, Z - 0.015), (X / 2 - 0.02, 0, Z - 0.03), 0.014),
             _cyl(0.016, 0.05, x=X / 2 - 0.02, z=Z - 0.05)]
    for s in (-1, 1):
        parts += [_cyl(0.015, 0.05, x=bx, y=s * 0.35 * Y, z=0.045, c='silver'),
                  _box(0.06, 0.012, 0.012, bx + 0.025, s * 0.35 * Y, 0.075, c='silver')]
    return _finish(parts)


def _basin(X, Y, Z, wall, floor_c='light', rim=0.0):
    """An open rectangular basin (sink, bathtub): floor, walls, drain; optional flat rim."""
    parts = [_box(X, Y, 0.02, z=0.01), *_frame(X, Y, X - 2 * wall, Y - 2 * wall, Z - 0.02, 0.02),
             _box(X - 2 * wall, Y - 2 * wall, 0.003, z=0.0215, c=floor_c),
             _cyl(0.025, 0.003, y=-(Y / 2 - wall - 0.08), z=0.023, c='black')]
    if rim:
        parts += _frame(X + 2 * rim, Y + 2 * rim, X - 2 * wall, Y - 2 * wall, 0.02, Z - 0.02)
    return parts


def _sink(X, Y, Z):
    rim = 0.06
    bx, by = X - 2 * rim, Y - 2 * rim
    parts = _basin(bx, by, Z, 0.02, rim=rim)
    parts.append(_box(0.03, Y, 0.06, -X / 2 + 0.015, 0, Z + 0.03))
    return _finish(parts, surfaces=[_surf(0, 0, 0.023, bx / 2 - 0.05, by / 2 - 0.05, Z, True)])


def _sink_basin(X, Y, Z):
    return _finish(_basin(X, Y, Z, 0.02, rim=0.02),
                   surfaces=[_surf(0, 0, 0.023, X / 2 - 0.05, Y / 2 - 0.05, Z, True)])


def _bathtub(X, Y, Z):
    ledge = 0.2
    wall = 0.08
    parts = _basin(X - ledge, Y, Z, wall)
    parts = [Part(p.shape, p.half_extents, (p.pos[0] + ledge / 2, p.pos[1], p.pos[2]), p.rpy, p.colour)
             for p in parts]
    parts += [_box(ledge, Y, Z, -X / 2 + ledge / 2, 0, Z / 2),
              _box(0.04, 0.04, 0.2, -X / 2 + 0.06, Y / 2 - 0.25, Z + 0.1, 'silver'),
              _rod((-X / 2 + 0.06, Y / 2 - 0.25, Z + 0.18), (-X / 2 + 0.25, Y / 2 - 0.25, Z + 0.15), 0.015,
                   'silver')]
    inner = (X - ledge) / 2 - wall
    return _finish(parts, surfaces=[_surf(-X / 2 + ledge / 2, 0, Z, ledge / 2 - 0.03, Y / 2 - 0.3, 0.5),
                                    _surf(ledge / 2, 0, 0.023, inner - 0.05, Y / 2 - wall - 0.1, Z, True)])


def _bathtub_basin(X, Y, Z):
    parts = _basin(X, Y, Z, 0.04, rim=0.03)
    return _finish(parts, surfaces=[_surf(0, 0, 0.023, X / 2 - 0.1, Y / 2 - 0.15, Z, True)])


def _shower_glass(X, Y, Z):
    return _finish([_box(0.012, Y - 0.04, Z - 0.06, z=Z / 2), _box(0.05, Y, 0.03, z=0.015, c='silver'),
                    _box(0.03, Y, 0.03, z=Z - 0.015, c='silver'),
                    _box(0.03, 0.02, Z, 0, Y / 2 - 0.01, Z / 2, 'silver'),
                    _box(0.03, 0.02, Z, 0, -Y / 2 + 0.01, Z / 2, 'silver')])


def _shower_head(X, Y, Z):
    px = -X / 2 + 0.02
    return _finish([_cyl(0.012, 0.75 * Z, x=px, z=0.375 * Z, c='silver'),
                    _cyl(0.04, 0.015, x=px + 0.008, z=0.3 * Z, c='silver', axis='x'),
                    _rod((px, 0, 0.75 * Z), (X / 2 - 0.06, 0, 0.9 * Z), 0.012, 'silver'),
                    _cyl(0.06, 0.03, x=X / 2 - 0.06, z=0.9 * Z, rpy=(0.0, -0.7, 0.0)),
                    _cyl(0.052, 0.003, x=X / 2 - 0.06 + 0.011, z=0.9 * Z - 0.013, c='dark',
                         rpy=(0.0, -0.7, 0.0))])


def _towel_holder(X, Y, Z):
    bar_x = X / 2 - 0.015
    parts = [_box(X, 0.03, max(Z, 0.04), 0, s * (Y / 2 - 0.015), max(Z, 0.04) / 2) for s in (-1, 1)]
    parts.append(_cyl(0.012, Y, x=bar_x, z=max(Z, 0.04) / 2, c='silver', axis='y'))
    return _finish(parts, surfaces=[_surf(bar_x, 0, max(Z, 0.04) / 2 + 0.012, 0.01, Y / 2 - 0.05, 0.6)])


def _hand_towel_holder(X, Y, Z):
    R = 0.45 * min(Y, Z)
    cz = Z - 0.03 - R
    rx = X / 2 - 0.015
    ring = _loop([(rx, R * math.cos(a), cz + R * math.sin(a))
                  for a in (2 * PI * k / 8 + PI / 8 for k in range(8))], 0.012, 0.012, 'silver')
    bottom = cz - R * math.cos(PI / 8) + 0.006
    parts = [_box(0.015, 0.06, 0.06, -X / 2 + 0.0075, 0, Z - 0.03),
             _box(X - 0.015, 0.015, 0.015, 0.0075, 0, Z - 0.02, 'silver'),
             _box(0.015, 0.015, 0.02, rx, 0, Z - 0.02 - 0.01, 'silver'), *ring]
    return _finish(parts, surfaces=[_surf(rx, 0, bottom, 0.004, 0.8 * R * math.sin(PI / 8), 0.4)])


def _toilet_paper_hanger(X, Y, Z):
    sz = 0.45 * Z
    parts = [_box(0.015, Y, 0.04, -X / 2 + 0.0075, 0, Z - 0.02),
             *[_box(X - 0.015, 0.015, 0.025, 0.0075, s * (Y / 2 - 0.0075), Z - 0.0125) for s in (-1, 1)],
             *[_box(0.015, 0.015, Z - sz, X / 2 - 0.0075, s * (Y / 2 - 0.0075), sz + (Z - sz) / 2)
               for s in (-1, 1)],
             _cyl(0.01, Y - 0.02, x=X / 2 - 0.0075, z=sz, c='silver', axis='y')]
    return _finish(parts, surfaces=[_surf(X / 2 - 0.0075, 0, sz + 0.01, 0.01, Y / 2 - 0.04, 0.15)])


def _light_switch(X, Y, Z):
    return _finish([_box(0.01, Y, Z, z=Z / 2),
                    _box(0.004, 0.4 * Y, 0.45 * Z, 0.006, 0, Z / 2, 'gray'),
                    _box(0.016, 0.2 * Y, 0.2 * Z, 0.012, 0, 0.56 * Z, 'white', (0.0, 0.35, 0.0))])


# ---------------------------------------------------------------------------------------------------
# Lamps, plants, screens, wall decoration


def _floor_lamp(X, Y, Z):
    R = 0.42 * min(X, Y)
    return _finish([_cyl(0.6 * R, 0.03, z=0.015, c='dark'), _cyl(0.015, Z - 0.3, z=(Z - 0.3) / 2, c='silver'),
                    _cyl(R, 0.22, z=Z - 0.21), _cyl(0.8 * R, 0.1, z=Z - 0.05),
                    _cyl(0.78 * R, 0.002, z=Z - 0.32, c='yellow')])


def _desk_lamp(X, Y, Z):
    bx = -X / 2 + 0.08
    return _finish([_cyl(0.08, 0.03, x=bx, z=0.015),
                    _rod((bx, 0, 0.03), (bx - 0.02, 0, 0.6 * Z), 0.012, 'silver'),
                    _sph(0.02, x=bx - 0.02, z=0.6 * Z, c='silver'),
                    _rod((bx - 0.02, 0, 0.6 * Z), (X / 2 - 0.12, 0, Z - 0.04), 0.012, 'silver'),
                    _cyl(0.075, 0.12, x=X / 2 - 0.08, z=Z - 0.09, rpy=(0.0, 0.6, 0.0)),
                    _cyl(0.065, 0.003, x=X / 2 - 0.08 + 0.034, z=Z - 0.09 - 0.049, c='yellow',
                         rpy=(0.0, 0.6, 0.0))])


def _lamp(X, Y, Z):
    R = 0.45 * min(X, Y)
    return _finish([_cyl(0.55 * R, 0.03, z=0.015, c='dark'), _sph(0.55 * R, z=0.03 + 0.5 * R, c='dark'),
                    _cyl(0.012, 0.4 * Z, z=0.2 * Z + 0.5 * R, c='silver'),
                    _cyl(R, 0.35 * Z, z=Z - 0.175 * Z), _cyl(0.75 * R, 0.002, z=Z + 0.001, c='light')])


def _house_plant(X, Y, Z):
    r = 0.32 * min(X, Y)
    pot = 0.32 * Z
    parts = [_cyl(0.85 * r, pot, z=pot / 2), _cyl(r, 0.04, z=pot - 0.02),
             _cyl(0.8 * r, 0.004, z=pot + 0.002, c='brown'),
             _cyl(0.012, 0.3 * Z, z=pot + 0.15 * Z, c='olive'),
             _sph(0.2 * Z, z=Z - 0.22 * Z, c='green'),
             _sph(0.14 * Z, x=0.12 * Z, y=0.08 * Z, z=Z - 0.3 * Z, c='olive'),
             _sph(0.14 * Z, x=-0.1 * Z, y=-0.1 * Z, z=Z - 0.32 * Z, c='green')]
    return _finish(parts)


def _television(X, Y, Z):
    neck = 0.12
    ph = Z - neck
    return _finish([_box(min(X, 0.3), 0.4 * Y, 0.02, z=0.01, c='dark'),
                    _box(0.05, 0.08, neck, z=neck / 2, c='dark'),
                    _box(0.05, Y, ph, z=neck + ph / 2),
                    _box(0.004, Y - 0.05, ph - 0.05, 0.027, 0, neck + ph / 2, 'black')])


def _wall_frame(Y, Z, w, depth, c):
    """Four bars framing a Y*Z opening, as seen from +x (a mirror, painting or window frame)."""
    return [_box(depth, Y, w, 0, 0, Z - w / 2, c), _box(depth, Y, w, 0, 0, w / 2, c),
            _box(depth, w, Z - 2 * w, 0, Y / 2 - w / 2, Z / 2, c),
            _box(depth, w, Z - 2 * w, 0, -Y / 2 + w / 2, Z / 2, c)]


def _mirror(X, Y, Z):
    return _finish(_wall_frame(Y, Z, 0.05, 0.03, 'main') +
                   [_box(0.01, Y - 0.08, Z - 0.08, 0.005, 0, Z / 2, 'silver')])


def _painting(X, Y, Z):
    w = 0.05
    cy, cz = Y - 2 * w, Z - 2 * w
    return _finish(_wall_frame(Y, Z, w, 0.04, 'gold') + [
        _box(0.01, cy, cz, 0.0, 0, Z / 2),
        _box(0.002, cy, 0.35 * cz, 0.006, 0, w + 0.175 * cz, 'green'),
        _box(0.002, 0.5 * cy, 0.3 * cz, 0.007, 0.2 * cy, w + 0.4 * cz, 'olive'),
        _cyl(0.1 * min(cy, cz), 0.002, x=0.006, y=-0.25 * cy, z=w + 0.78 * cz, c='yellow', axis='x')])


def _poster(X, Y, Z):
    t = 0.006
    return _finish([_box(t, Y, Z, z=Z / 2),
                    _box(0.002, 0.8 * Y, 0.12 * Z, t / 2 + 0.001, 0, 0.88 * Z, 'white'),
                    _box(0.002, 0.7 * Y, 0.45 * Z, t / 2 + 0.001, 0, 0.5 * Z, 'dark'),
                    _box(0.002, 0.6 * Y, 0.04 * Z, t / 2 + 0.001, 0, 0.18 * Z, 'white'),
                    _box(0.002, 0.5 * Y, 0.04 * Z, t / 2 + 0.001, 0, 0.1 * Z, 'white')])


def _window(X, Y, Z):
    w = 0.06
    d = min(max(X, 0.06), 0.12)
    return _finish(_wall_frame(Y, Z, w, d, 'main') + [
        _box(0.01, Y - 2 * w + 0.02, Z - 2 * w + 0.02, -d / 2 + 0.01, 0, Z / 2, 'blue'),
        _box(d - 0.01, 0.04, Z - 2 * w, 0.005, 0, Z / 2),
        _box(d - 0.01, Y - 2 * w, 0.04, 0.005, 0, 0.55 * Z),
        _box(d + 0.06, Y + 0.1, 0.03, 0.03, 0, -0.015)])


def _curtains(X, Y, Z):
    n = 5
    pw = 0.28 * Y
    parts = [_cyl(0.015, Y + 0.1, z=Z - 0.02, c='black', axis='y'),
             *[_sph(0.03, y=s * (Y / 2 + 0.05), z=Z - 0.02, c='black') for s in (-1, 1)]]
    for s in (-1, 1):
        for k in range(n):
            yc = s * (Y / 2 - pw * (k + 0.5) / n)
            parts.append(_box(0.03, pw / n + 0.01, Z - 0.06, 0.02 * (1 if k % 2 else -1), yc, (Z - 0.06) / 2,
                              'main' if k % 2 else 'dark'))
    return _finish(parts)


def _tennis_racket(X, Y, Z):
    ry = Y / 2
    rx = min(0.3 * X, 1.3 * ry)
    cx = X / 2 - rx
    t = 0.014
    z = 0.012
    head = _loop([(cx + (rx - t / 2) * math.cos(a), (ry - t / 2) * math.sin(a), z)
                  for a in (2 * PI * k / 12 for k in range(12))], t, 0.02)
    strings = [_box(2 * rx * math.sqrt(max(1 - (dy / ry) ** 2, 0.0)) - 0.01, 0.004, 0.003, cx, dy, z, 'white')
               for dy in (-0.5 * ry, 0.0, 0.5 * ry)]
    strings += [_box(0.004, 2 * ry * math.sqrt(max(1 - (dx / rx) ** 2, 0.0)) - 0.01, 0.003, cx + dx, 0, z,
                     'white') for dx in (-0.5 * rx, 0.0, 0.5 * rx)]
    neck = cx - rx
    throat_end = neck - 0.1
    grip = throat_end + 0.01 + X / 2
    throat = [_bar((neck + 0.01, s * 0.5 * ry, z), (throat_end, 0, z), 0.014, 0.018) for s in (-1, 1)]
    return _finish(head + strings + throat +
                   [_box(grip, 0.03, 0.024, -X / 2 + grip / 2, 0, z, 'black')])


# ---------------------------------------------------------------------------------------------------
# Registry

_Builder = Callable[[float, float, float], ShapeSpec]


def _flat(d):  # pickupable lying down: longest edge along x, shortest up
    return d[0], d[1], d[2]


def _flat_wide(d):  # lying down, longest edge across (y): laptops, boxes
    return d[1], d[0], d[2]


def _up(d):  # standing: longest edge up
    return d[1], d[2], d[0]


def _panel(d):  # thin along x, standing: hanging towels, clocks
    return d[2], d[1], d[0]


def _wide(d):  # fixed object: long horizontal side along y (its front), height as given
    return min(d[0], d[1]), max(d[0], d[1]), d[2]


def _deep(d):  # fixed object that is deeper than wide (bed, toilet)
    return max(d[0], d[1]), min(d[0], d[1]), d[2]


_TYPES: dict[str, tuple[_Builder, Callable, Vec3]] = {
    # food
    'Apple': (_apple, _flat, (0.1, 0.1, 0.1)),
    'AppleSliced': (_apple_sliced, _flat, (0.09, 0.09, 0.012)),
    'Bread': (_bread, _flat, (0.29, 0.16, 0.14)),
    'BreadSliced': (_bread_sliced, _flat, (0.11, 0.11, 0.015)),
    'Egg': (_egg, _flat, (0.07, 0.05, 0.05)),
    'Lettuce': (_lettuce, _flat, (0.24, 0.15, 0.15)),
    'LettuceSliced': (_lettuce_sliced, _flat, (0.09, 0.06, 0.02)),
    'Potato': (_potato, _flat, (0.12, 0.08, 0.08)),
    'PotatoSliced': (_potato_sliced, _flat, (0.09, 0.05, 0.012)),
    'Tomato': (_tomato, _flat, (0.12, 0.12, 0.1)),
    'TomatoSliced': (_tomato_sliced, _flat, (0.1, 0.1, 0.01)),
    # kitchenware
    'Bowl': (_bowl, _flat, (0.19, 0.19, 0.09)),
    'ButterKnife': (_butter_knife, _flat, (0.27, 0.02, 0.01)),
    'Cup': (_cup, _up, (0.11, 0.11, 0.15)),
    'Fork': (_fork, _flat, (0.25, 0.03, 0.02)),
    'Glassbottle': (_glassbottle, _up, (0.11, 0.11, 0.25)),
    'Kettle': (_kettle, _flat, (0.21, 0.2, 0.19)),
    'Knife': (_knife, _flat, (0.33, 0.05, 0.01)),
    'Ladle': (_ladle, _flat, (0.27, 0.09, 0.06)),
    'Mug': (_mug, _flat, (0.11, 0.1, 0.09)),
    'Pan': (_pan, _flat, (0.43, 0.26, 0.05)),
    'PepperShaker': (lambda X, Y, Z: _shaker(X, Y, Z, True), _up, (0.07, 0.07, 0.11)),
    'Plate': (_plate, _flat, (0.24, 0.24, 0.02)),
    'Pot': (_pot, _flat, (0.4, 0.28, 0.16)),
    'SaltShaker': (lambda X, Y, Z: _shaker(X, Y, Z, False), _up, (0.07, 0.07, 0.11)),
    'Spatula': (_spatula, _flat, (0.3, 0.06, 0.02)),
    'Spoon': (_spoon, _flat, (0.21, 0.04, 0.02)),
    'WineBottle': (_wine_bottle, _up, (0.09, 0.09, 0.33)),
    # small household objects
    'AlarmClock': (_alarm_clock, _panel, (0.09, 0.18, 0.19)),
    'BaseballBat': (_baseball_bat, _flat, (0.96, 0.09, 0.08)),
    'BasketBall': (_basketball, _flat, (0.24, 0.24, 0.24)),
    'Book': (_book, _flat, (0.3, 0.22, 0.03)),
    'Boots': (_boots, _up, (0.28, 0.22, 0.52)),
    'Box': (_box_container, _flat_wide, (0.41, 0.45, 0.29)),
    'Candle': (_candle, _up, (0.05, 0.05, 0.13)),
    'CD': (_cd, _flat, (0.1, 0.1, 0.002)),
    'CellPhone': (_cell_phone, _flat, (0.16, 0.08, 0.01)),
    'Cloth': (_cloth, _flat, (0.21, 0.18, 0.02)),
    'CreditCard': (_credit_card, _flat, (0.09, 0.05, 0.002)),
    'DishSponge': (_dish_sponge, _flat, (0.14, 0.07, 0.03)),
    'HandTowel': (_hand_towel, _panel, (0.04, 0.13, 0.4)),
    'KeyChain': (_key_chain, _flat, (0.13, 0.07, 0.01)),
    'Laptop': (_laptop, _flat_wide, (0.3, 0.4, 0.3)),
    'Newspaper': (_newspaper, _flat, (0.33, 0.13, 0.03)),
    'PaperTowel': (_paper_towel, _up, (0.12, 0.12, 0.3)),
    'PaperTowelRoll': (_paper_towel_roll, _up, (0.08, 0.06, 0.21)),
    'Pen': (lambda X, Y, Z: _pen(X, Y, Z, False), _flat, (0.2, 0.012, 0.012)),
    'Pencil': (lambda X, Y, Z: _pen(X, Y, Z, True), _flat, (0.18, 0.01, 0.01)),
    'Pillow': (_pillow, _flat, (0.42, 0.34, 0.14)),
    'Plunger': (_plunger, _up, (0.15, 0.15, 0.54)),
    'RemoteControl': (_remote, _flat, (0.22, 0.07, 0.02)),
    'ScrubBrush': (_scrub_brush, _up, (0.13, 0.13, 0.48)),
    'SoapBar': (_soap_bar, _flat, (0.09, 0.05, 0.02)),
    'SoapBottle': (_soap_bottle, _up, (0.12, 0.09, 0.24)),
    'SprayBottle': (_spray_bottle, _up, (0.11, 0.03, 0.25)),
    'Statue': (_statue, _up, (0.21, 0.15, 0.34)),
    'TeddyBear': (_teddy_bear, _flat, (0.47, 0.47, 0.33)),
    'TennisRacket': (_tennis_racket, _flat, (0.65, 0.26, 0.04)),
    'TissueBox': (_tissue_box, _flat_wide, (0.15, 0.2, 0.1)),
    'ToiletPaper': (_toilet_paper, _flat, (0.12, 0.07, 0.07)),
    'ToiletPaperRoll': (_toilet_paper_roll, _up, (0.045, 0.045, 0.1)),
    'Towel': (_towel, _panel, (0.04, 0.41, 0.59)),
    'Vase': (_vase, _up, (0.18, 0.18, 0.24)),
    'Watch': (_watch, _flat, (0.08, 0.05, 0.04)),
    'WateringCan': (_watering_can, _flat, (0.27, 0.19, 0.15)),
    # openable furniture and appliances
    'Blinds': (_blinds, _wide, (0.03, 0.89, 1.3)),
    'Cabinet': (_cabinet, _wide, (0.32, 0.47, 0.66)),
    'Drawer': (_drawer, _wide, (0.34, 0.52, 0.19)),
    'Fridge': (_fridge, _wide, (0.72, 1.0, 1.87)),
    'Microwave': (_microwave, _wide, (0.36, 0.61, 0.35)),
    'Safe': (_safe, _wide, (0.5, 0.56, 0.51)),
    'ShowerCurtain': (_shower_curtain, _wide, (0.05, 1.2, 1.94)),
    'ShowerDoor': (_shower_door, _wide, (0.06, 0.91, 1.96)),
    'Toilet': (_toilet, _deep, (0.7, 0.53, 0.8)),
    # furniture
    'ArmChair': (_arm_chair, _wide, (0.88, 1.0, 0.91)),
    'Bed': (_bed, _deep, (2.34, 1.42, 0.91)),
    'Cart': (_cart, _wide, (0.45, 0.7, 0.85)),
    'Chair': (_chair, _wide, (0.54, 0.61, 0.95)),
    'CoffeeTable': (_coffee_table, _wide, (0.7, 1.17, 0.44)),
    'CounterTop': (_counter_top, _wide, (0.7, 1.87, 0.9)),
    'Desk': (_desk, _wide, (0.66, 1.57, 0.8)),
    'DiningTable': (_dining_table, _wide, (0.92, 1.47, 0.78)),
    'Dresser': (_dresser, _wide, (0.56, 1.52, 0.97)),
    'Footstool': (_footstool, _wide, (0.28, 0.28, 0.31)),
    'GarbageCan': (_garbage_can, _wide, (0.36, 0.43, 0.54)),
    'LaundryHamper': (_laundry_hamper, _wide, (0.44, 0.52, 0.74)),
    'LaundryHamperLid': (_laundry_hamper_lid, _wide, (0.44, 0.52, 0.04)),
    'Ottoman': (_ottoman, _wide, (0.52, 0.85, 0.43)),
    'Shelf': (_shelf, _wide, (0.27, 0.6, 0.23)),
    'SideTable': (_side_table, _wide, (0.37, 0.62, 0.67)),
    'Sofa': (_sofa, _wide, (0.93, 2.48, 0.96)),
    'TVStand': (_tv_stand, _wide, (0.6, 1.2, 0.73)),
    # kitchen and bathroom fixtures
    'Bathtub': (_bathtub, _wide, (1.13, 2.09, 0.6)),
    'BathtubBasin': (_bathtub_basin, _wide, (0.64, 1.71, 0.42)),
    'CoffeeMachine': (_coffee_machine, _wide, (0.43, 0.48, 0.44)),
    'Faucet': (_faucet, _wide, (0.23, 0.32, 0.21)),
    'HandTowelHolder': (_hand_towel_holder, _wide, (0.05, 0.17, 0.21)),
    'LightSwitch': (_light_switch, _wide, (0.02, 0.12, 0.15)),
    'ShowerGlass': (_shower_glass, _wide, (0.07, 1.79, 1.97)),
    'ShowerHead': (_shower_head, _deep, (0.25, 0.12, 1.0)),
    'Sink': (_sink, _wide, (0.46, 0.67, 0.16)),
    'SinkBasin': (_sink_basin, _wide, (0.33, 0.53, 0.13)),
    'StoveBurner': (_stove_burner, _wide, (0.22, 0.22, 0.02)),
    'StoveKnob': (_stove_knob, _wide, (0.06, 0.07, 0.07)),
    'Toaster': (_toaster, _wide, (0.22, 0.36, 0.21)),
    'ToiletPaperHanger': (_toilet_paper_hanger, _wide, (0.1, 0.23, 0.08)),
    'TowelHolder': (_towel_holder, _wide, (0.11, 0.66, 0.04)),
    # lamps, plants, screens, wall decoration
    'Curtains': (_curtains, _wide, (0.14, 2.17, 2.17)),
    'DeskLamp': (_desk_lamp, _wide, (0.28, 0.29, 0.46)),
    'FloorLamp': (_floor_lamp, _wide, (0.52, 0.52, 1.88)),
    'HousePlant': (_house_plant, _wide, (0.33, 0.39, 0.64)),
    'Lamp': (_lamp, _wide, (0.35, 0.35, 0.62)),
    'Mirror': (_mirror, _wide, (0.05, 0.84, 0.85)),
    'Painting': (_painting, _wide, (0.09, 0.88, 0.84)),
    'Poster': (_poster, _wide, (0.09, 0.62, 0.71)),
    'Television': (_television, _wide, (0.32, 1.12, 0.81)),
    'Window': (_window, _wide, (0.11, 1.07, 1.55)),
}

TYPES_WITH_SHAPES: tuple[str, ...] = tuple(sorted(_TYPES))


def shape_for(type_name: str, dims: Optional[tuple[float, float, float]]) -> ShapeSpec:
    """The composed shape of `type_name`, scaled by the catalogue's approx_size_m `dims`.

    dims: the three numbers of approx_size_m as given (sorted edges for pickupables, length x
    width x height for fixed objects), or None to use the type's default extents.
    Raises KeyError for an unknown type. Specs are immutable and cached per (type, dims).
    """
    return _shape(type_name, None if dims is None else tuple(float(v) for v in dims))


@functools.lru_cache(maxsize=None)
def _shape(type_name: str, dims: Optional[tuple[float, ...]]) -> ShapeSpec:
    builder, layout, default = _TYPES[type_name]
    xyz = default if dims is None else layout(dims)
    return builder(*(max(v, _MIN_EDGE) for v in xyz))
