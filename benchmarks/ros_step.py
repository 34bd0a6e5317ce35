#!/usr/bin/env python3
"""`/sim/step` round trip through ROS between two processes vs the same step in-process.

Starts the real `dialfred_sim node` executable (as `ros2 run` would), plays a fixed action sequence
through `/sim/step` from this process, then plays the same sequence on an in-process DialfredEnv.
Also reads the node's peak resident memory (VmHWM). Prints JSON.

    ./dialfred bench ros_step [--resolution 300] [--steps 300]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dialfred_launch import Graph, sim_node  # noqa: E402

PATTERN = ['MoveAhead', 'RotateLeft', 'LookDown', 'MoveAhead', 'RotateRight', 'LookUp', 'RotateRight',
           'MoveAhead', 'RotateLeft', 'RotateLeft', 'Pickup']


def peak_rss_mb(pid: int) -> float:
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmHWM:'):
            return int(line.split()[1]) / 1024
    return float('nan')


def ros_times(resolution: int, steps: int, scene: str, seed: int):
    from dialfred_msgs.msg import Action
    from dialfred_msgs.srv import SimReset, SimStep
    node = sim_node(resolution)
    with Graph([node]) as graph:
        reset_cli = graph.client(SimReset, '/sim/reset')
        step_cli = graph.client(SimStep, '/sim/step')
        graph.call(reset_cli, SimReset.Request(scene=scene, seed=seed))
        times = []
        c = resolution // 2
        for k in range(steps):
            req = SimStep.Request(action=Action(action=PATTERN[k % len(PATTERN)], x=c, y=c))
            t0 = time.perf_counter()
            reply = graph.call(step_cli, req)
            times.append(time.perf_counter() - t0)
            if not reply.ok:
                raise RuntimeError(reply.error)
            if reply.terminated or reply.truncated:
                graph.call(reset_cli, SimReset.Request(scene=scene, seed=seed + k + 1))
        rss = peak_rss_mb(node.proc.pid)
    return times, rss


def inprocess_times(resolution: int, steps: int, scene: str, seed: int):
    from dialfred_sim.env import DialfredEnv
    env = DialfredEnv(resolution=resolution)
    env.reset(seed=seed, options={'scene': scene})
    times = []
    c = resolution // 2
    for k in range(steps):
        t0 = time.perf_counter()
        _, _, term, trunc, _ = env.step({'action': PATTERN[k % len(PATTERN)], 'pixel': (c, c)})
        times.append(time.perf_counter() - t0)
        if term or trunc:
            env.reset(seed=seed + k + 1, options={'scene': scene})
    env.close()
    return times


def summary(times):
    ms = sorted(t * 1e3 for t in times)
    return {'median_ms': round(statistics.median(ms), 3), 'mean_ms': round(statistics.fmean(ms), 3),
            'p90_ms': round(ms[int(0.9 * (len(ms) - 1))], 3)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--resolution', type=int, default=300)
    ap.add_argument('--steps', type=int, default=300)
    ap.add_argument('--scene', default='FloorPlan1')
    ap.add_argument('--seed', type=int, default=0)
    args = ap.parse_args()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    ros, rss = ros_times(args.resolution, args.steps, args.scene, args.seed)
    local = inprocess_times(args.resolution, args.steps, args.scene, args.seed)
    r, l = summary(ros), summary(local)
    print(json.dumps({
        'benchmark': 'ros_step', 'resolution': args.resolution, 'steps': args.steps, 'scene': args.scene,
        'ros_round_trip': r, 'in_process': l,
        'added_by_ros_median_ms': round(r['median_ms'] - l['median_ms'], 3),
        'added_by_ros_mean_ms': round(r['mean_ms'] - l['mean_ms'], 3),
        'sim_node_peak_rss_mb': round(rss, 1),
    }, indent=2))


if __name__ == '__main__':
    main()
