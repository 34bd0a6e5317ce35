"""Does performer training give the same numbers in every process? Prints JSON.

Starts `--runs` fresh processes of `python -m dialfred_performer.train` with the same seed and config,
each for `--updates` optimiser updates with one metrics line per update, and compares the runs' loss
streams bit for bit against the first run's. For each run: the first update whose loss differs (null:
none) and the largest relative difference. `--env VAR=VALUE` (repeatable) runs the same processes with
that environment (e.g. `MKL_CBWR=COMPATIBLE`, `MKL_DYNAMIC=FALSE`, `OMP_NUM_THREADS=1`), to tell which
setting removes a difference; `--threads` sets the trainer's torch threads. `--busy N` starts N
busy-looping processes beside every second run (runs 2, 4, ...), so quiet and loaded processes are
compared in one invocation (load is not what makes a process differ: a quiet one did too).
`common_stream_sha256` names the stream most runs gave, so invocations can be compared.

    ./dialfred bench training_determinism [--runs 6] [--updates 60] [--demonstrations DIR] [--env VAR=VALUE]

Defaults train the shipped performer's configuration (2 epochs, 24,000 updates planned, seed 0; the
learning-rate schedule is the full run's) on the train demonstrations in ~/.cache (`./dialfred reproduce`
or `python -m dialfred_performer.prepare` makes them); `--tiny` trains a tiny model instead (seconds).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dialfred_bringup.machine import cpu_model
from dialfred_sim.tasks.demonstrations import default_dir

REPO = Path(__file__).resolve().parents[1]
TINY = ['--d-model', '32', '--heads', '2', '--layers', '1', '--ff', '64', '--batch-size', '4', '--warmup-updates', '5']


def run_once(args, out: Path, env: dict) -> tuple[list[float], float]:
    cmd = [sys.executable, '-m', 'dialfred_performer.train', '--demonstrations', args.demonstrations,
           '--out', str(out), '--epochs', '2', '--max-updates', '24000', '--seed', str(args.seed),
           '--log-every', '1', '--stop-after', str(args.updates), '--threads', str(args.threads), '--no-progress',
           *(TINY if args.tiny else [])]
    t0 = time.monotonic()
    subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    rows = [json.loads(line) for line in (out / 'metrics.jsonl').read_text().splitlines()]
    return [r['loss'] for r in rows if r['kind'] == 'train'], time.monotonic() - t0


BUSY_LOOP = 'while True:\n    sum(range(10000))\n'


def start_busy(count: int) -> list:
    return [subprocess.Popen([sys.executable, '-c', BUSY_LOOP], stdout=subprocess.DEVNULL) for _ in range(count)]


def stop_busy(procs: list) -> None:
    for p in procs:
        p.kill()
    for p in procs:
        p.wait()


def compare(reference: list[float], losses: list[float]) -> dict:
    first = next((k + 1 for k, (a, b) in enumerate(zip(reference, losses)) if a != b), None)
    worst = max((abs(a - b) / max(abs(a), 1e-12) for a, b in zip(reference, losses)), default=0.0)
    return {'first_different_update': first, 'max_relative_difference': worst, 'updates': len(losses)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--runs', type=int, default=6)
    ap.add_argument('--updates', type=int, default=60)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--threads', type=int, default=0, help="trainer's torch threads (0: the cores it may use)")
    ap.add_argument('--demonstrations', default=str(default_dir('train', 64)))
    ap.add_argument('--env', action='append', default=[], metavar='VAR=VALUE')
    ap.add_argument('--busy', type=int, default=0, metavar='N',
                    help='N busy-looping processes beside every second run (0: none)')
    ap.add_argument('--tiny', action='store_true', help='a tiny model (checks the benchmark, says nothing)')
    args = ap.parse_args()
    if args.runs < 2 or args.updates < 1 or args.busy < 0:
        ap.error('--runs must be at least 2, --updates at least 1 and --busy at least 0')
    extra = {}
    for item in args.env:
        name, sep, value = item.partition('=')
        if not sep or not name:
            ap.error(f'--env takes VAR=VALUE, got {item!r}')
        extra[name] = value
    env = {**os.environ, **extra}
    runs, seconds, busy = [], [], []
    with tempfile.TemporaryDirectory(prefix='dialfred_determinism_') as tmp:
        for k in range(args.runs):
            burners = start_busy(args.busy) if k % 2 == 1 else []
            try:
                losses, s = run_once(args, Path(tmp) / f'run{k}', env)
            finally:
                stop_busy(burners)
            runs.append(losses)
            seconds.append(round(s, 1))
            busy.append(len(burners))
            print(f'[determinism] run {k + 1}/{args.runs}: {len(losses)} updates in {s:.1f} s'
                  + (f' ({len(burners)} busy processes beside it)' if burners else ''), file=sys.stderr)
    per_run = [dict(compare(runs[0], r), busy_beside=b) for r, b in zip(runs[1:], busy[1:])]
    streams = [','.join(float(x).hex() for x in r) for r in runs]
    distinct = len(set(streams))
    # Which stream is the common one, comparable across invocations (e.g. with and without an --env setting)
    counts = {h: streams.count(h) for h in streams}
    common = max(counts, key=counts.get)
    print(json.dumps({
        'benchmark': 'training_determinism', 'cpu': cpu_model(), 'runs': args.runs, 'updates': args.updates, 'seed': args.seed,
        'threads': args.threads, 'tiny': args.tiny, 'env': extra, 'busy': args.busy, 'demonstrations': args.demonstrations,
        'identical': distinct == 1, 'distinct_loss_streams': distinct,
        'common_stream_sha256': hashlib.sha256(common.encode()).hexdigest(), 'runs_with_common_stream': counts[common], 'against_run_1': per_run,
        'seconds_per_run': seconds}, indent=1))


if __name__ == '__main__':
    main()
