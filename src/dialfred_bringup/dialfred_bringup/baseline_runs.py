#!/usr/bin/env python3
"""The paper's baselines 1-4 (Table II) with the learned performer: results files, JSON and a results document (out/baselines/results.md).

    ./dialfred baselines [--checkpoint PATH] [--splits valid_seen,valid_unseen]
                         [--baselines instruction_only,all_qas,random_qa,random_mc] [--limit N] [--workers 2]
                         [--resolution 64] [--graph] [--out out/baselines] [--doc out/baselines/results.md]
    ./dialfred baselines --results-only      # run nothing: rewrite the doc from the results files there are

Each (split, baseline) is one `dialfred_bringup.evaluation.run_eval` of the `et` performer of `--checkpoint` with the
baseline's questioner: (1) instruction only = no questioner, (2) All QAs = `all`, (3) Random QA =
`random`, (4) Random MC = `confusion`. Its results go to `<out>/<split>_<baseline>.jsonl` episode by
episode, so a rerun resumes; `<out>/<split>_<baseline>.runs.jsonl` keeps each run's wall time. The
performer plays in this process (`--agent et`), or with `--graph` through the ROS graph (a performer
node per worker, `--performer et`): the same episodes either way.

Prints one JSON object: per split and baseline n, SR, PWSR, GC, NQ, their 95% bootstrap intervals
(`dialfred_sim.metrics.intervals`), SR with and without a same-class distractor and with the target
out of view or in view at the start (each with n), and the evaluation's wall time. Writes `--doc`:
the checkpoint (path, sha256, the command stored in it), the baselines beside the paper's Table II,
the distractor / out-of-view table and what holds of the paper's comparisons, all from the numbers.
"""

from __future__ import annotations

import json
import shlex
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from dialfred_performer.model import load_checkpoint
from dialfred_sim.dataclass_cli import arg, parse
from dialfred_sim.metrics import intervals, summarize
from dialfred_sim.tasks import load_split

from .evaluation import EvalConfig, EvalRun, resumable_results, run_eval
from .paths import REPO

SPLITS = ('valid_seen', 'valid_unseen')


@dataclass(frozen=True)
class Baseline:
    number: int                 # the paper's numbering (Table II)
    key: str                    # the results files' name
    name: str                   # as the paper names it
    questioner: str             # dialfred_questioner baseline; '' = no questions
    paper_sr: dict              # {split: SR}, Table II
    paper_pwsr: dict            # {split: PWSR}, Table II
    paper_nq: float             # Table II (one column for both splits)


BASELINES = {b.key: b for b in (
    Baseline(1, 'instruction_only', 'Instruction only', '',
             {'valid_seen': 25.4, 'valid_unseen': 18.3}, {'valid_seen': 18.4, 'valid_unseen': 11.4}, 0.0),
    Baseline(2, 'all_qas', 'All QAs', 'all',
             {'valid_seen': 43.4, 'valid_unseen': 32.0}, {'valid_seen': 31.2, 'valid_unseen': 19.9}, 3.24),
    Baseline(3, 'random_qa', 'Random QA', 'random',
             {'valid_seen': 39.9, 'valid_unseen': 27.9}, {'valid_seen': 28.4, 'valid_unseen': 17.3}, 0.81),
    Baseline(4, 'random_mc', 'Random MC', 'confusion',
             {'valid_seen': 46.6, 'valid_unseen': 29.5}, {'valid_seen': 35.5, 'valid_unseen': 18.7}, 0.52),
)}


def _names(value: str) -> tuple[str, ...]:
    return tuple(v.strip() for v in value.split(',') if v.strip())


