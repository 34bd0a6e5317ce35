"""Food: whole and sliced fruit, vegetables, bread and eggs.

Builders take the object-frame extents (x, y, z) the catalogue suggests.
"""

from __future__ import annotations

import math

from .primitives import PI, _box, _cyl, _finish, _sph


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
