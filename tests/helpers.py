"""Helpers to set up simulator situations deterministically in tests (no ROS).

The tests put objects where they need them (`spawn_on`, `World.place`, `World.hold`), then use
`face()` to stand the agent where the target is visible and within reach and get the pixel to act on.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Optional

import numpy as np

from dialfred_sim.actions import REACH
from dialfred_sim.world.rooms import GRID

HORIZONS = (0, 15, 30, 45, 60, -15, -30)


def reset(env, scene: str = 'FloorPlan1', seed: int = 0, **options):
    return env.reset(seed=seed, options={'scene': scene, **options})


def rerender(env):
    """Render the current world state again from the agent's current pose (after direct edits)."""
    a = env.world.agent
    return env.teleport(a.i, a.j, a.rotation, a.horizon)


def agent_pose(env) -> tuple:
    a = env.world.agent
    return (a.i, a.j, a.rotation, a.horizon)


def snapshot(env) -> tuple:
    """Everything an action may change: every object's ground truth, the agent pose, the hand."""
    return env.world.object_states(), agent_pose(env), env.world.held


def first_of(env, type_name: str):
    """The first object of `type_name` (by id), failing the test if the scene has none."""
    ids = sorted(k for k, o in env.world.objects.items() if o.type_name == type_name)
    assert ids, f'{env.world.layout.scene} has no {type_name}'
    return env.world.objects[ids[0]]


def spawn_on(env, type_name: str, receptacle_id: str, colour: Optional[str] = None, near=None):
    """A new `type_name` resting on/in `receptacle_id` (the free spot nearest the world point `near`,
    else the first free spot); re-renders the frame."""
    w = env.world
    obj = w.spawn(type_name, colour or _colour(type_name))
    assert w.place(obj, w.objects[receptacle_id], near=near), f'no room for {type_name} on {receptacle_id}'
    rerender(env)
    return obj


def spawn_held(env, type_name: str, colour: Optional[str] = None):
    """A new `type_name` in the agent's hand; re-renders the frame."""
    w = env.world
    obj = w.spawn(type_name, colour or _colour(type_name))
    w.hold(obj)
    rerender(env)
    return obj


def _colour(type_name: str) -> str:
    from dialfred_sim.catalog import load_catalog
    return load_catalog()[type_name].colours[0]


def distance_at(env, pixel) -> float:
    """Distance from the agent's vertical axis (the reach's measure) to the point seen at `pixel` of the
    current frame."""
    _, depth, _ = env._frame
    return env.world.axis_distance(env.world.pixel_point(pixel[0], pixel[1], depth)[0])


def pixel(env, object_id: str):
    """A pixel of `object_id` in the current frame; fails the test if it is not visible."""
    px = env.pixel_of(object_id)
    assert px is not None, f'{object_id} is not visible from {agent_pose(env)}'
    return px


def _candidates(env, target, radius: float, min_radius: float = 0.0):
    """Poses the agent may stand in (free floor, room for what it holds) looking towards `target`,
    best guesses first; for a closed openable only those from which it can open without hitting the agent."""
    w = env.world
    ox, oy, oz = target.position
    held = w.objects[w.held] if w.held else None
    to_open = target.otype.openable and not target.is_open and target.spec.articulation is not None
    out = []
    for i, j in w.free_floor():
        x, y = i * GRID, j * GRID
        d = math.hypot(ox - x, oy - y)
        if not min_radius <= d <= radius or (to_open and w.would_hit_agent(target, i, j)):
            continue
        bearing = math.degrees(math.atan2(oy - y, ox - x))
        pitch = math.degrees(math.atan2(1.5 - oz, max(d, 0.05)))
        for rot in (0, 90, 180, 270):
            off = abs((bearing - rot + 180) % 360 - 180)
            if off > 60 and d > 0.3 or held is not None and w.carry_spot(held, i, j, rot)[0] is None:
                continue
            for hor in HORIZONS:
                out.append((off + abs(hor - pitch) / 2 + 10 * d * (min_radius == 0), (i, j, rot, hor)))
    out.sort()
    return [pose for _, pose in out]


def poses_towards(env, object_id: str, radius: float = 1.3) -> list:
    """The poses face() tries for `object_id`, in its order (best guesses first): free grid points
    within `radius` metres, headings towards the object, camera pitches; for tests that need more of
    a pose than that the object is in view."""
    return _candidates(env, env.world.objects[object_id], radius)


def face(env, object_id: str, reach: float = REACH - 0.1, radius: float = 1.3):
    """Teleport the agent so that `object_id` is visible within `reach` metres; return its pixel.

    Searches free grid points within `radius` metres (horizontal) of the object, the 4 rotations and
    the camera pitches, best guesses first. Fails the test if no pose shows the object in reach.
    """
    target = env.world.objects[object_id]
    for i, j, rot, hor in _candidates(env, target, radius):
        env.teleport(i, j, rot, hor)
        px = env.pixel_of(object_id)
        if px is not None and distance_at(env, px) <= reach:
            return px
    raise AssertionError(f'{object_id} cannot be seen within {reach} m from any free point of '
                         f'{env.world.layout.scene}')


