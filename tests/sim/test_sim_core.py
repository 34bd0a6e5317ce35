"""The simulator core (no ROS): ALFRED's actions and world rules as the DialFRED paper states them.

Situations are set up deterministically: a test resets a known floor plan, clears the scattered
small objects where it needs a clean slate, spawns the objects it needs on known receptacles and
uses `face()` to stand where the target is visible within reach. Every failed action is checked to
leave the world and the agent exactly as they were and to count as a failed action.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from dialfred_sim.actions import ACTION_NAMES, REACH
from dialfred_sim.world.bodies import articulation_joint
from dialfred_sim.world.catalog import ROOM_TYPES, load_catalog
from dialfred_sim.world.rooms import AGENT_RADIUS, GRID, all_scenes, footprint, room_layout
from dialfred_sim.world.scene import COLD, HOT, ROOM

from helpers import (act, agent_pose, distance_at, face, face_from_afar, first_of, free_ahead_pose,
                     pixel, pixel_of_structure, poses_towards, rerender, reset, snapshot, spawn_held, spawn_on,
                     unproject)

KITCHEN = 'FloorPlan1'


# ---------------------------------------------------------------------------------------------- helpers

def clear_small_objects(env) -> None:
    """Remove every scattered small object, leaving only the floor plan's fixtures."""
    w = env.world
    for oid in [k for k, o in w.objects.items() if not o.fixture]:
        if oid in w.objects:
            w.remove(oid)
    rerender(env)


def kitchen(env, seed: int = 0):
    """A clean FloorPlan1: fixtures only."""
    reset(env, KITCHEN, seed)
    clear_small_objects(env)
    return env.world


def counter(env):
    """A counter top with a placement surface (not a sink rim)."""
    tops = sorted((o for o in env.world.objects.values() if o.type_name == 'CounterTop' and o.spec.surfaces),
                  key=lambda o: o.object_id)
    assert tops
    return tops[0]


