"""Everything the performer's training needs from a split, in its demonstrations folder (no ROS).

    ./dialfred prepare-performer --split train --resolution 64 --workers 2

1. the expert demonstrations (`dialfred_sim.tasks.demonstrations`: frames.npy, tasks.jsonl, meta.json);
2. `dialogues.jsonl`: the real oracle's answers at every step of each expert episode, as a log of
   changes (`data.AnswerLog`: every QA at step 0, then a QA only where its answer changed; the looks,
   appearance, asked at step 0 and the middle step only: along a path they differ in 1 of 122 nouns
   of valid_unseen's first 80 tasks). They are asked while stage 1 plays each task (`data.OracleProbe`,
   a probe of the build), which saves a second reset and replay of every task. The few tasks it cannot
   answer (the goal held early, so the middle step moved; about 0.3% of train), or all tasks of a build
   made without the probe, are replayed (`data.task_dialogue` in DialfredEnv): workers each take every
   n-th task and append a line per task to `dialogues-<worker>.part` as it is produced, so an
   interrupted run resumes where it stopped; the parts are merged in task order at the end (same bytes
   with any number of workers, and with or without the probe: tests/performer/test_performer_train.py);
3. `vocabulary.json`: every token of the instructions, nouns and QAs of the folder, plus every word
   the oracle can say (templates, object nouns, colours, materials), so that no answer heard at
   evaluation is <unk>.

Each stage is skipped when its output is complete. Prints a JSON report with each stage's seconds.
"""

from __future__ import annotations

import json
import os
import resource
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from dialfred_oracle import answers
from dialfred_oracle.questions import oracle_questions
from dialfred_sim.dataclass_cli import arg, parse
from dialfred_sim.processes import worker_pool
from dialfred_sim.tasks.demonstrations import build_demonstrations, default_dir, load_demonstrations, probe_values
from dialfred_sim.tasks.splits import SPLIT_SIZES
from dialfred_sim.catalog import load_catalog
from dialfred_sim.palette import COLOUR_NAMES

from .data import DIALOGUES_FILE, dialogue_line, task_dialogue, vocabulary_texts
from .malloc import ensure_malloc_settings
from .preprocess import Vocabulary

VOCABULARY_FILE = 'vocabulary.json'
ORACLE_PROBE = 'dialfred_performer.data:OracleProbe'    # the dialogues' QAs asked while rendering
ANNOTATING_PROBE = 'dialfred_performer.data:AnnotatingProbe'   # ... and the synthetic annotators' rows
DETOUR_PROBE = 'dialfred_performer.data:DetourProbe'       # a build with detours (its looks at step 0 only)
DIRECTION_GUIDE = 'dialfred_performer.data:DirectionGuide'   # a build with guided walks: the direction answers' way
SYNC_EVERY = 10          # tasks between fsyncs of a worker's part file


