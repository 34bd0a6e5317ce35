"""Frustum culling (dialfred_sim/world/culling.py): a draw that leaves out the objects wholly outside the
view gives the very image, depth and segmentation of a draw of everything."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from dialfred_sim.ground_truth import closeup_pixels
from dialfred_sim.tasks import load_split
from dialfred_sim.tasks.demonstrations import play_demonstration
from dialfred_sim.catalog import load_catalog
from dialfred_sim.world.culling import frustum_planes, shape_radius
from dialfred_sim.world.shapes import shape_for


def same(a, b) -> bool:
    return all(np.array_equal(x, y) for x, y in zip(a, b))


def frames_both_ways(env, task):
    """Play the task's expert; at every frame render with the culling off, then on. Returns
    (frames, frames that differ, the largest share of the world's objects hidden at a frame)."""
    seen = {'frames': 0, 'differing': 0, 'hidden': 0.0}

    def observe(env, k: int) -> None:
        w = env.world
        w.culling.enabled = False
        full = w.render()
        w.culling.enabled = True
        culled = w.render()
        seen['frames'] += 1
        seen['differing'] += not same(full, culled)
        seen['hidden'] = max(seen['hidden'], len(w.culling.hidden) / len(w.objects))
    r = env.resolution
    play_demonstration(env, task, np.zeros((len(task.expert_actions) + 1, r, r, 3), np.uint8), observe)
    return seen['frames'], seen['differing'], seen['hidden']


@pytest.mark.parametrize('split, first', [('valid_unseen', 0), ('train', 40)])
def test_culled_frames_are_the_full_draws_along_expert_episodes(env, split, first):
    tasks = load_split(split)[first:first + 3]
    frames = differing = 0
    hidden = []
    for task in tasks:
        f, d, h = frames_both_ways(env, task)
        frames, differing = frames + f, differing + d
        hidden.append(h)
    assert frames >= 20
    assert differing == 0
    assert max(hidden) > 0.2            # the culling did leave things out (the test compares something)


def test_an_object_brought_into_view_is_drawn_again(env):
    task = load_split('valid_unseen')[0]
    env.reset(options={'task': task})
    w = env.world
    w.render()
    assert w.culling.hidden
    for _ in range(4):                   # a whole turn: every hidden body comes into view at some heading
        _, _, _, _, info = env.step({'action': 'RotateLeft', 'pixel': (-1, -1)})
        w.culling.enabled = False
        full = w.render()
        w.culling.enabled = True
        assert same(full, w.render())


def test_the_oracle_close_ups_are_the_same_with_and_without_culling(env):
    task = load_split('valid_unseen')[3]
    env.reset(options={'task': task})
    w = env.world
    w.render()                           # the agent's view hides what is behind it
    small = sorted((o for o in w.objects.values() if not o.fixture), key=lambda o: o.object_id)[:6]
    culled = [closeup_pixels(w, o) for o in small]
    w.closeup_cache = {}
    w.culling.enabled = False
    full = [closeup_pixels(w, o) for o in small]
    w.culling.enabled = True
    assert any(p is not None for p in full)
    for a, b in zip(full, culled):
        assert (a is None and b is None) or np.array_equal(a, b)


def test_a_shapes_radius_holds_every_part_in_every_pose_of_its_joint():
    catalog = load_catalog()
    checked = 0
    for name, otype in sorted(catalog.items()):
        spec = shape_for(name, otype.dims)
        r = shape_radius(spec)
        art = spec.articulation
        for part in spec.parts:
            corners = np.array(list(itertools.product(*[(-h, h) for h in part.half_extents])))
            # rpy is at most a turn; the norm of a corner is its distance from the part's centre in any turn
            reach = np.linalg.norm(corners, axis=1).max()
            for value in np.linspace(0, art.open_value if (part.moving and art) else 0.0, 5):
                centre = np.asarray(part.pos, dtype=float)
                if part.moving and art and art.kind == 'revolute':
                    axis = np.asarray(art.axis, dtype=float) / np.linalg.norm(art.axis)
                    v = centre - np.asarray(art.origin)
                    turned = (v * math.cos(value) + np.cross(axis, v) * math.sin(value)
                              + axis * axis.dot(v) * (1 - math.cos(value)))
                    centre = np.asarray(art.origin) + turned
                elif part.moving and art:
                    centre = centre + np.asarray(art.axis, dtype=float) * value
                assert np.linalg.norm(centre) + reach <= r + 1e-9, (name, part)
                checked += 1
    assert checked > 100


def test_the_frustum_planes_hold_what_the_camera_sees_and_nothing_behind_it(env):
    env.reset(options={'task': load_split('valid_unseen')[0]})
    w = env.world
    planes = frustum_planes(w.view_matrix(), w.projection)
    eye, d = w.camera()
    ahead = np.array(eye) + 2.0 * np.array(d)
    behind = np.array(eye) - 2.0 * np.array(d)
    assert (planes[:, :3] @ ahead + planes[:, 3] > 0).all()
    assert (planes[:, :3] @ behind + planes[:, 3] < 0).any()
