#!/usr/bin/env python3
"""Score a results file by playing it again: `./dialfred score RESULTS [--tasks PATH] [--workers N]`.

Every episode of the file is played again from its trace (`<results>.trace.jsonl`, dialfred_sim.traces:
each action with its target pixel, each question at its step) in a fresh simulator and oracle, under the
protocol, goal rule, camera and oracle setting the file records. Every answer the oracle gives is checked
against the recorded one, and every outcome and count (success, goal conditions, steps, failed actions,
questions, end reason, the tasks held at a chained start, the reference length) against the recorded
line. The evaluation's table is printed when all of it agrees.

A file whose recorded outcome, answer, question count or action differs from the replay is refused, with
the first difference in task order and its task (exit status 1). A file that cannot be scored at all (no
trace, another tasks file, lines of two runs, a cut-off line in the middle) is an error (exit status 2).
Nothing is written.

So a results file of a sealed split of a stated seed, with its trace, is a submission anyone can verify
without a server: docs/evaluation.md, "Scoring a results file by replay".
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Optional

from dialfred_oracle.answerers import ANSWERER_PREFIX, AnswersError, resolved_spec, same_answerer, speaking
from dialfred_oracle.answers import Perturbation
from dialfred_oracle.in_process import answer_now
from dialfred_oracle.swap import AnswerSwap
from dialfred_sim import tasks as task_sets
from dialfred_sim.dataclass_cli import Parser
from dialfred_sim.chained import chain_episodes, reference_length
from dialfred_sim.env import DialfredEnv
from dialfred_sim.metrics import (DEFAULT_PROTOCOL, EpisodeResult, ResultsFileError, end_reason,
                                  format_table, load_results, summarize)
from dialfred_sim.processes import worker_pool
from dialfred_sim.progress import progress_bar
from dialfred_sim.tasks.splits import read_tasks_file
from dialfred_sim.traces import load_traces, trace_path

# The fields of a results line a replay recomputes (the rest name the run, or are its wall time and commit).
CHECKED = ('success', 'goal_conditions_met', 'goal_conditions_total', 'steps', 'failed_actions', 'questions',
           'invalid_questions', 'end_reason', 'held_at_start', 'expert_length')


class Refused(Exception):
    """The replay differs from the file: `task_id` and what differs."""

    def __init__(self, task_id: str, what: str):
        super().__init__(f'{task_id}: {what}')
        self.task_id, self.what = task_id, what


@dataclass
class Setting:
    """What the file's episodes were played under (from its lines and <results>.run.json)."""

    protocol: str
    goal_rule: str
    oracle: str
    seed: int
    resolution: int
    answers: str = ''        # an answerer's --answers (dialfred_oracle.answerers), from the run record


# ------------------------------------------------------------------------------------------ the replay

