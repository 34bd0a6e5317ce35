#!/usr/bin/env python3
"""Resetting the simulator to a task: World._free_spots vectorised (session 12) vs the point-by-point loop it
replaced. Prints JSON.

A reset rebuilds the room and scatters its small objects; each placement asks `_free_spots` for every
grid point of every surface whether it overlaps what is there. Profiling an RL rollout (session 12)
found resets at about 40% of an episode's time and this loop at a third of a reset. This resets one
`DialfredEnv` to the first `--tasks` tasks of a split, `--rounds` times each way, interleaved, and
checks that both ways scatter every object to the same pose (the numpy version does the same float64
operations; tests/test_scene_spots.py compares them spot by spot).

    ./dialfred bench free_spots [--split valid_seen] [--tasks 100] [--rounds 2]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dialfred_sim.world.scene import _to_local  # noqa: E402


def reference_free_spots(world, receptacle, obj, surface_index: int):
    """The point-by-point loop of sessions 1-11 (World._free_spots before session 12), the reference."""
    surf = receptacle.spec.surfaces[surface_index]
    hx, hy = obj.spec.size[0] / 2, obj.spec.size[1] / 2
    if obj.spec.size[2] > surf.clearance + 1e-6:
        return []
    if hx > surf.half_size[0] + 1e-6 or hy > surf.half_size[1] + 1e-6:
        named = obj.type_name in receptacle.otype.accepts
        if surf.inside or not named and (hx > surf.half_size[0] * 1.6 + 0.02 or hy > surf.half_size[1] * 1.6 + 0.02):
            return []
    taken = []
    for cid in receptacle.contents:
        other = world.objects[cid]
        if other.fixture or other.surface != surface_index or cid == obj.object_id:
            continue
        ox, oy = other.spec.size[0] / 2, other.spec.size[1] / 2
        taken.append((other.local[0] - ox, other.local[1] - oy, other.local[0] + ox, other.local[1] + oy))
    for cid in receptacle.contents:
        other = world.objects[cid]
        if other.fixture:
            rel = _to_local(receptacle.position, receptacle.yaw, other.position)
            ox, oy = other.spec.size[0] / 2, other.spec.size[1] / 2
            taken.append((rel[0] - ox, rel[1] - oy, rel[0] + ox, rel[1] + oy))
    ax = max(surf.half_size[0] - hx, 0.0)
    ay = max(surf.half_size[1] - hy, 0.0)
    xs = np.arange(-ax, ax + 1e-9, 0.04) if ax > 0 else np.array([0.0])
    ys = np.arange(-ay, ay + 1e-9, 0.04) if ay > 0 else np.array([0.0])
    spots = []
    for x in xs:
        for y in ys:
            cx, cy = surf.center[0] + x, surf.center[1] + y
            rect = (cx - hx, cy - hy, cx + hx, cy + hy)
            if not any(rect[0] < t[2] + 0.01 and t[0] < rect[2] + 0.01 and
                       rect[1] < t[3] + 0.01 and t[1] < rect[3] + 0.01 for t in taken):
                spots.append((float(cx), float(cy)))
    return spots


def main() -> None:
    from dialfred_sim.env import DialfredEnv
    from dialfred_sim.machine import cpu_model
    from dialfred_sim.tasks import load_split
    from dialfred_sim.world.scene import World
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--split', default='valid_seen')
    ap.add_argument('--tasks', type=int, default=100)
    ap.add_argument('--rounds', type=int, default=2)
    args = ap.parse_args()
    if args.tasks < 1 or args.rounds < 1:
        ap.error('--tasks and --rounds must be at least 1')
    tasks = [t.task_id for t in load_split(args.split)[:args.tasks]]
    env = DialfredEnv(resolution=64)
    env.reset(options={'task_id': tasks[0]})
    vectorised = World._free_spots
    ways = {'loop': reference_free_spots, 'numpy': vectorised}
    seconds, digests = {k: [] for k in ways}, {}
    try:
        for _ in range(args.rounds):
            for name, fn in ways.items():
                World._free_spots = fn
                h = hashlib.sha256()
                t0 = time.perf_counter()
                for task_id in tasks:
                    env.reset(options={'task_id': task_id})
                    for oid, o in sorted(env.world.objects.items()):
                        h.update(repr((oid, o.parent, o.surface, o.local, tuple(map(float, o.position)))).encode())
                seconds[name].append(time.perf_counter() - t0)
                digests.setdefault(name, set()).add(h.hexdigest())
    finally:
        World._free_spots = vectorised
        env.close()
    ms = {k: round(1000 * min(v) / len(tasks), 2) for k, v in seconds.items()}
    print(json.dumps({
        'benchmark': 'free_spots', 'split': args.split, 'tasks': len(tasks), 'rounds': args.rounds,
        'cpu': cpu_model(), 'ms_per_reset_best_round': ms,
        'speedup': round(ms['loop'] / ms['numpy'], 3),
        'same_poses': len(digests['loop'] | digests['numpy']) == 1,
        'poses_sha256': sorted(digests['numpy'])[0]}))


if __name__ == '__main__':
    main()
