"""Where a `./dialfred reproduce` run stands, read from its stamps (`./dialfred reproduce --status`):
each stage done (with its time), stale (done, but a run would redo it: the hashes of its inputs now,
computed as a run computes them, differ from its stamp's), running (since when, how long so far, over how many runs) or not
started, and the items of the rl and eval stages. Nothing is run or written. With the times of the run
whose models are shipped (`shipped_run.json`), the stages not done are given that run's times as an
estimate of what is left.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Optional

from .plan import SHIPPED_RUN, STAGES, TRAINING


def _read(path: Path) -> Optional[dict]:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _clock(t: float) -> str:
    return time.strftime('%Y-%m-%d %H:%M', time.localtime(t))


def run_status(run: Path, shipped: bool = False, now: Optional[float] = None, shipped_run: Path = SHIPPED_RUN,
               planned: Optional[dict] = None) -> dict:
    """{'run', 'stages': {stage: {'status', 'seconds', 'runs', 'since', 'items': {...}}}, 'left_s'}:
    status is done, stale (done, but its stamp's hash is not `planned[stage]`, the hash a run would
    compare now: its code, config or an upstream stage changed, so a run redoes it),
    running (a run in progress or one cut off: the stamps cannot tell them apart), not started, or
    shipped (a training stage of a `--shipped` run); `seconds` of a running one are its earlier runs'
    and this one's so far."""
    now = time.time() if now is None else now
    times = (_read(shipped_run) or {}).get('stages', {})
    stages, left = {}, 0.0
    for stage in STAGES:
        if shipped and stage in TRAINING:
            stages[stage] = {'status': 'shipped'}
            continue
        stamp = _read(run / 'stamps' / f'{stage}.json')
        items = {}
        for path in sorted((run / 'stamps' / stage).glob('*.json')) if (run / 'stamps' / stage).is_dir() else []:
            item = _read(path) or {}
            items[path.stem] = {'status': item.get('status', 'unreadable'),
                                'seconds': item.get('seconds', item.get('seconds_before', 0.0))}
        if stamp is None:
            row = {'status': 'not started'}
        elif stamp.get('status') == 'done':
            stale = planned is not None and stage in planned and stamp.get('hash') != planned[stage]
            row = {'status': 'stale' if stale else 'done', 'seconds': stamp.get('seconds', 0.0),
                   'runs': stamp.get('runs', 1)}
        else:
            since = stamp.get('started_at', now)
            row = {'status': 'running', 'since': _clock(since), 'runs': stamp.get('runs', 1),
                   'seconds': round(stamp.get('seconds_before', 0.0) + max(0.0, now - since), 1)}
        if items:
            row['items'] = items
        if row['status'] == 'stale' and stage in times:
            left += times[stage]['seconds']
        elif row['status'] != 'done' and stage in times:
            left += max(0.0, times[stage]['seconds'] - (row.get('seconds') or 0.0))
        stages[stage] = row
    return {'run': str(run), 'stages': stages, 'left_s': round(left, 1) if times and not shipped else None}


def status_lines(status: dict) -> list[str]:
    """The status as a table, a line per stage, and the estimate of what is left."""
    lines = [f'{status["run"]}', f'{"stage":<11} {"status":<12} {"time":>9}  note']
    for stage, row in status['stages'].items():
        seconds = f'{row["seconds"] / 60:.1f} min' if row.get('seconds') is not None else ''
        notes = []
        if row['status'] == 'stale':
            notes.append('its inputs (code, config or an upstream stage) changed since: a run redoes it')
        if row['status'] == 'running':
            notes.append(f'since {row["since"]}' + (f', run {row["runs"]}' if row['runs'] > 1 else '')
                         + ' (or cut off: rerun the same command to resume)')
        items = row.get('items') or {}
        if items:
            done = [k for k, v in items.items() if v['status'] == 'done']
            running = [k for k, v in items.items() if v['status'] != 'done']
            notes.append(f'{len(done)} items done' + (f', {", ".join(running)} running or cut off' if running else ''))
        lines.append(f'{stage:<11} {row["status"]:<12} {seconds:>9}  {"; ".join(notes)}'.rstrip())
    if status['left_s'] is not None:
        lines.append(f'left, by the times of the run that made the shipped models: about {status["left_s"] / 60:.0f} min')
    return lines
