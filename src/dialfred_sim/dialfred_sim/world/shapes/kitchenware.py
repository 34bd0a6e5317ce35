"""Kitchenware: vessels, bottles, shakers, candles and paper rolls."""

from __future__ import annotations

from ..geometry import Part
from .primitives import _bar, _box, _cyl, _finish, _hinge_lid, _loop, _ring, _rod, _sph, _surf


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
