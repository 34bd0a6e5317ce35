#!/usr/bin/env python3
"""Probe the simulator's geometry from outside its own rules (no ROS): where pybullet actually draws
the bodies, not where the simulator's geometry says they are.

- doors: every openable of every scene, opened fully; for each grid point the simulator calls free
  floor now (`World.free_floor`), the distance to the door, lid or drawer as pybullet places it (each
  visual box of the moving links, from pybullet's link poses, where it reaches below 1.6 m) must be at
  least the agent's radius (0.2 m).
- held: the expert plays each task until it picks something up, then the agent wanders (80 seeded
  random moves, turns and looks) with it in hand; after every step, every visual box of the held
  object and of what rides on it must stay inside the room's walls.

    ./dialfred bench physics_probe [--split valid_seen] [--tasks 200] [--seed 0]

Prints JSON: how many points and boxes were checked, how many broke a rule, the worst ones.
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np
from tqdm import tqdm

from dialfred_sim.env import DialfredEnv
from dialfred_sim.tasks import load_split
from dialfred_sim.world.bodies import articulation_joint
from dialfred_sim.world.bullet import pybullet as p
from dialfred_sim.world.open_parts import AGENT_HEIGHT, _convex_hull, _distance_to_polygon
from dialfred_sim.world.rooms import AGENT_RADIUS, GRID


def visual_boxes(client, body: int) -> list[tuple[int, np.ndarray]]:
    """(link, 8x3 world corners) of each box, cylinder or sphere `body` is drawn with, placed by
    pybullet's own forward kinematics."""
    out = []
    for vs in client.getVisualShapeData(body):
        link, kind, dims, local_pos, local_orn = vs[1], vs[2], vs[3], vs[5], vs[6]
        if link == -1:
            pos, orn = client.getBasePositionAndOrientation(body)
        else:
            state = client.getLinkState(body, link, computeForwardKinematics=True)
            pos, orn = state[4], state[5]
        wpos, worn = client.multiplyTransforms(pos, orn, local_pos, local_orn)
        if kind == p.GEOM_BOX:
            half = np.asarray(dims[:3]) / 2
        elif kind in (p.GEOM_CYLINDER, p.GEOM_CAPSULE):
            half = np.array([dims[1], dims[1], dims[0] / 2])
        elif kind == p.GEOM_SPHERE:
            half = np.full(3, dims[0])
        else:
            continue
        rot = np.array(client.getMatrixFromQuaternion(worn)).reshape(3, 3)
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        out.append((link, (signs * half) @ rot.T + np.asarray(wpos)))
    return out


def probe_doors(env, task) -> tuple[int, list]:
    w, points, close = env.world, 0, []
    for obj in list(w.objects.values()):
        joint = articulation_joint(obj.spec)
        if joint is None:
            continue
        was = obj.is_open
        if not was:
            w.set_open(obj, True)
        hulls = [_convex_hull(b[:, :2]) for link, b in visual_boxes(env.client, obj.body)
                 if link > joint and b[:, 2].min() < AGENT_HEIGHT and b[:, 2].max() > 0.0]
        for i, j in w.free_floor():
            points += 1
            d = min((_distance_to_polygon((i * GRID, j * GRID), h) for h in hulls), default=math.inf)
            if d < AGENT_RADIUS - 1e-3:
                close.append({'task': task.task_id, 'object': obj.object_id, 'point': [i, j], 'metres': round(d, 3)})
        if not was:
            w.set_open(obj, False)
    return points, close


def probe_held(env, task, rng) -> tuple[int, list]:
    boxes, into = 0, []

    def check(tag: str) -> None:
        nonlocal boxes
        w = env.world
        if w.held is None:
            return
        obj = w.objects[w.held]
        for o in [obj, *w.descendants(obj)]:
            for _, b in visual_boxes(env.client, o.body):
                boxes += 1
                depth = max(-b[:, 0].min(), -b[:, 1].min(), b[:, 0].max() - w.layout.width, b[:, 1].max() - w.layout.depth)
                if depth > 1e-4:
                    into.append({'task': task.task_id, 'step': tag, 'object': o.object_id, 'metres': round(float(depth), 3)})

    env.reset(options={'task': task})
    over = False
    for k, a in enumerate(task.expert_actions):
        _, _, done, truncated, _ = env.step({'action': a.action, 'pixel': (a.x, a.y)} if a.x >= 0 else {'action': a.action})
        check(f'expert {k}')
        over = done or truncated
        if over or (env.world.held is not None and a.action == 'Pickup'):
            break
    moves = ('MoveAhead', 'MoveAhead', 'RotateLeft', 'RotateRight', 'LookDown', 'LookUp')
    for k in range(0 if over else 80):
        _, _, done, truncated, _ = env.step({'action': moves[int(rng.integers(len(moves)))]})
        check(f'wander {k}')
        if done or truncated:
            break
    return boxes, into


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--split', default='valid_seen', help='a shipped split')
    parser.add_argument('--tasks', type=int, default=200, help='the first N tasks of the split')
    parser.add_argument('--seed', type=int, default=0, help='seed of the wandering')
    args = parser.parse_args()
    tasks = load_split(args.split)[:args.tasks]
    env = DialfredEnv(resolution=tasks[0].resolution)
    rng = np.random.default_rng(args.seed)
    t0 = time.monotonic()
    points = boxes = 0
    close, into = [], []
    try:
        for task in tqdm(tasks, unit='task', desc='physics probe'):
            env.reset(options={'task': task})
            n, c = probe_doors(env, task)
            points, close = points + n, close + c
            n, i = probe_held(env, task, rng)
            boxes, into = boxes + n, into + i
    finally:
        env.close()
    print(json.dumps({
        'benchmark': 'physics_probe', 'split': args.split, 'tasks': len(tasks), 'seed': args.seed,
        'seconds': round(time.monotonic() - t0, 1),
        'doors': {'free_points_checked': points, 'closer_than_the_agent_radius': len(close),
                  'closest': sorted(close, key=lambda r: r['metres'])[:10]},
        'held': {'boxes_checked': boxes, 'into_a_wall': len(into),
                 'deepest': sorted(into, key=lambda r: -r['metres'])[:10]},
    }, indent=1))


if __name__ == '__main__':
    main()
