"""The splits: train, valid_seen (rooms of train), valid_unseen (rooms never in train), and a sealed
test_unseen that each user makes from a seed of their own in ALFRED's held-out test rooms.

Everything follows from seeds: episode k of a split is played in room k mod (number of rooms of the
split) with a seed drawn from (split, k) -- for test_unseen from (split, the user's seed, k) -- and
its tasks are numbered in order until the split has its size. A split is stored as gzipped JSON
lines, one episode (with its tasks) per line. The shipped splits are in the package; a test split
lives in the file its user names, and is read with `read_tasks_file`:

    python -m dialfred_sim.tasks.splits test_unseen --seed S --size N --out PATH [--workers 2]
"""

from __future__ import annotations

import argparse
import functools
import gzip
import hashlib
import io
import json
import os
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Iterator, Optional

import numpy as np

from ..world.rooms import SCENE_RANGES
from .generator import cut_tasks, generate_episode
from .schema import Condition, Episode, ExpertAction, Primitive, Task

SPLIT_SIZES = {'train': 34253, 'valid_seen': 1296, 'valid_unseen': 1363}
TEST_SPLIT = 'test_unseen'           # made by each user from a seed of their own; never shipped
SPLIT_CODES = {'train': 1, 'valid_seen': 2, 'valid_unseen': 3, TEST_SPLIT: 4}
# ALFRED's released scene split: valid_unseen and test_unseen rooms never appear in train.
VALID_UNSEEN_SCENES = (10, 219, 308, 424)
TEST_UNSEEN_SCENES = (9, 29, 215, 226, 315, 325, 404, 425)
CACHE_ENV = 'DIALFRED_TASK_DIR'      # where generated splits (train) are kept
PARALLEL_AHEAD = 4                   # episodes queued per worker process beyond the one it plays


def split_scenes(split: str) -> list[str]:
    if split == 'valid_unseen':
        numbers = list(VALID_UNSEEN_SCENES)
    elif split == TEST_SPLIT:
        numbers = list(TEST_UNSEEN_SCENES)
    elif split in ('train', 'valid_seen'):
        held_out = set(VALID_UNSEEN_SCENES) | set(TEST_UNSEEN_SCENES)
        numbers = [n for r in SCENE_RANGES.values() for n in r if n not in held_out]
    else:
        raise ValueError(f'unknown split {split!r}: expected one of {", ".join([*SPLIT_SIZES, TEST_SPLIT])}')
    return [f'FloorPlan{n}' for n in numbers]


def episode_seed(split: str, index: int, split_seed: Optional[int] = None) -> int:
    """The seed of episode `index`: from (split, index), or (split, split_seed, index) for a test split."""
    entropy = [SPLIT_CODES[split], index] if split_seed is None else [SPLIT_CODES[split], split_seed, index]
    return int(np.random.SeedSequence(entropy).generate_state(1)[0])


def check_split_seed(split: str, split_seed: Optional[int]) -> None:
    """ValueError unless a test split has a seed (an integer >= 0) and the shipped splits have none."""
    if split == TEST_SPLIT:
        if split_seed is None or isinstance(split_seed, bool) or not isinstance(split_seed, int) or split_seed < 0:
            raise ValueError(f'{TEST_SPLIT} needs a seed of your own: an integer >= 0, got {split_seed!r}')
    elif split_seed is not None:
        raise ValueError(f'{split} is defined by its fixed seeds; a seed of your own is for {TEST_SPLIT} only')
    split_scenes(split)      # ValueError for an unknown split


def play_episode(env, split: str, index: int, first_index: int, limit: int,
                 scenes: Optional[list[str]] = None, split_seed: Optional[int] = None) -> Optional[dict]:
    """Episode `index` of `split` with the tasks cut from it (ids from `first_index`, at most `limit`),
    as a JSON-ready dict; None when its job was dropped. Episodes depend only on (split, split_seed,
    index), and the tasks cut with a lower `limit` are the first ones of those cut with a higher one."""
    scenes = scenes or split_scenes(split)
    seed = episode_seed(split, index, split_seed)
    episode = generate_episode(env, split, index, scenes[index % len(scenes)], seed)
    if episode is None:
        return None
    tasks = cut_tasks(env, episode, np.random.default_rng(seed + 1), first_index, limit)
    return episode_to_json(episode, tasks) if tasks else None


