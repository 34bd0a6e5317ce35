"""Evaluation throughput against workers on this machine, and what a 1,000-task evaluation costs on N
machines (docs/scaling.md).

For each --workers W, a fresh `./dialfred launch eval` (a process of its own, in a ROS domain of its
own, its results in a temporary folder) plays the first --limit tasks of --split, --repeats times; its
summary gives the start-up (nodes started and answering) and the episode loop's time. Printed as JSON:
per W, the loop's episodes/s, seconds per task, start-up and speed-up over the first W; then, with the
W of the highest throughput, the estimated wall time and machine-hours of --cost-tasks tasks on each
of --machines hosts like this one, each playing one shard (`launch eval --shard K/N`, then
`./dialfred merge`): start-up + ceil(tasks / N) x seconds per task. Draws --plot (default
docs/scaling.png; '' for none).

    ./dialfred bench bench_scaling --workers 1 2 3 --limit 60 --agent expert
    ./dialfred bench bench_scaling --workers 1 2 3 --limit 12 --performer et --questioner all

Per-task time depends on the agent: the expert's tasks are a few steps; a weak agent's run to 10
failed actions or the step limit. A small --limit leaves workers idle at the end (the last episodes
run alone), so it understates the throughput of many workers.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dialfred_performer.curves import draw_series

REPO = Path(__file__).resolve().parents[1]


def run_once(args, workers: int, out: Path) -> dict:
    """One evaluation with `workers` workers in a process of its own: its summary's `this_run`."""
    cmd = [sys.executable, '-m', 'dialfred_bringup.launch', 'eval', '--split', args.split, '--agent', args.agent,
           '--limit', str(args.limit), '--workers', str(workers), '--resolution', str(args.resolution),
           '--seed', str(args.seed), '--out', str(out), '--no-progress']
    if args.performer:
        cmd += ['--performer', args.performer]
    if args.questioner:
        cmd += ['--questioner', args.questioner]
    t0 = time.monotonic()
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f'eval with {workers} workers failed ({proc.returncode}):\n{proc.stdout[-2000:]}'
                           f'{proc.stderr[-2000:]}')
    run = json.loads(out.with_suffix('.summary.json').read_text())
    info = run['this_run']
    loop_s = info['wall_s'] - info['startup_s']
    return {'episodes': info['episodes'], 'startup_s': info['startup_s'], 'loop_s': round(loop_s, 3),
            'wall_s': info['wall_s'], 'process_s': round(time.monotonic() - t0, 3),
            'episodes_per_s': round(info['episodes'] / loop_s, 4) if loop_s > 0 else None,
            'success_rate': run['summary']['overall']['SR']}


def measure(args) -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory(prefix='bench_scaling_') as tmp:
        for w in args.workers:
            runs = [run_once(args, w, Path(tmp) / f'w{w}_r{r}.jsonl') for r in range(args.repeats)]
            rate = statistics.median(r['episodes_per_s'] for r in runs)
            rows.append({'workers': w, 'episodes': runs[0]['episodes'], 'episodes_per_s': round(rate, 4),
                         's_per_task': round(1.0 / rate, 4),
                         'startup_s': round(statistics.median(r['startup_s'] for r in runs), 3), 'runs': runs})
    base = rows[0]
    for row in rows:
        row['speedup'] = round(row['episodes_per_s'] / base['episodes_per_s'], 3)
        row['efficiency_per_worker'] = round(row['speedup'] * base['workers'] / row['workers'], 3)
    return rows


def cost_table(best: dict, tasks: int, machines: list[int]) -> list[dict]:
    """Wall time and machine-hours of `tasks` tasks on N machines like this one, one shard each, each
    running `best['workers']` workers (interleaved shards: alike tasks, sizes within 1)."""
    table = []
    for n in machines:
        per_machine = math.ceil(tasks / n)
        wall = best['startup_s'] + per_machine * best['s_per_task']
        table.append({'machines': n, 'tasks_per_machine': per_machine, 'wall_min': round(wall / 60, 2),
                      'machine_hours': round(n * wall / 3600, 3)})
    return table


def plot(rows: list[dict], table: list[dict], tasks: int, path: Path) -> Path:
    first = rows[0]
    points = [{'x': r['workers'], 'measured': r['episodes_per_s'],
               'linear': first['episodes_per_s'] * r['workers'] / first['workers']} for r in rows]
    points += [{'x': t['machines'], 'wall_min': t['wall_min']} for t in table]
    panels = (('episodes/s by workers, this machine',
               (('measured', 'measured', (31, 119, 180)), ('linear', f'linear from {first["workers"]}', (160, 160, 160))),
               None),
              (f'{tasks:,} tasks: wall minutes by machines',
               (('wall_min', 'estimated (one shard each)', (255, 127, 14)),), None))
    path.parent.mkdir(parents=True, exist_ok=True)
    return draw_series(points, panels, path, x_key='x', x_label='x: workers | machines')


def positive_ints(ap: argparse.ArgumentParser, values, name: str) -> None:
    if not values or any(v < 1 for v in values):
        ap.error(f'{name} must be integers >= 1, got {values}')      # exit status 2


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument('--workers', type=int, nargs='+', default=[1, 2, 3], help='worker counts to measure')
    ap.add_argument('--limit', type=int, default=40, help='tasks per run (the first of --split)')
    ap.add_argument('--repeats', type=int, default=1, help='runs per worker count (the median is reported)')
    ap.add_argument('--split', default='valid_unseen')
    ap.add_argument('--agent', default='expert')
    ap.add_argument('--performer', default=None, choices=['et'], help='the performer node plays (RunTask goals)')
    ap.add_argument('--questioner', default=None)
    ap.add_argument('--resolution', type=int, default=128)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--cost-tasks', type=int, default=1000, help='the evaluation whose cost is estimated')
    ap.add_argument('--machines', type=int, nargs='+', default=[1, 2, 4, 8, 16])
    ap.add_argument('--plot', default=str(REPO / 'docs' / 'scaling.png'), help="PNG to draw ('' for none)")
    args = ap.parse_args(argv)
    positive_ints(ap, args.workers, '--workers')
    positive_ints(ap, [args.limit, args.repeats, args.cost_tasks], '--limit, --repeats and --cost-tasks')
    positive_ints(ap, args.machines, '--machines')
    load_before = os.getloadavg()
    t0 = time.monotonic()
    try:
        rows = measure(args)
    except RuntimeError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
    best = max(rows, key=lambda r: r['episodes_per_s'])
    table = cost_table(best, args.cost_tasks, sorted(set(args.machines)))
    report = {
        'split': args.split, 'agent': args.agent, 'performer': args.performer, 'questioner': args.questioner,
        'resolution': args.resolution, 'limit': args.limit, 'repeats': args.repeats,
        'cores': len(os.sched_getaffinity(0)), 'load_average_before': [round(x, 2) for x in load_before],
        'load_average_after': [round(x, 2) for x in os.getloadavg()], 'seconds': round(time.monotonic() - t0, 1),
        'by_workers': rows,
        'cost': {'tasks': args.cost_tasks, 'workers_per_machine': best['workers'],
                 'model': 'startup_s + ceil(tasks / machines) * s_per_task, with the fastest worker count; '
                          'machines like this one, one shard each, merge time left out',
                 'table': table},
    }
    if args.plot:
        report['plot'] = str(plot(rows, table, args.cost_tasks, Path(args.plot)))
    print(json.dumps(report, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
