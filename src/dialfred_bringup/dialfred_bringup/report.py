"""One static HTML page of an evaluation (no ROS): `./dialfred report RESULTS.jsonl [--bags DIR]`.

From the results file of `launch eval` (and its `.summary.json`, when there is one) it writes a page
that opens from disk with no server and no network: the run's settings; SR, PWSR, GC and NQ with
their 95% bootstrap intervals (`metrics.intervals`); SR per task type as bars; and every episode with
its outcome, steps, dialogue and, when `--bags` holds its bag (`launch eval --record DIR`), a captioned
GIF rendered from the bag alone (`replay.film` + `film.save_captioned_gif`). The episodes can be
filtered by task type and outcome.

    ./dialfred report out/eval/valid_unseen_expert.jsonl --bags out/bags
    # -> out/eval/valid_unseen_expert.html and its GIFs in out/eval/valid_unseen_expert_media/

The GIFs go to a folder beside the page by default, not into it: a full split's 1,363 GIFs would
make one page of well over 100 MB, which a browser parses slowly, while files load lazily as one
scrolls. `--embed` puts them into the page as data URIs instead (one file to send; for small runs).

Bad input: a missing, empty or corrupt results file is an error (exit 2, no page written); a cut-off
last line is skipped with a warning (on stderr and on the page). An episode whose bag is missing or
cannot be read is shown without a GIF, saying why, and the problem is reported on stderr.
"""

from __future__ import annotations

import base64
import json
import os
import sys
import tempfile
import time
import urllib.parse
import warnings
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

from dialfred_oracle.answerers import ANSWERER_PREFIX
from dialfred_sim.bag import BagError, bag_name, read_bag
from dialfred_sim.dataclass_cli import REQUIRED, arg, parse
from dialfred_sim.metrics import (END_REASONS, EpisodeResult, TruncatedResultsWarning, intervals, load_results,
                                  played_through, summarize)
from dialfred_sim.tasks.split_files import get_task

from .film import save_captioned_gif
from .replay import bag_film
from .report_page import OUTCOME_LABELS, render_page

GIF_WIDTH = 256


class ReportError(ValueError):
    """Input the report cannot be made from (no results file, an empty or corrupt one, no bags folder)."""


@dataclass
class EpisodeView:
    """One episode as the page shows it."""

    result: EpisodeResult
    instruction: str = ''
    scene: str = ''
    gif: str = ''             # the GIF's address, relative to the page, or a data: URI; '' = none
    media_note: str = ''      # why there is no GIF ('no recording', 'recording unreadable: ...')


@dataclass
class Report:
    """Everything the page shows (report_page.render_page draws it)."""

    title: str
    subtitle: str
    settings: list            # (label, value) pairs
    summary: dict             # metrics.summarize
    bounds: dict              # metrics.intervals: metric -> (lo, hi)
    type_bounds: dict         # task type -> SR's (lo, hi)
    episodes: list            # EpisodeView, in the results' order
    resamples: int = 2000
    seed: int = 0
    warnings: list = field(default_factory=list)

    @property
    def type_counts(self) -> dict:
        return {t: row['n'] for t, row in self.summary['per_type'].items()}

    @property
    def outcome_counts(self) -> dict:
        """filter value -> (label, episodes): success, failure, then failure:<reason> for each reason seen."""
        results = [ep.result for ep in self.episodes]
        out = {'success': ('success', sum(r.success for r in results)),
               'failure': ('failure (any)', sum(not r.success for r in results))}
        for reason in END_REASONS[1:]:
            n = sum(not r.success and r.end_reason == reason for r in results)
            if n:
                out[f'failure:{reason}'] = (f'failure: {OUTCOME_LABELS[reason]}', n)
        return out


# ------------------------------------------------------------------------------------------------ input

