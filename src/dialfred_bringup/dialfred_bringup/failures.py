"""Why the episodes of a results file failed: each failure sorted by how it ended and what its last
failed action was told, the distances of the out-of-reach interactions, and the task types they
come from; for a chained run, also the 10 most common ways its episodes go wrong (each episode's first
failed task: its type, how it ended, and which task of the episode it was). Prints JSON (the diagnosis a
performer change should start from).

    ./dialfred env python -m dialfred_bringup.failures out/eval/valid_unseen_et_all.jsonl [--examples 3]
"""

from __future__ import annotations

import collections
import json
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from dialfred_sim.dataclass_cli import REQUIRED, arg, parse
from dialfred_sim.metrics import load_results

_DISTANCE = re.compile(r'is out of reach \(([\d.]+) m away')
_OBJECT = re.compile(r'\b[A-Z][A-Za-z]+_\d+\b')
_PIXEL = re.compile(r'pixel \(\d+, \d+\)')


def kind_of(error: str) -> str:
    """The failed action's error with object ids and pixels taken out: 'X is out of reach', 'MoveAhead
    blocked by X', 'no object at pixel (wall is there)', ... ('' for an episode without a failed action)."""
    if not error:
        return ''
    if 'out of reach' in error:
        return 'X is out of reach'
    return _PIXEL.sub('pixel', _OBJECT.sub('X', error))


@dataclass(frozen=True)
class FailuresConfig:
    """Break a results file's failures down by how they ended and their last failed action."""

    results: str = arg(REQUIRED, 'a results file (JSON lines) of ./dialfred launch eval', positional=True)
    examples: int = arg(3, 'task ids listed per kind of failure')


def failure_kind(r) -> tuple[str, str]:
    """(how a failed task ended, its last failed action's error as a kind); a chained task whose goal held at
    its start is a kind of its own ('held at start': scored as not done whatever the agent did)."""
    if r.held_at_start:
        return ('held at start', '')
    return (r.end_reason, kind_of(r.error))


def episode_failures(results: list, top: int = 10, examples: int = 3) -> list[dict]:
    """How the chained episodes of `results` go wrong: each episode's first failed task (in the order its tasks
    were played), by its task type and failure_kind, the `top` most common."""
    by_episode: dict[str, list] = collections.defaultdict(list)
    for r in results:
        by_episode[r.episode_id].append(r)
    kinds: dict[tuple, list] = collections.defaultdict(list)
    for rows in by_episode.values():
        rows.sort(key=lambda r: r.task_id)
        first = next((k for k, r in enumerate(rows) if not r.success), None)
        if first is not None:
            r = rows[first]
            kinds[(r.task_type, *failure_kind(r), first + 1)].append(r)
    ranked = sorted(kinds.items(), key=lambda kv: (-len(kv[1]), kv[0]))[:top]
    return [{'task_type': t, 'end_reason': end, 'last_error': kind or '(no failed action)', 'task_in_episode': k,
             'episodes': len(rs), 'share_of_episodes': round(len(rs) / len(by_episode), 3),
             'examples': [r.task_id for r in rs[:examples]]} for (t, end, kind, k), rs in ranked]


def breakdown(path: Path, examples: int = 3) -> dict:
    results = load_results(path, skip_bad=True)
    if not results:
        raise ValueError(f'{path}: no results')
    return breakdown_of(results, str(path), examples)


def breakdown_of(results: list, name: str, examples: int = 3) -> dict:
    """`breakdown` of results in hand; a chained run's also says how its episodes go wrong."""
    failed = [r for r in results if not r.success]
    kinds: dict[tuple, list] = collections.defaultdict(list)
    for r in failed:
        kinds[failure_kind(r)].append(r)
    distances = np.array([float(m.group(1)) for r in failed if (m := _DISTANCE.search(r.error or ''))])
    reach = [r for r in failed if 'out of reach' in (r.error or '')]
    chained = any(r.protocol == 'chained' for r in results)
    return {
        'results': name, 'episodes': len(results), 'failed': len(failed),
        'by_end_and_last_error': [
            {'end_reason': end, 'last_error': kind or '(no failed action)', 'episodes': len(rs),
             'share_of_failures': round(len(rs) / len(failed), 3),
             'goal_conditions_met': round(sum(r.goal_conditions_met for r in rs) / max(1, sum(r.goal_conditions_total for r in rs)), 3),
             'examples': [r.task_id for r in rs[:examples]]}
            for (end, kind), rs in sorted(kinds.items(), key=lambda kv: -len(kv[1]))],
        'out_of_reach_metres': {
            'episodes': len(distances),
            **({f'p{q}': round(float(np.percentile(distances, q)), 2) for q in (10, 25, 50, 75, 90)} if len(distances) else {}),
            'within_0.25_m_of_reach': round(float((distances < 1.75).mean()), 3) if len(distances) else None,
            'task_types': dict(collections.Counter(r.task_type for r in reach).most_common(8)),
        },
        **({'chained_episodes_go_wrong': episode_failures(results, examples=examples)} if chained else {}),
    }


def main(argv: Optional[list[str]] = None) -> int:
    cfg = parse(FailuresConfig, argv, prog='python -m dialfred_bringup.failures')
    try:
        print(json.dumps(breakdown(Path(cfg.results), cfg.examples), indent=1))
    except (OSError, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