def generate_split(split: str, size: Optional[int] = None, progress: bool = True,
                   split_seed: Optional[int] = None, workers: int = 1) -> Iterator[dict]:
    """Episodes of `split` (as JSON-ready dicts, each with its tasks), in episode order, until `size`
    tasks exist; the last episode keeps only the tasks still needed.

    With workers > 1, that many processes play the episodes ahead and this one takes their rows in
    episode order: the same rows as one process gives. `progress` shows a bar of tasks on stderr."""
    from tqdm import tqdm
    size = SPLIT_SIZES[split] if size is None else size
    check_split_seed(split, split_seed)
    if isinstance(size, bool) or not isinstance(size, int) or size < 1:
        raise ValueError(f'size must be a number of tasks >= 1, got {size!r}')
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f'workers must be an integer >= 1, got {workers!r}')
    rows = _played_in_process(split, split_seed) if workers == 1 else _played_in_workers(split, split_seed, workers)
    n_tasks = 0
    with tqdm(total=size, unit='task', desc=split, file=sys.stderr, disable=not progress, dynamic_ncols=True) as bar:
        try:
            for index, row in rows:
                if row is None:
                    continue
                # Numbered here, in episode order, so that any number of workers gives the same ids.
                row['tasks'] = row['tasks'][:size - n_tasks]
                for t in row['tasks']:
                    t['task_id'] = f'{split}/{n_tasks:06d}'
                    n_tasks += 1
                bar.update(len(row['tasks']))
                bar.set_postfix(episodes_tried=index + 1, refresh=False)
                yield row
                if n_tasks >= size:
                    break
        finally:
            rows.close()


def _played_in_process(split: str, split_seed: Optional[int]) -> Iterator[tuple[int, Optional[dict]]]:
    """(index, row) of episodes 0, 1, 2, ... of `split`, played by this process."""
    from ..env import DialfredEnv
    env, scenes = DialfredEnv(), split_scenes(split)
    try:
        index = 0
        while True:
            # Every task of the episode: the caller keeps the ones it needs (a prefix, see play_episode).
            yield index, play_episode(env, split, index, 0, 10 ** 9, scenes, split_seed)
            index += 1
    finally:
        env.close()


_WORKER_ENV = None


def _worker_play(split: str, split_seed: Optional[int], index: int) -> Optional[dict]:
    global _WORKER_ENV
    if _WORKER_ENV is None:
        from ..env import DialfredEnv
        _WORKER_ENV = DialfredEnv()
    return play_episode(_WORKER_ENV, split, index, 0, 10 ** 9, split_scenes(split), split_seed)