def read_results(path: Path) -> tuple[list[EpisodeResult], list[str]]:
    """The results and any warning about them; ReportError for a missing, empty or corrupt file."""
    path = Path(path)
    if not path.is_file():
        raise ReportError(f'no results file {path} (write one with `./dialfred launch eval ... --out {path}`)')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always', TruncatedResultsWarning)
        try:
            results = load_results(path, skip_bad=True)
        except ValueError as exc:
            raise ReportError(str(exc)) from None
    notes = [str(w.message) for w in caught if issubclass(w.category, TruncatedResultsWarning)]
    if not results:
        raise ReportError(f'{path} holds no episode results' + (f' ({notes[0]})' if notes else ''))
    return results, notes


def read_summary(results_path: Path) -> tuple[Optional[dict], list[str]]:
    """The run's `.summary.json` beside the results (None if there is none) and warnings about it."""
    path = Path(results_path).with_suffix('.summary.json')
    if not path.is_file():
        return None, [f'no {path.name} beside the results: the settings below come from the results alone']
    try:
        summary = json.loads(path.read_text())
        if not isinstance(summary, dict):
            raise ValueError('not a JSON object')
    except (ValueError, OSError) as exc:
        return None, [f'{path} cannot be read ({exc}): the settings below come from the results alone']
    return summary, []


def _one_or_several(values) -> str:
    values = sorted({str(v) for v in values})
    return values[0] if len(values) == 1 else 'several: ' + ', '.join(values)


def agent_name(results: list[EpisodeResult], run: Optional[dict]) -> str:
    """The name the run's results carry: agent, and its questioner after a '+' (e.g. et-7505bda0+all)."""
    return (run or {}).get('agent') or _one_or_several(r.agent for r in results)


def oracle_text(oracle: str) -> str:
    """How the oracle answered: '' exactly; 'location:0.5' withholding that type's answers that often."""
    if not oracle:
        return 'exact answers'
    if oracle.startswith(ANSWERER_PREFIX):
        return f'the oracle\'s answers worded by {oracle[len(ANSWERER_PREFIX):]}'
    kind, _, probability = oracle.partition(':')
    return f'withholds {kind} answers with probability {probability}' if probability else oracle


def run_settings(results: list[EpisodeResult], run: Optional[dict]) -> tuple[list, list[str]]:
    """(label, value) pairs describing the run, and warnings where the summary and the results disagree."""
    run = run or {}
    agent_names = {r.agent for r in results}
    agent, _, questioner = agent_name(results, run).partition('+')
    settings = [('split', run.get('split') or _one_or_several(r.split for r in results)),
                ('agent', agent + (' (privileged reference: it sees the solution)' if any(r.privileged for r in results)
                                   else '')),
                ('questioner', questioner or 'none'),
                ('oracle', oracle_text(run.get('oracle', _one_or_several(r.oracle for r in results)))),
                ('seed', str(run.get('seed', _one_or_several(r.seed for r in results))))]
    checkpoint = run.get('checkpoint')
    if isinstance(checkpoint, dict):
        settings.append(('checkpoint', f'sha256 {checkpoint.get("sha256", "?")} ({checkpoint.get("path", "?")})'))
    elif agent.startswith('et-'):
        settings.append(('checkpoint', f'sha256 {agent[3:]}... (from the agent name)'))
    settings.append(('tasks', str(len(results))))
    recorded = {'through': played_through(results)} if any(r.played for r in results) else {}
    for key, label in (('tasks_file', 'tasks file'), ('resolution', 'resolution'), ('through', 'played'),
                       ('workers', 'workers'), ('limit', 'limit'), ('shard', 'shard')):
        value = recorded.get(key, run.get(key))      # how the episodes were played: their lines say
        if value is not None:
            if key == 'shard':
                value = f'{value.get("index")}/{value.get("count")}'
            settings.append((label, str(value)))
    notes = []
    if run:
        if run.get('tasks') is not None and run['tasks'] != len(results):
            notes.append(f'the summary file counts {run["tasks"]} tasks, the results file holds {len(results)}')
        if run.get('agent') and agent_names != {run['agent']}:
            notes.append(f'the summary file names agent {run["agent"]}, the results {", ".join(sorted(agent_names))}')
    return settings, notes