@dataclass(frozen=True)
class BaselinesConfig:
    """Run the paper's baselines 1-4 with the learned performer and write the results document."""

    checkpoint: str = arg('', "the performer's checkpoint; '' = the evaluation's default (the shipped checkpoint)")
    splits: str = arg(','.join(SPLITS), 'comma-separated splits')
    baselines: str = arg(','.join(BASELINES), 'comma-separated baselines, of ' + ', '.join(BASELINES))
    limit: int = arg(0, 'only the first N tasks of each split (0: all)')
    workers: int = arg(2, 'simulator nodes playing episodes in parallel')
    resolution: int = arg(64, 'frame size; the performer is trained at 64 px, as the demonstrations are rendered')
    graph: bool = arg(False, 'play through the ROS graph (a performer node per worker, eval --performer et) '
                             'instead of in this process (eval --agent et)')
    seed: int = arg(0, "the evaluation's seed (each episode's seed comes from it)")
    out: str = arg('out/baselines', 'folder of the results files <split>_<baseline>.jsonl')
    doc: str = arg('out/baselines/results.md', 'the results document to write (the tables of docs/results.md come from ./dialfred reproduce)')
    results_only: bool = arg(False, 'run nothing: print the JSON and rewrite the doc from the results files')
    resamples: int = arg(2000, 'bootstrap resamples of the 95% intervals')
    progress: bool = arg(True, 'progress bars on stderr')

    def __post_init__(self):
        unknown = [s for s in _names(self.splits) if s not in SPLITS]
        if unknown or not _names(self.splits):
            raise ValueError(f'--splits takes {", ".join(SPLITS)}; got {self.splits!r}')
        unknown = [b for b in _names(self.baselines) if b not in BASELINES]
        if unknown or not _names(self.baselines):
            raise ValueError(f'--baselines takes {", ".join(BASELINES)}; got {self.baselines!r}')
        if self.limit < 0 or self.workers < 1 or self.resamples < 1:
            raise ValueError('--limit must be >= 0, --workers and --resamples >= 1')

    def path(self, value: str) -> Path:
        """A path of the command line: relative ones are relative to the repository root."""
        return Path(value) if Path(value).is_absolute() else REPO / value

    def eval_config(self, split: str, baseline: Baseline) -> EvalConfig:
        return EvalConfig(split=split, agent='et', performer='et' if self.graph else '',
                          questioner=baseline.questioner, limit=self.limit or None, workers=self.workers,
                          out=self.path(self.out) / f'{split}_{baseline.key}.jsonl', seed=self.seed,
                          resolution=self.resolution,
                          checkpoint=self.path(self.checkpoint) if self.checkpoint else None)


def runs_path(run: EvalRun) -> Path:
    """Where each run of one (split, baseline) records its wall time (one JSON line per run)."""
    return run.results_path.with_suffix('.runs.jsonl')


def run_baseline(config: EvalConfig, progress: bool, silent: Optional[tuple[str, Path]] = None) -> None:
    """Evaluate one (split, baseline) (`run_eval`; `silent` as there) and add a line for this run's time to
    its `runs_path`."""
    run = EvalRun(config)
    report = run_eval(run, progress=progress, silent=silent)
    if report.ran:
        line = {'episodes': report.ran, 'wall_s': round(report.wall_s, 3), 'startup_s': round(report.startup_s, 3),
                'workers': config.workers, 'through': report.to_json()['through'], 'replayed': report.replayed}
        with open(runs_path(run), 'a') as f:
            f.write(json.dumps(line) + '\n')


def sr_of(results: list) -> dict:
    n = len(results)
    return {'n': n, 'SR': round(100.0 * sum(r.success for r in results) / n, 2) if n else None}