def _played_in_workers(split: str, split_seed: Optional[int], workers: int) -> Iterator[tuple[int, Optional[dict]]]:
    """(index, row) of episodes 0, 1, 2, ... in order, played by `workers` processes a few episodes ahead."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context('spawn'))
    ahead: deque = deque()
    try:
        index = 0
        while True:
            while len(ahead) < workers * (1 + PARALLEL_AHEAD):
                ahead.append(pool.submit(_worker_play, split, split_seed, index + len(ahead)))
            yield index, ahead.popleft().result()
            index += 1
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


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
    return _parse_lines(path, _decompress(path))


def _decompress(path: Path) -> bytes:
    try:
        return gzip.decompress(path.read_bytes())
    except (OSError, EOFError) as exc:      # not gzip, or cut off
        raise ValueError(f'{path} is not a complete gzipped split file ({exc})') from None


def _parse_lines(path: Path, data: bytes) -> list[Task]:
    tasks: list[Task] = []
    for n, line in enumerate(io.BytesIO(data), 1):
        try:
            tasks.extend(tasks_from_json(json.loads(line)))
        except (ValueError, KeyError, IndexError, TypeError) as exc:
            raise ValueError(f'{path}: line {n} is malformed ({exc})') from exc
    return tasks


@functools.lru_cache(maxsize=4)
def task_index(split: str) -> dict[str, Task]:
    return {t.task_id: t for t in load_split(split)}


def get_task(task_id: str) -> Task:
    """The task with id '<split>/<number>' of a shipped split; ValueError for a malformed or unknown id
    (test_unseen ids are only known to the file that holds them: see `resolve_task`)."""
    split = task_id.split('/', 1)[0]
    if split == TEST_SPLIT:
        raise ValueError(f'{task_id!r} is a task of a test split, which lives in the file you made with '
                         f'`python -m dialfred_sim.tasks.splits {TEST_SPLIT} --seed S --size N --out PATH`: '
                         "give that file (the sim node's tasks_file parameter, `launch eval --tasks PATH`), "
                         "or reset the env with options={'task': read_tasks_file(PATH).task(task_id)}")
    if split not in SPLIT_SIZES or '/' not in task_id:
        raise ValueError(f'unknown task_id {task_id!r}: expected "<split>/<number>", split one of '
                         f'{", ".join(SPLIT_SIZES)}')
    task = task_index(split).get(task_id)
    if task is None:
        raise ValueError(f'unknown task_id {task_id!r}')
    return task


# ---------------------------------------------------------------------- a split file of one's own

@dataclass
class TasksFile:
    """A split file given by its path (a test split, or any file this module writes): its tasks, and
    the digest that identifies them. Its task ids mean something only together with the file."""

    path: Path              # absolute
    sha256: str             # of the uncompressed JSON lines: the same tasks give the same digest
    split: str              # the one split all its episodes belong to
    tasks: list[Task]
    index: dict[str, Task] = field(repr=False, default_factory=dict)

    def task(self, task_id: str) -> Task:
        """The task `task_id` of this file; ValueError naming the file if it has none such."""
        task = self.index.get(task_id)
        if task is None:
            raise ValueError(f'unknown task_id {task_id!r} in {self.path} ({len(self.tasks)} tasks of '
                             f'{self.split}, {self.split}/000000 to {self.split}/{len(self.tasks) - 1:06d})')
        return task

    def describe(self) -> dict:
        """What results record of the file they came from."""
        return {'path': str(self.path), 'sha256': self.sha256, 'split': self.split, 'tasks': len(self.tasks)}


def read_tasks_file(path) -> TasksFile:
    """The tasks of a split file (gzipped JSON lines). FileNotFoundError if it does not exist;
    ValueError if it is not such a file, holds no task, mixes splits or repeats a task id."""
    path = Path(path).expanduser().absolute()
    if not path.is_file():
        raise FileNotFoundError(f'tasks file {path} does not exist (or is not a file); make one with '
                                f'`python -m dialfred_sim.tasks.splits {TEST_SPLIT} --seed S --size N --out PATH`')
    data = _decompress(path)
    tasks = _parse_lines(path, data)
    if not tasks:
        raise ValueError(f'{path} holds no task')
    splits = sorted({t.split for t in tasks})
    if len(splits) > 1:
        raise ValueError(f'{path} mixes the splits {", ".join(splits)}')
    index = {t.task_id: t for t in tasks}
    if len(index) < len(tasks):
        raise ValueError(f'{path} repeats task ids')
    return TasksFile(path, hashlib.sha256(data).hexdigest(), splits[0], tasks, index)


def resolve_task(task_id: str, tasks_file: Optional[TasksFile] = None) -> Task:
    """The task `task_id`: of `tasks_file` when it holds it or names its split, else of a shipped split
    (`get_task`). ValueError for an unknown id."""
    if tasks_file is not None and (task_id in tasks_file.index or task_id.split('/', 1)[0] == tasks_file.split):
        return tasks_file.task(task_id)
    return get_task(task_id)


# ---------------------------------------------------------------------- writing a split

def write_split(split: str, path: Path, size: Optional[int] = None, split_seed: Optional[int] = None,
                workers: int = 1, progress: bool = True) -> dict:
    """Generate `split` into `path` (gzipped JSON lines) and return a JSON-ready report.

    The file appears only complete (written beside it, then renamed over it); its bytes depend only
    on (split, split_seed, size), not on `workers` or on the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f'.{path.name}.{os.getpid()}.tmp')
    t0, n_tasks, n_episodes = time.monotonic(), 0, 0
    sha = hashlib.sha256()
    try:
        # mtime=0 and no file name in the header keep the gzip bytes identical across runs and paths.
        with open(tmp, 'wb') as raw, gzip.GzipFile(filename='', fileobj=raw, mode='wb', mtime=0) as f:
            for row in generate_split(split, size, progress, split_seed, workers):
                line = (json.dumps(row, separators=(',', ':')) + '\n').encode()
                f.write(line)
                sha.update(line)
                n_tasks += len(row['tasks'])
                n_episodes += 1
        tmp.replace(path)   # a half-written split never replaces a good one
    finally:
        tmp.unlink(missing_ok=True)
    report = {'split': split, 'seed': split_seed, 'tasks': n_tasks, 'episodes': n_episodes,
              'rooms': split_scenes(split), 'workers': workers, 'seconds': round(time.monotonic() - t0, 1),
              'bytes': path.stat().st_size, 'sha256': sha.hexdigest(), 'path': str(path.absolute())}
    if split_seed is None:
        del report['seed']
    return report