def task_text(task_id: str) -> tuple[str, str]:
    """(instruction, scene) of a task of a shipped split, ('', '') if it cannot be found there."""
    try:
        task = get_task(task_id)
    except Exception:  # noqa: BLE001 - a test split or a split not generated here: the page shows less
        return '', ''
    return task.instruction, task.scene


# ------------------------------------------------------------------------------------------------ GIFs

EPISODE_FIELDS = ('success', 'steps', 'questions', 'failed_actions', 'end_reason')


def episode_of(result) -> dict:
    """What identifies an episode, from a results line (EpisodeResult) or a bag's recorded result (dict):
    its outcome fields and its dialogue (type, noun, answer)."""
    get = (lambda k: result[k]) if isinstance(result, dict) else (lambda k: getattr(result, k))
    return {k: get(k) for k in EPISODE_FIELDS}


def render_gif(bag: Path, gif: Path, width: int, expected: Optional[dict] = None) -> dict:
    """Render one bag's captioned GIF (runs in a worker process): a task's, or a chained episode's with all its
    tasks. Returns {'ok', 'note', 'tasks': {task id: {'instruction', 'scene'}}, 'frames'}; a bag that cannot be
    read or has no frames gives ok False and why. With `expected` ({task id: episode_of its results line, with
    'dialogue' [(type, noun, answer)]}), a bag of other episodes (bags are named by task: another run's,
    recorded into the same folder) gives ok False, 'mismatch' True."""
    try:
        parts = read_bag(bag)
    except BagError as exc:
        return {'ok': False, 'note': f'recording unreadable: {exc}'}
    except Exception as exc:  # noqa: BLE001 - a damaged file can fail anywhere in the reader; report it
        return {'ok': False, 'note': f'recording unreadable: {type(exc).__name__}: {exc}'}
    info = {'tasks': {ep.task['task_id']: {'instruction': ep.task.get('instruction', ''), 'scene': ep.task.get('scene', '')}
                      for ep in parts},
            'frames': sum(len(ep.frames) for ep in parts)}
    if expected is not None:
        held = {ep.task['task_id']: {**episode_of(ep.result), 'dialogue': [(d[1], d[2], d[4] if d[5] else '')
                                                                           for d in ep.dialogue]}
                for ep in parts if ep.result}
        ids = set(info['tasks'])
        differ = ([f'tasks {", ".join(sorted(ids ^ set(expected)))}'] if ids != set(expected) else
                  list(dict.fromkeys(k for t in held for k in expected[t] if held[t].get(k) != expected[t][k])))
        if differ:
            return {'ok': False, 'mismatch': True, **info,
                    'note': f'the recording is of another episode of this task ({", ".join(differ)} differ from the '
                            'results): another run recorded into that folder'}
    if not info['frames']:
        return {'ok': False, 'note': 'the recording has no camera frames', **info}
    save_captioned_gif(bag_film(parts), gif, width=width)
    return {'ok': True, 'note': '', **info}


def bag_of(view: EpisodeView, first: dict) -> str:
    """The folder name of the bag that holds a view's episode: its task's, or its chained episode's (`first`:
    {episode id: its first task id})."""
    r = view.result
    if r.protocol == 'chained':
        return bag_name(first[r.episode_id], chained=True)
    return bag_name(r.task_id)


