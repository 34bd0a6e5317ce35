#!/usr/bin/env python3
"""What replaying silent episodes saves an evaluation (dialfred_bringup/silent.py): the performer alone is
played once with its episodes kept; then one questioner's setting is played twice, every episode played,
and with each episode in which the questioner asks nothing taken from the kept ones. Prints JSON: the wall
times, how many episodes were replayed, and whether both ways gave the same episodes (every result field
but the wall time).

    ./dialfred bench silent_replay [--split valid_unseen] [--limit 300] [--questioner rl-anytime] [--workers 2]

`./dialfred reproduce` evaluates its no-question settings first and replays in the others (the eval stage).
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
from dialfred_bringup.reproduce.plan import camera


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--split', default='valid_unseen')
    ap.add_argument('--limit', type=int, default=300)
    ap.add_argument('--questioner', default='rl-anytime', help="a questioner of `launch eval` (not 'none')")
    ap.add_argument('--agent', default='et', help='the performer model (et or map)')
    ap.add_argument('--workers', type=int, default=2)
    args = ap.parse_args()
    if args.limit < 1 or args.workers < 1 or args.questioner in ('', 'none'):
        ap.error('--limit and --workers must be at least 1, and --questioner must name a questioner')
    base = dict(split=args.split, agent=args.agent, limit=args.limit, workers=args.workers, local=True,
                resolution=camera(args.agent))
    seconds, reports = {}, {}
    with tempfile.TemporaryDirectory(prefix='silent_replay_') as tmp:
        folder = Path(tmp) / 'silent'
        plan = {'alone_recorded': (dict(), ('record', folder)),
                'questioner_played': (dict(questioner=args.questioner), None),
                'questioner_replayed': (dict(questioner=args.questioner), ('replay', folder))}
        for name, (extra, silent) in plan.items():
            t0 = time.perf_counter()
            reports[name] = run_eval(EvalConfig(**base, **extra, out=Path(tmp) / f'{name}.jsonl'), progress=False,
                                     silent=silent)
            seconds[name] = time.perf_counter() - t0
    played, replayed = (reports[k].results for k in ('questioner_played', 'questioner_replayed'))
    same = [dataclasses.replace(r, wall_s=0.0) for r in played] == [dataclasses.replace(r, wall_s=0.0) for r in replayed]
    print(json.dumps({
        'benchmark': 'silent_replay', 'split': args.split, 'agent': args.agent, 'tasks': args.limit,
        'questioner': args.questioner, 'workers': args.workers, 'cpu': cpu_model(),
        'wall_s': {k: round(v, 2) for k, v in seconds.items()},
        'silent_episodes': sum(not r.questions for r in played),
        'replayed': reports['questioner_replayed'].replayed,
        'speedup_of_replay': round(seconds['questioner_played'] / seconds['questioner_replayed'], 2),
        'same_episodes': same,
        'SR': round(100.0 * sum(r.success for r in played) / len(played), 2),
        'NQ': round(sum(r.questions for r in played) / len(played), 3)}, indent=1))


if __name__ == '__main__':
    main()
