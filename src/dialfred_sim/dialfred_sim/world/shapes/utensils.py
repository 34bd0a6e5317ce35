"""Cutlery and utensils (and pens), lying flat along x (handle towards -x)."""

from __future__ import annotations

import math

from .primitives import PI, _bar, _box, _cyl, _finish, _sph


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
