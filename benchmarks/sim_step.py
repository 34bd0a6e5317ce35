#!/usr/bin/env python3
"""Simulator step throughput with rendering vs the bare pybullet render of the same views.

For each resolution: plays a fixed navigation/interaction sequence through DialfredEnv.step and,
right after each step, renders the very same view with a bare `getCameraImage` (same client, same
scene, same arguments). Prints JSON; ratio = bare time / step time (1.0 = no overhead).

    ./dialfred bench sim_step [--steps 300] [--rounds 3] [--scene FloorPlan1]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

from dialfred_sim.env import DialfredEnv
from dialfred_sim.world.camera import LIGHT_DIRECTION

PATTERN = ['MoveAhead', 'MoveAhead', 'RotateLeft', 'LookDown', 'MoveAhead', 'RotateRight', 'LookUp',
           'RotateRight', 'MoveAhead', 'RotateLeft', 'RotateLeft', 'Pickup']


def play(env: DialfredEnv, steps: int, seed: int, scene: str):
    """Paired timings: each env.step, then a bare render of the view that step produced.

    Pairing step by step means load from other processes hits both measurements alike.
    Returns (seconds per step, seconds per bare render).
    """
    c, r = env.client, env.resolution
    proj = env.world.projection
    env.reset(seed=seed, options={'scene': scene})
    t_step = t_bare = 0.0
    for k in range(steps):
        name = PATTERN[k % len(PATTERN)]
        action = {'action': name, 'pixel': (r // 2, r // 2)}
        t0 = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(action)
        t1 = time.perf_counter()
        c.getCameraImage(r, r, env.world.view_matrix(), proj, renderer=c.ER_TINY_RENDERER, shadow=0,
                         lightDirection=LIGHT_DIRECTION)
        t2 = time.perf_counter()
        t_step += t1 - t0
        t_bare += t2 - t1
        if terminated or truncated:
            env.reset(seed=seed + k + 1, options={'scene': scene})
    return t_step / steps, t_bare / steps


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--steps', type=int, default=300)
    ap.add_argument('--rounds', type=int, default=3)
    ap.add_argument('--scene', default='FloorPlan1')
    ap.add_argument('--resolutions', default='128,300')
    args = ap.parse_args()
    results = {}
    for res in (int(r) for r in args.resolutions.split(',')):
        env = DialfredEnv(resolution=res)
        step_times, bare_times = [], []
        for rnd in range(args.rounds):
            st, bt = play(env, args.steps, seed=rnd, scene=args.scene)
            step_times.append(st)
            bare_times.append(bt)
        st, bt = statistics.median(step_times), statistics.median(bare_times)
        results[f'{res}x{res}'] = {
            'step_ms': round(st * 1e3, 3), 'steps_per_s': round(1 / st, 1),
            'bare_render_ms': round(bt * 1e3, 3), 'bare_renders_per_s': round(1 / bt, 1),
            'ratio_bare_over_step': round(bt / st, 3), 'overhead_pct': round((st / bt - 1) * 100, 1),
        }
        env.close()
    print(json.dumps({'benchmark': 'sim_step', 'scene': args.scene, 'steps': args.steps,
                      'rounds': args.rounds, 'results': results}, indent=2))


if __name__ == '__main__':
    main()