def baseline_row(config: EvalConfig, resamples: int) -> dict:
    """The numbers of one (split, baseline) from its results file: the first `limit` tasks of the split
    that have a result (ResultsFileError if the file holds another checkpoint's or seed's results)."""
    run = EvalRun(config, check=False)
    tasks = load_split(config.split)[:config.limit]
    done = resumable_results(run, [t.task_id for t in tasks])
    played = [t for t in tasks if t.task_id in done]
    results = [done[t.task_id] for t in played]
    overall = summarize(results)['overall']
    ci = intervals(results, resamples=resamples, seed=config.seed)
    runs = [json.loads(line) for line in runs_path(run).read_text().splitlines() if line.strip()] \
        if runs_path(run).exists() else []
    of = lambda keep: [done[t.task_id] for t in played if keep(t)]
    return {
        'n': len(results), 'tasks': len(tasks), 'complete': len(results) == len(tasks),
        **{k: round(overall[k], 2 if k != 'NQ' else 3) for k in ('SR', 'PWSR', 'GC', 'NQ')},
        'CI95': {k: [round(lo, 2 if k != 'NQ' else 3), round(hi, 2 if k != 'NQ' else 3)] for k, (lo, hi) in ci.items()},
        'distractor': {'with': sr_of(of(lambda t: t.has_distractor)), 'without': sr_of(of(lambda t: not t.has_distractor))},
        'target_at_start': {'out_of_view': sr_of(of(lambda t: not t.target_visible_at_start)),
                            'in_view': sr_of(of(lambda t: t.target_visible_at_start))},
        'eval_wall_s': round(sum(r['wall_s'] for r in runs), 1), 'runs': len(runs),
        'results_file': str(run.results_path),
    }


def checkpoint_info(config: EvalConfig) -> dict:
    run = EvalRun(config, check=False)
    _, _, info = load_checkpoint(run.checkpoint_path)
    return {'path': str(run.checkpoint_path), 'sha256': run.checkpoint_sha256,
            'command': info.get('command', ''), 'git_commit': info.get('git_commit', '')}


# ------------------------------------------------------------------------------------------ the document

def _value(row: dict, key: str) -> str:
    if not row['n']:
        return 'no results'
    digits = 2 if key == 'NQ' else 1
    lo, hi = row['CI95'][key]
    return f'{row[key]:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]'


def _sr_n(part: dict) -> str:
    return f'{part["SR"]:.1f} ({part["n"]})' if part['n'] else '- (0)'


def _relative(path: str) -> str:
    try:
        return str(Path(path).resolve().relative_to(REPO))
    except ValueError:
        return path


def what_holds(results: dict) -> list[str]:
    """Generated statements comparing the numbers with the paper's Table II."""
    lines = []
    for split, rows in results.items():
        base = rows.get('instruction_only')
        for key, row in rows.items():
            b = BASELINES[key]
            if not row['n']:
                continue
            played = '' if row['complete'] else f' (on the {row["n"]} of {row["tasks"]} tasks played so far)'
            lo, hi = row['CI95']['SR']
            paper = b.paper_sr[split]
            where = 'inside' if lo <= paper <= hi else ('above' if paper > hi else 'below')
            lines.append(f'{b.name} on {split}: SR {row["SR"]:.1f} >= {paper} (paper): '
                         f'{"holds" if row["SR"] >= paper else "does not hold"}; the paper\'s value is {where} '
                         f'the 95% interval [{lo:.1f}, {hi:.1f}]{played}.')
            if key != 'instruction_only' and base and base['n']:
                ours = row['SR'] - base['SR']
                theirs = paper - BASELINES['instruction_only'].paper_sr[split]
                lines.append(f'{b.name} minus instruction only on {split}: {ours:+.1f} points SR '
                             f'(paper {theirs:+.1f}){played}.')
    return lines


