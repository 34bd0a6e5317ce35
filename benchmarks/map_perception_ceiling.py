"""How much better the map performer would do if it saw perfectly: the same agent, the same tasks and
the same answers, once with its perception network (RGB only, as evaluated) and once reading the
simulator's own labels (each cell's class from the segmentation, its depth from the depth image: a
privileged reference, never a benchmark result). Each sight plays the tasks instruction only and with
All QAs, so the run tells what a question is worth under each: whether the map, the plan and the use of
answers are what holds the agent back, or what it sees.

Prints JSON: SR, PWSR, NQ and end reasons per setting, SR per task type, and the SR points a question
buys under each sight. The network's rows are the episodes of `./dialfred launch eval --agent map
--local [--questioner all] --shard K/N` (the same seeds). Results files go to --out as episodes end;
a run cut off goes on where it stopped.

    ./dialfred bench map_perception_ceiling [--shard 0/4] [--limit N] [--workers 2] [--out DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from dialfred_bringup.evaluation import EvalConfig, EvalRun
from dialfred_bringup.local import play_episode
from dialfred_bringup.shards import parse_shard
from dialfred_performer.mapper.agent import MapAgent
from dialfred_performer.model import SHIPPED_CHECKPOINT
from dialfred_questioner.baselines import with_questioner
from dialfred_questioner.questioners import make_questioner
from dialfred_sim.env import DialfredEnv
from dialfred_sim.metrics import summarize
from dialfred_sim.metrics import EpisodeResult, load_results
from dialfred_sim.processes import worker_pool
from dialfred_sim.tasks.demonstrations import pixel_classes
from dialfred_sim.tasks.split_files import load_split

SIGHTS = ('network', 'truth')
QUESTIONERS = ('none', 'all')
_W: dict = {}


def truth_sight(agent_cls):
    """A subclass of MapAgent that reads the simulator's labels of each frame instead of perceiving it."""

    class GroundTruthSight(agent_cls):
        def attach(self, env) -> None:
            self.env = env

        def sense(self, observation):
            # The episode's observations carry RGB only (as through the graph): the labels and depth of this
            # same frame are read from the simulator itself.
            _, depth, segmentation = self.env.frames()
            classes = pixel_classes(self.env.world, np.asarray(segmentation)).astype(np.int64)
            s = self.resolution // 2                                # the network's cells
            b = classes.shape[0] // s
            k = len(self.classes)
            cell = (np.arange(s)[:, None, None, None] * s + np.arange(s)[None, None, :, None])
            cell = np.broadcast_to(cell, (s, b, s, b))
            counts = np.bincount((cell * k + classes.reshape(s, b, s, b)).ravel(), minlength=s * s * k)
            # Each cell's majority class: the network's training target (`perception.cell_targets`'
            # shares) read perfectly. A click on a cell lands at its centre pixel, which a class covering
            # less of the cell (a lamp's pole across a quarter of it) often misses.
            labels = counts.reshape(s * s, k).argmax(1).reshape(s, s)
            depth = np.asarray(depth, np.float32).reshape(s, b, s, b).mean(axis=(1, 3))
            return labels, np.ones((s, s), np.float32), depth

    return GroundTruthSight


def _init(checkpoint: str, seed: int, resolution: int) -> None:
    torch.set_num_threads(1)
    env = DialfredEnv(resolution=resolution)
    _W['env'] = env
    for sight in SIGHTS:
        cls = truth_sight(MapAgent) if sight == 'truth' else MapAgent
        for questioner in QUESTIONERS:
            agent = cls.from_checkpoint(Path(checkpoint))
            if sight == 'truth':
                agent.attach(env)
            config = EvalRun(EvalConfig(split='valid_unseen', agent='map', checkpoint=checkpoint, local=True, seed=seed,
                                        questioner='' if questioner == 'none' else questioner, resolution=resolution),
                             check=False)
            policy = with_questioner(agent, make_questioner(questioner)) if questioner != 'none' else agent
            _W[sight, questioner] = (config, policy)


