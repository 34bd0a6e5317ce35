"""DialFRED's evaluation metrics over episode results: SR, PWSR, GC and NQ (no ROS).

Per episode (Gao et al., 2022, after ALFRED): success s in {0, 1}; goal-condition fraction
GC = met / total, where total counts the goal conditions that did not hold at the task's start and
met those of them that hold at its end (tasks.goals.goal_progress; ALFRED counts every condition,
see docs/dataset.md "Metrics"); path-weighted success p = s * L* / max(L*, L) with L* the expert's
length and L the agent's steps; NQ the number of questions asked (NQ_invalid: those the oracle could
not answer).
`summarize` averages them overall and per task type (SR, PWSR and GC in percent, NQ and NQ_invalid
as mean counts), in the task order of the paper's table; `intervals` gives their 95% percentile-
bootstrap intervals (seeded: the same results and seed, the same numbers).

Results are kept one JSON object per line (`append_result`, `load_results`), written and synced
episode by episode so that an interrupted evaluation loses nothing and can resume.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import socket
import subprocess
import sys
import time
import warnings
from dataclasses import MISSING, asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Iterable, Optional, Union

import numpy as np

from .chained import episode_metrics
from .protocol import DEFAULT_PROTOCOL, MAX_FAILURES, PROTOCOLS
from .tasks.types import task_types

END_REASONS = ('success', 'stop', 'max_steps', 'max_failures', 'error')


@dataclass
class EpisodeResult:
    """What one evaluated episode came to.

    `end_reason` is one of END_REASONS; `error` is why a request failed ('error' episodes) or the
    last failed action's error message (other unsuccessful episodes), else ''.
    """

    task_id: str
    task_type: str
    split: str
    success: bool
    goal_conditions_met: int
    goal_conditions_total: int
    steps: int
    expert_length: int
    questions: int = 0
    failed_actions: int = 0
    invalid_questions: int = 0       # of `questions`, those the oracle could not answer
    end_reason: str = 'stop'
    error: str = ''
    agent: str = ''
    oracle: str = ''                 # '' = exact answers; 'location:0.5' = withholding that type that often
    seed: int = 0
    wall_s: float = 0.0
    privileged: bool = False         # played by a reference agent that saw the task's solution (the expert)
    dialogue: list = field(default_factory=list)   # the questions asked, in order: {type, noun, valid, answer}
                                                   # (absent from results written before it was recorded)
    code: str = ''                   # the commit of the code that played it ('+dirty': an edited checkout;
                                     # '' in results written before it was recorded)
    goal_rule: str = ''              # how its go-to was judged (tasks.goals.GOAL_RULES); '' in results written
                                     # before it was recorded, which the 'visible' rule judged
    # The chained protocol's fields (dialfred_sim.chained); lines of the expert protocol leave them out.
    protocol: str = DEFAULT_PROTOCOL   # how it was played: 'expert' (from the expert's state) or 'chained'
    episode_id: str = ''               # chained: the episode ('valid_unseen/ep000003') whose tasks were played in order
    held_at_start: bool = False        # chained: its whole goal held when it began (scored as not done)
    # How it was played: 'local processes (no ROS)', 'in-process agent' (through the simulator and oracle
    # nodes) or 'performer node' ('' in results written before it was recorded); the same episode either way,
    # so two results that differ only here are equal.
    played: str = field(default='', compare=False)
    # Not in the line: how the episode got there (traces.make_trace), which a run writes to its trace file.
    trace: Optional[dict] = field(default=None, compare=False, repr=False)

    def __post_init__(self):
        if self.end_reason not in END_REASONS:
            raise ValueError(f'end_reason must be one of {END_REASONS}, got {self.end_reason!r}')
        if self.protocol not in PROTOCOLS:
            raise ValueError(f'protocol must be one of {PROTOCOLS}, got {self.protocol!r}')
        if self.protocol == DEFAULT_PROTOCOL and (self.episode_id or self.held_at_start):
            raise ValueError(f'episode_id and held_at_start belong to chained results, not {self.protocol!r} ones')

    @property
    def gc(self) -> float:
        """Fraction of the goal conditions left to do at the start that hold at the end (a task with
        none left to do counts its success)."""
        if self.goal_conditions_total <= 0:
            return float(self.success)
        return self.goal_conditions_met / self.goal_conditions_total

    @property
    def path_weighted_success(self) -> float:
        """s * L* / max(L*, L): full credit at or under the expert's length, less the longer it took."""
        if not self.success:
            return 0.0
        longest = max(self.expert_length, self.steps)
        return 1.0 if longest <= 0 else self.expert_length / longest

    @property
    def question_types(self) -> dict:
        """{question type: how many of this episode's questions were of it} (from `dialogue`)."""
        counts: dict = {}
        for qa in self.dialogue:
            counts[qa['type']] = counts.get(qa['type'], 0) + 1
        return counts

    def to_json(self) -> str:
        """One line of JSON (no newline); a line of the expert protocol leaves out the chained fields, as it
        was written before they existed."""
        data = asdict(self)
        del data['trace']
        if self.protocol == DEFAULT_PROTOCOL:
            for name in CHAINED_FIELDS:
                del data[name]
        return json.dumps(data, separators=(',', ':'))

    @classmethod
    def from_json(cls, line: str) -> 'EpisodeResult':
        """Parse a line written by `to_json`; ValueError says what is wrong with a bad line."""
        try:
            data = json.loads(line)
        except json.JSONDecodeError as exc:
            raise ValueError(f'not a JSON episode result ({exc.msg} at column {exc.colno}): {line[:80]!r}') from None
        if not isinstance(data, dict):
            raise ValueError(f'an episode result must be a JSON object, got {type(data).__name__}')
        known = {f.name: f for f in fields(cls) if f.name != 'trace'}
        unknown = sorted(set(data) - set(known))
        if unknown:
            raise ValueError(f'unknown episode result fields {unknown}')
        missing = [name for name, f in known.items()
                   if name not in data and f.default is MISSING and f.default_factory is MISSING]
        if missing:
            raise ValueError(f'episode result is missing fields {missing}')
        for name, value in data.items():
            want = _FIELD_TYPES[name]
            if not _has_type(value, want):
                raise ValueError(f'episode result field {name!r} should be {want.__name__}, got {value!r}')
        for entry in data.get('dialogue', []):
            if not (isinstance(entry, dict) and set(entry) == set(_DIALOGUE_TYPES)
                    and all(_has_type(entry[k], t) for k, t in _DIALOGUE_TYPES.items())):
                raise ValueError(f'a dialogue entry is {{"type", "noun", "valid", "answer"}}, got {entry!r:.80}')
        return cls(**data)


