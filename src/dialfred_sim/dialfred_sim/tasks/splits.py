"""The splits: train, valid_seen (rooms of train) and valid_unseen (rooms never in train).

Everything follows from seeds: episode k of a split is played in room k mod (number of rooms of the
split) with a seed drawn from (split, k), and its tasks are numbered in order until the split has
its size. A split is stored as gzipped JSON lines, one episode (with its tasks) per line; the valid
splits ship in the package, train is generated on demand (`python -m dialfred_sim.tasks.splits`).
"""

from __future__ import annotations

import argparse
import functools
import gzip
import json
import os
import sys
import time
from importlib import resources
from pathlib import Path
from typing import Iterator, Optional

import numpy as np

from ..world.rooms import SCENE_RANGES
from .generator import cut_tasks, generate_episode
from .schema import Condition, Episode, ExpertAction, Primitive, Task

SPLIT_SIZES = {'train': 34253, 'valid_seen': 1296, 'valid_unseen': 1363}
SPLIT_CODES = {'train': 1, 'valid_seen': 2, 'valid_unseen': 3}
# ALFRED's released scene split: valid_unseen and test_unseen rooms never appear in train.
VALID_UNSEEN_SCENES = (10, 219, 308, 424)
TEST_UNSEEN_SCENES = (9, 29, 215, 226, 315, 325, 404, 425)
CACHE_ENV = 'DIALFRED_TASK_DIR'      # where generated splits (train) are kept


def split_scenes(split: str) -> list[str]:
    if split == 'valid_unseen':
        numbers = list(VALID_UNSEEN_SCENES)
    elif split in ('train', 'valid_seen'):
        held_out = set(VALID_UNSEEN_SCENES) | set(TEST_UNSEEN_SCENES)
        numbers = [n for r in SCENE_RANGES.values() for n in r if n not in held_out]
    else:
        raise ValueError(f'unknown split {split!r}: expected one of {", ".join(SPLIT_SIZES)}')
    return [f'FloorPlan{n}' for n in numbers]


def episode_seed(split: str, index: int) -> int:
    return int(np.random.SeedSequence([SPLIT_CODES[split], index]).generate_state(1)[0])


def play_episode(env, split: str, index: int, first_index: int, limit: int,
                 scenes: Optional[list[str]] = None) -> Optional[dict]:
    """Episode `index` of `split` with the tasks cut from it (ids from `first_index`, at most `limit`),
    as a JSON-ready dict; None when its job was dropped. Episodes depend only on (split, index)."""
    scenes = scenes or split_scenes(split)
    seed = episode_seed(split, index)
    episode = generate_episode(env, split, index, scenes[index % len(scenes)], seed)
    if episode is None:
        return None
    tasks = cut_tasks(env, episode, np.random.default_rng(seed + 1), first_index, limit)
    return episode_to_json(episode, tasks) if tasks else None


def generate_split(split: str, size: Optional[int] = None, progress: bool = True,
                   shard: int = 0, shards: int = 1) -> Iterator[dict]:
    """Episodes of `split` (as JSON-ready dicts, each with its tasks) until `size` tasks exist.

    With shards > 1, only episodes k = shard (mod shards) are played and tasks are numbered within
    the shard; `merge_shards` then renumbers them in episode order, giving the same split."""
    from ..env import DialfredEnv
    size = SPLIT_SIZES[split] if size is None else size
    scenes = split_scenes(split)
    env = DialfredEnv()
    n_tasks, index, t0 = 0, shard, time.monotonic()
    try:
        while n_tasks < size:
            row = play_episode(env, split, index, n_tasks, size - n_tasks, scenes)
            if row is not None:
                n_tasks += len(row['tasks'])
                yield row
            index += shards
            if progress and index % 10 < shards:
                rate = n_tasks / max(time.monotonic() - t0, 1e-9)
                print(f'\r{split}: {n_tasks}/{size} tasks, {index} episodes tried, {rate:.1f} tasks/s',
                      end='', file=sys.stderr, flush=True)
    finally:
        env.close()
        if progress:
            print(file=sys.stderr)


