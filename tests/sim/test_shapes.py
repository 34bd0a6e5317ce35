"""Every object type has a composed shape that builds, renders and opens as the world needs."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pybullet
import pytest
from pybullet_utils.bullet_client import BulletClient

from dialfred_sim.world import shapes
from dialfred_sim.world.bodies import (ShapeCache, articulation_joint, build_body, link_arguments, set_articulation,
                                       triangle_count)
from dialfred_sim.world.geometry import Part, ShapeSpec
from dialfred_sim.world.shapes import TYPES_WITH_SHAPES, shape_for, surface_offset

ROOT = Path(__file__).resolve().parents[2]

CATALOG = ROOT / 'src' / 'dialfred_sim' / 'dialfred_sim' / 'data' / 'object_types.csv'
with open(CATALOG, newline='') as _f:
    ROWS = {row['type']: row for row in csv.DictReader(_f)}


def spec_of(name: str) -> ShapeSpec:
    text = ROWS[name]['approx_size_m']
    return shape_for(name, tuple(float(v) for v in text.split('x')) if text else None)


def inside_part(part: Part, point) -> bool:
    """Whether `point` (object frame) lies inside the primitive `part`."""
    rot = shapes._rot(part.rpy)
    d = [point[i] - part.pos[i] for i in range(3)]
    local = [sum(rot[j][i] * d[j] for j in range(3)) for i in range(3)]
    he = part.half_extents
    if part.shape == 'box':
        return all(abs(local[i]) <= he[i] + 1e-9 for i in range(3))
    if part.shape == 'cylinder':
        return math.hypot(local[0], local[1]) <= he[0] + 1e-9 and abs(local[2]) <= he[2] + 1e-9
    return math.sqrt(sum(v * v for v in local)) <= he[0] + 1e-9


def to_world(position, yaw: float, local) -> tuple[float, float, float]:
    """World point of `local` (object frame) for a body at `position` turned by `yaw` about +z."""
    c, s = math.cos(yaw), math.sin(yaw)
    return (position[0] + c * local[0] - s * local[1], position[1] + s * local[0] + c * local[1],
            position[2] + local[2])


def flag(name: str, column: str) -> bool:
    return ROWS[name][column] == '1'


@pytest.fixture
def client():
    c = BulletClient(connection_mode=pybullet.DIRECT)
    yield c
    c.disconnect()


def segmentation(client, eye, target, px=96):
    view = client.computeViewMatrix(list(eye), list(target), [0, 0, 1])
    proj = client.computeProjectionMatrixFOV(50, 1.0, 0.02, 20)
    seg = client.getCameraImage(px, px, view, proj, renderer=pybullet.ER_TINY_RENDERER, shadow=0)[4]
    return [v for v in (seg if not hasattr(seg, 'flatten') else seg.flatten())]


def test_every_catalogue_type_has_a_shape():
    assert set(ROWS) <= set(TYPES_WITH_SHAPES)
    for name in ROWS:
        spec_of(name)
    with pytest.raises(KeyError):
        shape_for('Spaceship', None)


@pytest.mark.parametrize('name', sorted(ROWS))
def test_shape_is_well_formed_and_sits_on_its_origin(name):
    spec = spec_of(name)
    assert all(s > 0 for s in spec.size)
    for part in spec.parts:
        assert all(h > 0 for h in part.half_extents)
        if part.shape != 'box':
            assert part.half_extents[0] == part.half_extents[1]
        if part.shape == 'sphere':
            assert part.half_extents[0] == part.half_extents[2]
    bounds = [shapes.part_bounds(p) for p in spec.parts]
    lo = [min(b[0][i] for b in bounds) for i in range(3)]
    hi = [max(b[1][i] for b in bounds) for i in range(3)]
    assert lo[2] == pytest.approx(0.0, abs=1e-9)
    assert (lo[0] + hi[0]) == pytest.approx(0.0, abs=1e-9)
    assert (lo[1] + hi[1]) == pytest.approx(0.0, abs=1e-9)
    assert spec.size == pytest.approx(tuple(hi[i] - lo[i] for i in range(3)), abs=1e-3)
    assert any(p.colour == 'main' for p in spec.parts)
    assert triangle_count(spec) <= 800


def test_sizes_follow_the_catalogue():
    fridge = spec_of('Fridge')
    assert fridge.size[2] == pytest.approx(1.87, abs=0.01)
    assert spec_of('Apple').size[0] == pytest.approx(0.10, abs=0.02)
    bigger = shape_for('Mug', (0.22, 0.2, 0.18))
    assert bigger.size[2] == pytest.approx(2 * spec_of('Mug').size[2], rel=0.05)


@pytest.mark.parametrize('name', sorted(n for n in ROWS if flag(n, 'receptacle')))
def test_receptacles_have_free_supported_surfaces(name):
    spec = spec_of(name)
    assert spec.surfaces, f'{name} is a receptacle without a surface'
    if ROWS[name]['preposition'] == 'in':
        assert any(s.inside for s in spec.surfaces), f'things go in a {name}'
    for s in spec.surfaces:
        assert s.clearance > 0 and min(s.half_size) > 0
        cx, cy, z = s.center
        below = (cx, cy, z - 0.002)
        assert any(inside_part(p, below) for p in spec.parts), f'{name}: nothing under {s}'
        for fx in (-1, 0, 1):
            for fy in (-1, 0, 1):
                above = (cx + fx * s.half_size[0], cy + fy * s.half_size[1], z + 0.004)
                assert not any(inside_part(p, above) for p in spec.parts if not p.moving), \
                    f'{name}: {s} is buried at {above}'


@pytest.mark.parametrize('name', sorted(ROWS))
def test_openables_have_one_articulation_with_moving_parts(name):
    spec = spec_of(name)
    moving = [p for p in spec.parts if p.moving]
    if flag(name, 'openable'):
        assert spec.articulation is not None
        assert moving and len(moving) < len(spec.parts)
        assert spec.articulation.open_value != 0
    else:
        assert spec.articulation is None and not moving


def test_every_type_renders_with_its_own_id(client):
    cache = ShapeCache(client)
    for name in sorted(ROWS):
        spec = spec_of(name)
        body = build_body(client, spec, 'red', (0.0, 0.0, 0.0), 0.4, cache)
        r = 0.6 * math.dist((0, 0, 0), spec.size)
        seg = segmentation(client, (2.5 * r, 1.2 * r, spec.size[2] / 2 + 1.2 * r), (0, 0, spec.size[2] / 2),
                           px=64)
        ids = set(seg)
        assert body in ids, name
        assert ids <= {-1, body}, f'{name}: segmentation holds {ids}'  # no link bits by default
        client.removeBody(body)


def test_cache_shares_visual_shapes_between_bodies(client):
    cache = ShapeCache(client)
    spec = spec_of('Mug')
    build_body(client, spec, 'blue', (0, 0, 0), 0.0, cache)
    n = len(cache._ids)
    build_body(client, spec, 'blue', (1, 0, 0), 1.0, cache)
    assert len(cache._ids) == n
    build_body(client, spec, 'red', (2, 0, 0), 1.0, cache)
    assert len(cache._ids) > n
    cache.clear()
    assert not cache._ids


def body_state(client, body: int) -> tuple:
    """What pybullet holds of a built body: its visual shapes (geometry, pose, colour) and joints."""
    visuals = tuple(tuple(v[1:]) for v in client.getVisualShapeData(body))
    joints = tuple(tuple(client.getJointInfo(body, j)[2:]) for j in range(client.getNumJoints(body)))
    return visuals, joints, client.getBasePositionAndOrientation(body)


def test_cached_link_arguments_build_the_same_bodies(client):
    """build_body takes a (spec, colour)'s link lists from the cache after its first body; the bodies
    are those built from lists worked out afresh, for every catalogue type (and an articulated one
    again after others were built)."""
    cache = ShapeCache(client)
    for name in sorted(ROWS) + ['Fridge', 'Drawer', 'Mug']:
        spec = spec_of(name)
        fresh = link_arguments(spec, 'green', cache)
        assert fresh == link_arguments(spec, 'green', cache)        # a pure function of spec and colour
        a = build_body(client, spec, 'green', (0.5, -0.2, 0.1), 0.7, cache)
        b = build_body(client, spec, 'green', (0.5, -0.2, 0.1), 0.7, cache)       # cached lists
        c = client.createMultiBody(baseMass=0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
                                   basePosition=[0.5, -0.2, 0.1],
                                   baseOrientation=client.getQuaternionFromEuler((0.0, 0.0, 0.7)), **fresh)
        assert cache.links(spec, 'green') == fresh
        assert body_state(client, a) == body_state(client, b), name
        assert body_state(client, a)[:2] == body_state(client, c)[:2], name
        for body in (c, b, a):
            client.removeBody(body)
    assert cache.links(spec_of('Mug'), 'red') != cache.links(spec_of('Mug'), 'green')
    cache.clear()
    assert not cache._links and not cache._ids


def test_set_articulation_drives_the_joint(client):
    spec = spec_of('Fridge')
    body = build_body(client, spec, 'white', (0, 0, 0), 0.0)
    joint = articulation_joint(spec)
    for fraction, expected in ((0.5, 0.5), (1.0, 1.0), (2.0, 1.0), (-1.0, 0.0)):
        set_articulation(client, body, spec, fraction)
        assert client.getJointState(body, joint)[0] == pytest.approx(expected * spec.articulation.open_value)


# (type, camera height over distance): an open box is looked into from above
@pytest.mark.parametrize('name, rise', [('Fridge', 0.45), ('Cabinet', 0.45), ('Microwave', 0.45),
                                        ('Safe', 0.45), ('Drawer', 0.45), ('Box', 1.5)])
def test_closed_door_hides_what_is_inside_and_open_door_shows_it(client, name, rise):
    spec = spec_of(name)
    position, yaw = (1.0, -0.5, 0.0), 0.7
    cache = ShapeCache(client)
    body = build_body(client, spec, 'white', position, yaw, cache)
    inner = sorted((s for s in spec.surfaces if s.inside), key=lambda s: s.center[2])
    surface = inner[len(inner) // 2]  # the fridge's middle shelf
    item_at = to_world(position, yaw, surface.center)
    item = build_body(client, spec_of('Apple'), 'red', item_at, 0.0, cache)
    # camera on the object's front axis, above the surface, looking at the item
    dist = max(spec.size[0], spec.size[1], 0.3) * 2.5
    eye = to_world(position, yaw, (surface.center[0] + dist, surface.center[1], surface.center[2] + rise * dist))
    target = (item_at[0], item_at[1], item_at[2] + 0.04)
    seen = segmentation(client, eye, target)
    assert body in seen
    assert item not in seen, f'{name}: closed, yet the item shows'
    set_articulation(client, body, spec, 1.0)
    shift = surface_offset(spec, surface, 1.0)  # a drawer carries its contents out
    moved = to_world(position, yaw, tuple(surface.center[i] + shift[i] for i in range(3)))
    client.resetBasePositionAndOrientation(item, moved, [0, 0, 0, 1])
    assert item in segmentation(client, eye, target), f'{name}: open, yet the item is hidden'
