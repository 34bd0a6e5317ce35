"""Situations of the simulator core's tests (tests/sim/test_world_*.py): a known kitchen, its counters and
shelves, and the checks that an action succeeds or fails leaving the world as it was."""

from __future__ import annotations

import math
import re

import numpy as np

from dialfred_sim.world.rooms import footprint
from helpers import act, rerender, reset, snapshot

KITCHEN = 'FloorPlan1'


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


HEADING = {0: (1, 0), 90: (0, 1), 180: (-1, 0), 270: (0, -1)}   # a heading's grid step
UNSEEN_KITCHEN = 'FloorPlan10'     # 4 free points within 0.075 m of an open door


def near_furniture(env, x, y, margin):
    for fx in env.world.layout.fixtures:
        if fx.blocks_floor:
            r = footprint(fx.position, fx.yaw, fx.spec.size)
            dx, dy = max(r[0] - x, 0.0, x - r[2]), max(r[1] - y, 0.0, y - r[3])
            if math.hypot(dx, dy) < margin:
                return fx.object_id
    return None
