#!/usr/bin/env python3
"""Resetting the simulator to a task: each body's createMultiBody link arguments worked out once per
(shape, colour) and kept in the ShapeCache (session 13) vs worked out part by part for every body built.
Prints JSON.

A reset to a task in another room builds about 47 bodies (walls, furniture, small objects), each a
multibody of about 8 visual links. Profiling resets in the order RL samples them (shuffled valid_seen
tasks, so most land in another room than the last) put `build_body` at half a reset, and about 40% of
that in Python working out the same link lists again. This resets one `DialfredEnv` to `--tasks`
shuffled tasks of a split, `--rounds` times each way, interleaved, and checks that both ways give the
same body ids, object poses and first frames (colour and segmentation) (the same pybullet calls with the same arguments;
tests/test_bodies.py compares the arguments).

    ./dialfred bench body_links [--split valid_seen] [--tasks 200] [--rounds 2] [--seed 0]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import random
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def main() -> None:
    from dialfred_sim.env import DialfredEnv
    from dialfred_sim.machine import cpu_model
    from dialfred_sim.tasks import load_split
    from dialfred_sim.world.bodies import ShapeCache, link_arguments
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--split', default='valid_seen')
    ap.add_argument('--tasks', type=int, default=200)
    ap.add_argument('--rounds', type=int, default=2)
    ap.add_argument('--seed', type=int, default=0, help='the shuffle of the tasks')
    args = ap.parse_args()
    if args.tasks < 1 or args.rounds < 1:
        ap.error('--tasks and --rounds must be at least 1')
    tasks = [t.task_id for t in load_split(args.split)]
    random.Random(args.seed).shuffle(tasks)
    tasks = tasks[:args.tasks]
    cached = ShapeCache.links

    def every_time(self, spec, colour):                # the code before session 13: no memory
        return link_arguments(spec, colour, self)

    ways = {'every body': every_time, 'cached': cached}
    env = DialfredEnv(resolution=64)
    for task_id in tasks:                               # rooms' layouts and shapes made once, outside the timing
        env.reset(options={'task_id': task_id})
    seconds, digests = {k: [] for k in ways}, {}
    try:
        for _ in range(args.rounds):
            for name, fn in ways.items():
                ShapeCache.links = fn
                h = hashlib.sha256()
                t0 = time.perf_counter()
                for task_id in tasks:
                    obs, _ = env.reset(options={'task_id': task_id})
                    h.update(obs['rgb'].tobytes() + obs['segmentation'].tobytes())
                    for oid, o in sorted(env.world.objects.items()):
                        h.update(repr((oid, o.body, o.parent, o.surface, tuple(map(float, o.position)))).encode())
                seconds[name].append(time.perf_counter() - t0)
                digests.setdefault(name, set()).add(h.hexdigest())
    finally:
        ShapeCache.links = cached
        env.close()
    ms = {k: round(1000 * min(v) / len(tasks), 2) for k, v in seconds.items()}
    print(json.dumps({
        'benchmark': 'body_links', 'split': args.split, 'tasks': len(tasks), 'rounds': args.rounds,
        'order': f'shuffled (seed {args.seed})', 'cpu': cpu_model(), 'ms_per_reset_best_round': ms,
        'speedup': round(ms['every body'] / ms['cached'], 3),
        'same_bodies_poses_frames': len(digests['every body'] | digests['cached']) == 1,
        'sha256': sorted(digests['cached'])[0]}))


if __name__ == '__main__':
    main()
