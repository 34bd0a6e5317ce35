#!/usr/bin/env python3
"""Memory growth of a long-lived simulator over many task resets, with and without client recycling.

pybullet 3.2.7 keeps about 0.5 KB for every body made and removed and frees it only with its client;
`DialfredEnv` therefore moves its world to a fresh client every `CLIENT_RECYCLE_BUILDS` rooms. This
resets one `DialfredEnv` to the first `--tasks` tasks of a split, one after another, in a child
process, once as shipped and once with recycling switched off. It reports the resident memory (VmRSS)
growth per reset over the first and the second half of the run. Prints JSON.

    ./dialfred bench reset_memory [--split train] [--tasks 1000]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import dialfred_sim.env as env_module
from dialfred_sim.tasks.splits import load_split


def rss_mb() -> float:
    for line in Path('/proc/self/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024
    return float('nan')


def measure(split: str, n: int, recycle: bool) -> dict:
    if not recycle:
        env_module.CLIENT_RECYCLE_BUILDS = 10 ** 9
    task_ids = [t.task_id for t in load_split(split)[:n]]
    env = env_module.DialfredEnv()
    env.reset(options={'task_id': task_ids[0]})
    start, t0 = rss_mb(), time.perf_counter()
    half = len(task_ids) // 2
    for k, task_id in enumerate(task_ids):
        env.reset(options={'task_id': task_id})
        if k + 1 == half:
            middle = rss_mb()
    end = rss_mb()
    env.close()
    return {'recycle_every': env_module.CLIENT_RECYCLE_BUILDS if recycle else None, 'resets': len(task_ids),
            'seconds': round(time.perf_counter() - t0, 1), 'rss_start_mb': round(start, 1),
            'rss_end_mb': round(end, 1),
            'mb_per_reset_first_half': round((middle - start) / half, 4),
            'mb_per_reset_second_half': round((end - middle) / (len(task_ids) - half), 4)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--split', default='train')
    ap.add_argument('--tasks', type=int, default=1000)
    ap.add_argument('--child', choices=['recycle', 'no-recycle'], help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.tasks < 2:
        ap.error('--tasks must be at least 2 (growth is reported per half)')
    if args.child:
        print(json.dumps(measure(args.split, args.tasks, args.child == 'recycle')))
        return
    report = {'benchmark': 'reset_memory', 'split': args.split, 'tasks': args.tasks}
    for label in ('recycle', 'no-recycle'):
        out = subprocess.run([sys.executable, __file__, '--split', args.split, '--tasks', str(args.tasks),
                              '--child', label], capture_output=True, text=True, check=True).stdout
        report[label.replace('-', '_')] = json.loads(out[out.index('{'):])
    print(json.dumps(report, indent=2))


if __name__ == '__main__':
    main()
