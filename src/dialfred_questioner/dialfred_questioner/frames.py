"""The first frame of every task of a split, for the questioner's pre-training (no ROS).

    ./dialfred env python3 -m dialfred_questioner.frames train --resolution 64 --workers 2

The synthetic annotators ask at a task's start, so a pre-training example needs only the task's first
frame, not its whole demonstration. This renders each task's start state (`DialfredEnv.reset` to the
task, the same state the demonstrations and the evaluation start from) at `resolution` and writes
`<split>_first_<resolution>.npz` (`frames` [N, R, R, 3] uint8 in the split's task order, `task_ids`)
into `~/.cache/dialfred/questioner/` (or `$DIALFRED_QUESTIONER_CACHE`). Workers render interleaved
chunks; the result does not depend on their number. The file is written whole, under a temporary
name first, so an interrupted build leaves nothing half-written.

With `--demonstrations DIR` nothing is rendered: the first frames are copied out of a finished
demonstrations build of the same split and resolution (each task's demonstration starts with the same
reset; seconds instead of about 10 min for train, and the same bytes: tested).
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from dialfred_sim.dataclass_cli import REQUIRED, arg, parse
from dialfred_sim.processes import worker_pool
from dialfred_sim.tasks import load_split

CACHE_ENV = 'DIALFRED_QUESTIONER_CACHE'
CHUNK = 64


def cache_dir() -> Path:
    return Path(os.environ.get(CACHE_ENV, Path.home() / '.cache' / 'dialfred' / 'questioner'))


def default_path(split: str, resolution: int) -> Path:
    return cache_dir() / f'{split}_first_{resolution}.npz'


_ENV = None


def _render_chunk(args: tuple[str, int, int, int]) -> np.ndarray:
    global _ENV
    from dialfred_sim.env import DialfredEnv  # lazy: gymnasium, pybullet, which the rest of this module does without
    split, resolution, start, stop = args
    if _ENV is None or _ENV.resolution != resolution:
        _ENV = DialfredEnv(resolution=resolution)
    tasks = load_split(split)[start:stop]
    return np.stack([_ENV.reset(options={'task': t})[0]['rgb'] for t in tasks])


def frames_from_demonstrations(folder: Path, task_ids: list[str], resolution: int) -> np.ndarray:
    """The first frames of `task_ids` out of a finished demonstrations build (ValueError if it cannot serve)."""
    # lazy: pybullet, which the rest of this module does without
    from dialfred_sim.tasks.demonstrations import load_demonstrations
    demos = load_demonstrations(Path(folder))
    if int(demos.meta['resolution']) != resolution:
        raise ValueError(f'{folder} is rendered at {demos.meta["resolution"]}, not {resolution}')
    index = {t['task_id']: t['first_frame'] for t in demos.tasks}
    missing = [t for t in task_ids if t not in index]
    if missing:
        raise ValueError(f'{folder} lacks {len(missing)} of the tasks (first: {missing[0]})')
    return np.ascontiguousarray(demos.frames[[index[t] for t in task_ids]])


def build_first_frames(split: str, resolution: int = 64, out: Optional[Path] = None, workers: int = 1,
                       limit: int = 0, progress: bool = True, demonstrations: Optional[Path] = None) -> Path:
    """Save the first frames of `split` (its first `limit` tasks if > 0), rendered or copied out of
    `demonstrations`; returns the path."""
    if resolution < 16:
        raise ValueError(f'resolution must be at least 16, got {resolution}')
    tasks = load_split(split)[:limit or None]
    out = Path(out) if out else default_path(split, resolution)
    if demonstrations:
        frames = frames_from_demonstrations(demonstrations, [t.task_id for t in tasks], resolution)
        _save(out, frames, tasks, resolution)
        return out
    chunks = [(split, resolution, k, min(k + CHUNK, len(tasks))) for k in range(0, len(tasks), CHUNK)]
    parts, t0, done = [], time.monotonic(), 0
    with worker_pool(max(1, workers), maxtasksperchild=50) as pool:
        for frames in pool.imap(_render_chunk, chunks):
            parts.append(frames)
            done += len(frames)
            if progress:
                rate = done / max(time.monotonic() - t0, 1e-9)
                print(f'\r{split} first frames: {done}/{len(tasks)}, {rate:.0f} tasks/s, '
                      f'{(len(tasks) - done) / max(rate, 1e-9):.0f} s left ', end='', file=sys.stderr, flush=True)
    if progress:
        print(file=sys.stderr)
    _save(out, np.concatenate(parts) if parts else np.zeros((0, resolution, resolution, 3), np.uint8), tasks,
          resolution)
    return out


def _save(out: Path, frames: np.ndarray, tasks, resolution: int) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + '.tmp.npz')
    np.savez(tmp, frames=frames, task_ids=np.array([t.task_id for t in tasks]), resolution=resolution)
    tmp.replace(out)


class FirstFrames:
    """A first-frames file: `frames` [N, R, R, 3] and the index of each task id."""

    def __init__(self, path: Path):
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f'no first frames at {path}; make them with '
                                    f'`python -m dialfred_questioner.frames <split>`')
        try:
            with np.load(path) as data:
                self.frames = data['frames']
                self.task_ids = [str(t) for t in data['task_ids']]
                self.resolution = int(data['resolution'])
        except Exception as exc:  # noqa: BLE001 - a truncated or foreign file raises many kinds
            raise ValueError(f'{path} is not a first-frames file ({type(exc).__name__}: {exc})') from exc
        if len(self.frames) != len(self.task_ids):
            raise ValueError(f'{path}: {len(self.frames)} frames for {len(self.task_ids)} tasks')
        self.index = {t: k for k, t in enumerate(self.task_ids)}


@dataclass
class FirstFramesConfig:
    """The first frame of every task of a split, for the questioner's pre-training."""

    split: str = arg(REQUIRED, 'the split', positional=True)
    resolution: int = arg(64, 'camera pixels')
    workers: int = arg(1, 'processes rendering')
    limit: int = arg(0, 'only the first N tasks (0: all)', metavar='N')
    out: Optional[Path] = arg(None, 'the file (none: <cache>/<split>_first_<resolution>.npz)', metavar='PATH')
    demonstrations: Optional[Path] = arg(None, 'copy the first frames out of this finished demonstrations build '
                                         'instead of rendering', metavar='DIR')


def main(argv=None) -> int:
    args = parse(FirstFramesConfig, argv, description=__doc__.split('\n\n')[0])
    try:
        path = build_first_frames(args.split, args.resolution, args.out, args.workers, args.limit,
                                  demonstrations=args.demonstrations)
    except (FileNotFoundError, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    print(path)
    return 0


if __name__ == '__main__':
    sys.exit(main())