def replay_task(env, task, result: EpisodeResult, trace: dict, oracle, continues: bool,
                length: Optional[int]) -> Optional[Refused]:
    """Play `task` again from `trace` in `env` (reset to it, or with `continues` gone on to it) with the
    oracle's answers `oracle(question_type, noun, task) -> (valid, text)`; the first difference with
    `result`, or None."""
    tid = result.task_id
    actions, asked_at = trace['actions'], trace['asked_at']
    if len(asked_at) != len(result.dialogue):
        return Refused(tid, f'the trace holds {len(asked_at)} questions, the results line {len(result.dialogue)}')
    if len(result.dialogue) != result.questions:
        return Refused(tid, f'the results line counts {result.questions} questions and records {len(result.dialogue)}')
    try:
        if continues:
            _, info = env.continue_task(task)
        elif result.protocol == DEFAULT_PROTOCOL:
            _, info = env.reset(options={'task': task})
        else:
            _, info = env.reset(options={'task': task, 'protocol': result.protocol})
    except (ValueError, FileNotFoundError) as exc:
        if result.end_reason == 'error' and not actions:
            return None                               # it could not be set up then either
        return Refused(tid, f'the replay cannot start the task: {exc}')
    total = int(info['goal_conditions_total'])
    q, ended, refused_action, last, last_error = 0, None, False, '', ''
    for k in range(len(actions) + 1):
        while q < len(asked_at) and asked_at[q] == k:
            entry = result.dialogue[q]
            valid, text = oracle(entry['type'], entry['noun'], task)
            if (entry['valid'], entry['answer']) != (valid, text if valid else ''):
                return Refused(tid, f'question {q + 1} ({entry["type"]} {entry["noun"]!r}) before action {k + 1}: '
                                    f'recorded {_said(entry["valid"], entry["answer"])}, the oracle says {_said(valid, text)}')
            q += 1
        if k == len(actions):
            break
        if ended is not None or refused_action:
            return Refused(tid, f'the trace goes on for {len(actions) - k} actions after the episode ended '
                                f'({ended or "a refused action"})')
        name, x, y = actions[k]
        last = name
        try:
            _, _, terminated, truncated, info = env.step({'action': name, 'pixel': (x, y)})
        except (ValueError, RuntimeError):
            refused_action = True                      # the simulator refused it: the episode ended with an error
            continue
        if not info['last_action_success']:
            last_error = str(info['last_action_error'])
        if terminated or truncated:
            ended = end_reason(bool(info['success']), name, int(info['failed_actions']), bool(truncated))
    replayed = {
        'success': bool(info['success']) and ended is not None, 'goal_conditions_met': int(info['goal_conditions_met']),
        'goal_conditions_total': total, 'steps': int(info['step_count']), 'failed_actions': int(info['failed_actions']),
        'questions': len(asked_at), 'invalid_questions': sum(not e['valid'] for e in result.dialogue),
        'end_reason': ended or 'error', 'held_at_start': bool(info['held_at_start']) if result.protocol != DEFAULT_PROTOCOL
        else False, 'expert_length': int(length if length is not None else env.task.expert_length)}
    if result.end_reason == 'error' and ended is None:
        # The loop ended it (a refused action, too many questions, a lost reply): what the world shows
        # at that moment, but not whether it succeeded (an error never does).
        replayed['success'] = False
        if result.steps == 0 and not actions:
            replayed['goal_conditions_met'], replayed['goal_conditions_total'] = \
                result.goal_conditions_met, result.goal_conditions_total
    for name in CHECKED:
        if getattr(result, name) != replayed[name]:
            return Refused(tid, f'recorded {name} {getattr(result, name)!r}, the replay gives {replayed[name]!r}'
                                f' (last action {last or "none"})')
    if result.end_reason not in ('success', 'error') and result.error != last_error:
        return Refused(tid, f'recorded error {result.error!r}, the replay\'s last failed action says {last_error!r}')
    return None


def _said(valid: bool, text: str) -> str:
    return repr(text) if valid else 'no answer'


# ------------------------------------------------------------------------------------------ in workers

_W: dict = {}


def _init(setting: Setting, tasks_path: Optional[str], split: str) -> None:
    tasks = read_tasks_file(tasks_path).tasks if tasks_path else task_sets.load_split(split)
    _W['tasks'] = {t.task_id: t for t in tasks}
    env = _W['env'] = DialfredEnv(resolution=setting.resolution, goal_rule=setting.goal_rule)
    perturbation = swap = None
    if setting.oracle == 'swapped':
        swap = AnswerSwap(tasks, setting.resolution, setting.goal_rule)
    elif setting.oracle.startswith(ANSWERER_PREFIX):
        swap = answerer_of(setting)       # words the oracle's answers where the swap would
    elif setting.oracle not in ('', 'human'):
        kind, _, p = setting.oracle.partition(':')
        perturbation = Perturbation(kind, float(p), setting.seed)

    def oracle(question_type: str, noun: str, task):
        ans = answer_now(env, question_type, noun, perturbation)
        if swap is not None:
            ans = swap.apply(ans, task.task_id, noun)
        return bool(ans.valid), ans.text

    _W['oracle'] = oracle


def _score_job(job) -> list:
    """[(task_id, the first difference or None)] of a job: [(result, trace)] of one task, or of a chained
    episode's tasks in order."""
    env, oracle, tasks = _W['env'], _W['oracle'], _W['tasks']
    out = []
    chain = [tasks[r.task_id] for r, _ in job]
    for k, (result, trace) in enumerate(job):
        chained = result.protocol != DEFAULT_PROTOCOL
        refused = replay_task(env, chain[k], result, trace, oracle, continues=chained and k > 0,
                              length=reference_length(chain, k) if chained else None)
        out.append((result.task_id, None if refused is None else refused.what))
    return out


# ------------------------------------------------------------------------------------------ the file