CHAINED_FIELDS = ('protocol', 'episode_id', 'held_at_start')
OUTCOME_FIELDS = ('success', 'goal_conditions_met', 'goal_conditions_total', 'steps', 'questions',
                  'invalid_questions', 'failed_actions', 'end_reason', 'error')


def episode_result(task, outcome, dialogue: list, *, agent: str, oracle: str, seed: int, goal_rule: str,
                   wall_s: float, privileged: bool = False, protocol: str = DEFAULT_PROTOCOL,
                   expert_length: Optional[int] = None, trace: Optional[dict] = None) -> EpisodeResult:
    """The results line of `task`'s episode, whichever way it was played: `outcome` has OUTCOME_FIELDS (the
    episode loop's EpisodeState, a RunTask result, ...), `dialogue` its questions as dialogue_entry dicts; the
    run's identity (agent, oracle, seed, goal rule, protocol) and the episode's wall time. Under the chained
    protocol `expert_length` is the task's chained reference (chained.reference_length), and a task that
    had no goal condition left to do when it began is marked held at start. `trace`: the episode's actions
    and question steps (traces.make_trace), carried with the result to the trace file."""
    o = {k: getattr(outcome, k) for k in OUTCOME_FIELDS}
    chained = {}
    if protocol != DEFAULT_PROTOCOL:
        chained = {'protocol': protocol, 'episode_id': task.episode.episode_id,
                   'held_at_start': int(o['goal_conditions_total']) == 0 and o['end_reason'] != 'error'}
    return EpisodeResult(**chained,
        task_id=task.task_id, task_type=task.task_type, split=task.split, success=bool(o['success']),
        goal_conditions_met=int(o['goal_conditions_met']), goal_conditions_total=int(o['goal_conditions_total']),
        steps=int(o['steps']), expert_length=int(task.expert_length if expert_length is None else expert_length),
        questions=int(o['questions']),
        invalid_questions=int(o['invalid_questions']), failed_actions=int(o['failed_actions']),
        end_reason=o['end_reason'], error=o['error'], agent=agent, oracle=oracle, seed=seed, wall_s=round(wall_s, 4),
        goal_rule=goal_rule, privileged=bool(privileged), dialogue=list(dialogue), trace=trace)


