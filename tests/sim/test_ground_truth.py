"""The simulator's ground truth for the oracle (dialfred_sim.ground_truth), without ROS."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from dialfred_sim.ground_truth import (MAX_APPEARANCE_PIXELS, MIN_SEEN_PIXELS, Appearance, GroundTruthCache, Snapshot,
                                       appearance, seen_positions, snapshot, snapshot_from_dict, snapshot_to_dict,
                                       task_object_ids)
from dialfred_sim.tasks import load_split
from dialfred_sim.tasks.expert import replay
from dialfred_sim.catalog import load_catalog
from dialfred_sim.world.rooms import GRID

from helpers import agent_pose, face, first_of, reset, rerender, spawn_held, spawn_on

# DialFRED's put_in_list (utils.py): receptacles described with "in".
PUT_IN_LIST = {'box', 'bathtubbasin', 'bowl', 'cabinet', 'cup', 'drawer', 'fridge', 'garbagecan', 'microwave',
               'mug', 'pan', 'pot', 'safe', 'sinkbasin', 'sink'}


@pytest.fixture(scope='module')
def valid_unseen():
    return load_split('valid_unseen')


def spawn_in_a_drawer(env, type_name: str, colour: str | None = None):
    """(a new `type_name` in a drawer, the drawer): the first drawer by id with room for it, else (every
    drawer full of scattered things) the first drawer, emptied of them first; re-renders the frame."""
    w = env.world
    drawers = sorted(k for k, o in w.objects.items() if o.type_name == 'Drawer')
    assert drawers, f'{w.layout.scene} has no Drawer'
    obj = w.spawn(type_name, colour or load_catalog()[type_name].colours[0])
    for oid in drawers:
        if w.place(obj, w.objects[oid]):
            rerender(env)
            return obj, w.objects[oid]
    w.remove(obj.object_id)
    drawer = w.objects[drawers[0]]
    for oid in [d.object_id for d in w.descendants(drawer) if not d.fixture]:
        w.remove(oid)
    return spawn_on(env, type_name, drawer.object_id, colour), drawer


def test_a_snapshot_holds_every_object_with_its_parent_colour_and_state(env):
    reset(env, 'FloorPlan1', seed=0)
    s = snapshot(env)
    world = env.world
    assert set(s.objects) == set(world.objects)
    assert s.task_id == '' and s.expert_end is None and s.task_objects == {}
    a = world.agent
    assert s.agent == (a.x, a.y, a.rotation, a.horizon)
    for oid, fact in s.objects.items():
        obj = world.objects[oid]
        assert fact.type_name == obj.type_name and fact.noun == obj.otype.noun
        assert fact.colour == obj.colour and fact.material == obj.otype.material
        assert fact.position[:2] == pytest.approx(obj.position[:2])
        assert fact.position[2] == pytest.approx(obj.position[2] + obj.spec.size[2] / 2)   # box centre
        assert fact.parent_id == (obj.parent or '')
        if obj.parent:
            parent = world.objects[obj.parent]
            assert (fact.parent_type, fact.parent_noun) == (parent.type_name, parent.otype.noun)
            assert fact.preposition == ('in' if parent.type_name.lower() in PUT_IN_LIST else 'on')
        else:
            assert fact.parent_type == fact.parent_noun == fact.preposition == ''


def test_things_are_in_containers_and_on_surfaces(env):
    reset(env, 'FloorPlan1', seed=0)
    fridge, counter = first_of(env, 'Fridge'), first_of(env, 'CounterTop')
    basin = first_of(env, 'SinkBasin')
    for oid in [o.object_id for o in env.world.objects.values() if o.parent == basin.object_id and not o.fixture]:
        if oid in env.world.objects:
            env.world.remove(oid)                  # room in the basin for the washed apple
    cold = spawn_on(env, 'Apple', fridge.object_id)
    shelved = spawn_on(env, 'Apple', counter.object_id)
    kept, _ = spawn_in_a_drawer(env, 'Spoon')
    washed = spawn_on(env, 'Apple', basin.object_id)
    s = snapshot(env)
    assert (s.objects[cold.object_id].preposition, s.objects[cold.object_id].parent_noun) == ('in', 'fridge')
    assert (s.objects[shelved.object_id].preposition, s.objects[shelved.object_id].parent_noun) == ('on', 'counter')
    assert (s.objects[kept.object_id].preposition, s.objects[kept.object_id].parent_type) == ('in', 'Drawer')
    assert (s.objects[washed.object_id].preposition, s.objects[washed.object_id].parent_type) == ('in', 'SinkBasin')


def test_a_held_object_has_no_parent(env):
    reset(env, 'FloorPlan1', seed=0)
    mug = spawn_held(env, 'Mug')
    fact = snapshot(env).objects[mug.object_id]
    assert fact.held and fact.parent_id == fact.parent_type == fact.preposition == ''


def test_a_task_snapshot_names_the_tasks_objects_and_the_experts_end_pose(env, valid_unseen):
    for task in valid_unseen[:20]:
        env.reset(options={'task': task})
        s = snapshot(env)
        assert (s.task_id, s.task_type, s.instruction) == (task.task_id, task.task_type, task.instruction)
        i, j, rot, hor = task.expert_end_pose
        assert s.expert_end == (i * GRID, j * GRID, rot, hor)
        ids = {q for p in task.primitives for q in (p.target, p.receptacle) if q}
        assert set(s.task_objects.values()) <= ids
        assert {env.world.objects[q].otype.noun for q in ids} == set(s.task_objects)
        for noun, oid in s.task_objects.items():
            assert s.objects[oid].noun == noun
        put = [p for p in task.primitives if p.kind == 'put']
        for p in put:   # a put names both the object and where it goes
            assert s.objects[p.target].noun in s.task_objects and s.objects[p.receptacle].noun in s.task_objects


def test_a_sliced_target_is_replaced_by_its_slices_among_the_task_objects(env, valid_unseen):
    task = next(t for t in valid_unseen if t.task_type == 'Slice')
    env.reset(options={'task': task})
    target = task.primitives[-1].target
    assert target in snapshot(env).task_objects.values()
    replay(env.world, task.expert_actions)
    rerender(env)
    assert target not in env.world.objects
    s = snapshot(env)
    slices = sorted(o for o, obj in env.world.objects.items() if obj.sliced_from == target)
    assert len(slices) >= 4 and target not in task_object_ids(env) and target not in s.task_objects.values()
    assert set(slices) <= set(task_object_ids(env))
    assert s.task_objects[s.objects[slices[0]].noun] == slices[0]


def test_an_object_in_view_is_sampled_from_the_current_frame(env):
    reset(env, 'FloorPlan1', seed=0)
    fridge = first_of(env, 'Fridge')
    face(env, fridge.object_id)
    look = appearance(env, fridge.object_id)
    assert look.from_current_view
    assert look.pixels.dtype == np.uint8 and look.pixels.shape[1] == 3
    assert 20 <= len(look.pixels) <= MAX_APPEARANCE_PIXELS
    rgb, _, seg = env._frame
    frame_colours = {tuple(p) for p in rgb[seg == fridge.body]}
    assert all(tuple(p) in frame_colours for p in look.pixels)


def test_an_object_out_of_view_or_shut_away_gets_a_close_up(env):
    reset(env, 'FloorPlan1', seed=0)
    fridge = first_of(env, 'Fridge')
    assert not fridge.is_open
    inside = spawn_on(env, 'Tomato', fridge.object_id, colour='red')
    look = appearance(env, inside.object_id)
    assert not look.from_current_view and len(look.pixels) >= 20
    spoon, drawer = spawn_in_a_drawer(env, 'Spoon', colour='blue')
    assert not drawer.is_open
    look = appearance(env, spoon.object_id)
    assert not look.from_current_view and len(look.pixels) >= 20


def test_an_object_no_camera_shows_well_enough_has_no_pixels(env):
    reset(env, 'FloorPlan1', seed=0)
    apple = spawn_on(env, 'Apple', first_of(env, 'CounterTop').object_id)
    look = appearance(env, apple.object_id, min_pixels=64 * 64 + 1)    # more than any image holds
    assert look.pixels.shape == (0, 3) and not look.from_current_view


def test_taking_a_snapshot_changes_nothing(env, make_env):
    reset(env, 'FloorPlan201', seed=4)
    before = env.world.object_states(), agent_pose(env), env.world.held
    frame = [a.copy() for a in env._frame]
    snapshot(env, appearance_of=sorted(env.world.objects))      # every object, close-ups included
    assert (env.world.object_states(), agent_pose(env), env.world.held) == before
    for a, b in zip(frame, env._frame):
        assert np.array_equal(a, b)
    again = rerender(env)
    assert np.array_equal(again['rgb'], frame[0]) and np.array_equal(again['segmentation'], frame[2])
    # The same seed and actions still give the same frames as in a world never snapshotted.
    other = make_env()
    reset(other, 'FloorPlan201', seed=4)
    for action in ('RotateLeft', 'MoveAhead', 'LookDown'):
        mine, theirs = env.step({'action': action})[0], other.step({'action': action})[0]
        assert np.array_equal(mine['rgb'], theirs['rgb'])


def test_a_snapshot_survives_a_json_round_trip(env, valid_unseen):
    env.reset(options={'task': valid_unseen[0]})
    s = snapshot(env, task_object_ids(env))
    assert s.appearances
    d = json.loads(json.dumps(snapshot_to_dict(s)))
    back = snapshot_from_dict(d)
    assert isinstance(back, Snapshot)
    assert back.objects == s.objects and back.task_objects == s.task_objects
    assert (back.agent, back.expert_end, back.task_id) == (s.agent, s.expert_end, s.task_id)
    for oid, look in s.appearances.items():
        got = back.appearances[oid]
        assert isinstance(got, Appearance) and got.pixels.dtype == np.uint8
        assert np.array_equal(got.pixels, look.pixels) and got.from_current_view == look.from_current_view
    empty = snapshot_from_dict(snapshot_to_dict(Snapshot((0, 0, 0, 30), None, '', '', '', {}, {},
                                                         {'X': Appearance('X', np.zeros((0, 3), np.uint8), False)})))
    assert empty.appearances['X'].pixels.shape == (0, 3)


def test_an_object_in_view_is_seen_at_the_middle_of_its_visible_pixels(env):
    reset(env, 'FloorPlan1', seed=0)
    world = env.world
    _, depth, seg = env._frame
    seen = seen_positions(world, depth, seg)
    assert seen
    a = world.agent
    for oid, obj in world.objects.items():
        ys, xs = np.nonzero(seg == obj.body)
        if len(xs) < MIN_SEEN_PIXELS:
            assert oid not in seen
            continue
        points = [world.pixel_point(x, y, depth)[0] for x, y in zip(xs, ys)]
        def bearing(p):
            return (math.degrees(math.atan2(p[1] - a.y, p[0] - a.x)) - a.rotation + 180) % 360 - 180
        bearings = sorted(bearing(p) for p in points)
        # One of its own pixels' points, with the median bearing of them all.
        assert min(math.dist(seen[oid], p) for p in points) < 1e-6, oid
        assert bearing(seen[oid]) == pytest.approx(bearings[(len(bearings) - 1) // 2], abs=1e-6), oid
    s = snapshot(env)
    assert {oid for oid, f in s.objects.items() if f.seen_position is not None} == set(seen)
    for oid, f in s.objects.items():
        assert f.where == (f.seen_position if oid in seen else f.position)


def test_the_cache_gives_the_snapshot_of_the_moment_and_computes_it_once_per_state(env, valid_unseen):
    cache = GroundTruthCache(env, first_version=100)
    versions = []
    for task in valid_unseen[:3]:
        env.reset(options={'task': task})
        for action in (None, 'RotateLeft', 'MoveAhead', 'LookDown', 'RotateRight'):
            if action:
                env.step({'action': action})
            ids = task_object_ids(env)
            version = cache.version()
            got, want = cache.snapshot(ids), snapshot(env, ids)
            assert (got.objects, got.agent, got.expert_end, got.task_objects, got.task_id) == \
                (want.objects, want.agent, want.expert_end, want.task_objects, want.task_id)
            assert list(got.appearances) == list(want.appearances)
            for oid, look in want.appearances.items():
                assert np.array_equal(got.appearances[oid].pixels, look.pixels)
                assert got.appearances[oid].from_current_view == look.from_current_view
            # Asked again in the same state: the same version and the very same objects, not recomputed.
            assert cache.version() == version and cache.snapshot() is cache.snapshot()
            assert cache.appearances(ids[:1]).get(ids[0]) is got.appearances.get(ids[0])
            versions.append(version)
    assert versions == list(range(100, 100 + len(versions)))      # every reset and step is a new state


def test_every_receptacle_type_uses_dialfreds_preposition():
    for name, t in load_catalog().items():
        if t.receptacle:
            assert t.preposition == ('in' if name.lower() in PUT_IN_LIST else 'on'), name


def _counting_closeups(monkeypatch):
    import dialfred_sim.ground_truth as gt
    calls = []
    search = gt._search_closeup
    monkeypatch.setattr(gt, '_search_closeup', lambda w, o, m: calls.append(o.object_id) or search(w, o, m))
    return calls


def test_a_close_up_is_rendered_once_per_world_state(env, monkeypatch):
    calls = _counting_closeups(monkeypatch)
    reset(env, 'FloorPlan1', seed=0)
    fridge = first_of(env, 'Fridge')
    tomato = spawn_on(env, 'Tomato', fridge.object_id, colour='red')
    first = appearance(env, tomato.object_id)
    first.pixels[:] = 0                                   # the caller's copy, not the cache's
    again = appearance(env, tomato.object_id)
    assert calls == [tomato.object_id] and len(again.pixels) >= 20 and again.pixels.any()
    env.world.set_open(fridge, True)                      # a joint moved: rendered again
    appearance(env, tomato.object_id)
    assert calls == [tomato.object_id] * 2
    env.world.set_open(fridge, False)                     # back to the first state: remembered
    assert np.array_equal(appearance(env, tomato.object_id).pixels, again.pixels)
    assert len(calls) == 2
    spawn_on(env, 'Apple', first_of(env, 'CounterTop').object_id)    # a body made: the cache is dropped
    assert np.array_equal(appearance(env, tomato.object_id).pixels, again.pixels) and len(calls) == 3


def test_cached_close_ups_equal_fresh_renders_along_expert_episodes(make_env, valid_unseen, monkeypatch):
    """The oracle's appearances at the start and halfway through the expert's episode, cache on vs off."""
    import dialfred_sim.ground_truth as gt
    env = make_env(resolution=valid_unseen[0].resolution)
    _counting_closeups(monkeypatch)
    fresh = lambda w, o, m=gt.MIN_APPEARANCE_PIXELS: gt._search_closeup(w, o, m)
    compared = 0
    for task in valid_unseen[:12]:
        env.reset(options={'task': task})
        plan = task.expert_actions
        for step in range(len(plan) // 2 + 1):
            if step in (0, len(plan) // 2):
                ids = task_object_ids(env)
                cached = snapshot(env, ids).appearances
                monkeypatch.setattr(gt, 'closeup_pixels', fresh)
                uncached = snapshot(env, ids).appearances
                monkeypatch.undo()
                for oid in ids:
                    assert np.array_equal(cached[oid].pixels, uncached[oid].pixels), (task.task_id, step, oid)
                    compared += not cached[oid].from_current_view
            if step < len(plan) // 2:
                a = plan[step]
                env.step({'action': a.action, 'pixel': (a.x, a.y)})
    assert compared >= 8