def face_from_afar(env, object_id: str, beyond: float = REACH + 0.2):
    """Like face(), but from a pose where the object is visible and more than `beyond` m away."""
    target = env.world.objects[object_id]
    for i, j, rot, hor in _candidates(env, target, radius=8.0, min_radius=beyond):
        env.teleport(i, j, rot, hor)
        px = env.pixel_of(object_id)
        if px is not None and distance_at(env, px) > beyond:
            return px
    raise AssertionError(f'{object_id} cannot be seen from farther than {beyond} m')


def pixel_of_structure(env, name: str):
    """A pixel showing room structure `name` ('Floor', 'Wall', 'Ceiling') in the current frame."""
    _, _, seg = env._frame
    bodies = [b for b, n in env.world.structure_bodies.items() if n == name]
    ys, xs = np.nonzero(np.isin(seg, bodies))
    if len(xs) == 0:
        return None
    k = len(xs) // 2
    return int(xs[k]), int(ys[k])


def act(env, action: str, px=None):
    """One step; returns (observation, terminated, truncated, info)."""
    cmd = {'action': action} if px is None else {'action': action, 'pixel': px}
    obs, reward, terminated, truncated, info = env.step(cmd)
    return obs, terminated, truncated, info


def free_ahead_pose(env):
    """A free grid point and rotation whose forward neighbour is free too (for MoveAhead)."""
    nav = env.world.layout.navigable
    steps = {0: (1, 0), 90: (0, 1), 180: (-1, 0), 270: (0, -1)}
    for i, j in sorted(nav):
        for rot, (di, dj) in steps.items():
            if (i + di, j + dj) in nav:
                return i, j, rot
    raise AssertionError('no free step in this room')


def unproject(env, px: int, py: int) -> np.ndarray:
    """The world point seen at pixel (px, py) of the current frame, from pybullet's own camera matrices.

    Independent of World.pixel_point: inverts the view and projection matrices the frame was rendered
    with, using the observation's metric depth (OpenGL camera frame: x right, y up, looking along -z).
    pybullet's TinyRenderer samples pixel (px, py) at normalised device coordinates
    (2 px / W - 1, 1 - 2 (py + 1) / H) (measured: floor and wall pixels then land exactly on their
    planes), not at the pixel centre.
    """
    w = env.world
    _, depth, _ = env._frame
    view = np.array(w.view_matrix(), dtype=float).reshape(4, 4).T
    proj = np.array(w.projection, dtype=float).reshape(4, 4).T
    x_ndc = px / w.width * 2 - 1
    y_ndc = 1 - (py + 1) / w.height * 2
    d = float(depth[py, px])
    cam = np.array([x_ndc * d / proj[0, 0], y_ndc * d / proj[1, 1], -d, 1.0])
    return (np.linalg.inv(view) @ cam)[:3]


def tiny_checkpoint(path: Path, favour: str = '', resolution: int = 64) -> Path:
    """A random-init performer with the model's own save function; `favour`: an action whose logit
    is pushed up (e.g. RotateLeft: an episode that runs until the step limit)."""
    import torch

    from dialfred_performer.model import Performer, PerformerConfig, save_checkpoint
    from dialfred_performer.preprocess import Vocabulary
    from dialfred_sim.protocol import ACTIONS
    from dialfred_sim.tasks import load_split
    vocab = Vocabulary.build([t.instruction for t in load_split('valid_unseen')[:40]]
                             + ['the apple is to your left in the fridge', 'you should turn around'])
    torch.manual_seed(0)
    model = Performer(PerformerConfig(resolution=resolution, d_model=32, heads=2, layers=1, ff=64), len(vocab))
    if favour:
        with torch.no_grad():
            model.action_head.linear.bias[ACTIONS.index(favour)] += 50.0
    save_checkpoint(path, model, vocab, command='tests/helpers.py tiny_checkpoint')
    return path


def interrupt_after(cmd: list, path: Path, lines: int, within_s: float, settle_s: float = 0.0, **popen) -> tuple:
    """Start `cmd`, wait until its results file `path` holds `lines` lines (within `within_s` seconds), then
    `settle_s` more, and press Ctrl-C (SIGINT): (its exit status, its output, stdout and stderr together)."""
    import signal
    import subprocess
    import time
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **popen)
    try:
        deadline = time.monotonic() + within_s
        while not (path.exists() and path.read_text().count('\n') >= lines):
            assert proc.poll() is None, proc.stdout.read()
            assert time.monotonic() < deadline, f'{lines} episodes did not finish in {within_s:g} s'
            time.sleep(0.02)
        time.sleep(settle_s)
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, out