def _job(job):
    sight, questioner, index, task = job
    config, policy = _W[sight, questioner]
    result = play_episode(config, _W['env'], policy, None, index, task)
    if sight == 'truth':
        result = dataclasses.replace(result, agent=f'{result.agent}+truth-sight', privileged=True)
    return sight, questioner, result


def summarise(rows: list) -> dict:
    s = summarize(rows)['overall']
    ends = Counter(r.end_reason for r in rows if not r.success)
    return {'n': len(rows), 'SR': round(s['SR'], 2), 'PWSR': round(s['PWSR'], 2), 'NQ': round(s['NQ'], 3),
            'failures_by_end': dict(ends)}


def measure(shard: str, limit: int, workers: int, out: Path, checkpoint: str, seed: int, resolution: int,
            progress: bool) -> dict:
    k, n = parse_shard(shard)
    tasks = [(i, t) for i, t in enumerate(load_split('valid_unseen')[:limit or None]) if i % n == k]
    out.mkdir(parents=True, exist_ok=True)
    done: dict = {}
    for sight in SIGHTS:
        for questioner in QUESTIONERS:
            path = out / f'{sight}_{questioner}.jsonl'
            done[sight, questioner] = {r.task_id: r for r in load_results(path)} if path.exists() else {}
    jobs = [(sight, q, i, t) for sight in SIGHTS for q in QUESTIONERS for i, t in tasks
            if t.task_id not in done[sight, q]]
    t0 = time.monotonic()
    files = {key: open(out / f'{key[0]}_{key[1]}.jsonl', 'a') for key in done}
    with worker_pool(max(1, workers), initializer=_init, initargs=(checkpoint, seed, resolution)) as pool, \
            tqdm(total=len(jobs), disable=not progress, file=sys.stderr, unit='ep') as bar:
        for sight, questioner, result in pool.imap_unordered(_job, jobs, chunksize=1):
            files[sight, questioner].write(result.to_json() + "\n")
            files[sight, questioner].flush()
            done[sight, questioner][result.task_id] = result
            bar.update(1)
    for f in files.values():
        f.close()
    ids = [t.task_id for _, t in tasks]
    report: dict = {'split': 'valid_unseen', 'shard': shard, 'limit': limit, 'tasks': len(ids), 'seed': seed,
                    'camera_px': resolution, 'checkpoint': checkpoint, 'settings': {}, 'per_type_SR': {},
                    'seconds_this_run': round(time.monotonic() - t0, 1), 'results': str(out)}
    for (sight, questioner), rows in done.items():
        rows = [rows[i] for i in ids if i in rows]
        assert all(isinstance(r, EpisodeResult) for r in rows)
        report['settings'][f'{sight}/{questioner}'] = summarise(rows)
        per_type = defaultdict(list)
        for r in rows:
            per_type[r.task_type].append(r.success)
        report['per_type_SR'][f'{sight}/{questioner}'] = {t: round(100 * float(np.mean(v)), 1)
                                                         for t, v in sorted(per_type.items())}
    s = report['settings']
    report['points_per_question'] = {
        sight: round((s[f'{sight}/all']['SR'] - s[f'{sight}/none']['SR']) / max(s[f'{sight}/all']['NQ'], 1e-9), 2)
        for sight in SIGHTS}
    return report


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--shard', default='0/1', help='K/N: the valid_unseen tasks whose index is K modulo N')
    ap.add_argument('--limit', type=int, default=0, help='only the first N tasks of the split (0: all)')
    ap.add_argument('--workers', type=int, default=2)
    ap.add_argument('--out', type=Path, default=Path('out/bench/map_perception_ceiling'))
    ap.add_argument('--checkpoint', default=str(SHIPPED_CHECKPOINT))
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--resolution', type=int, default=128, help='camera pixels (the map performer plays at 128)')
    ap.add_argument('--no-progress', action='store_true')
    args = ap.parse_args()
    try:
        parse_shard(args.shard)
    except ValueError as exc:
        raise SystemExit(f'--shard: {exc}') from None
    print(json.dumps(measure(args.shard, args.limit, args.workers, args.out, args.checkpoint, args.seed,
                             args.resolution, not args.no_progress), indent=1))


if __name__ == '__main__':
    main()