def write_doc(path: Path, report: dict, command: str) -> None:
    s = report['settings']
    ck = report['checkpoint']
    out = [
        '# Results: the paper\'s baselines 1-4 with the learned performer',
        '',
        f'<!-- Generated file: written by `{command}` (dialfred_bringup/baseline_runs.py). Do not edit by hand; rerun it. -->',
        f'Generated by `{command}` (`dialfred_bringup/baseline_runs.py`) from the results files in '
        f'`{_relative(s["out"])}/`; every number here is computed from them.',
        '',
        '## Checkpoint',
        '',
        f'- path: `{_relative(ck["path"])}`',
        f'- sha256: `{ck["sha256"][:16]}`...',
        f'- command stored in the checkpoint: `{ck["command"] or "(none)"}`',
        f'- git commit stored in the checkpoint: `{ck["git_commit"] or "(none)"}`',
        '',
        '## Settings',
        '',
        f'Performer `et` at {s["resolution"]} px, played {s["through"]}; evaluation seed {s["seed"]}; '
        f'{"the first " + str(s["limit"]) + " tasks of each split" if s["limit"] else "every task of each split"}. '
        f'Intervals: 95% percentile bootstrap over episodes, {s["resamples"]} resamples '
        '(`dialfred_sim.metrics.intervals`). SR, PWSR and GC in percent; NQ questions per episode.',
        '',
        '## Baselines (paper, Table II)',
        '',
    ]
    for split, rows in report['results'].items():
        out += [f'### {split}', '',
                '| # | baseline | questioner | n | SR [95%] | paper SR | PWSR [95%] | paper PWSR | GC [95%] '
                '| NQ [95%] | paper NQ | eval wall time |',
                '|---|---|---|---|---|---|---|---|---|---|---|---|']
        for key, row in rows.items():
            b = BASELINES[key]
            n = f'{row["n"]}' if row['complete'] else f'{row["n"]} of {row["tasks"]}'
            out.append(f'| {b.number} | {b.name} | {b.questioner or "none"} | {n} | {_value(row, "SR")} | '
                       f'{b.paper_sr[split]} | {_value(row, "PWSR")} | {b.paper_pwsr[split]} | {_value(row, "GC")} | '
                       f'{_value(row, "NQ")} | {b.paper_nq} | {row["eval_wall_s"]:.0f} s ({row["runs"]} run{"" if row["runs"] == 1 else "s"}) |')
        out.append('')
    out += ['## Same-class distractor and target out of view at the start', '',
            'SR (n) on the tasks whose target has a same-class distractor in the room or not, and whose target '
            'is out of view or in view at the start (the task records\' `has_distractor`, '
            '`target_visible_at_start`).', '',
            '| split | # | baseline | with distractor | without distractor | target out of view | target in view |',
            '|---|---|---|---|---|---|---|']
    for split, rows in report['results'].items():
        for key, row in rows.items():
            b = BASELINES[key]
            out.append(f'| {split} | {b.number} | {b.name} | {_sr_n(row["distractor"]["with"])} | '
                       f'{_sr_n(row["distractor"]["without"])} | {_sr_n(row["target_at_start"]["out_of_view"])} | '
                       f'{_sr_n(row["target_at_start"]["in_view"])} |')
    out += ['', '## What holds', '', 'Computed from the tables above and the paper\'s Table II.', '']
    out += [f'- {line}' for line in what_holds(report['results'])] or ['- no results yet']
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text('\n'.join(out) + '\n')


# ------------------------------------------------------------------------------------------ entry point

def run(cfg: BaselinesConfig, command: str) -> dict:
    """Play what is missing (unless results_only), then the report (also written to cfg.doc)."""
    splits, keys = _names(cfg.splits), _names(cfg.baselines)
    if not cfg.results_only:
        for split in splits:
            for key in keys:
                run_baseline(cfg.eval_config(split, BASELINES[key]), cfg.progress)
    first = cfg.eval_config(splits[0], BASELINES[keys[0]])
    report = {
        'checkpoint': checkpoint_info(first),
        'settings': {'resolution': cfg.resolution, 'seed': cfg.seed, 'limit': cfg.limit or None,
                     'through': 'through the ROS graph (performer nodes)' if cfg.graph else 'in process',
                     'workers': cfg.workers, 'resamples': cfg.resamples, 'out': str(cfg.path(cfg.out))},
        'results': {split: {key: baseline_row(cfg.eval_config(split, BASELINES[key]), cfg.resamples) for key in keys}
                    for split in splits},
        'doc': str(cfg.path(cfg.doc)),
    }
    write_doc(cfg.path(cfg.doc), report, command)
    return report


def main(argv: Optional[list[str]] = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    cfg = parse(BaselinesConfig, argv, prog='./dialfred baselines')
    try:
        report = run(cfg, shlex.join(['./dialfred', 'baselines', *argv]))
    except (FileNotFoundError, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    print(json.dumps(report))
    return 0


if __name__ == '__main__':
    sys.exit(main())
