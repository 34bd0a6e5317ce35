#!/usr/bin/env python3
"""What the chained protocol costs against the expert protocol: the same first N tasks of a split played both
ways (`launch eval --local --protocol expert|chained`), for each agent, interleaved in one run. Prints JSON:
wall seconds per task and per action (start-up included), actions per task, SR, and the ratio chained /
expert of each. A chained task saves the reset (the room rebuilt, the expert's actions replayed) of every task
after an episode's first; it may take more actions, since success no longer ends it and the agent must Stop.

    ./dialfred bench chained_cost [--split valid_unseen] [--limit 200] [--agents expert et map] [--workers 2]
                                  [--rounds 1]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from dialfred_bringup.evaluation import EvalConfig, run_eval
from dialfred_bringup.machine import cpu_model

PROTOCOLS = ('expert', 'chained')


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--split', default='valid_unseen')
    ap.add_argument('--limit', type=int, default=200)
    ap.add_argument('--agents', nargs='+', default=['expert', 'et', 'map'])
    ap.add_argument('--workers', type=int, default=2)
    ap.add_argument('--rounds', type=int, default=1, help='each setting timed this many times, interleaved')
    args = ap.parse_args()
    if args.limit < 1 or args.rounds < 1 or args.workers < 1:
        ap.error('--limit, --rounds and --workers must be at least 1')
    seconds = {(a, p): [] for a in args.agents for p in PROTOCOLS}
    outcome = {}
    with tempfile.TemporaryDirectory(prefix='chained_cost_') as tmp:
        for r in range(args.rounds):
            for agent in args.agents:
                for protocol in PROTOCOLS:
                    config = EvalConfig(split=args.split, agent=agent, limit=args.limit, workers=args.workers,
                                        local=True, protocol=protocol, out=Path(tmp) / f'{agent}_{protocol}_{r}.jsonl')
                    t0 = time.perf_counter()
                    report = run_eval(config, progress=False)
                    seconds[agent, protocol].append(time.perf_counter() - t0)
                    steps = sum(x.steps for x in report.results)
                    outcome[agent, protocol] = {'tasks': len(report.results), 'actions': steps,
                                                'SR': round(report.summary['overall']['SR'], 2)}
    rows = {}
    for agent in args.agents:
        row = {}
        for protocol in PROTOCOLS:
            best, o = min(seconds[agent, protocol]), outcome[agent, protocol]
            row[protocol] = {'wall_s': round(best, 2), 's_per_task': round(best / o['tasks'], 4),
                             'ms_per_action': round(1000 * best / max(1, o['actions']), 3),
                             'actions_per_task': round(o['actions'] / o['tasks'], 2), 'SR': o['SR']}
        row['ratio_chained_over_expert'] = {
            k: round(row['chained'][k] / row['expert'][k], 3) if row['expert'][k] else None
            for k in ('s_per_task', 'ms_per_action', 'actions_per_task')}
        rows[agent] = row
    print(json.dumps({'benchmark': 'chained_cost', 'split': args.split, 'tasks': args.limit, 'workers': args.workers,
                      'rounds': args.rounds, 'cpu': cpu_model(), 'agents': rows}, indent=1))


if __name__ == '__main__':
    main()