def attach_gifs(views: list[EpisodeView], bags: Path, media: Path, page_dir: Path, width: int, embed: bool,
                workers: int, say: Callable[[str], None]) -> dict:
    """Render the GIF of every episode whose bag `bags` holds into `media`, and set each view's gif or
    media_note. The tasks of a chained episode share its one bag and GIF. Returns counts {'gifs', 'missing',
    'unreadable', 'mismatched' (a bag of another episode)}, each of views."""
    counts = {'gifs': 0, 'missing': 0, 'unreadable': 0, 'mismatched': 0}
    first: dict = {}
    for view in views:
        if view.result.protocol == 'chained':
            e = view.result.episode_id
            first[e] = min(first.get(e, view.result.task_id), view.result.task_id)
    groups: dict = {}      # bag name -> the views it shows, in order
    for view in views:
        groups.setdefault(bag_of(view, first), []).append(view)
    todo = []
    for name, group in groups.items():
        bag = bags / name
        if bag.exists():     # a folder that is no bag is reported as unreadable below
            todo.append((group, bag))
        else:
            for view in group:
                view.media_note = 'no recording'
            counts['missing'] += len(group)
    if counts['missing']:
        say(f'{counts["missing"]} of {len(views)} episodes have no bag in {bags}: shown without a GIF')
    if not todo:
        return counts
    if not embed:
        media.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix='dialfred-report-') as scratch:
        target = Path(scratch) if embed else media
        jobs = [(group, bag, target / f'{bag.name}.gif') for group, bag in todo]
        expected = [{v.result.task_id: {**episode_of(v.result),
                                        'dialogue': [(d['type'], d['noun'], d['answer']) for d in v.result.dialogue]}
                     for v in group} for group, _ in todo]
        start = last = time.monotonic()
        pool = ProcessPoolExecutor(max_workers=workers) if workers > 1 else None
        try:
            outcomes = (pool.map(render_gif, [b for _, b, _ in jobs], [g for *_, g in jobs], [width] * len(jobs),
                                 expected)
                        if pool else (render_gif(b, g, width, e) for (_, b, g), e in zip(jobs, expected)))
            for k, ((group, bag, gif), outcome) in enumerate(zip(jobs, outcomes), start=1):
                address = ''
                if outcome['ok']:
                    address = (f'data:image/gif;base64,{base64.b64encode(gif.read_bytes()).decode("ascii")}' if embed
                               else urllib.parse.quote(os.path.relpath(gif, page_dir).replace(os.sep, '/')))
                else:
                    say(f'{bag}: {outcome["note"]}; the episode is shown without a GIF')
                for view in group:
                    told = outcome.get('tasks', {}).get(view.result.task_id, {})
                    view.instruction = told.get('instruction') or view.instruction
                    view.scene = told.get('scene') or view.scene
                    if outcome['ok']:
                        counts['gifs'] += 1
                        view.gif = address
                    else:
                        counts['mismatched' if outcome.get('mismatch') else 'unreadable'] += 1
                        view.media_note = outcome['note']
                now = time.monotonic()
                if k == 1 or k == len(jobs) or now - last >= 2.0:
                    left = (now - start) / k * (len(jobs) - k)
                    say(f'GIFs: {k}/{len(jobs)} ({now - start:.1f} s' + (f', about {left:.0f} s left)' if k < len(jobs)
                                                                         else ')'))
                    last = now
        finally:
            if pool:
                pool.shutdown()
    if counts['gifs'] == 0 and not embed:
        try:
            media.rmdir()     # nothing was written there (and it held nothing before)
        except OSError:
            pass
    return counts


# ------------------------------------------------------------------------------------------------ report