def has_goto(task_type: str) -> bool:
    """Whether a task type's steps include a go-to ('Move & Pick'): its goal then includes standing within 4
    actions of the expert's end pose (DialFRED's rule). A type not registered in this process (a results
    file of someone's own types) has one when its name says Move."""
    known = {kind.name: kind for kind in task_types()}
    return known[task_type].has_goto if task_type in known else 'Move' in task_type


def dialogue_entry(question_type: str, object_noun: str, valid: bool, answer: str) -> dict:
    """One question of EpisodeResult.dialogue (an answer the oracle could not give is recorded as '')."""
    return {'type': question_type, 'noun': object_noun, 'valid': bool(valid), 'answer': answer if valid else ''}


_DIALOGUE_TYPES = {'type': str, 'noun': str, 'valid': bool, 'answer': str}
_FIELD_TYPES = {'task_id': str, 'task_type': str, 'split': str, 'success': bool, 'goal_conditions_met': int,
                'goal_conditions_total': int, 'steps': int, 'expert_length': int, 'questions': int,
                'invalid_questions': int, 'failed_actions': int, 'end_reason': str, 'error': str, 'agent': str,
                'oracle': str, 'seed': int, 'wall_s': float, 'privileged': bool, 'dialogue': list, 'code': str,
                'goal_rule': str, 'protocol': str, 'episode_id': str, 'held_at_start': bool, 'played': str}
# Fields that say how and where an episode was played, not what happened in it.
RUN_FIELDS = ('wall_s', 'code', 'played')


def played_through(results) -> str:
    """How the results were played (EpisodeResult.played): the one way, or each way with its count."""
    counts: dict = {}
    for r in results:
        counts[r.played or 'unrecorded'] = counts.get(r.played or 'unrecorded', 0) + 1
    if len(counts) == 1:
        return next(iter(counts))
    return ', '.join(f'{way}: {n}' for way, n in counts.items())


def played_at(results) -> dict:
    """{commit: episodes} of these results ('unrecorded' for results written before rows carried it)."""
    counts: dict = {}
    for r in results:
        counts[r.code or 'unrecorded'] = counts.get(r.code or 'unrecorded', 0) + 1
    return dict(sorted(counts.items()))


def same_episode(a: EpisodeResult, b: EpisodeResult) -> bool:
    """Whether two results record the same episode, field for field except RUN_FIELDS."""
    blank = {name: EpisodeResult.__dataclass_fields__[name].default for name in RUN_FIELDS}
    return replace(a, **blank) == replace(b, **blank)


def _has_type(value, want: type) -> bool:
    if want is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if want is int:
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, want)


