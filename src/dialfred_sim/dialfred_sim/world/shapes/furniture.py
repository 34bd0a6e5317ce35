"""Tables, seats, beds, storage (long side along y, front +x)."""

from __future__ import annotations

from .primitives import _box, _cyl, _finish, _frame, _legs, _ring, _rod, _surf


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