def read_setting(path: Path, results: list) -> Setting:
    """The one setting of the file's lines and run record; ResultsFileError for a mixed file."""
    first = results[0]
    for r in results:
        for name in ('split', 'agent', 'oracle', 'seed', 'goal_rule', 'protocol'):
            if getattr(r, name) != getattr(first, name):
                raise ResultsFileError(f'{path}: lines of two runs ({name} {getattr(first, name)!r} and '
                                       f'{getattr(r, name)!r}, at {r.task_id})')
    record = path.with_suffix('.run.json')
    try:
        held = json.loads(record.read_text())
        resolution = int(held['resolution'])
    except (OSError, ValueError, KeyError, TypeError):
        raise ResultsFileError(f'{record}: no record of the camera the episodes were played with (written by '
                               '`launch eval` beside its results)') from None
    answers = held.get('answers', '')
    if first.oracle.startswith(ANSWERER_PREFIX) and not (isinstance(answers, str) and answers):
        raise ResultsFileError(f'{record}: no record of the answerer that worded the answers ({first.oracle})')
    return Setting(first.protocol, first.goal_rule or 'visible', first.oracle, first.seed, resolution, answers)


def answerer_of(setting: Setting, given: Optional[Path] = None):
    """The answerer of a results file's answers (dialfred_oracle.answerers.Speaking), None without one:
    the recorded one, or `given` (an answers file moved or renamed since), checked to be the one that answered
    (a file by its content's digest)."""
    if not setting.oracle.startswith(ANSWERER_PREFIX):
        if given is not None:
            raise ResultsFileError(f'--answers {given}: these results were not worded by an answerer '
                                   f'(oracle {setting.oracle or "exact"!r})')
        return None
    spec = str(given) if given is not None else setting.answers
    try:
        answerer = speaking(spec)
    except AnswersError as exc:
        raise ResultsFileError(f'the answerer of these results: {exc} (--answers FILE where it lies now)') from None
    want = setting.oracle[len(ANSWERER_PREFIX):]
    if answerer is None or not same_answerer(answerer.label, want):
        raise ResultsFileError(f'--answers {spec} is {answerer.label if answerer else spec!r}, not the answerer '
                               f'that answered these results ({want})')
    return answerer


def tasks_source(path: Path, given: Optional[Path], split: str) -> Optional[Path]:
    """The tasks file to replay with: --tasks, checked against the file's record of it; or the recorded one;
    None for a shipped split. ResultsFileError when they disagree."""
    record_path = path.with_suffix('.tasks.json')
    record = json.loads(record_path.read_text()) if record_path.exists() else None
    if given is None:
        if record is None:
            return None
        given = Path(record['path'])
    source = read_tasks_file(given)
    if record is not None and source.sha256 != record.get('sha256'):
        raise ResultsFileError(f'{given} (sha256 {source.sha256[:12]}...) is not the tasks file {path} was played '
                               f'on (sha256 {str(record.get("sha256"))[:12]}...)')
    if record is None and source.split != split:
        raise ResultsFileError(f'{path} holds results of {split!r}; {given} is a {source.split!r} tasks file')
    return source.path


