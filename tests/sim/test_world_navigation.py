"""The simulator core (no ROS): ALFRED's actions and world rules as the DialFRED paper states them.

Situations are set up deterministically: a test resets a known floor plan, clears the scattered
small objects where it needs a clean slate, spawns the objects it needs on known receptacles and
uses `face()` to stand where the target is visible within reach. Every failed action is checked to
leave the world and the agent exactly as they were and to count as a failed action.

This file: Moving, turning and looking; doors that open into the free floor.
"""

from __future__ import annotations


import pytest

from dialfred_sim.actions import REACH
from dialfred_sim.world.rooms import AGENT_RADIUS, GRID

from helpers import act, agent_pose, distance_at, face, first_of, free_ahead_pose, reset
from world_helpers import HEADING, KITCHEN, UNSEEN_KITCHEN, fails, kitchen, near_furniture, ok


# ---------------------------------------------------------------------------------------------- navigation

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


def test_move_ahead_into_a_wall_fails_and_changes_nothing(env):
    reset(env, KITCHEN)
    lay = env.world.layout
    for i, j, rot, x, y in _blocked_poses(env):
        at_wall = min(x, y, lay.width - x, lay.depth - y) < AGENT_RADIUS
        if at_wall and near_furniture(env, x, y, 0.6) is None:
            env.teleport(i, j, rot, 30)
            fails(env, 'MoveAhead', match=r'^MoveAhead blocked by a wall$')
            return
    pytest.fail('no pose facing a bare wall')


def test_move_ahead_into_furniture_fails_naming_it(env):
    reset(env, KITCHEN)
    lay = env.world.layout
    for i, j, rot, x, y in _blocked_poses(env):
        inside = min(x, y, lay.width - x, lay.depth - y) > AGENT_RADIUS + 0.1
        blocker = near_furniture(env, x, y, AGENT_RADIUS)
        if inside and blocker is not None:
            env.teleport(i, j, rot, 30)
            fails(env, 'MoveAhead', match=rf'^MoveAhead blocked by {blocker}$')
            assert env.world.objects[blocker].fixture
            return
    pytest.fail('no pose facing furniture')


# ---------------------------------------------------------------------------------------------- open doors

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


