"""The simulator core (no ROS): ALFRED's actions and world rules as the DialFRED paper states them.

Situations are set up deterministically: a test resets a known floor plan, clears the scattered
small objects where it needs a clean slate, spawns the objects it needs on known receptacles and
uses `face()` to stand where the target is visible within reach. Every failed action is checked to
leave the world and the agent exactly as they were and to count as a failed action.

This file: turning and looking, and what the camera sees (metric depth, the point behind a pixel).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from helpers import act, agent_pose, free_ahead_pose, reset, unproject
from world_helpers import KITCHEN, fails


# ---------------------------------------------------------------------------------------------- the camera

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




@pytest.mark.parametrize('horizon', [-30, 0, 30, 45, 60])
def test_reach_lengths_give_each_pixels_distance_from_the_agents_axis(env, horizon):
    from dialfred_sim.world.camera import reach_lengths
    reset(env, KITCHEN)
    i, j, rot = free_ahead_pose(env)
    obs = env.teleport(i, j, rot, horizon)
    depth = obs['depth']
    lengths = depth * reach_lengths(depth.shape[1], depth.shape[0], horizon)
    eye_lengths = []
    for y in range(0, 64, 7):
        for x in range(0, 64, 7):
            point, dist = env.world.pixel_point(x, y, depth)
            axis = math.hypot(point[0] - env.world.agent.x, point[1] - env.world.agent.y)
            assert lengths[y, x] == pytest.approx(axis, abs=1e-4), (x, y)
            eye_lengths.append(dist - axis)
    # Not the distance from the eye: below or above the eye a point is farther from it than from the axis.
    assert max(eye_lengths) > 0.3
