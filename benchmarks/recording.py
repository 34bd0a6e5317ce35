"""Cost of `--record`: the same evaluation through the graph without recording and recording raw, PNG
and JPEG frames; wall time, overhead and bag size per episode. Prints JSON.

The shipped performer node plays the first `--limit` valid_unseen tasks with the given questioner
(RunTask goals, `--workers` workers); each setting runs `--rounds` times, interleaved (off, raw, png,
jpeg, off, raw, ...) so that a drift of the machine's speed falls on all of them alike. Every run
plays the same seeded episodes (checked: the results of every run are the same).

    ./dialfred bench recording [--limit 40] [--workers 2] [--rounds 2] [--questioner all] [--resolution 64]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

from dialfred_bringup.evaluation import EvalConfig, run_eval
from dialfred_bringup.graph import use_private_ros_domain

REPO = Path(__file__).resolve().parents[1]
SETTINGS = ('off', 'raw', 'png', 'jpeg')


def folder_bytes(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob('*') if p.is_file())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--limit', type=int, default=40)
    ap.add_argument('--workers', type=int, default=2)
    ap.add_argument('--rounds', type=int, default=2)
    ap.add_argument('--questioner', default='all')
    ap.add_argument('--resolution', type=int, default=64)
    ap.add_argument('--settings', nargs='+', default=list(SETTINGS), choices=SETTINGS)
    args = ap.parse_args()
    use_private_ros_domain()
    walls = {s: [] for s in args.settings}
    sizes, outcomes = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for s in args.settings:
                run = Path(tmp) / f'{s}_{r}'
                config = EvalConfig(split='valid_unseen', performer='et', questioner=args.questioner, limit=args.limit,
                                    workers=args.workers, resolution=args.resolution, out=run / 'results.jsonl',
                                    record=None if s == 'off' else run / 'bags',
                                    record_format='raw' if s == 'off' else s)
                t0 = time.perf_counter()
                report = run_eval(config, progress=False)
                walls[s].append(time.perf_counter() - t0)
                outcomes[(s, r)] = [(x.task_id, x.success, x.steps, x.questions) for x in report.results]
                if s != 'off':
                    bags = list((run / 'bags').iterdir())
                    sizes[s] = {'episodes': len(bags), 'bytes_per_episode': round(folder_bytes(run / 'bags') / len(bags)),
                                'frames': sum(report.results[k].steps + 1 for k in range(len(report.results)))}
                print(f'[recording] round {r + 1} {s}: {walls[s][-1]:.1f} s', file=sys.stderr, flush=True)
    same = len({json.dumps(v) for v in outcomes.values()}) == 1
    base = statistics.median(walls['off']) if 'off' in walls else None
    out = {'tasks': args.limit, 'workers': args.workers, 'rounds': args.rounds, 'questioner': args.questioner,
           'resolution': args.resolution, 'same_episodes_in_every_run': same, 'settings': {}}
    for s in args.settings:
        med = statistics.median(walls[s])
        row = {'wall_s': [round(w, 2) for w in walls[s]], 'median_s': round(med, 2)}
        if base and s != 'off':
            row['overhead_pct'] = round(100 * (med - base) / base, 1)
        if s in sizes:
            row.update(sizes[s])
            row['kB_per_frame'] = round(sizes[s]['bytes_per_episode'] * sizes[s]['episodes'] / sizes[s]['frames'] / 1024, 2)
        out['settings'][s] = row
    print(json.dumps(out, indent=1))


if __name__ == '__main__':
    main()
