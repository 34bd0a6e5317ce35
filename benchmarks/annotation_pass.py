#!/usr/bin/env python3
"""The synthetic annotators' train rows made while the demonstrations are rendered (`prepare --annotate`,
session 13) vs the annotators' own pass that resets every task again (`scripts/annotate_dialogues.py`).
Prints JSON.

`./dialfred reproduce` renders every train task's expert (prepare, 64 px), asks the oracle on the way
(OracleProbe), and before session 13 then reset every task once more for the annotators, whose frame is
the simulator's default 128 px. `AnnotatingProbe` annotates each task at its start inside the render pass,
seeing that start at 128 px through `DialfredEnv.viewed_at`. Session 11 tried the merge at 64 px and got 1
row of 200 different (an appearance colour is sampled from the frame); at the annotators' own resolution the
rows are the same. This times both ways on the first `--limit` tasks of a split in one process, each way
from an empty folder, `--rounds` times interleaved, and compares the rows, dialogues.jsonl and frames.

    ./dialfred bench annotation_pass [--split train] [--limit 200] [--rounds 1]
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.util
import json
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dialfred_sim.machine import cpu_model  # noqa: E402


def load_script():
    spec = importlib.util.spec_from_file_location('annotate_dialogues', REPO / 'scripts' / 'annotate_dialogues.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> None:
    from dialfred_performer.data import probed_annotations
    from dialfred_performer.prepare import PrepareConfig, prepare
    from dialfred_sim.tasks import load_split
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--split', default='train')
    ap.add_argument('--limit', type=int, default=200)
    ap.add_argument('--rounds', type=int, default=1, help='each way timed this many times, interleaved')
    args = ap.parse_args()
    if args.limit < 1 or args.rounds < 1:
        ap.error('--limit and --rounds must be at least 1')
    script = load_script()
    script._init_worker(args.split)                  # the script's own env (the annotators' 128 px)
    ids = [t.task_id for t in load_split(args.split)[:args.limit]]

    def files(out: Path) -> str:
        h = hashlib.sha256()
        for name in ('frames.npy', 'tasks.jsonl', 'dialogues.jsonl'):
            h.update((out / name).read_bytes())
        return h.hexdigest()

    def separate(out: Path):
        prepare(PrepareConfig(split=args.split, limit=args.limit, workers=1, out=str(out), progress=False))
        return files(out), script._annotate_chunk((0, args.limit))

    def one_pass(out: Path):
        prepare(PrepareConfig(split=args.split, limit=args.limit, workers=1, out=str(out), progress=False,
                              annotate=True))
        rows = probed_annotations(out)
        return files(out), [rows[i] for i in ids]

    ways = {'render, then the annotators\' own pass': separate, 'annotated while rendering': one_pass}
    seconds, results = {k: [] for k in ways}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for n, (name, fn) in enumerate(ways.items()):
                t0 = time.perf_counter()
                results[name] = fn(Path(tmp) / f'{r}_{n}')
                seconds[name].append(time.perf_counter() - t0)
    best = {k: min(v) for k, v in seconds.items()}
    (before, (files_a, rows_a)), (now, (files_b, rows_b)) = results.items()
    print(json.dumps({
        'benchmark': 'annotation_pass', 'split': args.split, 'tasks': args.limit, 'rounds': args.rounds,
        'cpu': cpu_model(), 'ms_per_task': {k: round(1000 * v / args.limit, 1) for k, v in best.items()},
        'speedup': round(best[before] / best[now], 3),
        'same_files': files_a == files_b,
        'annotator_rows_differing': sum(a != b for a, b in zip(rows_a, rows_b)) + abs(len(rows_a) - len(rows_b)),
        'situations_differing': sum(a['situation'] != b['situation'] for a, b in zip(rows_a, rows_b))}))


if __name__ == '__main__':
    main()
