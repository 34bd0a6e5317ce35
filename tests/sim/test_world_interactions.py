"""The simulator core (no ROS): ALFRED's actions and world rules as the DialFRED paper states them.

Situations are set up deterministically: a test resets a known floor plan, clears the scattered
small objects where it needs a clean slate, spawns the objects it needs on known receptacles and
uses `face()` to stand where the target is visible within reach. Every failed action is checked to
leave the world and the agent exactly as they were and to count as a failed action.

This file: The interactions: Pickup, Put, Open / Close, Toggle, Slice and the state changes they make.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dialfred_sim.actions import REACH
from dialfred_sim.world.bodies import articulation_joint
from dialfred_sim.world.rooms import footprint
from dialfred_sim.world.objects import COLD, HOT, ROOM

from helpers import (distance_at, face, face_from_afar, first_of, free_ahead_pose, pixel, pixel_of_structure,
                     poses_towards, rerender, reset, spawn_held, spawn_on, unproject)
from world_helpers import (HEADING, KITCHEN, body_position, counter, fails, faucet_of,
                           kitchen, middle_shelf, ok, surface_height)


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


def test_reach_is_measured_from_the_agents_vertical_axis_not_from_the_eye(env):
    """AI2-THOR's rule: within 1.5 m of the agent's central vertical axis is within reach, however far
    below the eye the object lies (an apple on a counter 1.45 m away is 1.57 m from the eye)."""
    kitchen(env)
    apple = spawn_on(env, 'Apple', counter(env).object_id)
    for i, j, rot, hor in poses_towards(env, apple.object_id, radius=2.0):
        env.teleport(i, j, rot, hor)
        px = env.pixel_of(apple.object_id)
        if px is None:
            continue
        point, from_eye = env.world.pixel_point(px[0], px[1], env._frame[1])
        if from_eye > REACH and distance_at(env, px) < REACH - 0.05:
            ok(env, 'Pickup', px)
            assert env.world.held == apple.object_id
            return
    pytest.fail('no pose sees the apple beyond reach of the eye but within reach of the axis')


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
    from dialfred_sim.world.placement import _to_local
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


