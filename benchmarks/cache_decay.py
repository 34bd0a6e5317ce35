#!/usr/bin/env python3
"""How fast this machine's CPU caches go cold while a process waits: no ROS, no simulator.

Reads a working set (2 MB by default, about what one ROS service round trip of a 300x300 observation
touches: interpreter, rclpy, Fast DDS, the message), waits W ms, and times reading it again. The wait
is either a busy loop that touches almost no memory (a process computing elsewhere, as the simulator
node does while it renders) or a sleep (a client waiting for a reply). On a machine of its own the
re-read stays as fast as at W = 0; when it slows with W, something outside this process (other
tenants of the host, the hypervisor) evicts the caches meanwhile. That is the part of a service
round trip's latency no code here can remove; `ros_step` reports the rest. Prints JSON.

    ./dialfred bench cache_decay [--working-set-mb 2] [--reps 50]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

WAITS_MS = (0, 1, 3, 10, 30, 100)


def busy_wait(seconds: float) -> None:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        pass


def reread_us(data: np.ndarray, wait_ms: float, reps: int, sleep: bool) -> float:
    """Median microseconds to read `data` again after reading it, then waiting `wait_ms`."""
    wait = time.sleep if sleep else busy_wait
    times = []
    for _ in range(reps):
        data.sum()
        if wait_ms:
            wait(wait_ms / 1e3)
        t = time.perf_counter()
        data.sum()
        times.append(time.perf_counter() - t)
    return round(statistics.median(times) * 1e6, 1)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--working-set-mb', type=float, default=2.0)
    ap.add_argument('--reps', type=int, default=50)
    args = ap.parse_args()
    if args.reps < 1 or args.working_set_mb <= 0:
        ap.error('--reps must be >= 1 and --working-set-mb > 0')
    data = np.ones(int(args.working_set_mb * 2**20) // 8, dtype=np.float64)
    rows = {}
    for w in WAITS_MS:
        rows[f'{w}ms'] = {'busy_wait_us': reread_us(data, w, args.reps, sleep=False),
                          'sleep_us': reread_us(data, w, args.reps, sleep=True)}
    hot = rows['0ms']['busy_wait_us']
    report = {'benchmark': 'cache_decay', 'working_set_mb': args.working_set_mb, 'reps': args.reps,
              'reread_after_wait': rows,
              'slowdown_after_30ms_busy': round(rows['30ms']['busy_wait_us'] / hot, 2),
              'slowdown_after_30ms_sleep': round(rows['30ms']['sleep_us'] / hot, 2)}
    print(json.dumps(report, indent=2))


if __name__ == '__main__':
    main()
