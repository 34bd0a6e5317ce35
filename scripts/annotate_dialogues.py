#!/usr/bin/env python3
"""SYNTHETIC dialogue data: two synthetic annotators question and answer every task of the splits.

    ./dialfred env python3 scripts/annotate_dialogues.py [--splits valid_seen valid_unseen train] [--workers 2]
    ./dialfred env python3 scripts/annotate_dialogues.py --fit          # refit the choice model (valid splits)
    ./dialfred env python3 scripts/annotate_dialogues.py --doc-only     # rewrite the doc from the files present

For each task: reset a DialfredEnv to it, take the ground-truth snapshot at its start, and let
annotators 0 and 1 (`dialfred_oracle.annotator.annotate`, seeds from (split, task number, annotator))
pick a question or none and answer it in their own words. Writes one gzip JSON line per task
(`annotator.dialogue_path`: the valid splits into the package, train into ~/.cache/dialfred/dialogues/),
prints the statistics per split as JSON on stdout (progress on stderr) and writes docs/dialogue_data.md.
Everything is deterministic from seeds: a rerun writes the same bytes.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Sequence

import jinja2
import numpy as np

from dialfred_oracle.annotator import (  # noqa: F401  (SEED, ANNOTATORS, annotator_rng: the tests read them here)
    ANNOTATION_RESOLUTION, ANNOTATION_SEED as SEED, ANNOTATORS, annotate_task, annotator_rng, categories, choice_model,
    LENGTH_MEAN, LENGTH_SHAPE, necessary_p, Situation, TaskDialogues, annotate, dialogue_path, dialogue_statistics,
    evidence, expected_statistics, fit_choice_model, load_dialogues, write_dialogues)
from dialfred_sim.processes import worker_pool
from dialfred_sim.progress import progress_bar
from dialfred_sim.protocol import question_kinds
from dialfred_sim.tasks import SPLIT_SIZES, load_split

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / 'docs' / 'dialogue_data.md'
SPLITS = ('valid_seen', 'valid_unseen', 'train')
CHUNK = 16               # tasks per job sent to a worker
# Worker processes are replaced after this many chunks (400 tasks): a bound on any memory growth of
# the simulator across resets (about 1 MB per reset once, which killed a 2-worker train run).
CHUNKS_PER_WORKER = 25
EXAMPLES_SPLIT, EXAMPLE_COUNT = 'valid_unseen', 8


# ---------------------------------------------------------------------- workers (one env each)

_ENV = None
_SPLIT = ''


def _init_worker(split: str) -> None:
    global _ENV, _SPLIT
    from dialfred_sim.env import DialfredEnv  # lazy: --doc-only writes the doc without the simulator
    _ENV, _SPLIT = DialfredEnv(resolution=ANNOTATION_RESOLUTION), split


def _situation_and_snapshot(task):
    from dialfred_sim.ground_truth import snapshot  # lazy: as DialfredEnv in _init_worker
    _ENV.reset(options={'task': task})
    snap = snapshot(_ENV)
    return Situation.of(task, snap), snap


def _annotate_chunk(bounds: tuple[int, int]) -> list[dict]:
    tasks = load_split(_SPLIT)[bounds[0]:bounds[1]]
    rows = []
    for task in tasks:
        _ENV.reset(options={'task': task})
        rows.append(annotate_task(_ENV, task).to_json())
    return rows


def _situation_chunk(bounds: tuple[int, int]) -> list[dict]:
    return [_situation_and_snapshot(t)[0].to_json() for t in load_split(_SPLIT)[bounds[0]:bounds[1]]]


def run_split(split: str, job, workers: int, limit: int = 0) -> list[dict]:
    """`job` over every task of `split` (its first `limit` if > 0) in chunks, in task order, on `workers` processes."""
    n = len(load_split(split)[:limit or None])
    chunks = [(k, min(k + CHUNK, n)) for k in range(0, n, CHUNK)]
    out = []
    with worker_pool(max(1, workers), initializer=_init_worker, initargs=(split,),
                     maxtasksperchild=CHUNKS_PER_WORKER) as pool, \
            progress_bar(total=n, unit='task', desc=split) as bar:     # plain lines when stderr is a log
        for rows in pool.imap(job, chunks):
            out.extend(rows)
            bar.update(len(rows))
    return out


def probed_rows(split: str, demonstrations: Path, workers: int, limit: int = 0) -> list[dict]:
    """The rows of `split` (its first `limit` tasks if > 0) in task order: those an AnnotatingProbe made
    while `demonstrations` was rendered (`prepare --annotate`), the others annotated here as usual."""
    from dialfred_performer.data import probed_annotations  # lazy: torch, for --from-demonstrations alone
    tasks = load_split(split)[:limit or None]
    probed = probed_annotations(demonstrations)
    missing = [k for k, t in enumerate(tasks) if t.task_id not in probed]
    if len(missing) == len(tasks):
        raise SystemExit(f'{demonstrations} holds no annotator rows: build it with prepare --annotate')
    made = {}
    if missing:
        print(f'{split}: {len(missing)} tasks without a probed row, annotated here', file=sys.stderr)
        _init_worker(split)
        for k in missing:
            made[k] = _annotate_chunk((k, k + 1))[0]
    print(f'{split}: {len(tasks) - len(missing)} rows made while rendering {demonstrations}', file=sys.stderr)
    return [made[k] if k in made else probed[t.task_id] for k, t in enumerate(tasks)]


def valid_situations(split: str, workers: int) -> list[Situation]:
    """The situations of `split`'s tasks: read from its dialogue file if there is one (they do not
    depend on the choice model), else computed in the simulator."""
    try:
        return [r.situation for r in load_dialogues(split)]
    except FileNotFoundError:
        return [Situation.from_json(d) for d in run_split(split, _situation_chunk, workers)]


def available_splits(splits: Sequence[str]) -> tuple[list[str], list[str]]:
    """The splits whose tasks exist here, and the absent ones (with a message on stderr)."""
    present, absent = [], []
    for split in splits:
        try:
            load_split(split)
            present.append(split)
        except FileNotFoundError as exc:
            absent.append(split)
            print(f'skipping {split}: its tasks are not generated on this machine ({exc})', file=sys.stderr)
    return present, absent


# ---------------------------------------------------------------------- the data card

def situation_shares(rows: Sequence[TaskDialogues]) -> dict[str, dict[str, float]]:
    """Share of each choice (none / location / appearance / direction) among annotations in each situation."""
    groups = {
        'target not visible': lambda s: not s.target_visible,
        'same-class distractor of the target': lambda s: s.main_has_distractor,
        'target behind the agent': lambda s: s.target_behind,
        'clear (complete instruction, target visible, no distractor)': lambda s: s.clear,
        'all tasks': lambda s: True,
    }
    out = {}
    for label, test in groups.items():
        picked = [a for r in rows if test(r.situation) for a in r.annotations]
        out[label] = {'annotations': len(picked),
                      **{c: round(sum(a.category == c for a in picked) / max(len(picked), 1), 4) for c in categories()}}
    return out


def _f(v, digits=2) -> str:
    return '-' if v is None else f'{v:.{digits}f}'


# (row label, value from dialogue_statistics, paper's human figure)
STAT_ROWS = (
    ('tasks', lambda s: f"{s['tasks']:,}", '29,376 sub-goals'),
    ('annotations (2 per task)', lambda s: f"{s['annotations']:,}", '53K questions and answers'),
    ('questions per task and annotator', lambda s: _f(s['questions_per_task']), '0.66'),
    ('location share of questions', lambda s: _f(s['type_shares']['location']), '0.72'),
    ('appearance share of questions', lambda s: _f(s['type_shares']['appearance']), '0.22'),
    ('direction share of questions', lambda s: _f(s['type_shares']['direction']), '0.06'),
    ('words per answer, mean', lambda s: _f(s['answer_words']), '6.73'),
    ('answer vocabulary (distinct words)', lambda s: f"{s['answer_vocabulary']:,}", '7,915 (NDW)'),
    ('asking judged necessary (of questions)', lambda s: _f(s['necessary_fraction']), 'not reported'),
    ("Fleiss' kappa of the question choice", lambda s: _f(s['fleiss_kappa']), '0.13'),
)


def table(header: Sequence[str], rows: Sequence[Sequence[str]], align: str) -> list[str]:
    rule = ['---:' if a == 'r' else '---' for a in align]
    return ['| ' + ' | '.join(r) + ' |' for r in [list(header), rule, *map(list, rows)]]


def doc_text(stats: dict[str, dict], shares: dict[str, dict], absent: Sequence[str],
             examples: Sequence[TaskDialogues]) -> str:
    """docs/dialogue_data.md (its first line says that the data is synthetic); the words are
    templates/dialogue_data.md.j2, the model's numbers and the tables come from here."""
    m = choice_model()
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(Path(__file__).resolve().parent / 'templates'),
                             autoescape=False, keep_trailing_newline=True, undefined=jinja2.StrictUndefined)
    names = list(stats)
    stats_rows = [[label] + [value(stats[n]) for n in names] + [paper] for label, value, paper in STAT_ROWS]
    share_rows = [[label, f"{v['annotations']:,}"] + [f'{v[c]:.2f}' for c in categories()] for label, v in shares.items()]
    example_rows = []
    for r in examples:
        for a in r.annotations:
            asked = f'{a.question} -> "{a.answer}" ({"necessary" if a.necessary else "not necessary"})' \
                if a.question_type else '(no question)'
            example_rows.append([f'`{r.task_id}`' if a.annotator_id == 0 else '', r.instruction if a.annotator_id == 0 else '',
                                 str(a.annotator_id), asked.replace('|', '/'),
                                 a.oracle_answer.replace('|', '/') if a.question_type else ''])
    return env.get_template('dialogue_data.md.j2').render(
        seed=SEED, questions=', '.join(f'"{q.template}"' for q in question_kinds()),
        strength=m.strength, bias=', '.join(f'{c} {b:+.3f}' for c, b in zip(categories(), m.bias)),
        length_shape=f'{LENGTH_SHAPE:g}', length_mean=f'{LENGTH_MEAN - 1:g}',
        necessary='; '.join(f'{t} {lo} / {hi}' for t, (lo, hi) in necessary_p().items()),
        absent=', '.join(f'`{s}`' for s in absent),
        stats_table='\n'.join(table(['statistic', *names, 'paper (human)'], stats_rows, 'l' + 'r' * (len(names) + 1))),
        shares_table='\n'.join(table(['situation', 'annotations', *categories()], share_rows, 'lr' + 'r' * len(categories()))),
        examples_split=EXAMPLES_SPLIT,
        examples_table='\n'.join(table(['task', 'instruction', 'annotator', 'question -> free-form answer',
                                        'oracle\'s answer'], example_rows, 'lllll')))


