#!/usr/bin/env python3
"""Following directions: each agent asked "Which direction should I turn to?" before every action
(`--questioner every:direction`, which is `examples.direction_follower:AskForDirections`), against the
same agent asked nothing and against the blind follower of examples/direction_follower.py (it sees nothing
and only does what it hears: the baseline issue 74 names, 74.0% of valid_unseen's Move tasks). Prints JSON
per agent: SR on the Move tasks (the go-to alone, where a direction says everything) and overall, questions
a task, the SR points the directions are worth on the Move tasks and on the tasks with a go-to, and how
often an agent asked at every step did what the answer of the step said on the Move tasks (`obeyed`, per
answer: `data.obeys`; the traces of the results).

Results files go to --out (one per agent and questioner); a run that is cut off resumes there.

    ./dialfred bench direction_following [--agents follower et map] [--checkpoint PATH] [--split valid_unseen]
                                         [--limit N] [--workers 2] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dialfred_bringup.machine import cpu_model
from dialfred_performer.data import obeys
from dialfred_sim.metrics import load_results
from dialfred_sim.tasks import task_type

REPO = Path(__file__).resolve().parents[1]

FOLLOWER = 'examples.direction_follower:DirectionFollower'
AGENTS = {'follower': FOLLOWER, 'et': 'et', 'map': 'map'}
EVERY_STEP = 'every:direction'


def has_goto(task_type_name: str) -> bool:
    return 'goto' in task_type(task_type_name).steps


def rates(results: list) -> dict:
    def sr(rows):
        return round(100.0 * sum(r.success for r in rows) / len(rows), 2) if rows else None
    move = [r for r in results if r.task_type == 'Move']
    goto = [r for r in results if has_goto(r.task_type)]
    return {'tasks': len(results), 'SR': sr(results), 'move_tasks': len(move), 'move_SR': sr(move),
            'goto_tasks': len(goto), 'goto_SR': sr(goto),
            'NQ': round(sum(r.questions for r in results) / max(len(results), 1), 2),
            'move_NQ': round(sum(r.questions for r in move) / max(len(move), 1), 2)}


def obedience(results: Path) -> dict:
    """On the Move tasks of a results file asked for directions at every step: the share of the steps whose
    action did what the step's answer said, overall and per answer ({answer: [steps, share]})."""
    moves = {r['task_id']: [d['answer'] for d in r['dialogue'] if d['type'] == 'direction' and d['valid']]
             for r in map(json.loads, results.read_text().splitlines()) if r['task_type'] == 'Move'}
    counts: dict[str, list[int]] = {}
    for line in results.with_name(results.name.replace('.jsonl', '.trace.jsonl')).read_text().splitlines():
        trace = json.loads(line)
        said = moves.get(trace['task_id'])
        if said is None:
            continue
        for answer, step in zip(said, trace['asked_at']):
            if step < len(trace['actions']):
                row = counts.setdefault(answer, [0, 0])
                row[0] += 1
                row[1] += obeys(answer, trace['actions'][step][0])
    steps = sum(n for n, _ in counts.values())
    return {'steps': steps, 'share': round(sum(k for _, k in counts.values()) / steps, 3) if steps else None,
            'answers': {a: [n, round(k / n, 3)] for a, (n, k) in sorted(counts.items())}}


def play(agent: str, questioner: str, args, out: Path) -> dict:
    """One `launch eval --local` run, as a user types it (from the repository, where `examples` imports)."""
    results = out / f'{agent}_{questioner.replace(":", "-") or "none"}.jsonl'
    cmd = [sys.executable, '-m', 'dialfred_bringup.launch', 'eval', '--split', args.split, '--local',
           '--workers', str(args.workers), '--agent', AGENTS[agent], '--questioner', questioner or 'none',
           '--out', str(results), '--progress' if args.progress else '--no-progress']
    if args.limit:
        cmd += ['--limit', str(args.limit)]
    if args.checkpoint and agent == 'et':
        cmd += ['--checkpoint', args.checkpoint]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, cwd=REPO, stdout=subprocess.DEVNULL)
    if done.returncode != 0:
        raise SystemExit(f'{" ".join(cmd)} failed ({done.returncode})')
    return {**rates(load_results(results)), 'wall_s': round(time.perf_counter() - t0, 1),
            'results': str(results) if args.out else None}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--agents', nargs='+', default=list(AGENTS), choices=list(AGENTS))
    ap.add_argument('--checkpoint', default='', help="the Episodic Transformer's checkpoint (default: the shipped one)")
    ap.add_argument('--split', default='valid_unseen')
    ap.add_argument('--limit', type=int, default=None, help='only the first N tasks of the split')
    ap.add_argument('--workers', type=int, default=2)
    ap.add_argument('--out', default='', help='the results folder (default: a temporary one)')
    ap.add_argument('--progress', action=argparse.BooleanOptionalAction, default=True)
    args = ap.parse_args()
    if args.workers < 1 or (args.limit is not None and args.limit < 1):
        ap.error('--workers and --limit must be at least 1')
    with tempfile.TemporaryDirectory(prefix='direction_following_') as tmp:
        out = Path(args.out or tmp)
        out.mkdir(parents=True, exist_ok=True)
        report = {'benchmark': 'direction_following', 'split': args.split, 'limit': args.limit, 'cpu': cpu_model(),
                  'checkpoint': args.checkpoint or 'shipped', 'agents': {}}
        for agent in args.agents:
            row = {'every_step': play(agent, EVERY_STEP, args, out)}
            row['obeyed'] = obedience(out / f'{agent}_{EVERY_STEP.replace(":", "-")}.jsonl')
            if agent != 'follower':            # the follower without answers only turns and stops
                row['none'] = play(agent, '', args, out)
                for scope in ('move_SR', 'goto_SR'):
                    a, b = row['every_step'][scope], row['none'][scope]
                    row[f'{scope}_gain'] = round(a - b, 2) if a is not None and b is not None else None
            report['agents'][agent] = row
        follower = report['agents'].get('follower', {}).get('every_step', {}).get('move_SR')
        if follower is not None:
            report['beats_the_blind_follower_on_move'] = {
                a: r['every_step']['move_SR'] >= follower for a, r in report['agents'].items() if a != 'follower'}
    print(json.dumps(report, indent=1))


if __name__ == '__main__':
    main()