@dataclass(frozen=True)
class PrepareConfig:
    """Prepare a split for performer training: demonstrations, dialogues.jsonl, vocabulary.json."""

    split: str = arg('train', f'one of {sorted(SPLIT_SIZES)}')
    resolution: int = arg(64, 'frame size of the demonstrations')
    workers: int = arg(2, 'processes for rendering and for the dialogues')
    limit: int = arg(0, 'only the first N tasks of the split (0: all); use with --out')
    out: str = arg('', 'the demonstrations folder (default: ~/.cache/dialfred/demonstrations/<split>_<resolution>)')
    progress: bool = arg(True, 'progress bars on stderr')
    annotate: bool = arg(False, 'also make the synthetic annotators\' rows of every task while rendering '
                                '(scripts/annotate_dialogues.py --from-demonstrations then writes them)')
    labels: bool = arg(False, 'also write each frame\'s labels (classes, depth, the target\'s pixels) for training '
                              'perception (dialfred_sim.tasks.demonstrations)')
    detours: bool = arg(False, 'play every task with a detour in one of its go-tos and the expert\'s way back '
                               '(dialfred_sim.tasks.detours), into <split>_<resolution>_detours by default: frames '
                               'off the expert\'s path, the oracle\'s answers there, the moves that lead back')
    guided: bool = arg(False, 'play every task\'s last go-to as a guided walk (dialfred_sim.tasks.detours): the moves '
                              'and turns the oracle\'s direction answers say, step by step, into '
                              '<split>_<resolution>_guided by default (the expert\'s shortest way does not turn '
                              'where an answer says to)')

    def __post_init__(self):
        if self.split not in SPLIT_SIZES:
            raise ValueError(f'split must be one of {sorted(SPLIT_SIZES)}, got {self.split!r}')
        if self.resolution < 16:
            raise ValueError(f'resolution must be at least 16, got {self.resolution}')
        if self.workers < 1:
            raise ValueError(f'workers must be at least 1, got {self.workers}')
        if self.limit < 0:
            raise ValueError(f'limit must be >= 0 (0: all tasks), got {self.limit}')
        if self.detours and self.guided:
            raise ValueError('a build has --detours or --guided walks, not both')
        if (self.detours or self.guided) and self.annotate:
            raise ValueError('--annotate makes the annotators\' rows of the tasks\' starts: take them from the plain '
                             'build, not one with --detours or --guided')

    @property
    def folder(self) -> Path:
        if self.out:
            return Path(self.out).expanduser()
        plain = default_dir(self.split, self.resolution)
        return plain.with_name(plain.name + '_detours') if self.detours else \
            plain.with_name(plain.name + '_guided') if self.guided else plain


def oracle_texts() -> list[str]:
    """Every word the oracle's answers can contain: each question type's fixed words
    (`OracleQuestion.vocabulary`), the withheld answer, and every object noun, colour and material of
    the catalogue."""
    texts = [*(text for q in oracle_questions() for text in q.vocabulary()), answers.WITHHELD, *COLOUR_NAMES]
    for t in load_catalog().values():
        texts += [t.noun, *t.nouns, *t.materials]
    return texts


def build_vocabulary(folder: Path) -> Vocabulary:
    return Vocabulary.build(vocabulary_texts(folder) + oracle_texts())


# ---------------------------------------------------------------------- dialogues

def _part_path(folder: Path, shard) -> Path:
    return folder / f'dialogues-{shard}.part'


def _finished_lines(folder: Path) -> dict[str, str]:
    """{task_id: line} of every part file; a line an interruption cut off is skipped."""
    done = {}
    for path in sorted(folder.glob('dialogues-*.part')):
        for line in path.read_text().splitlines():
            try:
                done[json.loads(line)['task_id']] = line + '\n'
            except (ValueError, KeyError, TypeError):
                continue
    return done


def _dialogue_worker(folder: str, shard: int, shards: int) -> None:
    from dialfred_sim.env import DialfredEnv  # lazy: gymnasium, which the rest of this module does without
    folder = Path(folder)
    demo = load_demonstrations(folder)
    done = _finished_lines(folder)
    env = DialfredEnv(resolution=demo.meta['resolution'])
    path = _part_path(folder, shard)
    cut_off = path.exists() and path.stat().st_size > 0 and not path.read_bytes().endswith(b'\n')
    with open(path, 'a') as part:
        if cut_off:
            part.write('\n')              # never glue a line onto one an interruption cut off
        for n, task in enumerate(demo.tasks[shard::shards]):
            if task['task_id'] in done:
                continue
            part.write(dialogue_line(task, task_dialogue(env, task)))
            part.flush()
            if n % SYNC_EVERY == 0:
                os.fsync(part.fileno())
    env.close()


