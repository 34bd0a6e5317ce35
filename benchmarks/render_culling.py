#!/usr/bin/env python3
"""The camera's draw with and without frustum culling (dialfred_sim/world/culling.py). Prints JSON.

Plays the expert of the first `--tasks` tasks of a split at each resolution, twice per task: once with
the culling off, once on (alternating which goes first, so that load from other processes falls on
both alike), timing every `World.render` (the culling's own test included) and comparing the two
passes' frames: colour, depth and segmentation must be equal, pixel for pixel. With `--demos N`, also
renders the first N train tasks as the reproduce's demos stage does (64 px, labels, the oracle's QAs
and the annotators' rows: `prepare-performer --annotate --labels`, one process) with the culling off
and on (DIALFRED_CULLING, alternating rounds), and compares the files they write byte for byte.

    ./dialfred bench render_culling [--split valid_unseen] [--tasks 40] [--resolutions 64 128] [--demos 150]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from dialfred_sim.env import DialfredEnv
from dialfred_sim.tasks import load_split
from dialfred_sim.tasks.demonstrations import play_demonstration


def play(env: DialfredEnv, task, cull: bool) -> tuple[list, list[float], list[int]]:
    """The expert's frames of `task` with the culling on or off: (frames, seconds per render, hidden)."""
    env.world.culling.enabled = cull
    frames, seconds, hidden = [], [], []

    def observe(env: DialfredEnv, k: int) -> None:
        t0 = time.perf_counter()
        frames.append(env.world.render())
        seconds.append(time.perf_counter() - t0)
        hidden.append(len(env.world.culling.hidden))
    r = env.resolution
    play_demonstration(env, task, np.zeros((len(task.expert_actions) + 1, r, r, 3), np.uint8), observe)
    return frames, seconds, hidden


def demos(tasks: int, rounds: int) -> dict:
    """The demos stage's render of the first `tasks` train tasks, culling off and on: CPU seconds of each
    round and whether the two write the same files."""
    seconds: dict[str, list[float]] = {'off': [], 'on': []}
    digests: dict[str, set] = {'off': set(), 'on': set()}
    for r in range(rounds):
        for mode in (('off', 'on') if r % 2 == 0 else ('on', 'off')):
            with tempfile.TemporaryDirectory() as folder:
                env = {**os.environ, 'DIALFRED_CULLING': '1' if mode == 'on' else '0'}
                cmd = [sys.executable, '-m', 'dialfred_performer.prepare', '--split', 'train', '--limit', str(tasks),
                       '--workers', '1', '--annotate', '--labels', '--no-progress', '--out', folder]
                done = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, text=True, check=True)
                report = json.loads(done.stdout.strip().splitlines()[-1])
                seconds[mode].append(report['cpu_seconds']['demonstrations'])
                h = hashlib.sha256()
                for f in sorted(Path(folder).iterdir()):
                    if f.is_file() and f.name != 'meta.json':       # meta.json records the run's wall time
                        h.update(f.name.encode() + f.read_bytes())
                digests[mode].add(h.hexdigest())
    off, on = statistics.median(seconds['off']), statistics.median(seconds['on'])
    return {'tasks': tasks, 'rounds': rounds, 'cpu_s_off': seconds['off'], 'cpu_s_on': seconds['on'],
            'ms_per_task_off': round(1000 * off / tasks, 1), 'ms_per_task_on': round(1000 * on / tasks, 1),
            'speedup': round(off / on, 3), 'same_files': len(digests['off'] | digests['on']) == 1}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--split', default='valid_unseen')
    ap.add_argument('--tasks', type=int, default=40)
    ap.add_argument('--resolutions', type=int, nargs='+', default=[64, 128])
    ap.add_argument('--demos', type=int, default=0, help='also time the demos stage on this many train tasks')
    ap.add_argument('--rounds', type=int, default=2, help='rounds of --demos (each: off and on)')
    args = ap.parse_args()
    tasks = load_split(args.split)[:args.tasks]
    out = {'split': args.split, 'tasks': len(tasks), 'resolutions': {}}
    for res in args.resolutions:
        env = DialfredEnv(resolution=res)
        off, on, hidden, objects = [], [], [], []
        frames = differing = 0
        for k, task in enumerate(tasks):
            order = (False, True) if k % 2 == 0 else (True, False)
            runs = {cull: play(env, task, cull) for cull in order}
            (a, t_off, _), (b, t_on, h) = runs[False], runs[True]
            off += t_off
            on += t_on
            hidden += h
            objects.append(len(env.world.objects))
            frames += len(a)
            differing += sum(not all(np.array_equal(x, y) for x, y in zip(fa, fb)) for fa, fb in zip(a, b))
            differing += abs(len(a) - len(b))
        env.close()
        ms_off, ms_on = 1000 * statistics.fmean(off), 1000 * statistics.fmean(on)
        out['resolutions'][str(res)] = {
            'frames': frames, 'differing_frames': differing,
            'ms_per_render_off': round(ms_off, 3), 'ms_per_render_on': round(ms_on, 3),
            'speedup': round(ms_off / ms_on, 3),
            'hidden_objects_mean': round(statistics.fmean(hidden), 1),
            'objects_mean': round(statistics.fmean(objects), 1)}
    if args.demos:
        out['demos'] = demos(args.demos, args.rounds)
    print(json.dumps(out, indent=1))
    same = all(r['differing_frames'] == 0 for r in out['resolutions'].values())
    return 0 if same and out.get('demos', {}).get('same_files', True) else 1


if __name__ == '__main__':
    raise SystemExit(main())
