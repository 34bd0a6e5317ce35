"""Rendered expert demonstrations of a split: what the agent sees along the expert's path, with the
expert's actions, ready for imitation learning (no ROS).

    ./dialfred env python3 -m dialfred_sim.tasks.demonstrations valid_unseen --resolution 64 --workers 2

replays every task's expert in `DialfredEnv` at the given resolution and writes to
`~/.cache/dialfred/demonstrations/<split>_<resolution>/` (or `--out`):

- `frames.npy`: uint8 [F, R, R, 3], a standard .npy file (`np.load(..., mmap_mode='r')`). For each
  task, n + 1 frames: the frame before each of its n expert actions, then the frame after the last
  (n + 1 rows are kept per task of expert length n; fewer are used if the goal holds early).
- `tasks.jsonl`: one line per task, in split order. It holds `task_id`, `task_type`, `instruction`,
  `step_instructions`, `object_nouns`, `first_frame` and `actions`, which are
  `[name, x, y, target type]` with x, y = -1 and target '' for moves. It also holds `success` (the
  task's goal held at the end) and `failed_actions`.
- `meta.json`: split, resolution, tasks, frames, success rate and build time.
- with `--labels`, what the simulator knows about each frame, for training perception (never shown to
  an agent at evaluation): `classes.npy` uint8 [F, R, R], the class of each pixel (`LABEL_CLASSES`:
  0 nothing, then Floor, Wall, Ceiling and the object types); `depth.npy` uint8 [F, R, R], depth in
  steps of `DEPTH_STEP` m (255: that far or farther); `targets.npy` uint8 [F, ceil(R * R / 8)], the pixels of
  the expert's target on an interaction frame (np.packbits of the R x R mask; all zero otherwise).

The expert's pixels were chosen in 128x128 frames. At another resolution each pixel is scaled, and
if the scaled pixel misses the expert's target, the nearest pixel that shows the target is used
instead. Frames are written as tasks are played. Finished tasks go to `done-<worker>.txt` only after
their frames are on disk, so an interrupted build resumes where it stopped. The same split and
resolution always give the same bytes, with any number of workers. `load_demonstrations` reads a
finished build.
"""

from __future__ import annotations

import functools
import importlib
import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional, Sequence

import numpy as np

from ..dataclass_cli import REQUIRED, arg, from_args, parser_for
from ..metrics import write_text_atomically
from ..processes import worker_pool
from ..protocol import scale_pixel
from ..catalog import load_catalog
from .detours import DETOUR_ROWS, GuidedWalk, detour_plan, guided_plan, rejoin_step, way_back
from .schema import ExpertAction
from .splits import SPLIT_SIZES, load_split

CACHE_ENV = 'DIALFRED_DEMO_DIR'
SYNC_EVERY = 25        # tasks between pushes of frames, then their done records, to disk
DEPTH_STEP = 0.04      # metres per unit of depth.npy (255 units = 10.2 m and beyond)
LABEL_FILES = ('classes.npy', 'depth.npy', 'targets.npy')
DETOUR_SEED = 11        # detours.detour_plan draws from (DETOUR_SEED, the task's index in the split)


def label_classes() -> tuple[str, ...]:
    """The classes of classes.npy: '' (nothing), the room's structure, then every object type."""
    return ('', 'Floor', 'Wall', 'Ceiling', *sorted(load_catalog()))


class FrameLabels:
    """Writes the labels of frames into the rows of classes/depth/targets views (see the module)."""

    def __init__(self, classes: np.ndarray, depth: np.ndarray, targets: np.ndarray):
        self.classes, self.depth, self.targets = classes, depth, targets

    def write(self, k: int, env, obs: dict, target: str = '') -> None:
        """Row k: the labels of observation `obs` of `env`; `target` the object id of the action taken
        from it (its pixels go to targets.npy)."""
        seg = obs['segmentation']
        self.classes[k] = pixel_classes(env.world, seg)
        self.depth[k] = np.minimum(np.round(obs['depth'] / DEPTH_STEP), 255).astype(np.uint8)
        obj = env.world.objects.get(target) if target else None
        self.targets[k] = np.packbits(seg == obj.body) if obj is not None else 0