def write_dialogues(folder: Path, workers: int = 1, progress: bool = True) -> Path:
    """dialogues.jsonl for every task of the demonstrations `folder` (resumable; see the module doc).
    The QAs the build's OracleProbe asked while rendering are taken as they are; only the other
    tasks are replayed."""
    from dialfred_sim.progress import progress_bar  # lazy: tqdm, which the rest of this module does without
    folder = Path(folder)
    demo = load_demonstrations(folder)
    out = folder / DIALOGUES_FILE
    total = len(demo.tasks)
    if out.exists() and sum(1 for _ in out.open()) == total:
        return out
    probed = {tid: v['qas'] for tid, v in probe_values(folder).items() if isinstance(v, dict) and v.get('qas') is not None}
    if probed:
        done = _finished_lines(folder)
        lines = [json.dumps({'task_id': t['task_id'], 'every_step': True, 'qas': probed[t['task_id']]}) + '\n'
                 for t in demo.tasks
                 if t['task_id'] in probed and t['task_id'] not in done]
        with open(_part_path(folder, 'probe'), 'a') as part:
            part.writelines(lines)
    todo = total - len(_finished_lines(folder))
    workers = max(1, min(workers, todo))
    args = [(str(folder), k, workers) for k in range(workers)]

    def count() -> int:
        return sum(p.read_bytes().count(b'\n') for p in folder.glob('dialogues-*.part'))

    with progress_bar(total=total, initial=min(count(), total), unit='task', desc='dialogues',
              disable=not progress) as bar:
        if not todo:
            pass
        elif workers == 1:
            _dialogue_worker(*args[0])
        else:
            with worker_pool(workers) as pool:
                result = pool.starmap_async(_dialogue_worker, args)
                while not result.ready():
                    result.wait(1.0)
                    bar.n = min(count(), total)
                    bar.refresh()
                result.get()               # re-raises a worker's exception
        bar.n = min(count(), total)
        bar.refresh()
    done = _finished_lines(folder)
    missing = [t['task_id'] for t in demo.tasks if t['task_id'] not in done]
    if missing:
        raise RuntimeError(f'{len(missing)} tasks have no dialogue (first: {missing[0]})')
    tmp = out.with_name(out.name + '.tmp')
    tmp.write_text(''.join(done[t['task_id']] for t in demo.tasks))
    tmp.replace(out)
    for p in folder.glob('dialogues-*.part'):
        p.unlink()
    return out


def _clock() -> tuple[float, float]:
    """(wall seconds, CPU seconds of this process and its finished children)."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.monotonic(), own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def prepare(config: PrepareConfig) -> dict:
    """Run the three stages for `config` (each skipped when complete); the report, with each stage's
    wall and CPU seconds (CPU: this process and its workers; on a shared machine the better measure)."""
    folder = config.folder
    report = {'split': config.split, 'resolution': config.resolution, 'workers': config.workers,
              'folder': str(folder)}
    c0 = _clock()
    probe = DETOUR_PROBE if config.detours or config.guided else ANNOTATING_PROBE if config.annotate else ORACLE_PROBE
    meta = build_demonstrations(config.split, config.resolution, folder, workers=config.workers,
                                limit=config.limit or None, progress=config.progress, probe=probe,
                                labels=config.labels, detours=config.detours,
                                guide=DIRECTION_GUIDE if config.guided else '')
    c1 = _clock()
    write_dialogues(folder, config.workers, config.progress)
    c2 = _clock()
    vocab = build_vocabulary(folder)
    vocab.save(folder / VOCABULARY_FILE)
    c3 = _clock()
    stages = {'demonstrations': (c0, c1), 'dialogues': (c1, c2), 'vocabulary': (c2, c3)}
    report.update(tasks=meta['tasks'], frames=meta['frames'], vocabulary=len(vocab),
                  seconds={k: round(b[0] - a[0], 1) for k, (a, b) in stages.items()},
                  cpu_seconds={k: round(b[1] - a[1], 1) for k, (a, b) in stages.items()})
    return report


def main(argv: Optional[list[str]] = None) -> int:
    config = parse(PrepareConfig, argv, prog='python -m dialfred_performer.prepare')
    print(json.dumps(prepare(config)))
    return 0


if __name__ == '__main__':
    ensure_malloc_settings('dialfred_performer.prepare')
    sys.exit(main())
