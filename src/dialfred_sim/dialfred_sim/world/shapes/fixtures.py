"""Kitchen and bathroom fixtures: appliances, stove, sinks, bath, shower, holders."""

from __future__ import annotations

import math

from ..geometry import Part
from .primitives import PI, _box, _cyl, _finish, _frame, _legs, _loop, _ring, _rod, _surf


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
