"""Openable furniture and appliances (front +x; doors hinge on the object's right, -y)."""

from __future__ import annotations

from ..geometry import Articulation, Part
from .primitives import _box, _cyl, _finish, _frame, _hinge_lid, _hinge_z, _ring, _surf


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
