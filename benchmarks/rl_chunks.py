#!/usr/bin/env python3
"""RL fine-tuning's rollouts: episodes handed to the workers in small chunks as they free up (session 13)
vs one fixed share per worker. Prints JSON.

Each actor-critic update plays `--episodes` episodes with the current weights, then learns. With one
share per worker, the update waited for the worker whose share held the longest episodes while the
other sat idle. This fine-tunes RL anytime (gap 5) from the shipped pre-trained questioner against the
shipped performer on valid_seen for `--updates` updates, both ways, `--rounds` times, interleaved, and
checks that both ways end with the same weights (an episode depends only on its task, seeds and the
weights; tests/test_questioner_finetune.py checks one worker against two).

    ./dialfred bench rl_chunks [--updates 6] [--episodes 64] [--workers 2] [--rounds 2]
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
    import torch

    from dialfred_questioner import finetune as ft
    from dialfred_sim.machine import cpu_model
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--updates', type=int, default=6)
    ap.add_argument('--episodes', type=int, default=64, help='episodes per update')
    ap.add_argument('--workers', type=int, default=2)
    ap.add_argument('--rounds', type=int, default=2)
    args = ap.parse_args()
    if min(args.updates, args.episodes, args.workers, args.rounds) < 1:
        ap.error('--updates, --episodes, --workers and --rounds must be at least 1')
    chunked = ft.rollout_chunks

    def one_share_each(jobs, workers):                 # before session 13
        return [jobs[w::workers] for w in range(workers) if jobs[w::workers]]

    ways = {'one share per worker': one_share_each, 'chunks': chunked}
    seconds, digests = {k: [] for k in ways}, {}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for r in range(args.rounds):
                for name, fn in ways.items():
                    ft.rollout_chunks = fn
                    out = Path(tmp) / f'{r}_{len(seconds[name])}_{name.replace(" ", "_")}'
                    t0 = time.perf_counter()
                    ft.finetune(ft.FinetuneConfig(split='valid_seen', out=str(out), timing='anytime', gap=5,
                                                  updates=args.updates, episodes_per_update=args.episodes,
                                                  workers=args.workers, progress=False))
                    seconds[name].append(time.perf_counter() - t0)
                    state = torch.load(out / 'final.pt', weights_only=False)['state_dict']
                    h = hashlib.sha256()
                    for k in sorted(state):
                        h.update(k.encode() + state[k].numpy().tobytes())
                    digests.setdefault(name, set()).add(h.hexdigest())
    finally:
        ft.rollout_chunks = chunked
    s = {k: round(min(v), 2) for k, v in seconds.items()}
    print(json.dumps({
        'benchmark': 'rl_chunks', 'updates': args.updates, 'episodes_per_update': args.episodes,
        'workers': args.workers, 'rounds': args.rounds, 'cpu': cpu_model(),
        'seconds_best_round': s, 'all_seconds': {k: [round(x, 2) for x in v] for k, v in seconds.items()},
        'speedup': round(s['one share per worker'] / s['chunks'], 3),
        'same_weights': len(digests['one share per worker'] | digests['chunks']) == 1}))


if __name__ == '__main__':
    main()