# ---------------------------------------------------------------------- storage

def episode_to_json(episode: Episode, tasks: list[Task]) -> dict:
    return {
        'episode_id': episode.episode_id, 'split': episode.split, 'scene': episode.scene, 'seed': episode.seed,
        'alfred_type': episode.alfred_type, 'setup': episode.setup, 'resolution': episode.resolution,
        'actions': [a.to_json() for a in episode.actions],
        'primitives': [p.to_json() for p in episode.primitives],
        'poses': [list(p) for p in episode.poses],
        'tasks': [{
            'task_id': t.task_id, 'task_type': t.task_type, 'start': t.start, 'end': t.end,
            'goal': [c.to_json() for c in t.goal], 'instruction': t.instruction,
            'step_instructions': t.step_instructions, 'object_nouns': t.object_nouns,
            'primitives': [episode.primitives.index(p) for p in t.primitives],
            'target_visible_at_start': t.target_visible_at_start, 'has_distractor': t.has_distractor,
        } for t in tasks],
    }


def tasks_from_json(row: dict) -> list[Task]:
    episode = Episode(row['episode_id'], row['split'], row['scene'], int(row['seed']), row['alfred_type'],
                      row['setup'], [ExpertAction.from_json(a) for a in row['actions']],
                      [Primitive.from_json(p) for p in row['primitives']],
                      [(int(p[0]), int(p[1]), int(p[2]), float(p[3])) for p in row['poses']], int(row['resolution']))
    return [Task(t['task_id'], t['task_type'], episode, int(t['start']), int(t['end']),
                 [Condition.from_json(c) for c in t['goal']], t['instruction'], list(t['step_instructions']),
                 list(t['object_nouns']), [episode.primitives[i] for i in t['primitives']],
                 bool(t['target_visible_at_start']), bool(t['has_distractor'])) for t in row['tasks']]


def packaged_path(split: str) -> Path:
    return Path(str(resources.files('dialfred_sim') / 'data' / 'tasks' / f'{split}.jsonl.gz'))


def split_path(split: str) -> Path:
    """Where `split` is read from: the package for the shipped splits, else the task cache."""
    if split not in SPLIT_SIZES:
        raise ValueError(f'unknown split {split!r}: expected one of {", ".join(SPLIT_SIZES)}')
    shipped = packaged_path(split)
    if shipped.exists():
        return shipped
    cache = Path(os.environ.get(CACHE_ENV, Path.home() / '.cache' / 'dialfred' / 'tasks'))
    return cache / f'{split}.jsonl.gz'


@functools.lru_cache(maxsize=4)
def load_split(split: str) -> list[Task]:
    """Every task of `split`, in task-id order. FileNotFoundError names the command that makes it."""
    path = split_path(split)
    if not path.exists():
        raise FileNotFoundError(f'{path} does not exist; generate it with '
                                f'`./dialfred env python3 -m dialfred_sim.tasks.splits {split}`')
    tasks: list[Task] = []
    with gzip.open(path, 'rt') as f:
        for n, line in enumerate(f, 1):
            try:
                tasks.extend(tasks_from_json(json.loads(line)))
            except (ValueError, KeyError, IndexError, TypeError, EOFError) as exc:
                raise ValueError(f'{path}: line {n} is malformed ({exc})') from exc
    return tasks


@functools.lru_cache(maxsize=4)
def task_index(split: str) -> dict[str, Task]:
    return {t.task_id: t for t in load_split(split)}


def get_task(task_id: str) -> Task:
    """The task with id '<split>/<number>'; ValueError for a malformed or unknown id."""
    split = task_id.split('/', 1)[0]
    if split not in SPLIT_SIZES or '/' not in task_id:
        raise ValueError(f'unknown task_id {task_id!r}: expected "<split>/<number>", split one of '
                         f'{", ".join(SPLIT_SIZES)}')
    task = task_index(split).get(task_id)
    if task is None:
        raise ValueError(f'unknown task_id {task_id!r}')
    return task