def score(path: Path, tasks: Optional[Path] = None, workers: int = 2, progress: bool = True,
          answers: Optional[Path] = None) -> dict:
    """Replay every episode of the results file `path`: {'results', 'summary', 'refused': None or
    (task_id, what), 'tasks', 'episodes', 'wall_s'}. ResultsFileError for a file that cannot be scored."""
    t0 = time.monotonic()
    path = Path(path)
    if not path.is_file():
        raise ResultsFileError(f'no results file at {path}')
    try:
        results = load_results(path)
        traces = load_traces(path)
    except ValueError as exc:
        raise ResultsFileError(str(exc)) from None
    if not results:
        raise ResultsFileError(f'{path} holds no results')
    setting = read_setting(path, results)
    if answers is not None or setting.oracle.startswith(ANSWERER_PREFIX):
        answerer_of(setting, answers)            # refused here, not in every worker
        setting = replace(setting, answers=resolved_spec(str(answers)) if answers is not None else setting.answers)
    source = tasks_source(path, tasks, results[0].split)
    missing = [r.task_id for r in results if r.task_id not in traces]
    if missing:
        raise ResultsFileError(f'{trace_path(path)}: no trace of {len(missing)} of the {len(results)} episodes '
                               f'(first: {missing[0]}); results written without a trace cannot be replayed')
    if setting.oracle == 'human':
        raise ResultsFileError(f'{path}: a person answered these questions; a replay cannot ask them again')
    split_tasks = read_tasks_file(source).tasks if source else task_sets.load_split(results[0].split)
    index = {t.task_id: k for k, t in enumerate(split_tasks)}
    unknown = [r.task_id for r in results if r.task_id not in index]
    if unknown:
        raise ResultsFileError(f'{path}: task {unknown[0]} is not a task of the split it was played on')
    ordered = sorted(results, key=lambda r: index[r.task_id])
    if setting.protocol == DEFAULT_PROTOCOL:
        jobs = [[(r, traces[r.task_id])] for r in ordered]
    else:
        by_id = {r.task_id: r for r in ordered}
        try:
            episodes = chain_episodes((index[r.task_id], split_tasks[index[r.task_id]]) for r in ordered)
        except ValueError as exc:
            raise ResultsFileError(f'{path}: {exc}') from None
        for e in episodes:
            first = split_tasks[e.tasks[0][0]]
            whole = [t.task_id for t in split_tasks if t.split == first.split and t.episode.episode_id ==
                     first.episode.episode_id]
            if e.task_ids != whole[:len(e.task_ids)]:
                raise ResultsFileError(f'{path}: episode {e.episode_id} starts at {e.task_ids[0]}, not at its first '
                                       f'task {whole[0]}: a chained episode is scored from its start')
        jobs = [[(by_id[tid], traces[tid]) for tid in e.task_ids] for e in episodes]
    verdict: dict = {}
    n = max(1, min(workers, len(jobs)))
    with worker_pool(n, initializer=_init, initargs=(setting, str(source) if source else None,
                                                     results[0].split)) as pool, \
            progress_bar(total=len(results), unit='ep', disable=not progress) as bar:
        for out in pool.imap_unordered(_score_job, jobs, chunksize=1):
            for task_id, what in out:
                verdict[task_id] = what
                bar.update(1)
    refused = next(((r.task_id, verdict[r.task_id]) for r in ordered if verdict[r.task_id] is not None), None)
    return {'results': ordered, 'summary': summarize(ordered), 'refused': refused, 'tasks': len(ordered),
            'episodes': len(jobs), 'split_tasks': len(split_tasks), 'setting': setting,
            'wall_s': time.monotonic() - t0}


def main(argv=None) -> int:
    ap = Parser(prog='./dialfred score', description=__doc__.split('\n\n')[0])
    ap.add_argument('results', type=Path, help='a results file of `launch eval` (its .trace.jsonl, .run.json and, '
                    'for a tasks file, .tasks.json beside it)')
    ap.add_argument('--tasks', type=Path, default=None, metavar='PATH',
                    help='the tasks file it was played on (default: the one its .tasks.json records, or its shipped split)')
    ap.add_argument('--answers', type=Path, default=None, metavar='FILE',
                    help='the answers file that worded its answers, where it lies now (default: the path its '
                         '.run.json records; checked by its digest)')
    ap.add_argument('--workers', type=int, default=2, help='processes replaying episodes (default: 2)')
    ap.add_argument('--progress', action=argparse.BooleanOptionalAction, default=True,
                    help='a progress bar on stderr (default: --progress)')
    args = ap.parse_args(argv)
    if args.workers < 1:
        ap.error('--workers must be at least 1')
    try:
        report = score(args.results, args.tasks, args.workers, args.progress, args.answers)
    except (ResultsFileError, FileNotFoundError, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    s = report['setting']
    what = (f'{report["tasks"]} tasks ({report["episodes"]} chained episodes)' if s.protocol != DEFAULT_PROTOCOL
            else f'{report["tasks"]} tasks')
    if report['refused'] is not None:
        task_id, difference = report['refused']
        print(f'refused: {args.results}: {difference} (task {task_id}; {what} replayed in '
              f'{report["wall_s"]:.1f} s)', file=sys.stderr)
        return 1
    first = report['results'][0]
    print(f'{first.split}, {first.agent}, seed {first.seed}, {s.protocol} protocol, goal rule {s.goal_rule}, '
          f'oracle {s.oracle or "exact"}, {s.resolution} px: {what} of the split\'s {report["split_tasks"]} replayed '
          f'in {report["wall_s"]:.1f} s; every outcome, answer, count and action agrees')
    print(format_table(report['summary']))
    return 0


if __name__ == '__main__':
    sys.exit(main())