def middle_shelf(env, fridge):
    """The world point at the centre of the fridge's middle shelf."""
    from dialfred_sim.world.rooms import local_to_world
    surf = fridge.spec.surfaces[len(fridge.spec.surfaces) // 2]
    return local_to_world(fridge.position, fridge.yaw, surf.center)


def faucet_of(env, basin_id: str):
    return next(o for o in env.world.objects.values() if o.controls == basin_id)


def ok(env, action: str, px=None):
    """Step an action that must succeed; returns the info dict."""
    _, terminated, truncated, info = act(env, action, px)
    assert info['last_action_success'], f'{action} at {px} failed: {info["last_action_error"]}'
    assert info['last_action_error'] == ''
    return info


def fails(env, action: str, px=None, match: str = ''):
    """Step an action that must fail with an error matching `match`, changing nothing but the counters."""
    before = snapshot(env)
    view = env.world.render()[0]           # what the agent's camera sees of the world right now
    steps, failures = env.steps, env.failures
    obs, terminated, truncated, info = act(env, action, px)
    assert not info['last_action_success'], f'{action} at {px} unexpectedly succeeded'
    assert re.search(match, info['last_action_error']), info['last_action_error']
    assert snapshot(env) == before, f'failed {action} changed the world or the agent'
    assert np.array_equal(obs['rgb'], view), f'failed {action} changed what the agent sees'
    assert info['failed_actions'] == failures + 1
    assert info['step_count'] == steps + 1
    return info


def body_position(env, obj):
    pos, _ = env.world.client.getBasePositionAndOrientation(obj.body)
    return pos


def surface_height(env, obj) -> float:
    """World height of the surface `obj` rests on."""
    parent = env.world.objects[obj.parent]
    off = env.world.surface_offset(parent)
    return parent.position[2] + parent.spec.surfaces[obj.surface].center[2] + off[2]


# ---------------------------------------------------------------------------------------------- navigation

HEADING = {0: (1, 0), 90: (0, 1), 180: (-1, 0), 270: (0, -1)}


def test_move_ahead_moves_a_quarter_metre_along_the_heading(env):
    reset(env, KITCHEN)
    i, j, rot = free_ahead_pose(env)
    obs = env.teleport(i, j, rot, 30)
    x0, y0 = obs['pose'][:2]
    obs, _, _, info = act(env, 'MoveAhead')
    assert info['last_action_success']
    di, dj = HEADING[rot]
    assert obs['pose'][0] == pytest.approx(x0 + 0.25 * di)
    assert obs['pose'][1] == pytest.approx(y0 + 0.25 * dj)
    assert obs['pose'][2] == rot and obs['pose'][3] == 30
    assert agent_pose(env) == (i + di, j + dj, rot, 30.0)


def _blocked_poses(env):
    nav = env.world.layout.navigable
    for i, j in sorted(nav):
        for rot, (di, dj) in HEADING.items():
            if (i + di, j + dj) not in nav:
                yield i, j, rot, (i + di) * GRID, (j + dj) * GRID


def _near_furniture(env, x, y, margin):
    for fx in env.world.layout.fixtures:
        if fx.blocks_floor:
            r = footprint(fx.position, fx.yaw, fx.spec.size)
            dx, dy = max(r[0] - x, 0.0, x - r[2]), max(r[1] - y, 0.0, y - r[3])
            if math.hypot(dx, dy) < margin:
                return fx.object_id
    return None


def test_move_ahead_into_a_wall_fails_and_changes_nothing(env):
    reset(env, KITCHEN)
    lay = env.world.layout
    for i, j, rot, x, y in _blocked_poses(env):
        at_wall = min(x, y, lay.width - x, lay.depth - y) < AGENT_RADIUS
        if at_wall and _near_furniture(env, x, y, 0.6) is None:
            env.teleport(i, j, rot, 30)
            fails(env, 'MoveAhead', match=r'^MoveAhead blocked by a wall$')
            return
    pytest.fail('no pose facing a bare wall')


def test_move_ahead_into_furniture_fails_naming_it(env):
    reset(env, KITCHEN)
    lay = env.world.layout
    for i, j, rot, x, y in _blocked_poses(env):
        inside = min(x, y, lay.width - x, lay.depth - y) > AGENT_RADIUS + 0.1
        blocker = _near_furniture(env, x, y, AGENT_RADIUS)
        if inside and blocker is not None:
            env.teleport(i, j, rot, 30)
            fails(env, 'MoveAhead', match=rf'^MoveAhead blocked by {blocker}$')
            assert env.world.objects[blocker].fixture
            return
    pytest.fail('no pose facing furniture')


# ---------------------------------------------------------------------------------------------- open doors

UNSEEN_KITCHEN = 'FloorPlan10'     # 4 free points within 0.075 m of an open door


def openables(env):
    return sorted((o for o in env.world.objects.values() if o.fixture and o.otype.openable
                   and o.spec.articulation is not None), key=lambda o: o.object_id)


def test_no_free_grid_point_is_within_the_agents_radius_of_an_open_door(env):
    from dialfred_sim.world.open_parts import clearance
    reset(env, UNSEEN_KITCHEN)
    w = env.world
    doors = openables(env)
    assert {o.type_name for o in doors} >= {'Fridge', 'Cabinet', 'Microwave'}
    for door in doors:
        w.set_open(door, True)
    free = w.free_floor()
    taken = w.layout.navigable - free
    assert len(taken) >= 4 and free
    for door in doors:
        outlines = w.open_part_outlines(door)
        assert min(clearance(i * GRID, j * GRID, outlines) for i, j in free) >= AGENT_RADIUS, door.object_id
    for i, j in taken:
        assert w.open_blocker(i, j) is not None
        with pytest.raises(ValueError, match=r'is taken by the open '):
            env.teleport(i, j, 0, 30)


def test_an_open_fridge_door_blocks_the_agent_and_closing_it_clears_the_way(env):
    w = kitchen(env)
    fridge = first_of(env, 'Fridge')
    ok(env, 'Open', face(env, fridge.object_id))
    free = w.free_floor()
    for (i, j) in sorted(w.layout.navigable - free):
        for rot, (di, dj) in HEADING.items():
            if (i - di, j - dj) in free and w.open_blocker(i, j) == fridge.object_id:
                env.teleport(i - di, j - dj, rot, 0)
                fails(env, 'MoveAhead', match=rf'^MoveAhead blocked by {fridge.object_id}, which is open$')
                fridge_px = env.pixel_of(fridge.object_id)
                if fridge_px is None or distance_at(env, fridge_px) > REACH:
                    continue
                ok(env, 'Close', fridge_px)
                ok(env, 'MoveAhead')
                assert agent_pose(env)[:2] == (i, j)
                return
    pytest.fail('no free point next to the open door, facing it with the fridge in reach')


def test_a_door_does_not_open_into_the_agent(env):
    """Opening fails, changing nothing, where the door would swing into the agent on its way open."""
    w = kitchen(env)
    fridge = first_of(env, 'Fridge')
    in_the_way = [(i, j) for i, j in sorted(w.layout.navigable) if w.would_hit_agent(fridge, i, j)]
    assert in_the_way
    for i, j in in_the_way:
        for rot in HEADING:
            for hor in (0, 15, 30, 45, 60):
                env.teleport(i, j, rot, hor)
                px = env.pixel_of(fridge.object_id)
                if px is not None and distance_at(env, px) <= REACH:
                    fails(env, 'Open', px, match=rf'^{fridge.object_id} would hit you as it opens; step back first$')
                    assert not fridge.is_open
                    ok(env, 'Open', face(env, fridge.object_id))
                    assert fridge.is_open and not w.would_hit_agent(fridge)
                    return
    pytest.fail('the fridge is never in reach from where its door would hit the agent')


# ---------------------------------------------------------------------------------------------- the hand

def _carried_box(obj):
    rect = footprint(obj.position, obj.yaw, obj.spec.size)
    return rect, obj.position[2], obj.position[2] + obj.spec.size[2]


def _passes_into(env, obj):
    """What the held object's box overlaps: 'the wall', a fixture id, or None."""
    w = env.world
    rect, z0, z1 = _carried_box(obj)
    lay = w.layout
    if rect[0] < -1e-6 or rect[1] < -1e-6 or rect[2] > lay.width + 1e-6 or rect[3] > lay.depth + 1e-6:
        return 'the wall'
    for fx in lay.fixtures:
        r = footprint(fx.position, fx.yaw, fx.spec.size)
        if (rect[0] < r[2] - 1e-6 and r[0] < rect[2] - 1e-6 and rect[1] < r[3] - 1e-6 and r[1] < rect[3] - 1e-6
                and z0 < fx.position[2] + fx.spec.size[2] - 1e-6 and fx.position[2] < z1 - 1e-6):
            return fx.object_id
    return None


def test_a_held_object_stays_in_the_room_and_out_of_the_furniture(env):
    """A bread carried towards a wall must not end outside the room (it once ended 0.17 m out). On every free point
    and heading of the room the hand now draws it back until it is clear."""
    reset(env, UNSEEN_KITCHEN)
    w = env.world
    bread = spawn_held(env, 'Bread')
    drawn_back = 0
    for i, j in sorted(w.layout.navigable):
        for rot in HEADING:
            env.teleport(i, j, rot, 30)
            assert _passes_into(env, bread) is None, (i, j, rot, bread.position)
            a = w.agent
            ahead = (bread.position[0] - a.x) * math.cos(math.radians(rot)) + \
                (bread.position[1] - a.y) * math.sin(math.radians(rot))
            drawn_back += ahead < 0.42 - 1e-6
    assert drawn_back > 0        # the hand did have to draw back somewhere


def test_a_held_object_is_carried_at_full_reach_where_there_is_room(env):
    reset(env, KITCHEN)
    apple = spawn_held(env, 'Apple')
    w = env.world
    for i, j in sorted(w.layout.navigable):
        for rot in HEADING:
            env.teleport(i, j, rot, 30)
            ahead = (apple.position[0] - w.agent.x) * math.cos(math.radians(rot)) + \
                (apple.position[1] - w.agent.y) * math.sin(math.radians(rot))
            if ahead == pytest.approx(0.42):
                assert apple.position[2] == pytest.approx(0.95)
                return
    pytest.fail('the apple is never carried at full reach')


def _wall_approach(env):
    """(i, j, rot): a free point from which one step ahead lands on the free point nearest a wall,
    facing that wall."""
    w = env.world
    nav = w.layout.navigable
    for i, j in sorted(nav):
        for rot, (di, dj) in HEADING.items():
            a, b = (i + di, j + dj), (i + 2 * di, j + 2 * dj)
            x, y = b[0] * GRID, b[1] * GRID
            outside = x <= 0 or y <= 0 or x >= w.layout.width or y >= w.layout.depth
            if a in nav and outside and not _near_furniture(env, a[0] * GRID, a[1] * GRID, 0.7):
                return i, j, rot
    raise AssertionError('no free approach to a wall')


def test_a_baseball_bat_cannot_be_carried_into_the_wall(env):
    """A bat is longer than the agent is wide: facing the wall from the nearest point there is no
    room to hold it. The step that would push it through the wall fails and changes nothing."""
    kitchen(env)
    i, j, rot = _wall_approach(env)
    env.teleport(i, j, rot, 30)
    bat = spawn_held(env, 'BaseballBat')
    assert _passes_into(env, bat) is None
    fails(env, 'MoveAhead', match=rf'^MoveAhead blocked: the {bat.object_id} in hand would pass into the wall$')
    apple = spawn_on(env, 'Apple', counter(env).object_id)
    env.world.remove(bat.object_id)
    env.world.hold(apple)
    rerender(env)
    ok(env, 'MoveAhead')                  # an apple fits: the hand draws it back instead
    assert _passes_into(env, apple) is None


def test_what_rides_on_a_held_object_stays_out_of_the_wall_too(env):
    """A spatula on a plate reaches past the plate's rim: on the point nearest a wall, whichever way the
    agent faces, the hand carries the plate where the spatula is clear of the wall as well."""
    kitchen(env)
    i, j, rot = _wall_approach(env)
    di, dj = HEADING[rot]
    plate = spawn_on(env, 'Plate', counter(env).object_id)
    spatula = spawn_on(env, 'Spatula', plate.object_id)
    assert max(spatula.spec.size[:2]) > max(plate.spec.size[:2])
    env.world.hold(plate)
    checked = 0
    for heading in HEADING:
        try:
            env.teleport(i + di, j + dj, heading, 30)
        except ValueError:            # no room at all facing this way
            continue
        checked += 1
        assert _passes_into(env, plate) is None and _passes_into(env, spatula) is None, heading
    assert checked >= 2
    assert max(env.world.carried_size(plate)[:2]) >= max(spatula.spec.size[:2])


def test_turning_to_face_the_wall_with_a_bat_in_hand_fails(env):
    """Beside a wall with a bat held along it, turning right to face the wall would push the bat
    through it: the turn fails and changes nothing."""
    w = kitchen(env)
    bat = w.spawn('BaseballBat', load_catalog()['BaseballBat'].colours[0])
    w.hold(bat)

    def room(i, j, rot):
        return w.carry_spot(bat, i, j, rot)

    # the first free point and heading (in order) where the bat fits but would not facing the wall on the right
    pose = next(((i, j, rot) for i, j in sorted(w.layout.navigable) for rot in HEADING
                 if room(i, j, rot)[0] is not None and room(i, j, (rot - 90) % 360) == (None, 'the wall')), None)
    assert pose is not None, 'no point beside a wall where the bat fits until the agent turns to the wall'
    env.teleport(*pose, 30)
    fails(env, 'RotateRight', match=rf'^RotateRight blocked: the {bat.object_id} in hand would pass into the wall$')


def test_rotate_left_turns_90_degrees_counter_clockwise_and_right_clockwise(env):
    reset(env, KITCHEN)
    i, j, _ = free_ahead_pose(env)
    env.teleport(i, j, 270, 30)
    obs, _, _, info = act(env, 'RotateLeft')
    assert info['last_action_success'] and obs['pose'][2] == 0        # 270 + 90 wraps to 0
    obs, *_ = act(env, 'RotateLeft')
    assert obs['pose'][2] == 90                                        # facing +y: counter-clockwise
    obs, *_ = act(env, 'RotateRight')
    obs, *_ = act(env, 'RotateRight')
    assert obs['pose'][2] == 270
    assert agent_pose(env)[:2] == (i, j)                               # turning does not move


def test_look_up_and_down_move_15_degrees_and_stop_at_the_limits(env):
    reset(env, KITCHEN)
    assert env.world.agent.horizon == 30                              # ALFRED starts looking 30 down
    seen = []
    for _ in range(4):
        obs, _, _, info = act(env, 'LookUp')
        assert info['last_action_success']
        seen.append(float(obs['pose'][3]))
    assert seen == [15, 0, -15, -30]
    fails(env, 'LookUp', match=r'cannot look up further .*-30 to 60')
    seen = []
    for _ in range(6):
        obs, *_ = act(env, 'LookDown')
        seen.append(float(obs['pose'][3]))
    assert seen == [-15, 0, 15, 30, 45, 60]
    fails(env, 'LookDown', match=r'cannot look down further')


def test_depth_is_metric_floor_pixels_lie_on_the_floor(env):
    reset(env, KITCHEN)
    i, j, rot = free_ahead_pose(env)
    obs = env.teleport(i, j, rot, 60)
    floor = [b for b, n in env.world.structure_bodies.items() if n == 'Floor']
    ys, xs = np.nonzero(np.isin(obs['segmentation'], floor))
    assert len(xs) > 100
    for x, y in zip(xs[::5], ys[::5]):
        point = unproject(env, int(x), int(y))
        assert abs(point[2]) < 0.01, (x, y, point)      # the floor is the plane z = 0
        assert float(obs['depth'][y, x]) > 0



def test_a_slab_with_corners_in_the_cameras_plane_renders_whole_with_true_depth(env):
    """TinyRenderer blackens (NaN depth) or drops the faces of a box with a corner exactly in the
    camera's plane, as a 0.9 m island top ending 0.6 m behind an eye 1.5 m up pitched 45 degrees down
    did. Such slabs, below the eye and beside it, facing each way: each is seen lit, at its true depth,
    by as many pixels as the same slab moved 1 cm (its corners off the plane) shows, give or take its edge."""
    reset(env, KITCHEN)
    i, j, _ = free_ahead_pose(env)
    world = env.world
    c = world.client
    seen = 0
    for rot in (0, 90, 180, 270):
        env.teleport(i, j, rot, 45)
        (ex, ey, ez), _ = world.camera()
        fx, fy = round(math.cos(math.radians(rot))), round(math.sin(math.radians(rot)))
        top = ez - 0.6                      # pitched 45 degrees: the plane passes 0.6 m behind at this height
        for lateral in (-0.6, 0.0, 0.6):
            counts = []
            for back in (0.6, 0.59):        # the back corners in the camera's plane, then 1 cm ahead of it
                along, half_along, half_across = (0.6 - back) / 2, (0.6 + back) / 2, 0.31
                half = (half_along * abs(fx) + half_across * abs(fy), half_along * abs(fy) + half_across * abs(fx), 0.02)
                centre = (ex + fx * along - fy * lateral, ey + fy * along + fx * lateral, top - 0.02)
                body = c.createMultiBody(0, -1, c.createVisualShape(c.GEOM_BOX, halfExtents=half,
                                                                    rgbaColor=(0.8, 0.2, 0.2, 1)), basePosition=centre)
                try:
                    rgb, depth, seg = world.render()
                finally:
                    c.removeBody(body)
                mask = seg == body
                assert np.isfinite(depth).all(), (rot, lateral, back)
                counts.append(int(mask.sum()))
                if back == 0.6 and mask.any():
                    assert rgb[mask][:, 0].mean() > 60, (rot, lateral)    # lit red, not black
                    ys, xs = np.nonzero(mask)
                    for x, y in list(zip(xs, ys))[::13]:
                        point, _ = world.pixel_point(int(x), int(y), depth)
                        assert -0.05 < point[2] - top < 0.01, (rot, lateral, x, y, point)   # its top or sides
            assert abs(counts[0] - counts[1]) <= 0.1 * counts[1] + 8, (rot, lateral, counts)
            seen += counts[1] > 100
    assert seen >= 6                                # most of the twelve slabs are in view (the room hides some)


@pytest.mark.parametrize('horizon', [0, 30, 60])
def test_pixel_point_is_the_point_seen_at_the_pixel(env, horizon):
    reset(env, KITCHEN)
    i, j, rot = free_ahead_pose(env)
    obs = env.teleport(i, j, rot, horizon)
    eye = (env.world.agent.x, env.world.agent.y, 1.5)
    for y in range(0, 64, 9):
        for x in range(0, 64, 9):
            point, dist = env.world.pixel_point(x, y, obs['depth'])
            expected = unproject(env, x, y)
            # Within a pixel's width at that distance (pixel_point aims at pixel centres).
            tol = 0.02 + math.dist(eye, expected) * 2 / 64
            assert dist == pytest.approx(math.dist(eye, expected), abs=tol)
            assert math.dist(point, expected) < tol, (x, y, point, expected)


# ---------------------------------------------------------------------------------------------- Pickup

def test_pickup_puts_the_object_in_hand(env):
    w = kitchen(env)
    top = counter(env)
    apple = spawn_on(env, 'Apple', top.object_id)
    px = face(env, apple.object_id)
    info = ok(env, 'Pickup', px)
    assert info['held_object'] == apple.object_id == w.held
    assert info['last_action_target'] == apple.object_id
    state = w.object_state(apple.object_id)
    assert state.held and state.parent is None
    assert apple.object_id not in top.contents
    assert body_position(env, apple) == pytest.approx(apple.position)
    # Carried in front of the agent, about 1 m up.
    a = w.agent
    assert math.hypot(apple.position[0] - a.x, apple.position[1] - a.y) < 0.6
    assert 0.8 < apple.position[2] < 1.2


def test_pickup_fails_when_the_hand_is_full(env):
    kitchen(env)
    knife = spawn_held(env, 'Knife')
    apple = spawn_on(env, 'Apple', counter(env).object_id)
    px = face(env, apple.object_id)
    fails(env, 'Pickup', px, match=rf'hand is full \(holding {knife.object_id}\)')


@pytest.mark.parametrize('structure', ['Floor', 'Wall'])
def test_pickup_fails_on_nothing_at_the_pixel(env, structure):
    reset(env, KITCHEN)
    i, j, start = free_ahead_pose(env)
    for rot in (start, (start + 90) % 360, (start + 180) % 360, (start + 270) % 360):
        for hor in (60, 0):
            env.teleport(i, j, rot, hor)
            px = pixel_of_structure(env, structure)
            if px is not None:
                fails(env, 'Pickup', px, match=rf'^no object at pixel \({px[0]}, {px[1]}\) \({structure.lower()} is there\)$')
                return
    pytest.fail(f'no {structure} pixel found')


def test_pickup_fails_out_of_reach(env):
    w = kitchen(env)
    apple = spawn_on(env, 'Apple', counter(env).object_id)
    px = face_from_afar(env, apple.object_id)
    assert distance_at(env, px) > REACH
    fails(env, 'Pickup', px, match=rf'{apple.object_id} is out of reach \(\d+\.\d\d m away; reach is 1.50 m\)')
    assert w.held is None


@pytest.mark.parametrize('fixture', ['Microwave', 'CounterTop', 'Fridge'])
def test_pickup_fails_on_a_fixture(env, fixture):
    kitchen(env)
    obj = first_of(env, fixture) if fixture != 'CounterTop' else counter(env)
    px = face(env, obj.object_id)
    fails(env, 'Pickup', px, match=rf'^{obj.object_id} cannot be picked up$')


def apple_in_open_fridge(env):
    """The kitchen with its fridge open and an apple on the fridge's middle shelf."""
    w = kitchen(env)
    fridge = first_of(env, 'Fridge')
    w.set_open(fridge, True)
    apple = spawn_on(env, 'Apple', fridge.object_id, near=middle_shelf(env, fridge))
    return w, fridge, apple


def test_pickup_fails_inside_a_closed_container(env):
    w, fridge, apple = apple_in_open_fridge(env)
    px = face(env, apple.object_id)
    # The door shuts (a direct world edit) while the agent still acts on the frame showing the apple.
    w.set_open(fridge, False)
    fails(env, 'Pickup', px, match=rf'{apple.object_id} is inside {fridge.object_id}, which is closed')


def test_pickup_of_an_object_in_an_open_container_succeeds(env):
    w, fridge, apple = apple_in_open_fridge(env)
    ok(env, 'Pickup', face(env, apple.object_id))
    assert w.held == apple.object_id and apple.object_id not in fridge.contents


# ---------------------------------------------------------------------------------------------- Put

def test_put_rests_the_held_object_on_the_receptacle(env):
    w = kitchen(env)
    top = counter(env)
    apple = spawn_held(env, 'Apple')
    px = face(env, top.object_id)
    info = ok(env, 'Put', px)
    assert info['held_object'] == '' and w.held is None
    assert info['last_action_target'] == top.object_id
    state = w.object_state(apple.object_id)
    assert not state.held and state.parent == top.object_id and state.parent_type == 'CounterTop'
    assert apple.object_id in w.object_state(top.object_id).contents
    # Its pose is on the counter's top surface, within the counter's footprint, and the body is there.
    assert apple.position[2] == pytest.approx(surface_height(env, apple), abs=1e-6)
    assert apple.position[2] == pytest.approx(top.position[2] + top.spec.size[2], abs=0.01)
    r = footprint(top.position, top.yaw, top.spec.size)
    assert r[0] <= apple.position[0] <= r[2] and r[1] <= apple.position[1] <= r[3]
    assert body_position(env, apple) == pytest.approx(apple.position)
    # And it can be picked up again from there.
    ok(env, 'Pickup', face(env, apple.object_id))


def test_put_into_an_open_fridge(env):
    kitchen(env)
    fridge = first_of(env, 'Fridge')
    ok(env, 'Open', face(env, fridge.object_id))
    apple = spawn_held(env, 'Apple')
    ok(env, 'Put', pixel(env, fridge.object_id))
    assert apple.parent == fridge.object_id and apple.object_id in fridge.contents
    assert fridge.spec.surfaces[apple.surface].inside
    assert apple.position[2] == pytest.approx(surface_height(env, apple), abs=1e-6)


def test_put_places_the_object_on_the_shelf_the_agent_points_at(env):
    from dialfred_sim.world.scene import _to_local
    w = kitchen(env)
    fridge = first_of(env, 'Fridge')
    ok(env, 'Open', face(env, fridge.object_id))      # from where its door cannot hit the agent
    apple = spawn_held(env, 'Apple')

    def shelves_in_view() -> dict[int, list]:
        """Pixels (within reach) showing the top of each of the fridge's shelves, by shelf."""
        _, depth, seg = env._frame
        ys, xs = np.nonzero(seg == fridge.body)
        shelves: dict[int, list] = {}
        for x, y in zip(xs, ys):
            point = unproject(env, int(x), int(y))
            loc = _to_local(fridge.position, fridge.yaw, point)
            for k, s in enumerate(fridge.spec.surfaces):
                # a shelf's top is its surface's height; 5 mm below it for the float32 depth's rounding
                if (abs(loc[0] - s.center[0]) < s.half_size[0] - 0.05 and abs(loc[1] - s.center[1]) < s.half_size[1] - 0.05
                        and -0.005 <= loc[2] - s.center[2] < 0.03 and distance_at(env, (x, y)) < REACH):
                    shelves.setdefault(k, []).append((int(x), int(y)))
        return shelves

    # then step up to the open fridge: the first pose face() would try that shows two shelves or more
    for pose in poses_towards(env, fridge.object_id):
        env.teleport(*pose)
        shelves = shelves_in_view()
        if len(shelves) >= 2:
            break
    assert len(shelves) >= 2, 'fewer than two shelves in view from anywhere near the fridge'
    for k, pixels in sorted(shelves.items()):
        ok(env, 'Put', pixels[len(pixels) // 2])
        assert apple.parent == fridge.object_id
        assert apple.surface == k, f'aimed at shelf {k}, landed on shelf {apple.surface}'
        w.hold(apple)
        rerender(env)


def test_put_fails_with_nothing_in_hand(env):
    kitchen(env)
    px = face(env, counter(env).object_id)
    fails(env, 'Put', px, match=r'^nothing in hand to put$')


def test_put_fails_on_something_that_is_not_a_receptacle(env):
    kitchen(env)
    tomato = spawn_on(env, 'Tomato', counter(env).object_id)
    spawn_held(env, 'Apple')
    px = face(env, tomato.object_id)
    fails(env, 'Put', px, match=rf'^{tomato.object_id} is not a receptacle$')


def test_put_fails_into_a_closed_container(env):
    kitchen(env)
    spawn_held(env, 'Apple')
    mw = first_of(env, 'Microwave')
    px = face(env, mw.object_id)
    fails(env, 'Put', px, match=rf'^{mw.object_id} is closed$')


@pytest.mark.parametrize('receptacle', ['Toaster', 'CoffeeMachine'])
def test_put_fails_when_alfred_does_not_allow_the_object_there(env, receptacle):
    kitchen(env)
    spawn_held(env, 'Apple')
    target = first_of(env, receptacle)
    px = face(env, target.object_id)
    fails(env, 'Put', px, match=rf'^Apple cannot be put on {receptacle}$')


@pytest.mark.parametrize('action, error', [
    ('Put', r'^cannot put {} into itself$'),
    ('Pickup', r'^{} is in your hand; target something else$'),
    ('Open', r'^{} is in your hand; target something else$'),
])
def test_acting_on_the_held_object_itself_fails(env, action, error):
    w = kitchen(env)
    plate = spawn_held(env, 'Plate')
    i, j, rot = free_ahead_pose(env)
    for hor in (60, 45, 30):
        env.teleport(i, j, rot, hor)
        px = env.pixel_of(plate.object_id)
        if px is not None:
            fails(env, action, px, match=error.format(plate.object_id))
            assert w.held == plate.object_id
            return
    pytest.fail('the held plate is never in view')


# ---------------------------------------------------------------------------------------------- Open / Close

@pytest.mark.parametrize('openable', ['Fridge', 'Microwave', 'Cabinet', 'Drawer'])
def test_open_and_close(env, openable):
    w = kitchen(env)
    obj = first_of(env, openable)
    client = w.client
    joint = articulation_joint(obj.spec)
    px = face(env, obj.object_id)
    closed_value = client.getJointState(obj.body, joint)[0]
    fails(env, 'Close', px, match=rf'^{obj.object_id} is already closed$')
    info = ok(env, 'Open', px)
    assert info['last_action_target'] == obj.object_id
    assert w.object_state(obj.object_id).is_open
    assert client.getJointState(obj.body, joint)[0] != pytest.approx(closed_value)   # the door moved
    px = pixel(env, obj.object_id)
    fails(env, 'Open', px, match=rf'^{obj.object_id} is already open$')
    ok(env, 'Close', px)
    assert not w.object_state(obj.object_id).is_open
    assert client.getJointState(obj.body, joint)[0] == pytest.approx(closed_value)


def test_an_opening_drawer_carries_its_contents(env):
    kitchen(env)
    drawer = first_of(env, 'Drawer')
    spoon = spawn_on(env, 'Spoon', drawer.object_id)
    before = spoon.position
    ok(env, 'Open', face(env, drawer.object_id))
    assert spoon.parent == drawer.object_id
    moved = math.hypot(spoon.position[0] - before[0], spoon.position[1] - before[1])
    assert moved > 0.1
    assert body_position(env, spoon) == pytest.approx(spoon.position)


@pytest.mark.parametrize('action', ['Open', 'Close'])
def test_open_close_fail_on_something_not_openable(env, action):
    kitchen(env)
    top = counter(env)
    fails(env, action, face(env, top.object_id), match=rf'^{top.object_id} cannot be opened or closed$')


# ---------------------------------------------------------------------------------------------- Toggle

@pytest.mark.parametrize('toggleable', ['LightSwitch', 'Faucet', 'Microwave', 'CoffeeMachine'])
def test_toggle_on_and_off(env, toggleable):
    w = kitchen(env)
    obj = first_of(env, toggleable)
    px = face(env, obj.object_id)
    fails(env, 'ToggleOff', px, match=rf'^{obj.object_id} is already off$')
    ok(env, 'ToggleOn', px)
    assert w.object_state(obj.object_id).is_on
    fails(env, 'ToggleOn', pixel(env, obj.object_id), match=rf'^{obj.object_id} is already on$')
    ok(env, 'ToggleOff', pixel(env, obj.object_id))
    assert not w.object_state(obj.object_id).is_on


@pytest.mark.parametrize('action', ['ToggleOn', 'ToggleOff'])
def test_toggle_fails_on_something_not_toggleable(env, action):
    kitchen(env)
    top = counter(env)
    fails(env, action, face(env, top.object_id), match=rf'^{top.object_id} cannot be turned on or off$')


def test_a_stove_knob_lights_its_burner_and_heats_the_kettle_on_it(env):
    w = kitchen(env)
    knob = first_of(env, 'StoveKnob')
    burner = w.objects[knob.controls]
    kettle = spawn_on(env, 'Kettle', burner.object_id)
    ok(env, 'ToggleOn', face(env, knob.object_id))
    assert knob.is_on and burner.is_on
    assert w.object_state(kettle.object_id).temperature == HOT
    ok(env, 'ToggleOff', pixel(env, knob.object_id))
    assert not knob.is_on and not burner.is_on


@pytest.mark.parametrize('switch_on, switch_off', [('burner', 'knob'), ('knob', 'burner'), ('burner', 'burner')])
def test_a_stove_knob_and_its_burner_are_one_switch(env, switch_on, switch_off):
    """Turning the burner itself on turns its knob too, so either can turn it off again."""
    w = kitchen(env)
    knob = first_of(env, 'StoveKnob')
    burner = w.objects[knob.controls]
    parts = {'knob': knob, 'burner': burner}
    kettle = spawn_on(env, 'Kettle', burner.object_id)
    ok(env, 'ToggleOn', face(env, parts[switch_on].object_id))
    assert knob.is_on and burner.is_on and kettle.temperature == HOT
    other = parts['knob' if switch_on == 'burner' else 'burner']
    fails(env, 'ToggleOn', face(env, other.object_id), match=rf'^{other.object_id} is already on$')
    ok(env, 'ToggleOff', face(env, parts[switch_off].object_id))
    assert not knob.is_on and not burner.is_on
    other = parts['knob' if switch_off == 'burner' else 'burner']
    fails(env, 'ToggleOff', face(env, other.object_id), match=rf'^{other.object_id} is already off$')


def test_putting_on_a_lit_burner_heats(env):
    w = kitchen(env)
    knob = first_of(env, 'StoveKnob')
    burner = w.objects[knob.controls]
    ok(env, 'ToggleOn', face(env, knob.object_id))
    kettle = spawn_held(env, 'Kettle')
    ok(env, 'Put', face(env, burner.object_id))
    assert kettle.parent == burner.object_id and kettle.temperature == HOT


@pytest.mark.parametrize('cookware', ['Pan', 'Pot'])
def test_a_pan_or_pot_can_be_put_on_a_stove_burner(env, cookware):
    kitchen(env)
    burner = first_of(env, 'StoveBurner')
    pan = spawn_held(env, cookware)
    ok(env, 'Put', face(env, burner.object_id))
    assert pan.parent == burner.object_id


# ---------------------------------------------------------------------------------------------- Slice

def test_slice_with_a_knife_replaces_the_object_by_slices(env):
    w = kitchen(env)
    top = counter(env)
    apple = spawn_on(env, 'Apple', top.object_id)
    apple_id, where = apple.object_id, apple.position
    spawn_held(env, 'Knife')
    info = ok(env, 'Slice', face(env, apple_id))
    assert info['last_action_target'] == apple_id
    assert apple_id not in w.objects and apple_id not in top.contents
    slices = [o for o in w.objects.values() if o.type_name == 'AppleSliced']
    assert len(slices) == 4
    for s in slices:
        st = w.object_state(s.object_id)
        assert st.pickupable and st.parent == top.object_id and s.object_id in top.contents
        assert st.colour == apple.colour
        assert math.dist(st.position, where) < 0.2
    # A slice can be picked up (after putting the knife down).
    w.remove(w.held)
    rerender(env)
    ok(env, 'Pickup', face(env, slices[0].object_id))
    assert w.held == slices[0].object_id


def test_bread_gives_five_slices(env):
    w = kitchen(env)
    bread = spawn_on(env, 'Bread', counter(env).object_id)
    spawn_held(env, 'ButterKnife')
    ok(env, 'Slice', face(env, bread.object_id))
    assert len([o for o in w.objects.values() if o.type_name == 'BreadSliced']) == 5


@pytest.mark.parametrize('in_hand', [None, 'Spoon'])
def test_slice_fails_without_a_knife_in_hand(env, in_hand):
    kitchen(env)
    apple = spawn_on(env, 'Apple', counter(env).object_id)
    if in_hand:
        spawn_held(env, in_hand)
    fails(env, 'Slice', face(env, apple.object_id), match=r'^Slice needs a knife in hand$')


@pytest.mark.parametrize('target', ['Mug', 'AppleSliced'])
def test_slice_fails_on_something_not_sliceable(env, target):
    kitchen(env)
    obj = spawn_on(env, target, counter(env).object_id)
    spawn_held(env, 'Knife')
    fails(env, 'Slice', face(env, obj.object_id), match=rf'^{obj.object_id} cannot be sliced$')


# ---------------------------------------------------------------------------------------------- state changes

def test_running_the_faucet_cleans_what_is_in_the_sink_basin(env):
    w = kitchen(env)
    basin = first_of(env, 'SinkBasin')
    faucet = faucet_of(env, basin.object_id)
    mug = spawn_on(env, 'Mug', basin.object_id)
    mug.is_dirty = True
    elsewhere = spawn_on(env, 'Plate', counter(env).object_id)
    elsewhere.is_dirty = True
    ok(env, 'ToggleOn', face(env, faucet.object_id))
    assert w.object_state(mug.object_id).is_dirty is False
    assert w.object_state(elsewhere.object_id).is_dirty is True


def test_putting_into_the_basin_under_running_water_cleans(env):
    w = kitchen(env)
    basin = first_of(env, 'SinkBasin')
    faucet = faucet_of(env, basin.object_id)
    first = spawn_held(env, 'Mug')
    first.is_dirty = True
    ok(env, 'Put', face(env, basin.object_id))
    assert first.parent == basin.object_id and first.is_dirty      # the water is off: still dirty
    ok(env, 'ToggleOn', face(env, faucet.object_id))
    assert not first.is_dirty
    second = spawn_held(env, 'Apple')
    second.is_dirty = True
    ok(env, 'Put', face(env, basin.object_id))
    assert second.parent == basin.object_id
    assert w.object_state(second.object_id).is_dirty is False


def test_microwave_heats_what_is_inside_when_turned_on(env):
    w = kitchen(env)
    mw = first_of(env, 'Microwave')
    ok(env, 'Open', face(env, mw.object_id))
    potato = spawn_held(env, 'Potato')
    ok(env, 'Put', pixel(env, mw.object_id))
    assert potato.parent == mw.object_id and potato.temperature == ROOM
    ok(env, 'Close', pixel(env, mw.object_id))
    assert potato.temperature == ROOM
    ok(env, 'ToggleOn', pixel(env, mw.object_id))
    assert w.object_state(potato.object_id).temperature == HOT
    # Opening a running microwave stops it.
    ok(env, 'Open', pixel(env, mw.object_id))
    assert not mw.is_on


def test_microwave_cannot_be_turned_on_while_open(env):
    w = kitchen(env)
    mw = first_of(env, 'Microwave')
    ok(env, 'Open', face(env, mw.object_id))
    fails(env, 'ToggleOn', pixel(env, mw.object_id), match=rf'^{mw.object_id} is open; close it before turning it on$')
    assert not w.object_state(mw.object_id).is_on


def test_closing_the_fridge_cools_what_is_inside(env):
    w = kitchen(env)
    fridge = first_of(env, 'Fridge')
    ok(env, 'Open', face(env, fridge.object_id))
    apple = spawn_held(env, 'Apple')
    ok(env, 'Put', pixel(env, fridge.object_id))
    assert apple.parent == fridge.object_id and apple.temperature == ROOM
    ok(env, 'Close', pixel(env, fridge.object_id))
    assert w.object_state(apple.object_id).temperature == COLD


def test_a_held_object_moves_with_the_agent(env):
    w = kitchen(env)
    apple = spawn_held(env, 'Apple')
    i, j, rot = free_ahead_pose(env)
    env.teleport(i, j, rot, 30)
    p0 = apple.position
    ok(env, 'MoveAhead')
    p1 = apple.position
    di, dj = HEADING[rot]
    assert (p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]) == pytest.approx((0.25 * di, 0.25 * dj, 0.0))
    ok(env, 'RotateLeft')
    p2 = apple.position
    assert math.hypot(p2[0] - p1[0], p2[1] - p1[1]) > 0.2
    assert w.object_state(apple.object_id).position == pytest.approx(p2)
    assert body_position(env, apple) == pytest.approx(p2)


# ---------------------------------------------------------------------------------------------- episodes

def test_stop_terminates_the_episode_and_stepping_after_it_raises(env):
    reset(env, KITCHEN)
    _, terminated, truncated, info = act(env, 'Stop')
    assert terminated and not truncated and info['last_action_success']
    before = snapshot(env)
    with pytest.raises(RuntimeError, match='episode is over'):
        env.step('MoveAhead')
    assert snapshot(env) == before


def test_ten_failed_actions_terminate_the_episode(env):
    reset(env, KITCHEN)
    env.teleport(*agent_pose(env)[:3], -30)
    for k in range(1, 11):
        _, terminated, truncated, info = act(env, 'LookUp')
        assert not info['last_action_success'] and info['failed_actions'] == k
        assert terminated == (k == 10) and not truncated
    with pytest.raises(RuntimeError):
        env.step('LookDown')


def test_the_step_limit_truncates_the_episode(make_env):
    e = make_env(max_steps=3)
    reset(e, KITCHEN)
    for k in range(1, 4):
        _, terminated, truncated, info = act(e, 'RotateLeft')
        assert info['step_count'] == k
        assert not terminated and truncated == (k == 3)
    with pytest.raises(RuntimeError):
        e.step('RotateLeft')


def test_step_before_reset_raises(make_env):
    e = make_env()
    with pytest.raises(RuntimeError, match='before reset'):
        e.step('MoveAhead')


MALFORMED = [
    pytest.param('Jump', id='unknown-name'),
    pytest.param('moveahead', id='wrong-case'),
    pytest.param(len(ACTION_NAMES), id='index-too-large'),
    pytest.param(-1, id='negative-index'),
    pytest.param(True, id='bool'),
    pytest.param({'pixel': (3, 3)}, id='no-action-key'),
    pytest.param({'action': 'Pickup'}, id='interaction-without-pixel'),
    pytest.param({'action': 'Put', 'pixel': None}, id='pixel-none'),
    pytest.param({'action': 'Open', 'pixel': (64, 10)}, id='pixel-right-of-frame'),
    pytest.param({'action': 'Open', 'pixel': (10, 64)}, id='pixel-below-frame'),
    pytest.param({'action': 'Slice', 'pixel': (-1, 10)}, id='pixel-negative'),
    pytest.param({'action': 'ToggleOn', 'pixel': (1, 2, 3)}, id='pixel-three-values'),
]


@pytest.mark.parametrize('action', MALFORMED)
def test_malformed_actions_raise_value_error_and_change_nothing(env, action):
    reset(env, KITCHEN)
    act(env, 'RotateLeft')
    before = snapshot(env)
    frame = env.render().copy()
    with pytest.raises(ValueError):
        env.step(action)
    assert snapshot(env) == before
    assert env.steps == 1 and env.failures == 0 and not env.done
    assert np.array_equal(env.render(), frame)
    _, _, _, info = act(env, 'RotateRight')
    assert info['step_count'] == 2 and info['failed_actions'] == 0


# A pixel is two integers. Anything else is a caller's bug that used to be coerced silently (3.9 -> 3,
# '3' -> 3, True -> 1) or to escape as OverflowError (inf).
NOT_A_PIXEL = [
    pytest.param((3.9, 5.9), id='floats'),
    pytest.param((3.0, 5.0), id='whole-floats'),
    pytest.param(('3', '5'), id='digit-strings'),
    pytest.param('35', id='a-string'),
    pytest.param((True, False), id='bools'),
    pytest.param((float('inf'), 3), id='inf'),
    pytest.param((float('nan'), 3), id='nan'),
    pytest.param(np.array([3.5, 5.0]), id='float-array'),
    pytest.param({3, 5}, id='a-set'),
    pytest.param(7, id='one-number'),
]


@pytest.mark.parametrize('pixel', NOT_A_PIXEL)
def test_a_pixel_that_is_not_two_integers_is_a_value_error_naming_it(env, pixel):
    reset(env, KITCHEN)
    before, frame = snapshot(env), env.render().copy()
    with pytest.raises(ValueError, match=r'Pickup needs a target pixel \(x, y\) of two integers, got ') as caught:
        env.step({'action': 'Pickup', 'pixel': pixel})
    assert repr(pixel) in str(caught.value)
    assert snapshot(env) == before and np.array_equal(env.render(), frame)
    assert env.steps == 0 and env.failures == 0 and not env.done


@pytest.mark.parametrize('pixel', [(3, 5), [3, 5], np.array([3, 5]), (np.int32(3), np.int64(5))])
def test_a_pixel_may_be_any_pair_of_python_or_numpy_integers(env, pixel):
    reset(env, KITCHEN)
    _, _, _, info = act(env, 'Pickup', pixel)
    assert info['step_count'] == 1     # taken as an action (it may fail: there may be nothing there)


BAD_LIMITS = [
    pytest.param({'max_steps': 0}, ValueError, id='max_steps-0'),
    pytest.param({'max_steps': -5}, ValueError, id='max_steps-negative'),
    pytest.param({'max_failures': 0}, ValueError, id='max_failures-0'),
    pytest.param({'max_steps': 2.5}, TypeError, id='max_steps-float'),
    pytest.param({'max_steps': '100'}, TypeError, id='max_steps-string'),
    pytest.param({'max_failures': True}, TypeError, id='max_failures-bool'),
    pytest.param({'max_failures': None}, TypeError, id='max_failures-none'),
    pytest.param({'dirty_probability': 1.5}, ValueError, id='dirty_probability-above-1'),
    pytest.param({'dirty_probability': float('nan')}, ValueError, id='dirty_probability-nan'),
    pytest.param({'dirty_probability': '0.2'}, TypeError, id='dirty_probability-string'),
]


@pytest.mark.parametrize('kwargs, error', BAD_LIMITS)
def test_episode_limits_must_be_positive_integers(make_env, kwargs, error):
    name, value = next(iter(kwargs.items()))
    with pytest.raises(error, match=rf'^{name} must .*got {re.escape(repr(value))}'):
        make_env(**kwargs)


BAD_RESET_OPTIONS = [
    pytest.param({'task_id': 12}, TypeError, r"task_id must be a string .*got 12 \(int\)", id='task_id-int'),
    pytest.param({'task_id': ''}, ValueError, r"task_id must name a task .*got ''", id='task_id-empty'),
    pytest.param({'task_id': None}, TypeError, r'task_id must be a string .*got None', id='task_id-none'),
    pytest.param({'task_id': 'valid_unseen/999999'}, ValueError, r"unknown task_id 'valid_unseen/999999'",
                 id='task_id-unknown'),
    pytest.param({'task': None}, TypeError, r'task must be a dialfred_sim.tasks.Task, got None', id='task-none'),
    pytest.param({'task': 'valid_unseen/000012'}, TypeError, r"task must be .*got 'valid_unseen/000012'",
                 id='task-a-string'),
    pytest.param({'task_id': 'valid_unseen/000012', 'scene': 'FloorPlan1'}, ValueError,
                 r"give 'task_id' or 'task' alone", id='task-and-scene'),
    pytest.param({'scene': 7}, TypeError, r"scene must be a string .*got 7", id='scene-int'),
    pytest.param({'scene': ''}, ValueError, r"unknown scene ''", id='scene-empty'),
    pytest.param({'scene': 'FloorPlan99'}, ValueError, r"unknown scene 'FloorPlan99'", id='scene-unknown'),
    pytest.param({'taskid': 'valid_unseen/000012'}, ValueError, r"unknown reset option\(s\) 'taskid'",
                 id='misspelt-key'),
    pytest.param({'dirty_probability': -0.1}, ValueError, r'dirty_probability must be in \[0, 1\], got -0.1',
                 id='dirty_probability-negative'),
    pytest.param(['scene', 'FloorPlan1'], TypeError, r'options must be a dict', id='options-a-list'),
]


@pytest.mark.parametrize('options, error, message', BAD_RESET_OPTIONS)
def test_bad_reset_options_are_a_clear_error_and_change_nothing(env, options, error, message):
    reset(env, KITCHEN)
    act(env, 'RotateLeft')
    before, frame = snapshot(env), env.render().copy()
    rng_state = env.np_random.bit_generator.state
    with pytest.raises(error, match=message):
        env.reset(seed=5, options=options)
    assert snapshot(env) == before and np.array_equal(env.render(), frame)
    assert env.np_random.bit_generator.state == rng_state      # not even reseeded
    assert env.task is None and env.steps == 1 and not env.done
    _, _, _, info = act(env, 'RotateRight')                    # the episode goes on
    assert info['step_count'] == 2 and info['scene'] == KITCHEN


def test_navigation_ignores_the_pixel(env):
    reset(env, KITCHEN)
    _, _, _, info = act(env, 'RotateLeft', (999, -5))
    assert info['last_action_success']


SCRIPT = [('MoveAhead', None), ('RotateLeft', None), ('LookDown', None), ('Pickup', (32, 40)),
          ('MoveAhead', None), ('RotateRight', None), ('Open', (32, 32)), ('LookUp', None),
          ('MoveAhead', None), ('Put', (30, 45)), ('ToggleOn', (32, 20)), ('RotateRight', None),
          ('MoveAhead', None), ('LookDown', None)]


def _play(e, seed):
    frames = []
    obs, info = e.reset(seed=seed)
    frames.append((obs['rgb'].copy(), obs['depth'].copy(), obs['segmentation'].copy(), obs['pose'].copy()))
    outcomes = []
    for action, px in SCRIPT:
        obs, _, terminated, truncated, info = e.step({'action': action, 'pixel': px} if px else action)
        frames.append((obs['rgb'].copy(), obs['depth'].copy(), obs['segmentation'].copy(), obs['pose'].copy()))
        outcomes.append((info['last_action_success'], info['last_action_error'], info['held_object']))
        if terminated or truncated:
            break
    return info['scene'], frames, outcomes, e.world.object_states()


def test_same_seed_same_episode_bit_for_bit(make_env):
    a, b = make_env(), make_env()
    scene_a, frames_a, out_a, states_a = _play(a, 11)
    scene_b, frames_b, out_b, states_b = _play(b, 11)
    assert scene_a == scene_b and out_a == out_b and states_a == states_b
    assert len(frames_a) == len(frames_b)
    for fa, fb in zip(frames_a, frames_b):
        for xa, xb in zip(fa, fb):
            assert xa.dtype == xb.dtype and xa.tobytes() == xb.tobytes()


def test_a_different_seed_gives_a_different_episode(make_env):
    e = make_env()
    obs_a, info_a = e.reset(seed=11)
    states_a, rgb_a = e.world.object_states(), obs_a['rgb'].copy()
    obs_b, info_b = e.reset(seed=12)
    assert info_a['scene'] != info_b['scene'] or e.world.object_states() != states_a
    assert not np.array_equal(rgb_a, obs_b['rgb'])
    # In one fixed floor plan the seed still changes where things are.
    reset(e, KITCHEN, seed=1)
    s1 = e.world.object_states()
    reset(e, KITCHEN, seed=2)
    assert e.world.object_states() != s1


def test_observations_match_the_observation_space(env):
    obs, info = reset(env, 'FloorPlan301')
    assert env.observation_space.contains(obs)
    assert obs['rgb'].shape == (64, 64, 3) and obs['rgb'].dtype == np.uint8
    assert obs['depth'].dtype == np.float32 and obs['segmentation'].dtype == np.int32
    ids, names = info['instances']
    assert set(np.unique(obs['segmentation']).tolist()) - {-1} <= set(ids)   # -1: nothing rendered
    assert names[ids.index(env.world.objects['Bed_0'].body)] == 'Bed_0'
    assert info['room_type'] == 'bedroom' and info['scene'] == 'FloorPlan301'


def test_gymnasium_env_checker_passes(env):
    from gymnasium.utils.env_checker import check_env
    check_env(env.unwrapped, skip_render_check=True)


# ---------------------------------------------------------------------------------------------- scenes

def test_all_120_floor_plans_build_with_room_to_move(make_env):
    e = make_env(resolution=16)
    scenes = all_scenes()
    assert len(scenes) == len(set(scenes)) == 120
    per_type: dict[str, int] = {}
    types = set()
    for scene in scenes:
        lay = room_layout(scene)
        per_type[lay.room_type] = per_type.get(lay.room_type, 0) + 1
        types |= {f.type_name for f in lay.fixtures} | set(lay.small_object_types)
        _, info = e.reset(seed=0, options={'scene': scene})
        assert info['scene'] == scene and info['room_type'] == lay.room_type
        a = e.world.agent
        assert (a.i, a.j) in lay.navigable
        assert any(not o.fixture for o in e.world.objects.values()), f'{scene} has no small objects'
    assert per_type == {room: 30 for room in ROOM_TYPES}
    assert len(types) >= 80, sorted(types)
    assert types <= set(load_catalog())


def test_every_floor_plan_has_at_least_30_navigable_points():
    small = {s: len(room_layout(s).navigable) for s in all_scenes() if len(room_layout(s).navigable) < 30}
    assert small == {}


def test_floor_plan_numbers_follow_ai2thor(env):
    assert room_layout('FloorPlan1').room_type == 'kitchen'
    assert room_layout('FloorPlan230').room_type == 'living_room'
    assert room_layout('FloorPlan301').room_type == 'bedroom'
    assert room_layout('FloorPlan430').room_type == 'bathroom'
    reset(env, KITCHEN)
    act(env, 'RotateLeft')
    before = snapshot(env)
    for bad in ('FloorPlan0', 'FloorPlan31', 'FloorPlan999', 'Kitchen1', 'FloorPlanX'):
        with pytest.raises(ValueError, match='unknown scene'):
            room_layout(bad)
        with pytest.raises(ValueError, match='unknown scene'):
            env.reset(seed=0, options={'scene': bad})
    # A rejected reset leaves the running episode as it was.
    assert snapshot(env) == before and env.steps == 1 and not env.done
    act(env, 'RotateRight')


def test_layouts_are_the_same_on_every_call():
    room_layout.cache_clear()
    first = room_layout('FloorPlan207')
    room_layout.cache_clear()
    again = room_layout('FloorPlan207')
    assert first == again


def test_colour_variants_same_type_different_colours(env):
    found = []
    for scene in ('FloorPlan1', 'FloorPlan2', 'FloorPlan3', 'FloorPlan201', 'FloorPlan301', 'FloorPlan401'):
        reset(env, scene)
        by_type: dict[str, list[str]] = {}
        for o in env.world.objects.values():
            if not o.fixture:
                by_type.setdefault(o.type_name, []).append(o.colour)
        for type_name, colours in by_type.items():
            assert len(colours) == len(set(colours)), f'{scene}: two {type_name}s share a colour'
            if len(colours) >= 2:
                found.append((scene, type_name, colours))
    assert found, 'no scene holds two instances of one type'


def test_viewed_at_shows_the_state_as_an_env_of_that_resolution_would_and_restores_everything():
    from dialfred_sim.env import DialfredEnv
    from dialfred_sim.tasks import load_split
    task = load_split('valid_unseen')[7]
    small, large = DialfredEnv(resolution=64), DialfredEnv(resolution=128)
    try:
        with pytest.raises(RuntimeError, match='before reset'):
            with small.viewed_at(128):
                pass
        small.reset(options={'task': task})
        obs_large, _ = large.reset(options={'task': task})
        before = small._frame
        with pytest.raises(ValueError, match='resolution'):
            with small.viewed_at(8):
                pass
        assert small._frame is before
        with small.viewed_at(128) as seen:
            assert seen is small and small.resolution == 128 and small.world.width == 128
            for mine, theirs in zip(small._frame, large._frame):
                assert np.array_equal(mine, theirs)
        assert small._frame is before and small.resolution == 64 and (small.world.width, small.world.height) == (64, 64)
        obs, *_ = small.step({'action': 'RotateLeft'})
        obs_large, *_ = large.step({'action': 'RotateLeft'})
        assert obs['rgb'].shape == (64, 64, 3)
        with small.viewed_at(128):
            assert np.array_equal(small._frame[0], obs_large['rgb'])
    finally:
        small.close()
        large.close()
