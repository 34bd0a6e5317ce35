#!/usr/bin/env python3
"""Preparing the performer's data: the dialogues' oracle QAs asked while the demonstrations are rendered
(`dialfred_performer.data.OracleProbe`, session 13) vs a second pass that resets every task again and
replays its expert to the middle step (`write_dialogues` alone, as before). Prints JSON.

`./dialfred prepare-performer` renders every train task's expert (frames.npy, tasks.jsonl), then asks
the oracle at step 0 and at the middle step of each; the second pass cost as much again as the
render pass's reset and half its replay. This prepares the first `--limit` tasks of a split into
fresh folders both ways, `--rounds` times, interleaved, and checks that both ways write the same
frames.npy, tasks.jsonl and dialogues.jsonl.

    ./dialfred bench oracle_probe [--split train] [--limit 300] [--workers 1] [--rounds 2]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def main() -> None:
    from dialfred_performer import prepare as prep
    from dialfred_sim.machine import cpu_model
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--split', default='train')
    ap.add_argument('--limit', type=int, default=300)
    ap.add_argument('--workers', type=int, default=1)
    ap.add_argument('--rounds', type=int, default=2)
    args = ap.parse_args()
    if min(args.limit, args.workers, args.rounds) < 1:
        ap.error('--limit, --workers and --rounds must be at least 1')
    probe = prep.ORACLE_PROBE
    ways = {'render, then replay for the QAs': '', 'QAs asked while rendering': probe}
    seconds, stages, digests = {k: [] for k in ways}, {}, {}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for r in range(args.rounds):
                for name, way in ways.items():
                    prep.ORACLE_PROBE = way
                    out = Path(tmp) / f'{r}_{bool(way)}'
                    t0 = time.perf_counter()
                    report = prep.prepare(prep.PrepareConfig(split=args.split, resolution=64, workers=args.workers,
                                                             limit=args.limit, out=str(out), progress=False))
                    seconds[name].append(time.perf_counter() - t0)
                    stages.setdefault(name, []).append(report['seconds'])
                    h = hashlib.sha256()
                    for f in ('frames.npy', 'tasks.jsonl', 'dialogues.jsonl'):
                        h.update((out / f).read_bytes())
                    digests.setdefault(name, set()).add(h.hexdigest())
    finally:
        prep.ORACLE_PROBE = probe
    best = {k: min(v) for k, v in seconds.items()}
    before, now = ways
    print(json.dumps({
        'benchmark': 'oracle_probe', 'split': args.split, 'tasks': args.limit, 'workers': args.workers,
        'rounds': args.rounds, 'cpu': cpu_model(),
        'ms_per_task_best_round': {k: round(1000 * v / args.limit, 1) for k, v in best.items()},
        'stage_seconds': stages, 'speedup': round(best[before] / best[now], 3),
        'same_files': len(digests[before] | digests[now]) == 1, 'sha256': sorted(digests[now])[0]}))


if __name__ == '__main__':
    main()
