"""Where a `./dialfred reproduce` run stands, read from its stamps (`./dialfred reproduce --status`):
each stage done (with its time), stale (done, but a run would redo it: the hashes of its inputs now,
computed as a run computes them, differ from its stamp's), running (since when, how long so far, over
how many runs) or not started, and the items of the rl and eval stages. A running stage also says how
far it has come, read from what it has written (the perception network's frames and the performer's
updates from their metrics.jsonl, the rl stage's actor-critic updates over all its runs, the eval
stage's episodes over all its settings), and how long it has left at its own rate so far. Nothing is
run or written. The stages not done are given the times of the run whose models are shipped
(`shipped_run.json`) as an estimate of what is left; a running stage with a progress, its own estimate.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Optional

from dialfred_sim.tasks.split_files import SPLIT_SIZES

from .plan import SHIPPED_RUN, STAGES, TRAINING


def _read(path: Path) -> Optional[dict]:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _clock(t: float) -> str:
    return time.strftime('%Y-%m-%d %H:%M', time.localtime(t))


def _last_line(path: Path, key: str) -> Optional[dict]:
    """The last JSON line of `path` that has `key` (a metrics.jsonl being appended to: a torn last line is
    skipped), read from the file's end."""
    try:
        with open(path, 'rb') as f:
            f.seek(0, 2)
            f.seek(max(0, f.tell() - 65536))
            tail = f.read().decode('utf-8', 'replace').splitlines()
    except OSError:
        return None
    for line in reversed(tail):
        try:
            row = json.loads(line)
        except ValueError:
            continue
        if isinstance(row, dict) and isinstance(row.get(key), (int, float)):
            return row
    return None


def _lines(path: Path) -> int:
    try:
        with open(path, 'rb') as f:
            return sum(1 for line in f if line.strip())
    except OSError:
        return 0


def stage_progress(stage: str, stamp: dict, run: Path) -> Optional[dict]:
    """{'done', 'total', 'unit'} of a running stage, from its stamp's config and what it has written, or
    None where it cannot tell: perception counts frames trained on, the performer updates (its metrics'
    train lines), rl the actor-critic updates of all its runs (each run's metrics.jsonl) and eval and chained
    the episodes of all their settings (each setting's results file)."""
    config = (stamp.get('inputs') or {}).get('config') or {}
    if stage == 'perception' and config.get('frames') and config.get('out'):
        row = _last_line(Path(config['out']) / 'metrics.jsonl', 'frames')
        return {'done': row['frames'] if row else 0, 'total': config['frames'], 'unit': 'frames'}
    if stage == 'performer' and config.get('max_updates') and config.get('out'):
        row = _last_line(Path(config['out']) / 'metrics.jsonl', 'update')
        return {'done': row['update'] if row else 0, 'total': config['max_updates'], 'unit': 'updates'}
    if stage == 'rl' and config and all(isinstance(c, dict) and c.get('updates') and c.get('out')
                                        for c in config.values()):
        done = 0
        for c in config.values():
            row = _last_line(Path(c['out']) / 'metrics.jsonl', 'update')
            done += min(c['updates'], row['update']) if row else 0
        return {'done': done, 'total': sum(c['updates'] for c in config.values()), 'unit': 'RL updates'}
    if stage in ('eval', 'chained') and config.get('settings'):
        done = total = 0
        for s in config['settings']:
            size = SPLIT_SIZES.get(s.get('split'), 0)
            n = min(size, config['limit']) if config.get('limit') else size
            total += n
            done += min(n, _lines(run / stage / f'{s.get("split")}_{s.get("key")}.jsonl'))
        return {'done': done, 'total': total, 'unit': 'episodes'} if total else None
    return None


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
        if row['status'] == 'running':
            progress = stage_progress(stage, stamp, run)
            if progress:
                fraction = min(1.0, progress['done'] / progress['total'])
                if 0 < fraction < 1:     # its own rate so far, cut-off runs' time included
                    progress['left_s'] = round(row['seconds'] * (1 - fraction) / fraction, 1)
                row['progress'] = progress
        if row.get('progress', {}).get('left_s') is not None:
            left += row['progress']['left_s']
        elif row['status'] == 'stale' and stage in times:
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
        progress = row.get('progress')
        if progress:
            notes.append(f'{progress["done"]:,} of {progress["total"]:,} {progress["unit"]}'
                         f' ({100 * progress["done"] / progress["total"]:.0f}%)'
                         + (f', about {progress["left_s"] / 60:.0f} min more at its rate so far'
                            if progress.get('left_s') is not None else ''))
        items = row.get('items') or {}
        if items:
            done = [k for k, v in items.items() if v['status'] == 'done']
            running = [k for k, v in items.items() if v['status'] != 'done']
            notes.append(f'{len(done)} items done' + (f', {", ".join(running)} running or cut off' if running else ''))
        lines.append(f'{stage:<11} {row["status"]:<12} {seconds:>9}  {"; ".join(notes)}'.rstrip())
    if status['left_s'] is not None:
        lines.append(f'left, by the times of the run that made the shipped models (a running stage: its own rate): '
                     f'about {status["left_s"] / 60:.0f} min')
    return lines
