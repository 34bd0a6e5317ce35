"""Lamps, plants, screens, wall decoration."""

from __future__ import annotations

from .primitives import _box, _cyl, _finish, _rod, _sph


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