def write_split(split: str, path: Path, size: Optional[int] = None) -> dict:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix('.tmp')
    t0, n_tasks, n_episodes = time.monotonic(), 0, 0
    # mtime=0 keeps the gzip bytes identical across runs.
    with open(tmp, 'wb') as raw, gzip.GzipFile(fileobj=raw, mode='wb', mtime=0) as f:
        for row in generate_split(split, size):
            f.write((json.dumps(row, separators=(',', ':')) + '\n').encode())
            n_tasks += len(row['tasks'])
            n_episodes += 1
    tmp.replace(path)   # a half-written split never replaces a good one
    return {'split': split, 'tasks': n_tasks, 'episodes': n_episodes, 'seconds': round(time.monotonic() - t0, 1),
            'bytes': path.stat().st_size, 'path': str(path)}


def merge_shards(paths: list[Path], out: Path, size: int) -> dict:
    """Interleave shard files back into episode order, renumber tasks, stop at `size` tasks."""
    rows, last = [], []
    for p in paths:
        with gzip.open(p, 'rt') as f:
            shard_rows = [json.loads(line) for line in f]
        rows.extend(shard_rows)
        last.append(max(_episode_number(r) for r in shard_rows))
    # Past the point where the first shard stopped, episodes of that shard are missing.
    rows = sorted((r for r in rows if _episode_number(r) <= min(last)), key=_episode_number)
    if sum(len(r['tasks']) for r in rows) < size:
        raise RuntimeError('the shards stopped before the split was complete; raise the shard quota')
    tmp, n_tasks, n_episodes = out.with_suffix('.tmp'), 0, 0
    with open(tmp, 'wb') as raw, gzip.GzipFile(fileobj=raw, mode='wb', mtime=0) as f:
        for row in rows:
            if n_tasks >= size:
                break
            row['tasks'] = row['tasks'][:size - n_tasks]
            for t in row['tasks']:
                t['task_id'] = f'{row["split"]}/{n_tasks:06d}'
                n_tasks += 1
            n_episodes += 1
            f.write((json.dumps(row, separators=(',', ':')) + '\n').encode())
    tmp.replace(out)
    return {'tasks': n_tasks, 'episodes': n_episodes, 'bytes': out.stat().st_size, 'path': str(out)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description='Generate a DialFRED split.')
    ap.add_argument('split', choices=sorted(SPLIT_SIZES))
    ap.add_argument('--size', type=int, default=None, help='tasks (default: the split size)')
    ap.add_argument('--out', default=None, help='output file (default: where load_split reads it)')
    ap.add_argument('--workers', type=int, default=1, help='processes, each playing every n-th episode')
    args = ap.parse_args(argv)
    out = Path(args.out) if args.out else split_path(args.split)
    size = SPLIT_SIZES[args.split] if args.size is None else args.size
    if args.workers <= 1:
        print(json.dumps(write_split(args.split, out, size)))
        return 0
    import multiprocessing
    t0 = time.monotonic()
    out.parent.mkdir(parents=True, exist_ok=True)
    parts = [out.with_name(f'{out.name}.shard{k}') for k in range(args.workers)]
    with multiprocessing.get_context('spawn').Pool(args.workers) as pool:
        pool.starmap(_write_shard, [(args.split, p, size, k, args.workers) for k, p in enumerate(parts)])
    report = merge_shards(parts, out, size)
    for p in parts:
        p.unlink()
    report.update(split=args.split, seconds=round(time.monotonic() - t0, 1), workers=args.workers)
    print(json.dumps(report))
    return 0


def _episode_number(row: dict) -> int:
    return int(row['episode_id'].rsplit('/ep', 1)[1])


def _write_shard(split: str, path: Path, size: int, shard: int, shards: int) -> None:
    # Each shard plays until it alone has `size` tasks' worth / shards (plus a margin), in episode order.
    quota = int(size / shards * 1.1) + 100
    with open(path, 'wb') as raw, gzip.GzipFile(fileobj=raw, mode='wb', mtime=0) as f:
        for row in generate_split(split, quota, progress=shard == 0, shard=shard, shards=shards):
            f.write((json.dumps(row, separators=(',', ':')) + '\n').encode())


if __name__ == '__main__':
    sys.exit(main())