def pick_examples(rows: Sequence[TaskDialogues], count: int = EXAMPLE_COUNT) -> list[TaskDialogues]:
    """Tasks of different types spread over the split (a fixed shuffle), together showing every
    choice (none included), the rest with two questions; in task order."""
    order = [rows[int(k)] for k in np.random.default_rng(SEED).permutation(len(rows))]
    picked: list[TaskDialogues] = []
    want = set(categories())
    for first_pass in (True, False):
        for r in order:
            kinds = {a.category for a in r.annotations}
            fits = kinds & want if first_pass else 'none' not in kinds
            if len(picked) < count and fits and r not in picked \
                    and r.task_type not in {p.task_type for p in picked}:
                picked.append(r)
                want -= kinds
    return sorted(picked, key=lambda r: r.task_id)


def write_doc(path: Path = DOC) -> dict[str, dict]:
    """Write the doc from the dialogue files present; returns the statistics per split."""
    loaded, absent = {}, []
    for split in SPLITS:
        try:
            loaded[split] = load_dialogues(split)
        except FileNotFoundError:
            absent.append(split)
    stats = {s: dialogue_statistics([r.annotations for r in rows]) for s, rows in loaded.items()}
    shares = situation_shares([r for rows in loaded.values() for r in rows])
    examples = pick_examples(loaded.get(EXAMPLES_SPLIT, []))
    path.write_text(doc_text(stats, shares, absent, examples))
    return stats


