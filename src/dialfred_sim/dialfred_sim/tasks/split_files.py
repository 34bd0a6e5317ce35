"""The split files: which splits there are (names, sizes, rooms), where each one's tasks are kept,
reading them (`load_split`, `read_tasks_file` for a test split of one's own) and looking a task up by
id (`get_task`, `resolve_task`). ROS-free, and free of the simulator: the environment looks tasks up
here, and `splits` (which plays episodes in the simulator to make a split) writes what this reads.
"""

from __future__ import annotations

import functools
import gzip
import hashlib
import io
import json
import os
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Optional

from ..world.rooms import SCENE_RANGES
from .schema import Condition, Episode, ExpertAction, Primitive, Task

SPLIT_SIZES = {'train': 34253, 'valid_seen': 1296, 'valid_unseen': 1363}
TEST_SPLIT = 'test_unseen'           # made by each user from a seed of their own; never shipped
SPLIT_CODES = {'train': 1, 'valid_seen': 2, 'valid_unseen': 3, TEST_SPLIT: 4}
# ALFRED's released scene split: valid_unseen and test_unseen rooms never appear in train.
VALID_UNSEEN_SCENES = (10, 219, 308, 424)
TEST_UNSEEN_SCENES = (9, 29, 215, 226, 315, 325, 404, 425)
CACHE_ENV = 'DIALFRED_TASK_DIR'      # where generated splits (train) are kept


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
            **({'visible_end': t.visible_end} if t.visible_end is not None else {}),
        } for t in _under_dialfred_rule(tasks)],
    }


def tasks_from_json(row: dict) -> list[Task]:
    episode = Episode(row['episode_id'], row['split'], row['scene'], int(row['seed']), row['alfred_type'],
                      row['setup'], [ExpertAction.from_json(a) for a in row['actions']],
                      [Primitive.from_json(p) for p in row['primitives']],
                      [(int(p[0]), int(p[1]), int(p[2]), float(p[3])) for p in row['poses']], int(row['resolution']))
    return [Task(t['task_id'], t['task_type'], episode, int(t['start']), int(t['end']),
                 [Condition.from_json(c) for c in t['goal']], t['instruction'], list(t['step_instructions']),
                 list(t['object_nouns']), [episode.primitives[i] for i in t['primitives']],
                 bool(t['target_visible_at_start']), bool(t['has_distractor']),
                 int(t['visible_end']) if t.get('visible_end') is not None else None) for t in row['tasks']]


def _under_dialfred_rule(tasks: list[Task]) -> list[Task]:
    """Split files keep tasks as DialFRED's rule judges them (goals.under_rule makes the other rule's)."""
    bad = [t.task_id for t in tasks if t.goal_rule != 'dialfred']
    if bad:
        raise ValueError(f'tasks {bad[:3]} follow the {tasks[0].goal_rule!r} goal rule: a split file keeps DialFRED\'s')
    return tasks


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
