"""The simulator core (no ROS): ALFRED's actions and world rules as the DialFRED paper states them.

Situations are set up deterministically: a test resets a known floor plan, clears the scattered
small objects where it needs a clean slate, spawns the objects it needs on known receptacles and
uses `face()` to stand where the target is visible within reach. Every failed action is checked to
leave the world and the agent exactly as they were and to count as a failed action.

This file: Every floor plan builds, with room to move.
"""

from __future__ import annotations


import numpy as np
import pytest

from dialfred_sim.catalog import ROOM_TYPES, load_catalog
from dialfred_sim.world.rooms import all_scenes, room_layout

from helpers import act, reset, snapshot
from world_helpers import KITCHEN


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


def test_small_objects_choose_closed_receptacles_first_less_often_than_open_ones():
    from types import SimpleNamespace as NS
    from dialfred_sim.world.scene import CLOSED_HOST_WEIGHT, _host_order

    def host(type_name, closed, n):
        return NS(type_name=type_name, object_id=f'{type_name}_{n}', otype=NS(openable=closed),
                  spec=NS(surfaces=(NS(inside=closed),)))
    shelf, cabinets = host('Shelf', False, 0), [host('Cabinet', True, k) for k in range(5)]
    rng = np.random.default_rng(0)
    orders = [_host_order([shelf, *cabinets], rng) for _ in range(4000)]
    assert all(sorted(h.object_id for h in o) == sorted(h.object_id for h in [shelf, *cabinets]) for o in orders)
    # Five cabinets count as one type: a cabinet comes first w / (1 + w) of the time, not 5 / 6.
    first_closed = np.mean([o[0].type_name == 'Cabinet' for o in orders])
    assert CLOSED_HOST_WEIGHT < 1.0
    assert first_closed == pytest.approx(CLOSED_HOST_WEIGHT / (1 + CLOSED_HOST_WEIGHT), abs=0.03)