# ---------------------------------------------------------------------- entry point

def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--splits', nargs='+', choices=SPLITS, default=list(SPLITS))
    ap.add_argument('--workers', type=int, default=2, help='processes, each with its own simulator')
    ap.add_argument('--fit', action='store_true', help='fit the choice model on the valid splits and print it')
    ap.add_argument('--doc-only', action='store_true', help='only rewrite docs/dialogue_data.md')
    ap.add_argument('--doc', default=str(DOC), help='markdown file to write')
    ap.add_argument('--from-demonstrations', default='', metavar='DIR',
                    help='train only: take the rows an AnnotatingProbe made while DIR (prepare --annotate) was '
                         'rendered, and annotate only the tasks it has no row for (the same rows either way)')
    ap.add_argument('--limit', type=int, default=0,
                    help='only the first N tasks of each split (0: all); set DIALFRED_DIALOGUE_DIR and --doc '
                         'so that a slice does not replace the full files')
    args = ap.parse_args(argv)
    if args.fit:
        situations = [s for split in ('valid_seen', 'valid_unseen') for s in valid_situations(split, args.workers)]
        model = fit_choice_model(situations)
        shares, kappa = expected_statistics(model, situations)
        print(json.dumps({'model': repr(model), 'expected_shares': dict(zip(categories(), shares.round(4).tolist())),
                          'expected_kappa': round(kappa, 4),
                          'mean_evidence': dict(zip(categories(), np.mean([evidence(s) for s in situations], 0)
                                                    .round(4).tolist()))}, indent=1))
        return 0
    timings = {}
    if not args.doc_only:
        if args.limit and set(args.splits) - {'train'}:
            ap.error('--limit is for train only: the valid splits\' dialogues are shipped in the package')
        present, _ = available_splits(args.splits)
        if args.from_demonstrations and args.splits != ['train']:
            ap.error('--from-demonstrations is for --splits train only')
        for split in present:
            t0 = time.monotonic()
            if args.from_demonstrations:
                rows = [TaskDialogues.from_json(d) for d in probed_rows(split, Path(args.from_demonstrations),
                                                                         args.workers, args.limit)]
            else:
                rows = [TaskDialogues.from_json(d) for d in run_split(split, _annotate_chunk, args.workers, args.limit)]
            path = dialogue_path(split)
            write_dialogues(path, rows)
            timings[split] = round(time.monotonic() - t0, 1)
            stats = dialogue_statistics([r.annotations for r in rows])
            print(json.dumps({'split': split, 'path': str(path.resolve()), 'seconds': timings[split],
                              'workers': args.workers, **stats}))
            if len(rows) != (min(args.limit, SPLIT_SIZES[split]) if args.limit else SPLIT_SIZES[split]):
                print(f'warning: {split} has {len(rows)} tasks, expected {SPLIT_SIZES[split]}', file=sys.stderr)
    stats = write_doc(Path(args.doc))
    print(json.dumps({'doc': args.doc, 'statistics': stats}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
