"""Two physics edges reported from outside, checked against what legal moves can reach (no ROS).

Both were read off pybullet's boxes: an opened fridge door's axis-aligned box 0.074 m from a free grid
point (the agent's radius is 0.2 m), and a held bread's box reaching past a wall. The claims here are
about states an agent can reach with its actions, rotations included."""

from __future__ import annotations

import numpy as np
import pytest

from dialfred_sim.world.open_parts import blocks
from dialfred_sim.world.rooms import AGENT_RADIUS, GRID

SCENE = 'FloorPlan10'       # a valid_unseen kitchen, where both were seen



def openables(world):
    return sorted(o.object_id for o in world.objects.values()
                  if o.fixture and o.otype.openable and o.spec.articulation is not None)


def test_no_open_door_stands_within_the_agents_radius_of_a_point_it_may_stand_on(env):
    env.reset(seed=0, options={'scene': SCENE})
    world = env.world
    checked = 0
    for oid in openables(world)[::3]:       # every third of a kitchen's cabinets, drawers and appliances (time)
        obj = world.objects[oid]
        world.set_open(obj, True)
        free = world.free_floor()
        outlines = world.open_part_outlines(obj)
        close = [(i, j) for i, j in free if blocks(i * GRID, j * GRID, outlines, AGENT_RADIUS)]
        world.set_open(obj, False)
        assert close == [], f'{oid} open leaves free points inside the agent radius of its moving part: {close}'
        checked += 1
    assert checked >= 3


def test_a_door_does_not_open_into_the_agent_and_the_agent_cannot_walk_into_an_open_door(env):
    """The fridge of FloorPlan10 open: a grid point within the agent's radius of its door is not
    free; from there the fridge refuses to open, and walking there with it open is refused."""
    env.reset(seed=0, options={'scene': SCENE})
    world = env.world
    fridge = world.objects['Fridge_0']
    steps = {(-1, 0): 0, (1, 0): 180, (0, -1): 90, (0, 1): 270}   # from a neighbour, the heading onto the point
    world.set_open(fridge, True)
    door = world.open_part_outlines(fridge)
    free_open = world.free_floor()
    world.set_open(fridge, False)

    def approaches(i, j):
        """(neighbour, heading) pairs to walk onto (i, j) from free floor with the fridge open."""
        return [((i + di, j + dj), rot) for (di, dj), rot in steps.items() if (i + di, j + dj) in free_open]

    # the first free point (in order) within the agent's radius of the open door, that one can walk up to
    spot = next(((i, j) for i, j in sorted(world.layout.navigable)
                 if blocks(i * GRID, j * GRID, door, AGENT_RADIUS) and approaches(i, j)), None)
    assert spot is not None, 'no free point near the open fridge door to walk onto'
    i0, j0 = spot
    assert world.would_hit_agent(fridge, i0, j0)
    world.set_open(fridge, True)
    assert spot not in world.free_floor() and world.open_blocker(i0, j0) == 'Fridge_0'
    with pytest.raises(ValueError, match='taken by the open Fridge_0'):
        env.teleport(i0, j0, 0, 30.0)
    world.set_open(fridge, False)
    # walk up to the point with the fridge open: the step onto it is refused
    for (i, j), r in approaches(i0, j0):
        env.teleport(i, j, r, 30.0)
        world.set_open(fridge, True)
        _, _, _, _, info = env.step('MoveAhead')
        assert not info['last_action_success'] and 'Fridge_0' in info['last_action_error']
        assert (world.agent.i, world.agent.j) == (i, j)
        world.set_open(fridge, False)
    # and standing on the point, the fridge will not open
    env.reset(seed=0, options={'scene': SCENE})
    env.teleport(i0, j0, 180, 30.0)
    from dialfred_sim.actions import Action, interact
    result = interact(env.world, Action.Open, env.world.objects['Fridge_0'], None)
    assert not result.success and 'would hit you' in result.error


def test_a_held_bread_stays_inside_the_room_at_every_pose_it_can_be_carried_to(env):
    """Wherever the hand has room for the bread (every free point, every heading), pybullet's box of
    the bread lies inside the walls; where it has none, the agent cannot stand so holding it."""
    env.reset(seed=0, options={'scene': SCENE})
    world = env.world
    bread = world.objects['Bread_0']
    world.hold(bread)
    c = world.client
    width, depth = world.layout.width, world.layout.depth
    carried, refused = 0, 0
    for i, j in sorted(world.layout.navigable):
        for r in (0, 90, 180, 270):
            spot, _ = world.carry_spot(bread, i, j, r)
            if spot is None:
                refused += 1
                with pytest.raises(ValueError, match='no room'):
                    env.teleport(i, j, r, 30.0)
                continue
            world.agent.i, world.agent.j, world.agent.rotation = i, j, r
            world.update_held_pose()
            lo, hi = (np.array(v) for v in c.getAABB(bread.body, -1))
            for link in range(c.getNumJoints(bread.body)):
                a, b = c.getAABB(bread.body, link)
                lo, hi = np.minimum(lo, a), np.maximum(hi, b)
            assert lo[0] >= 0 and lo[1] >= 0 and hi[0] <= width and hi[1] <= depth, (i, j, r, lo, hi)
            carried += 1
    assert carried > 100     # the bread is short enough that the hand finds room for it at every pose here


def test_the_reach_message_never_says_an_object_is_as_far_as_the_reach(env):
    """A click 1.5004 m away used to read 'out of reach (1.50 m away; reach is 1.5 m)'."""
    from dialfred_sim.actions import REACH, target_at
    env.reset(seed=0, options={'scene': SCENE})
    _, depth, seg = env.world.render()
    ys, xs = np.isin(seg, list(env.world.body_to_object)).nonzero()      # a pixel of some object in view
    px, py = int(xs[0]), int(ys[0])
    point, _ = env.world.pixel_point(px, py, depth)
    scaled = depth * (REACH + 0.0004) / env.world.axis_distance(point)    # the same pixel, just beyond reach
    _, _, failure = target_at(env.world, px, py, scaled, seg)
    assert failure is not None and 'out of reach (1.51 m away; reach is 1.50 m)' in failure.error
