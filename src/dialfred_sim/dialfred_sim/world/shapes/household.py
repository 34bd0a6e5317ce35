"""Small household objects: clocks, balls, books, phones, towels, toys, tools ..."""

from __future__ import annotations

import math

from ..geometry import Articulation
from .primitives import PI, _bar, _box, _cyl, _finish, _loop, _rod, _sph


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