@functools.lru_cache(maxsize=1)
def _class_ids() -> dict[str, int]:
    return {name: k for k, name in enumerate(label_classes())}


def pixel_classes(world, segmentation: np.ndarray) -> np.ndarray:
    """Each pixel's label class (uint8: `label_classes()`'s index; 0 where no body shows) from a
    segmentation of `world`'s bodies."""
    class_id = _class_ids()
    ids, names = world.instance_table()
    table = np.zeros(max(ids, default=0) + 2, np.uint8)       # body id + 1 -> class; -1 (no body) -> 0
    for body, name in zip(ids, names):
        obj = world.objects.get(name)
        table[body + 1] = class_id.get(obj.type_name if obj is not None else name, 0)
    return table[np.clip(segmentation, -1, len(table) - 2) + 1]


def default_dir(split: str, resolution: int) -> Path:
    root = Path(os.environ.get(CACHE_ENV) or Path.home() / '.cache' / 'dialfred' / 'demonstrations')
    return root / f'{split}_{resolution}'


def frame_offsets(tasks, extra: int = 0) -> list[int]:
    """Index of each task's first frame in frames.npy (each task has expert length + 1 frames, and `extra`
    more: a build with detours keeps DETOUR_ROWS)."""
    offsets, n = [], 0
    for t in tasks:
        offsets.append(n)
        n += len(t.expert_actions) + 1 + extra
    return offsets + [n]


def expert_pixel(env, action, task_resolution: int, segmentation: np.ndarray) -> tuple[int, int]:
    """The pixel for the expert's interaction `action` in the current frame: its pixel scaled to the
    env's resolution, or the nearest pixel showing the action's target when the scaled one misses it."""
    x, y = scale_pixel(action.x, action.y, task_resolution, env.resolution)
    target = env.world.objects.get(action.target) if action.target else None
    if x < 0 or target is None or segmentation[y, x] == target.body:
        return x, y
    ys, xs = np.nonzero(segmentation == target.body)
    if len(xs) == 0:
        return x, y
    k = int(np.argmin((xs - x) ** 2 + (ys - y) ** 2))
    return int(xs[k]), int(ys[k])


def play_demonstration(env, task, frames: np.ndarray, observe: Optional[Callable] = None,
                       labels: Optional[FrameLabels] = None, detour: Optional[tuple] = None,
                       guide: Optional[Callable] = None) -> dict:
    """Replay `task`'s expert in `env`, writing its len(actions) + 1 frames into `frames` (a view of that
    many rows); the task's record for tasks.jsonl. `observe(env, k)`, if given, is called at every step
    k with the env as frame k shows it (before action k; k = len(actions) after the last). `labels`, if
    given, writes each frame's labels into the same rows of its views. With `detour` (step, wrong moves:
    `detours.detour_plan`), the agent strays at that step and the expert brings it back (`detours`); the
    record then also says which actions are imitation targets (`targets`: not the wrong moves) and
    `detour`: [step, wrong moves, moves back]; `frames` needs DETOUR_ROWS more rows. With `guide` (an
    `advise(env)`, see `detours.GuidedWalk`), the task's last go-to is a guided walk (`detours.guided_plan`):
    the record says `guided`: [step, actions walked, moves back], or None for a task without one (played as
    the expert played it), and `targets` (every action); `frames` needs DETOUR_ROWS more rows."""
    obs, _ = env.reset(options={'task': task})
    script = [(a, True) for a in task.expert_actions]
    rejoin, walk = None, None
    plan = guided_plan(task) if guide is not None else None
    if detour is not None:
        at, wrong = detour
        rejoin = rejoin_step(task, at)
        script = script[:at] + [(ExpertAction(w), False) for w in wrong]
    elif plan is not None:
        rejoin = plan[1]
        walk = GuidedWalk(task.episode.poses[task.start + rejoin], guide)
        script = script[:plan[0]]
    actions, targets, failed, success, k = [], [], 0, False, 0
    back = 0
    while True:
        if k == len(script) and rejoin is not None:
            # A detour's wrong moves made, or a guided walk's next action: then the way back and the rest.
            rest = task.expert_actions[rejoin:]
            told = walk.next(env, len(frames) - len(actions) - 1 - len(rest)) if walk is not None else None
            if told is not None:
                script.append((ExpertAction(told), True))
            else:
                moves = way_back(env.world, task.episode.poses[task.start + rejoin])
                if moves is None:
                    raise RuntimeError(f'{task.task_id}: no way back from step {k}')
                back = len(moves)
                script += [(ExpertAction(m), True) for m in moves] + [(a, True) for a in rest]
                rejoin = None
                if len(script) + 1 > len(frames):
                    raise RuntimeError(f'{task.task_id}: the detour needs {len(script) + 1} frames, {len(frames)} kept')
        if k == len(script):
            break
        a, target = script[k]
        frames[len(actions)] = obs['rgb']
        if labels is not None:
            labels.write(len(actions), env, obs, a.target)
        if observe is not None:
            observe(env, len(actions))
        x, y = expert_pixel(env, a, task.resolution, obs['segmentation'])
        kind = env.world.objects[a.target].type_name if a.target in env.world.objects else ''
        actions.append([a.action, x, y, kind])
        targets.append(target)
        obs, _, terminated, truncated, info = env.step({'action': a.action, 'pixel': (x, y)})
        failed += not info['last_action_success']
        success = bool(info['success'])
        if terminated or truncated:     # the goal held early (the rows left over stay zero)
            break
        k += 1
    frames[len(actions)] = obs['rgb']
    if labels is not None:
        labels.write(len(actions), env, obs)
    if observe is not None:
        observe(env, len(actions))
    record = {'task_id': task.task_id, 'task_type': task.task_type, 'instruction': task.instruction,
              'step_instructions': list(task.step_instructions), 'object_nouns': list(task.object_nouns),
              'actions': actions, 'success': success, 'failed_actions': failed}
    if detour is not None:
        record.update(targets=targets, detour=[detour[0], len(detour[1]), back])
    if guide is not None:
        record.update(targets=targets, guided=None if plan is None else [plan[0], walk.walked, back])
    return record