def end_reason(success: bool, last_action: str, failed_actions: int, truncated: bool,
               max_failures: int = MAX_FAILURES) -> str:
    """Why an episode ended, from its last step: success, the agent's Stop, too many failed actions,
    or the step limit (in that order of precedence)."""
    if success:
        return 'success'
    if last_action == 'Stop':
        return 'stop'
    if failed_actions >= max_failures:
        return 'max_failures'
    if truncated:
        return 'max_steps'
    raise ValueError('the episode has not ended: no success, no Stop, no failure or step limit')


# ---------------------------------------------------------------------------------------- summaries

def _row(results: list[EpisodeResult]) -> dict:
    n = len(results)
    if n == 0:
        return {'n': 0, 'SR': 0.0, 'PWSR': 0.0, 'GC': 0.0, 'NQ': 0.0, 'NQ_invalid': 0.0}
    return {
        'n': n,
        'SR': 100.0 * sum(r.success for r in results) / n,
        'PWSR': 100.0 * sum(r.path_weighted_success for r in results) / n,
        'GC': 100.0 * sum(r.gc for r in results) / n,
        'NQ': sum(r.questions for r in results) / n,
        'NQ_invalid': sum(r.invalid_questions for r in results) / n,
    }


def type_order(task_type: str) -> tuple:
    """Sort key: the registry's order (the paper's table, then types registered after it), unknown types
    after them by name."""
    names = [kind.name for kind in task_types()]
    return (names.index(task_type), '') if task_type in names else (len(names), task_type)


def summarize(results: Iterable[EpisodeResult]) -> dict:
    """{'overall': row, 'per_type': {task_type: row}, 'end_reasons': {reason: count}}, and for results of
    the chained protocol 'episodes': the per-episode figures (chained.episode_metrics: episodes whose
    every task succeeded, tasks done in order before the first failure, questions per episode, tasks
    whose goal held at their start).

    A row is {'n', 'SR', 'PWSR', 'GC' (percent), 'NQ', 'NQ_invalid' (mean questions per episode, and
    of those the ones the oracle could not answer)}; per_type holds
    the types present, in the paper's task order.
    """
    results = list(results)
    by_type: dict[str, list[EpisodeResult]] = {}
    for r in results:
        by_type.setdefault(r.task_type, []).append(r)
    reasons = {reason: sum(r.end_reason == reason for r in results) for reason in END_REASONS}
    summary = {
        'overall': _row(results),
        'per_type': {t: _row(by_type[t]) for t in sorted(by_type, key=type_order)},
        'end_reasons': {k: v for k, v in reasons.items() if v},
    }
    if any(r.protocol == 'chained' for r in results):
        summary['episodes'] = episode_metrics(results)
    return summary


INTERVAL_METRICS = ('SR', 'PWSR', 'GC', 'NQ')


def intervals(results: Iterable[EpisodeResult], resamples: int = 2000, seed: int = 0,
              confidence: float = 0.95) -> dict:
    """{'SR': (lo, hi), 'PWSR': ..., 'GC': ..., 'NQ': ...}: percentile-bootstrap intervals of the overall
    row of `summarize` (same units: percent, NQ per episode). `resamples` resamplings of the episodes
    with replacement, drawn from numpy's generator seeded with `seed`. No results: (0.0, 0.0) each,
    as `summarize` gives 0.0."""
    results = list(results)
    if resamples < 1:
        raise ValueError(f'resamples must be >= 1, got {resamples}')
    if not 0.0 < confidence < 1.0:
        raise ValueError(f'confidence must be in (0, 1), got {confidence}')
    if not results:
        return {k: (0.0, 0.0) for k in INTERVAL_METRICS}
    per_episode = np.array([[100.0 * r.success for r in results], [100.0 * r.path_weighted_success for r in results],
                            [100.0 * r.gc for r in results], [float(r.questions) for r in results]])
    n = len(results)
    picks = np.random.default_rng(seed).integers(0, n, size=(resamples, n))      # episode indices, per resample
    means = np.stack([values[picks].mean(axis=1) for values in per_episode], axis=1)    # (resamples, metrics)
    tail = 100.0 * (1.0 - confidence) / 2.0
    lo, hi = np.percentile(means, [tail, 100.0 - tail], axis=0)
    return {k: (float(lo[j]), float(hi[j])) for j, k in enumerate(INTERVAL_METRICS)}


