"""The splits: train, valid_seen (rooms of train), valid_unseen (rooms never in train), and a sealed
test_unseen that each user makes from a seed of their own in ALFRED's held-out test rooms.

Everything follows from seeds: episode k of a split is played in room k mod (number of rooms of the
split) with a seed drawn from (split, k) -- for test_unseen from (split, the user's seed, k) -- and
its tasks are numbered in order until the split has its size. A split is stored as gzipped JSON
lines, one episode (with its tasks) per line. The shipped splits are in the package; a test split
lives in the file its user names, and is read with `read_tasks_file` (in `split_files`, as is
everything that reads splits; this module makes them):

    python -m dialfred_sim.tasks.splits test_unseen --seed S --size N --out PATH [--workers 2]
"""

from __future__ import annotations

import gzip
import hashlib
import json
import os
import sys
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Optional

import numpy as np

from ..dataclass_cli import REQUIRED, arg, from_args, parser_for
from ..processes import worker_executor
from .generator import cut_tasks, generate_episode
# Reading the split files and looking tasks up live in split_files (the environment uses them, and
# this module plays episodes in the environment); the names stay importable from here.
from .split_files import (CACHE_ENV, SPLIT_CODES, SPLIT_SIZES, TEST_SPLIT, TEST_UNSEEN_SCENES,  # noqa: F401  (re-exported)
                          VALID_UNSEEN_SCENES, TasksFile, episode_to_json, get_task, load_split, packaged_path,
                          read_tasks_file, resolve_task, split_path, split_scenes, task_index, tasks_from_json)

PARALLEL_AHEAD = 4                   # episodes queued per worker process beyond the one it plays


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
    from ..progress import progress_bar  # lazy: tqdm, which the rest of this module does without
    size = SPLIT_SIZES[split] if size is None else size
    check_split_seed(split, split_seed)
    if isinstance(size, bool) or not isinstance(size, int) or size < 1:
        raise ValueError(f'size must be a number of tasks >= 1, got {size!r}')
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f'workers must be an integer >= 1, got {workers!r}')
    rows = _played_in_process(split, split_seed) if workers == 1 else _played_in_workers(split, split_seed, workers)
    n_tasks = 0
    with progress_bar(total=size, unit='task', desc=split, disable=not progress) as bar:
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
    from ..env import DialfredEnv  # lazy: gymnasium, which the rest of this module does without
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
        from ..env import DialfredEnv  # lazy: gymnasium, which the rest of this module does without
        _WORKER_ENV = DialfredEnv()
    return play_episode(_WORKER_ENV, split, index, 0, 10 ** 9, split_scenes(split), split_seed)


def _played_in_workers(split: str, split_seed: Optional[int], workers: int) -> Iterator[tuple[int, Optional[dict]]]:
    """(index, row) of episodes 0, 1, 2, ... in order, played by `workers` processes a few episodes ahead."""
    pool = worker_executor(workers)
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


def _test_split_out(out: Optional[Path], force: bool) -> Path:
    """The --out of a test split, checked before anything is generated or written."""
    if not out:
        raise ValueError(f'{TEST_SPLIT} needs --out PATH (a .jsonl.gz file of your own)')
    path = Path(out).expanduser()
    if not path.name.endswith('.jsonl.gz'):
        raise ValueError(f"--out must name a .jsonl.gz file, got '{out}'")
    if path.is_dir():
        raise ValueError(f"--out '{out}' is a directory")
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


@dataclass
class SplitConfig:
    """Generate a DialFRED split. test_unseen makes a sealed test split of your own: tasks in ALFRED's
    held-out test rooms, from your seed, with the generator and checks of the other splits."""

    split: str = arg(REQUIRED, 'the split', choices=[*sorted(SPLIT_SIZES), TEST_SPLIT], positional=True)
    seed: Optional[int] = arg(None, f'{TEST_SPLIT} only, and required there: the seed its episodes come from (>= 0)')
    size: Optional[int] = arg(None, f'number of tasks (none: the split size; {TEST_SPLIT}: '
                              f'{SPLIT_SIZES["valid_unseen"]:,}, as valid_unseen)')
    out: Optional[Path] = arg(None, f'output file (.jsonl.gz; required for {TEST_SPLIT}; none for the others: '
                              'where load_split reads them)', metavar='PATH')
    workers: int = arg(1, 'processes playing episodes ahead (the file is the same with any number)')
    force: bool = arg(False, f'{TEST_SPLIT}: replace an existing --out (without it, an existing file is refused)')
    progress: bool = arg(True, 'a progress bar on stderr')

    def __post_init__(self):
        check_split_seed(self.split, self.seed)
        if self.size is not None and self.size < 1:
            raise ValueError(f'--size must be a number of tasks >= 1, got {self.size}')
        if self.workers < 1:
            raise ValueError(f'--workers must be >= 1, got {self.workers}')


def main(argv=None) -> int:
    ap = parser_for(SplitConfig, prog='python -m dialfred_sim.tasks.splits',
                    description=' '.join(SplitConfig.__doc__.split()) + ' (The test rooms: FloorPlan'
                    + ', '.join(map(str, TEST_UNSEEN_SCENES)) + '.)',
                    epilog=f'example: python -m dialfred_sim.tasks.splits {TEST_SPLIT} --seed 7 --size 1363 '
                           '--out out/test_unseen_s7.jsonl.gz --workers 2')
    args = from_args(SplitConfig, ap.parse_args(argv), ap)
    try:
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
        report = write_split(args.split, out, size, args.seed, args.workers, args.progress)
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