def build_report(results_path: Path, bags: Optional[Path] = None, out: Optional[Path] = None, embed: bool = False,
                 gif_width: int = GIF_WIDTH, workers: int = 1, resamples: int = 2000, seed: int = 0,
                 say: Callable[[str], None] = lambda text: None) -> tuple[Path, Report, dict]:
    """Write the page of `results_path` (default beside it, `<stem>.html`; GIFs in `<page stem>_media/`).
    Returns (page path, Report, GIF counts). ReportError (nothing written) for unusable input."""
    results_path = Path(results_path)
    page = Path(out) if out else results_path.with_suffix('.html')
    inputs = [results_path, results_path.with_suffix('.summary.json'), results_path.with_suffix('.tasks.json')]
    if page.resolve() in {p.resolve() for p in inputs} or (
            bags is not None and page.resolve().is_relative_to(Path(bags).resolve())):
        raise ReportError(f'the page {page} would be written over an input of the report ({results_path}, its '
                          'summary or its bags): choose another --out')
    if bags is not None and not Path(bags).is_dir():
        raise ReportError(f'--bags {bags} is not a folder (record one with `launch eval ... --record DIR`)')
    if gif_width < 32:
        raise ValueError(f'--gif-width must be at least 32, got {gif_width}')
    results, notes = read_results(results_path)
    for note in notes:
        say(f'warning: {note}')
    run, run_notes = read_summary(results_path)
    settings, mismatch = run_settings(results, run)
    summary = summarize(results)
    by_type: dict = {}
    for r in results:
        by_type.setdefault(r.task_type, []).append(r)
    views = [EpisodeView(r, *task_text(r.task_id)) for r in results]
    counts = {'gifs': 0, 'missing': len(views) if bags is None else 0, 'unreadable': 0, 'mismatched': 0}
    if bags is None:
        for view in views:
            view.media_note = 'no recording'
    else:
        counts = attach_gifs(views, Path(bags), page.parent / f'{page.stem}_media', page.parent, gif_width, embed,
                             workers, say)
    split = next(value for label, value in settings if label == 'split')
    report = Report(
        title=f'DialFRED evaluation: {agent_name(results, run)} on {split}',
        subtitle=f'{len(results)} episodes from {results_path.name}'
                 + (f'; GIFs from the bags in {bags}' if bags is not None else '; no bags given (--bags DIR)'),
        settings=settings + [('results file', str(results_path))], summary=summary,
        bounds=intervals(results, resamples=resamples, seed=seed),
        type_bounds={t: intervals(rs, resamples=resamples, seed=seed)['SR'] for t, rs in by_type.items()},
        episodes=views, resamples=resamples, seed=seed, warnings=notes + run_notes + mismatch)
    page.parent.mkdir(parents=True, exist_ok=True)
    staging = page.with_name(f'.{page.name}.{os.getpid()}.part')
    staging.write_text(render_page(report), encoding='utf-8')
    staging.replace(page)       # a reader never sees half a page
    return page, report, counts


@dataclass
class ReportConfig:
    """Write one static HTML page of an evaluation: its summary with 95% intervals, SR per task type, and
    every episode with its outcome, dialogue and GIF (from its bag), filterable by type and outcome."""

    results: Path = arg(REQUIRED, 'a results file of `launch eval` (its .summary.json beside it is read too)',
                        positional=True)
    bags: Optional[Path] = arg(None, 'the folder given to `launch eval --record` (GIFs of its bags)', metavar='DIR')
    out: Optional[Path] = arg(None, 'the page (none: beside the results, <stem>.html)', metavar='PATH')
    embed: bool = arg(False, 'GIFs inside the page as data URIs (one file), not in <page stem>_media/')
    gif_width: int = arg(GIF_WIDTH, 'GIF width in pixels')
    workers: int = arg(1, 'processes rendering GIFs')
    resamples: int = arg(2000, 'bootstrap resamples of the intervals')
    seed: int = arg(0, 'seed of the bootstrap')


def main(argv=None) -> int:
    args = parse(ReportConfig, argv, prog='dialfred report',
                 description=' '.join(ReportConfig.__doc__.split()))

    def say(text: str) -> None:
        print(f'[report] {text}', file=sys.stderr, flush=True)

    try:
        page, report, counts = build_report(args.results, args.bags, args.out, args.embed, args.gif_width,
                                            max(1, args.workers), args.resamples, args.seed, say)
    except (ReportError, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    o = report.summary['overall']
    print(f'{page}: {o["n"]} episodes, SR {o["SR"]:.1f} {report.bounds["SR"][0]:.1f}-{report.bounds["SR"][1]:.1f}, '
          f'{counts["gifs"]} GIFs, {counts["missing"]} without a bag, {counts["unreadable"]} unreadable bags, '
          f'{counts["mismatched"]} bags of another run\'s episodes')
    return 0


if __name__ == '__main__':
    sys.exit(main())