def _done_rows(out: Path) -> dict[int, dict]:
    """{task index: row} from every done-*.txt; a line cut off by an interruption is skipped."""
    done = {}
    for path in sorted(out.glob('done-*.txt')):
        for line in path.read_text().splitlines():
            try:
                row = json.loads(line)
                if isinstance(row['record'], dict):
                    done[int(row['index'])] = row
            except (ValueError, KeyError, TypeError):
                continue
    return done


def _done_records(out: Path) -> dict[int, dict]:
    """{task index: record} from every done-*.txt; a line cut off by an interruption is skipped."""
    return {k: row['record'] for k, row in _done_rows(out).items()}


def probe_values(out: Path) -> dict[str, object]:
    """{task_id: value} of what the build's probe (see build_demonstrations) returned for each task it
    played with one; tasks played without a probe, or whose probe returned None, are absent."""
    return {row['record']['task_id']: row['probe'] for row in _done_rows(Path(out)).values()
            if row.get('probe') is not None}


def load_probe(name: str):
    """The class named 'package.module:Class': a probe or a guide (see build_demonstrations)."""
    module, _, attr = name.partition(':')
    if not module or not attr:
        raise ValueError(f"a probe is named 'package.module:Class', got {name!r}")
    return getattr(importlib.import_module(module), attr)