def format_table(summary: dict) -> str:
    """The summary as a fixed-width text table: one line per task type, then the overall line."""
    width = max([len('task type'), len('overall')] + [len(t) for t in summary['per_type']])
    header = f'{"task type":<{width}}  {"n":>5}  {"SR":>6}  {"PWSR":>6}  {"GC":>6}  {"NQ":>5}'

    def line(name: str, row: dict) -> str:
        return (f'{name:<{width}}  {row["n"]:>5d}  {row["SR"]:>6.1f}  {row["PWSR"]:>6.1f}  '
                f'{row["GC"]:>6.1f}  {row["NQ"]:>5.2f}')

    rule = '-' * len(header)
    body = [line(t, row) for t, row in summary['per_type'].items()]
    table = [header, rule, *body, rule, line('overall', summary['overall'])]
    e = summary.get('episodes')
    if e:
        table.append(f'chained: {e["episodes"]} episodes ({e["tasks_per_episode"]:.2f} tasks each), every task done '
                     f'in {e["all_succeeded"]:.1f}%, {e["in_order"]:.2f} tasks done in order before the first failure, '
                     f'{e["questions_per_episode"]:.2f} questions per episode; {e["held_at_start"]} tasks held at '
                     f'start (in {e["episodes_with_held"]} episodes), scored as not done')
    return '\n'.join(table)


# ---------------------------------------------------------------------------------------- JSON lines

class ResultsFileError(ValueError):
    """A results file that cannot be used as it is: corrupt or cut off, or written by another split,
    agent, seed or shard (resuming an evaluation, merging shards)."""


class TruncatedResultsWarning(UserWarning):
    """The last line of a results file was cut off (an interrupted write) and was skipped."""


def changes_code(status_lines) -> bool:
    """Whether `git status --porcelain --untracked-files=all` lines change the project's code: a tracked file
    changed, or a new file under src/ (a new file elsewhere, such as a user's module at the root, does not)."""
    return any(not line.startswith('?? ') or line[3:].lstrip('"').startswith('src/') for line in status_lines
               if line.strip())


def git_commit() -> str:
    """The commit of the code that runs: of the repository this file is in (with '+dirty' for uncommitted changes
    to its files, or a new file in its packages under src/), or 'unknown'. A user's own module saved beside the
    project (an agent or questioner of `--agent package.module:Class`, named in the results) leaves it clean."""
    here = Path(__file__).resolve().parent
    try:
        head = subprocess.run(['git', 'rev-parse', 'HEAD'], cwd=here, capture_output=True, text=True,
                              timeout=10, check=True).stdout.strip()
        status = subprocess.run(['git', 'status', '--porcelain', '--untracked-files=all'], cwd=here,
                                capture_output=True, text=True, timeout=10).stdout.splitlines()
        return head + ('+dirty' if changes_code(status) else '')
    except (OSError, subprocess.SubprocessError):
        return 'unknown'


def write_text_atomically(path: Union[str, Path], text: str) -> None:
    """Write a whole file so that a crash leaves the old file or the new one, never half of one: a
    temporary file beside it, pushed to disk, then renamed over it."""
    path = Path(path)
    tmp = path.with_name(f'.{path.name}.{os.getpid()}.tmp')
    try:
        with open(tmp, 'w') as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


