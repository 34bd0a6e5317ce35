"""What an evaluation played, beside what it came to: every episode's actions with their target pixels and
the step of each of its questions, kept in `<results>.trace.jsonl` next to the results file (no ROS).

A results line says how an episode ended; its trace line says how it got there, so that anyone can play
the episode again in a fresh simulator and oracle and check every outcome, answer and count
(`./dialfred score RESULTS`, dialfred_bringup/score.py). One JSON object a line, written and synced with
the results line it belongs to:

    {"task_id": "valid_unseen/000003", "actions": [["RotateLeft", -1, -1], ["Pickup", 41, 37], ...],
     "asked_at": [0, 0, 5]}

`asked_at[q]` is the number of actions taken before question q of the results line's `dialogue` was asked.
The results lines themselves are unchanged by it: a run of today writes the same results bytes as one
before traces were kept.
"""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path
from typing import Union

from .protocol import ACTIONS

SUFFIX = '.trace.jsonl'


def trace_path(results_path: Union[str, Path]) -> Path:
    """Where the traces of a results file are kept: <results without .jsonl>.trace.jsonl."""
    return Path(results_path).with_suffix(SUFFIX) if str(results_path).endswith('.jsonl') else \
        Path(str(results_path) + SUFFIX)


def make_trace(actions, asked_at) -> dict:
    """A trace of an episode: its actions [(name, x, y)] and the step of each question."""
    return {'actions': [[str(a), int(x), int(y)] for a, x, y in actions], 'asked_at': [int(s) for s in asked_at]}


def check_trace(task_id: str, trace) -> dict:
    """`trace` (a dict of make_trace's form) if it is well formed; ValueError saying what is wrong."""
    if not isinstance(trace, dict) or set(trace) != {'actions', 'asked_at'}:
        raise ValueError(f'{task_id}: a trace is {{"actions", "asked_at"}}, got {str(trace)[:80]!r}')
    for a in trace['actions']:
        if not (isinstance(a, list) and len(a) == 3 and isinstance(a[0], str) and all(
                isinstance(v, int) and not isinstance(v, bool) for v in a[1:])):
            raise ValueError(f'{task_id}: an action of a trace is [name, x, y], got {a!r:.80}')
        if a[0] not in ACTIONS:
            raise ValueError(f'{task_id}: unknown action {a[0]!r} in its trace')
    steps = trace['asked_at']
    if not all(isinstance(s, int) and not isinstance(s, bool) and 0 <= s <= len(trace['actions']) for s in steps) \
            or steps != sorted(steps):
        raise ValueError(f'{task_id}: asked_at must be action counts in order, 0 to {len(trace["actions"])}')
    return trace


def append_trace(results_path: Union[str, Path], task_id: str, trace: dict) -> None:
    """Append the trace line of `task_id` beside its results file and push it to disk."""
    path = trace_path(results_path)
    path.parent.mkdir(parents=True, exist_ok=True)
    line = json.dumps({'task_id': task_id, **trace}, separators=(',', ':')).encode() + b'\n'
    with open(path, 'a+b') as f:
        if f.tell() > 0:
            f.seek(-1, os.SEEK_END)
            if f.read(1) != b'\n':
                line = b'\n' + line       # never glue onto a line cut off by a crash
        f.write(line)
        f.flush()
        os.fsync(f.fileno())


def load_traces(results_path: Union[str, Path]) -> dict:
    """{task_id: trace} of a results file's traces ({} without a trace file). A line cut off at the end (a
    crash) is skipped with a warning; a bad line elsewhere is a ValueError naming it. A task traced twice
    (a replayed episode's trace is written again) keeps its last trace."""
    path = trace_path(results_path)
    if not path.exists():
        return {}
    lines = path.read_bytes().split(b'\n')
    last = max((k for k, line in enumerate(lines) if line.strip()), default=-1)
    traces = {}
    for k, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            data = json.loads(line)
            task_id = data.pop('task_id')
            traces[task_id] = check_trace(task_id, data)
        except (ValueError, KeyError, AttributeError, TypeError) as exc:
            if k == last:
                warnings.warn(f'{path}:{k + 1}: skipped a cut-off last line ({exc})', stacklevel=2)
                break
            raise ValueError(f'{path}:{k + 1}: not a trace line: {exc}') from None
    return traces