def _worker(split: str, resolution: int, out: str, limit: Optional[int], shard: int, shards: int,
            probe: str = '', labels: bool = False, detours: bool = False, guide: str = '') -> None:
    from ..env import DialfredEnv  # lazy: gymnasium, which the rest of this module does without
    out = Path(out)
    tasks = load_split(split)[:limit]
    offsets = frame_offsets(tasks, DETOUR_ROWS if detours or guide else 0)
    done = _done_records(out)
    watcher = load_probe(probe)() if probe else None
    advise = load_probe(guide)() if guide else None
    frames = np.load(out / 'frames.npy', mmap_mode='r+')
    label_maps = [np.load(out / name, mmap_mode='r+') for name in LABEL_FILES] if labels else []
    env = DialfredEnv(resolution=resolution)
    pending = []
    log_path = out / f'done-{shard}.txt'
    cut_off = log_path.exists() and log_path.stat().st_size > 0 and not log_path.read_bytes().endswith(b'\n')
    with open(log_path, 'a') as log:
        if cut_off:
            log.write('\n')            # never glue a record onto a line an interruption cut off
        def sync() -> None:
            frames.flush()                      # the frames first, then the records that vouch for them
            for m in label_maps:
                m.flush()
            log.writelines(json.dumps(row, separators=(',', ':')) + '\n' for row in pending)
            log.flush()
            os.fsync(log.fileno())
            pending.clear()

        for k in range(shard, len(tasks), shards):
            if k in done:
                continue
            rows = slice(offsets[k], offsets[k + 1])
            task_labels = FrameLabels(*(m[rows] for m in label_maps)) if labels else None
            detour = detour_plan(tasks[k], np.random.default_rng([DETOUR_SEED, k])) if detours else None
            if watcher is None:
                record = play_demonstration(env, tasks[k], frames[rows], labels=task_labels, detour=detour,
                                            guide=advise)
                pending.append({'index': k, 'record': record})
            else:
                watcher.begin(tasks[k])
                record = play_demonstration(env, tasks[k], frames[rows], watcher, labels=task_labels, detour=detour,
                                            guide=advise)
                pending.append({'index': k, 'record': record, 'probe': watcher.end(record)})
            if len(pending) >= SYNC_EVERY:
                sync()
        sync()
    env.close()