def _test_split_out(out: Optional[str], force: bool) -> Path:
    """The --out of a test split, checked before anything is generated or written."""
    if not out:
        raise ValueError(f'{TEST_SPLIT} needs --out PATH (a .jsonl.gz file of your own)')
    path = Path(out).expanduser()
    if not path.name.endswith('.jsonl.gz'):
        raise ValueError(f'--out must name a .jsonl.gz file, got {out!r}')
    if path.is_dir():
        raise ValueError(f'--out {out!r} is a directory')
    if path.exists() and not force:
        raise ValueError(f'{out} exists; pass --force to replace it (it is replaced only once the new split '
                         'is complete)')
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f'cannot write {out}: {exc.strerror} ({exc.filename})') from None
    if not os.access(path.parent, os.W_OK | os.X_OK):
        raise ValueError(f'cannot write {out}: {path.parent} is not a writable directory')
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog='python -m dialfred_sim.tasks.splits',
        description='Generate a DialFRED split. test_unseen makes a sealed test split of your own: tasks in '
                    "ALFRED's held-out test rooms (FloorPlan" + ', '.join(map(str, TEST_UNSEEN_SCENES))
                    + '), from your seed, with the generator and checks of the other splits.',
        epilog=f'example: python -m dialfred_sim.tasks.splits {TEST_SPLIT} --seed 7 --size 1363 '
               '--out out/test_unseen_s7.jsonl.gz --workers 2')
    ap.add_argument('split', choices=[*sorted(SPLIT_SIZES), TEST_SPLIT])
    ap.add_argument('--seed', type=int, default=None,
                    help=f'{TEST_SPLIT} only, and required there: the seed its episodes come from (>= 0)')
    ap.add_argument('--size', type=int, default=None,
                    help=f'number of tasks (default: the split size; {TEST_SPLIT}: '
                         f'{SPLIT_SIZES["valid_unseen"]:,}, as valid_unseen)')
    ap.add_argument('--out', default=None, help=f'output file (.jsonl.gz; required for {TEST_SPLIT}; '
                                                'default for the others: where load_split reads them)')
    ap.add_argument('--workers', type=int, default=1,
                    help='processes playing episodes ahead (the file is the same with any number)')
    ap.add_argument('--force', action='store_true',
                    help=f'{TEST_SPLIT}: replace an existing --out (without it, an existing file is refused)')
    ap.add_argument('--no-progress', action='store_true', help='no progress bar on stderr')
    args = ap.parse_args(argv)
    try:
        check_split_seed(args.split, args.seed)
        if args.size is not None and args.size < 1:
            raise ValueError(f'--size must be a number of tasks >= 1, got {args.size}')
        if args.workers < 1:
            raise ValueError(f'--workers must be >= 1, got {args.workers}')
        if args.split == TEST_SPLIT:
            out = _test_split_out(args.out, args.force)
            size = args.size or SPLIT_SIZES['valid_unseen']
        else:
            out = Path(args.out) if args.out else split_path(args.split)
            size = args.size or SPLIT_SIZES[args.split]
            if not args.out and size != SPLIT_SIZES[args.split]:
                # A part of a split where load_split reads the whole one would replace the shipped file.
                raise ValueError(f'--size {size} of {args.split} needs --out (the default is the split itself, '
                                 f'{SPLIT_SIZES[args.split]:,} tasks)')
    except ValueError as exc:
        ap.error(str(exc))      # exit 2, nothing written
    try:
        report = write_split(args.split, out, size, args.seed, args.workers, not args.no_progress)
    except OSError as exc:      # e.g. the disk filled up: the half-written file is gone, `out` untouched
        print(f'error: cannot write {out}: {exc}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f'interrupted: {out} was not written (nothing is kept of a split cut short)', file=sys.stderr)
        return 130
    print(json.dumps(report))
    return 0


if __name__ == '__main__':
    sys.exit(main())
