"""The simulator core (no ROS): ALFRED's actions and world rules as the DialFRED paper states them.

Situations are set up deterministically: a test resets a known floor plan, clears the scattered
small objects where it needs a clean slate, spawns the objects it needs on known receptacles and
uses `face()` to stand where the target is visible within reach. Every failed action is checked to
leave the world and the agent exactly as they were and to count as a failed action.

This file: The object in hand: where it is carried, and what it may pass into.
"""

from __future__ import annotations

import math

import pytest

from dialfred_sim.catalog import load_catalog
from dialfred_sim.world.rooms import GRID, footprint

from helpers import rerender, reset, spawn_held, spawn_on
from world_helpers import HEADING, KITCHEN, UNSEEN_KITCHEN, counter, fails, kitchen, near_furniture, ok


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
            if a in nav and outside and not near_furniture(env, a[0] * GRID, a[1] * GRID, 0.7):
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
