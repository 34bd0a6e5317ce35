#!/usr/bin/env python3
"""One evaluation played three ways: locally without ROS (`launch eval --local`, dialfred_bringup/local.py), with the
agent in the launcher's process and simulator / oracle nodes (`--agent et`), and through performer
nodes (`--performer et`, the robotics user's graph). Prints JSON: wall time (start-up included, what a
user waits), episodes per second, and whether every path played the same episodes (every result field
but the wall time).

    ./dialfred bench eval_local [--split valid_unseen] [--limit 200] [--questioner rl-anytime] [--workers 2]
                                [--rounds 1] [--paths local in-process graph]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
import time
from pathlib import Path

from dialfred_bringup.evaluation import EvalConfig, run_eval
from dialfred_bringup.machine import cpu_model

REPO = Path(__file__).resolve().parents[1]

PATHS = {'local': dict(local=True), 'in-process': dict(), 'graph': dict(performer='et')}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--split', default='valid_unseen')
    ap.add_argument('--limit', type=int, default=200)
    ap.add_argument('--questioner', default='rl-anytime', help="a questioner of `launch eval` ('none': no questions)")
    ap.add_argument('--workers', type=int, default=2)
    ap.add_argument('--rounds', type=int, default=1, help='each path timed this many times, interleaved')
    ap.add_argument('--paths', nargs='+', default=list(PATHS), choices=list(PATHS))
    args = ap.parse_args()
    if args.limit < 1 or args.rounds < 1 or args.workers < 1:
        ap.error('--limit, --rounds and --workers must be at least 1')
    questioner = '' if args.questioner == 'none' else args.questioner
    seconds, results, startup = {p: [] for p in args.paths}, {}, {}
    with tempfile.TemporaryDirectory(prefix='eval_local_') as tmp:
        for r in range(args.rounds):
            for path in args.paths:
                config = EvalConfig(split=args.split, agent='et', questioner=questioner, limit=args.limit,
                                    workers=args.workers, resolution=64, out=Path(tmp) / f'{path}_{r}.jsonl',
                                    **PATHS[path])
                t0 = time.perf_counter()
                report = run_eval(config, progress=False)
                seconds[path].append(time.perf_counter() - t0)
                startup[path] = round(report.startup_s, 2)
                results[path] = [dataclasses.replace(x, wall_s=0.0) for x in report.results]
    best = {p: min(v) for p, v in seconds.items()}
    first = results[args.paths[0]]
    out = {'benchmark': 'eval_local', 'split': args.split, 'tasks': args.limit, 'questioner': questioner or None,
           'workers': args.workers, 'rounds': args.rounds, 'cpu': cpu_model(),
           'wall_s_best': {p: round(v, 2) for p, v in best.items()},
           'episodes_per_s': {p: round(args.limit / v, 2) for p, v in best.items()},
           'graph_startup_s': {p: v for p, v in startup.items() if p != 'local'},
           'same_episodes': all(results[p] == first for p in args.paths),
           'SR': round(100.0 * sum(x.success for x in first) / len(first), 2),
           'NQ': round(sum(x.questions for x in first) / len(first), 3)}
    if 'local' in best:
        out['speedup_of_local'] = {p: round(v / best['local'], 2) for p, v in best.items() if p != 'local'}
    print(json.dumps(out, indent=1))


if __name__ == '__main__':
    main()