@contextlib.contextmanager
def results_lock(path: Union[str, Path]):
    """Own the results file `path` for one run: an exclusive OS lock (flock) on `<path>.lock`, held
    while the block runs and released when it ends or its process dies; the lock file is removed when
    the block ends. ResultsFileError naming the owner (pid, host, command) when another run holds it:
    two runs never append to one file."""
    lock = Path(str(path) + '.lock')
    lock.parent.mkdir(parents=True, exist_ok=True)
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            owner = os.pread(fd, 4096, 0).decode('utf-8', errors='replace').strip() or 'another process'
            os.close(fd)
            raise ResultsFileError(f'{path} is being written by another run ({owner}): wait for it to end, or '
                                   'choose another --out') from None
        try:
            same = os.stat(lock).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)     # the run before removed the file as we opened it: lock the one there now
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps({'pid': os.getpid(), 'host': socket.gethostname(), 'since': time.strftime('%FT%T'),
                                  'command': ' '.join(sys.argv)[:300]}).encode(), 0)
        yield
    finally:
        with contextlib.suppress(FileNotFoundError):
            lock.unlink()     # while still locked: a run waiting on this file sees it gone and starts over
        os.close(fd)


def append_result(path: Union[str, Path], result: EpisodeResult) -> None:
    """Append one result line and push it to disk (flush + fsync): a crash loses no finished episode."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, 'a+b') as f:
        # never glue onto a line without its newline (a file cut off mid-line, or edited by hand)
        if f.tell() > 0:
            f.seek(-1, os.SEEK_END)
            prefix = b'' if f.read(1) == b'\n' else b'\n'
        else:
            prefix = b''
        f.write(prefix + result.to_json().encode('utf-8') + b'\n')
        f.flush()
        os.fsync(f.fileno())


def load_results(path: Union[str, Path], drop_truncated: bool = False, skip_bad: bool = False) -> list[EpisodeResult]:
    """Every result in a JSON-lines file ([] if there is none).

    A bad final line (a write cut off by a crash) is skipped with a TruncatedResultsWarning; with
    `drop_truncated` it is also cut from the file, so that the next append starts on a clean line.
    A bad line anywhere else is corruption: ValueError naming the file and line (with `skip_bad`, for
    readers that only look, it is skipped with a TruncatedResultsWarning saying which and why).
    """
    path = Path(path)
    if not path.exists():
        return []
    lines = path.read_bytes().split(b'\n')
    last_number = max((k for k, line in enumerate(lines, start=1) if line.strip()), default=0)
    results: list[EpisodeResult] = []
    good_end = 0         # byte offset just past the last good line
    for number, line in enumerate(lines, start=1):
        if line.strip():
            try:
                results.append(EpisodeResult.from_json(line.decode('utf-8', errors='replace')))
            except ValueError as exc:
                if number != last_number and skip_bad:
                    warnings.warn(f'{path}:{number}: skipped 1 malformed line ({exc})', TruncatedResultsWarning,
                                  stacklevel=2)
                    good_end += len(line) + 1
                    continue
                if number != last_number:
                    raise ValueError(f'{path}:{number}: corrupt result line: {exc}') from None
                warnings.warn(f'{path}:{number}: skipped 1 truncated final line ({exc})', TruncatedResultsWarning,
                              stacklevel=2)
                if drop_truncated:
                    _truncate(path, good_end)
                break
        good_end += len(line) + 1
    return results


def _truncate(path: Path, size: int) -> None:
    with open(path, 'r+b') as f:
        f.truncate(size)
        f.flush()
        os.fsync(f.fileno())


def failures(results: Iterable[EpisodeResult]) -> list[EpisodeResult]:
    """The unsuccessful episodes, in task order."""
    return sorted((r for r in results if not r.success), key=lambda r: r.task_id)


def results_by_task(results: Iterable[EpisodeResult], task_ids: Optional[Iterable[str]] = None) -> dict:
    """{task_id: result}, the first result of each task (optionally only of `task_ids`)."""
    wanted = None if task_ids is None else set(task_ids)
    out: dict[str, EpisodeResult] = {}
    for r in results:
        if (wanted is None or r.task_id in wanted) and r.task_id not in out:
            out[r.task_id] = r
    return out