def build_demonstrations(split: str, resolution: int = 128, out: Optional[Path] = None, workers: int = 1,
                         limit: Optional[int] = None, progress: bool = True, probe: str = '',
                         labels: bool = False, detours: bool = False, guide: str = '') -> dict:
    """Render the expert demonstrations of `split` (its first `limit` tasks) into `out`; resumes a build
    that was interrupted. Returns the contents of meta.json.

    `probe` ('package.module:Class') lets another package look at every task while it is played,
    instead of replaying it later: each worker makes one `Class()`, calls `begin(task)` before a
    task, `probe(env, k)` at each of its steps (play_demonstration's `observe`) and `end(record)`
    after it, and keeps what `end` returns (JSON, or None for nothing) beside the task's record;
    `probe_values(out)` reads them back. A probe must leave the env as it found it: the frames and
    records are the same with or without one. `labels` also writes each frame's labels (the module's
    classes.npy, depth.npy, targets.npy); the frames are the same with or without them. `detours` plays
    every task with a detour in one of its go-tos (`detours.py`; drawn from the task's index), in
    DETOUR_ROWS more rows a task. `guide` ('package.module:Class', a class whose instances are an
    `advise(env)`: see `detours.GuidedWalk`) plays every task's last go-to as a guided walk, in as many rows."""
    if detours and guide:
        raise ValueError('a build has detours or guided walks, not both')
    t0 = time.monotonic()
    if resolution < 16:
        raise ValueError(f'resolution must be at least 16, got {resolution}')
    out = Path(out) if out else default_dir(split, resolution)
    out.mkdir(parents=True, exist_ok=True)
    tasks = load_split(split)[:limit]
    offsets = frame_offsets(tasks, DETOUR_ROWS if detours or guide else 0)
    shape = (offsets[-1], resolution, resolution, 3)
    frames_path = out / 'frames.npy'
    started = (out / 'build.json').exists() and json.loads((out / 'build.json').read_text())
    plan = {'split': split, 'resolution': resolution, 'tasks': len(tasks), 'frames': offsets[-1]}
    if labels:
        plan['labels'] = True         # a build without labels is not one with them: it is made again
    if detours:
        plan['detours'] = True
    if guide:
        plan['guide'] = guide
    if started != plan or not frames_path.exists():
        for stale in [frames_path, out / 'meta.json', out / 'tasks.jsonl', *out.glob('done-*.txt'),
                      *(out / name for name in LABEL_FILES)]:
            stale.unlink(missing_ok=True)
        np.lib.format.open_memmap(frames_path, mode='w+', dtype=np.uint8, shape=shape).flush()
        if labels:
            for name, row in zip(LABEL_FILES, [(resolution, resolution), (resolution, resolution),
                                               ((resolution * resolution + 7) // 8,)]):
                np.lib.format.open_memmap(out / name, mode='w+', dtype=np.uint8, shape=(offsets[-1], *row)).flush()
        (out / 'build.json').write_text(json.dumps(plan) + '\n')
    elif (out / 'meta.json').exists():
        return json.loads((out / 'meta.json').read_text())       # already complete
    workers = max(1, min(workers, len(tasks)))
    args = [(split, resolution, str(out), limit, k, workers, probe, labels, detours, guide) for k in range(workers)]
    if workers == 1:
        _run_with_progress(None, args, out, len(tasks), progress)
    else:
        with worker_pool(workers) as pool:
            _run_with_progress(pool, args, out, len(tasks), progress)
    done = _done_records(out)
    missing = [k for k in range(len(tasks)) if k not in done]
    if missing:
        raise RuntimeError(f'{len(missing)} tasks were not rendered (first: {tasks[missing[0]].task_id})')
    with open(out / 'tasks.jsonl', 'w') as f:
        for k in range(len(tasks)):
            f.write(json.dumps({**done[k], 'first_frame': offsets[k]}, separators=(',', ':')) + '\n')
    successes = sum(done[k]['success'] for k in range(len(tasks)))
    meta = {**plan, 'success_rate': round(successes / max(len(tasks), 1), 5),
            'failed_tasks': [done[k]['task_id'] for k in range(len(tasks)) if not done[k]['success']],
            'seconds_this_run': round(time.monotonic() - t0, 1), 'workers': workers,
            'frames_bytes': int(np.prod(shape))}
    write_text_atomically(out / 'meta.json', json.dumps(meta, indent=1) + '\n')   # the build's last word
    return meta


def _count_done(out: Path) -> int:
    """Finished tasks so far, for the progress bar (lines, without parsing them)."""
    return sum(path.read_bytes().count(b'\n') for path in out.glob('done-*.txt'))


def _run_with_progress(pool, args, out: Path, total: int, progress: bool) -> None:
    from ..progress import progress_bar  # lazy: tqdm, which the rest of this module does without
    with progress_bar(total=total, initial=_count_done(out), unit='task',
              disable=not progress) as bar:
        if pool is None:
            _worker(*args[0])
        else:
            result = pool.starmap_async(_worker, args)
            while not result.ready():
                result.wait(1.0)
                bar.n = min(_count_done(out), total)
                bar.refresh()
            result.get()                # re-raises a worker's exception
        bar.n = min(_count_done(out), total)
        bar.refresh()


@dataclass
class Demonstrations:
    """A finished build: `frames` (read-only memmap) and `tasks` (the records of tasks.jsonl)."""

    frames: np.ndarray
    tasks: list[dict]
    meta: dict
    labels: Optional[dict] = None      # {'classes', 'depth', 'targets'}: read-only memmaps of a --labels build

    def __len__(self) -> int:
        return len(self.tasks)

    def frames_of(self, k: int) -> np.ndarray:
        """The n + 1 frames of task k (a view: nothing is read until it is used)."""
        first = self.tasks[k]['first_frame']
        return self.frames[first:first + len(self.tasks[k]['actions']) + 1]

    def joined(self, others: Sequence['Demonstrations'], tags: Sequence[str]) -> 'Demonstrations':
        """This build and `others` read as one: their tasks after this one's, each task id of `others[i]`
        followed by `tags[i]` (a detour build's tasks have the plain build's ids), frames and labels
        (labels only if every build has them) as `JoinedRows`."""
        tasks, frames, offset = list(self.tasks), [self.frames], len(self.frames)
        for other, tag in zip(others, tags, strict=True):
            tasks += [{**t, 'task_id': t['task_id'] + tag, 'first_frame': t['first_frame'] + offset}
                      for t in other.tasks]
            frames.append(other.frames)
            offset += len(other.frames)
        builds = [self, *others]
        labels = None
        if all(b.labels is not None for b in builds):
            labels = {name: JoinedRows([b.labels[name] for b in builds]) for name in self.labels}
        return Demonstrations(JoinedRows(frames), tasks, {**self.meta, 'tasks': len(tasks), 'frames': offset}, labels)


class JoinedRows:
    """The rows of several arrays (memmaps of frames or labels) read as one array: an integer, a slice or an
    array of row indices gives what the concatenation would, reading only those rows."""

    def __init__(self, parts: Sequence[np.ndarray]):
        self.parts = list(parts)
        self.bounds = np.cumsum([0, *(len(p) for p in self.parts)])
        self.shape = (int(self.bounds[-1]), *self.parts[0].shape[1:])
        self.dtype = self.parts[0].dtype

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, key):
        if isinstance(key, slice):
            start, stop, step = key.indices(len(self))
            part = int(np.searchsorted(self.bounds, start, side='right')) - 1
            if step == 1 and 0 <= part < len(self.parts) and stop <= self.bounds[part + 1]:
                return self.parts[part][start - self.bounds[part]:stop - self.bounds[part]]
            key = np.arange(start, stop, step)
        ids = np.asarray(key)
        one = ids.ndim == 0
        ids = np.atleast_1d(ids).astype(np.int64)
        ids = np.where(ids < 0, ids + len(self), ids)
        if ids.size and (ids.min() < 0 or ids.max() >= len(self)):
            raise IndexError(f'row {int(ids.max()) if ids.max() >= len(self) else int(ids.min())} of {len(self)}')
        out = np.empty((len(ids), *self.shape[1:]), self.dtype)
        which = np.searchsorted(self.bounds, ids, side='right') - 1
        for part in np.unique(which):
            mask = which == part
            out[mask] = self.parts[part][ids[mask] - self.bounds[part]]
        return out[0] if one else out


def load_demonstrations(path: Path) -> Demonstrations:
    """Open a build made by `build_demonstrations`; FileNotFoundError if it is missing or unfinished."""
    path = Path(path)
    if not (path / 'meta.json').exists():
        raise FileNotFoundError(f'no finished demonstrations in {path} (meta.json is written last); '
                                'run python -m dialfred_sim.tasks.demonstrations')
    meta = json.loads((path / 'meta.json').read_text())
    tasks = [json.loads(line) for line in (path / 'tasks.jsonl').read_text().splitlines()]
    frames = np.load(path / 'frames.npy', mmap_mode='r')
    if len(tasks) != meta['tasks'] or frames.shape[0] != meta['frames']:
        raise ValueError(f'{path}: tasks.jsonl or frames.npy do not match meta.json')
    labels = None
    if meta.get('labels'):
        labels = {name[:-4]: np.load(path / name, mmap_mode='r') for name in LABEL_FILES}
        if any(m.shape[0] != meta['frames'] for m in labels.values()):
            raise ValueError(f'{path}: the label files do not match meta.json')
    return Demonstrations(frames, tasks, meta, labels)


@dataclass
class DemonstrationsConfig:
    """Render the expert demonstrations of a split (frames + actions)."""

    split: str = arg(REQUIRED, 'the split', choices=sorted(SPLIT_SIZES), positional=True)
    resolution: int = arg(128, 'camera pixels')
    workers: int = arg(1, 'processes, each playing every n-th task')
    limit: Optional[int] = arg(None, 'only the first N tasks of the split (none: all)', metavar='N')
    out: Optional[Path] = arg(None, 'output folder (none: ~/.cache/dialfred/demonstrations/<split>_<resolution>, '
                              'or $DIALFRED_DEMO_DIR/...)', metavar='DIR')
    progress: bool = arg(True, 'a progress bar on stderr')
    labels: bool = arg(False, 'also write each frame\'s labels (classes.npy, depth.npy, targets.npy) for training '
                       'perception')


def main(argv=None) -> int:
    ap = parser_for(DemonstrationsConfig)
    args = from_args(DemonstrationsConfig, ap.parse_args(argv), ap)
    try:
        meta = build_demonstrations(args.split, args.resolution, args.out, args.workers, args.limit,
                                    progress=args.progress, labels=args.labels)
    except ValueError as exc:
        ap.error(str(exc))
    except KeyboardInterrupt:
        print('interrupted: the same command resumes', file=sys.stderr)
        return 130
    print(json.dumps({k: v for k, v in meta.items() if k != 'failed_tasks'} |
                     {'failed_tasks': len(meta['failed_tasks'])}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
