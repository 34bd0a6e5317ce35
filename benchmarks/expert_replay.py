#!/usr/bin/env python3
"""The expert replayed over a whole split through the simulator nodes, as `dialfred_bringup/launch.py eval`
runs it (`--workers` nodes, asynchronous calls from one client), into a fresh results file.

Prints JSON: wall time (start-up included), tasks, episodes/s, simulator steps/s, SR / PWSR / GC and
every expert failure. The goal: all of valid_unseen (1,363 tasks) in at most 300 s on this 2-core CPU.

    ./dialfred bench expert_replay [--split valid_unseen] [--limit N] [--workers 2] [--resolution 128]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path


from dialfred_bringup.evaluation import EvalConfig, run_eval
GOAL_S = 300.0   # whole valid_unseen


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--split', default='valid_unseen')
    parser.add_argument('--limit', type=int, default=None, help='only the first N tasks (default: all)')
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--resolution', type=int, default=128)
    args = parser.parse_args()

    with tempfile.TemporaryDirectory(prefix='dialfred-expert-replay-') as tmp:
        config = EvalConfig(split=args.split, agent='expert', limit=args.limit, workers=args.workers,
                            out=Path(tmp) / 'results.jsonl', seed=0, resolution=args.resolution)
        report = run_eval(config, progress=sys.stderr.isatty())
    results = report.results
    steps = sum(r.steps for r in results)
    loop_s = report.wall_s - report.startup_s
    overall = report.summary['overall']
    print(json.dumps({
        'split': args.split,
        'tasks': len(results),
        'workers': args.workers,
        'resolution': args.resolution,
        'cpus': os.cpu_count(),
        'wall_s': round(report.wall_s, 2),
        'startup_s': round(report.startup_s, 2),
        'episodes_per_s': round(len(results) / loop_s, 2) if loop_s > 0 else None,
        'steps': steps,
        'steps_per_s': round(steps / loop_s, 1) if loop_s > 0 else None,
        'success_rate': round(overall['SR'], 2),
        'path_weighted_success_rate': round(overall['PWSR'], 2),
        'goal_condition_rate': round(overall['GC'], 2),
        'goal_wall_s_full_valid_unseen': GOAL_S,
        'goal_met': (report.wall_s <= GOAL_S) if (args.split, args.limit) == ('valid_unseen', None) else None,
        'failures': [{'task_id': r.task_id, 'task_type': r.task_type, 'end_reason': r.end_reason, 'error': r.error}
                     for r in results if not r.success],
    }, indent=1))


if __name__ == '__main__':
    main()
