"""Fault recovery of `launch eval` through the graph: nodes SIGKILLed at random moments, a killed
launcher, a node that keeps dying.

Claims: with any node of a worker (simulator, oracle, questioner, performer) SIGKILLed at random
moments (seeded), the launcher restarts that worker's nodes, replays the interrupted episode from its
start, and the results file has every task exactly once with the metrics and dialogues of an
uninterrupted run; a SIGKILLed launcher leaves no node running and the same command then resumes to
the same results; a node that dies every time it starts is given up on after --max-restarts restarts,
with a clear message; a results file cut mid-line is reported and its last line replayed.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


RES, TASKS = 64, 8
KEY = ('task_id', 'success', 'steps', 'goal_conditions_met', 'goal_conditions_total', 'questions',
       'invalid_questions', 'failed_actions', 'end_reason', 'error', 'dialogue')


def command(checkpoint: Path, out: Path, *extra: str) -> list[str]:
    return [sys.executable, '-m', 'dialfred_bringup.launch', 'eval', '--performer', 'et', '--checkpoint',
            str(checkpoint), '--questioner', 'random', '--split', 'valid_unseen', '--limit', str(TASKS),
            '--workers', '2', '--resolution', str(RES), '--seed', '4', '--out', str(out), '--no-progress', *extra]


def results(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def metrics(path: Path) -> dict:
    rows = results(path)
    assert len(rows) == len({r['task_id'] for r in rows}), 'a task recorded twice'
    return {r['task_id']: tuple(json.dumps(r[k]) for k in KEY) for r in rows}


def children(pid: int) -> list[int]:
    """Processes whose parent is `pid` (the launcher's node processes)."""
    found = []
    for entry in os.listdir('/proc'):
        if entry.isdigit():
            try:
                stat = Path(f'/proc/{entry}/stat').read_text()
            except OSError:
                continue
            if int(stat.rsplit(')', 1)[1].split()[1]) == pid:
                found.append(int(entry))
    return found


def cmdline(pid: int) -> str:
    """What a process runs ('' once it is gone), for error messages."""
    try:
        return Path(f'/proc/{pid}/cmdline').read_bytes().replace(b'\0', b' ').decode(errors='replace')[:200]
    except OSError:
        return ''


def alive(pid: int) -> bool:
    try:
        stat = Path(f'/proc/{pid}/stat').read_text()
    except OSError:
        return False
    return stat.rsplit(')', 1)[1].split()[0] != 'Z'


class uninterrupted_run:
    lines: list = []


@pytest.fixture(scope='module')
def uninterrupted(checkpoint, tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp('base') / 'r.jsonl'
    proc = subprocess.run(command(checkpoint, out), capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    found = metrics(out)
    assert len(found) == TASKS and sum(json.loads(v[5]) for v in found.values()) > 0    # questions were asked
    uninterrupted_run.lines = out.read_text().splitlines()
    return found


@pytest.mark.slow   # fault injection on whole evaluations; fast: test_eval (resume, Ctrl-C), test_integrity (resend), test_sim_node (restart)
def test_nodes_killed_at_random_moments_are_restarted_and_the_results_are_an_uninterrupted_runs(
        checkpoint, uninterrupted, tmp_path):
    out = tmp_path / 'r.jsonl'
    launcher = subprocess.Popen(command(checkpoint, out, '--max-restarts', '8'), stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
    rng = random.Random(7)
    killed = []

    def killer() -> None:
        time.sleep(4.0)                                      # while the nodes start, too
        while launcher.poll() is None and len(killed) < 5:
            nodes = [p for p in children(launcher.pid) if alive(p)]
            if nodes:
                victim = rng.choice(sorted(nodes))
                try:
                    name = Path(f'/proc/{victim}/cmdline').read_bytes().split(b'\0')[1].decode()
                    os.kill(victim, signal.SIGKILL)
                    killed.append(name)
                except (OSError, IndexError):
                    pass
            time.sleep(rng.uniform(2.0, 6.0))

    thread = threading.Thread(target=killer, daemon=True)
    thread.start()
    stdout, stderr = launcher.communicate(timeout=1500)
    thread.join(5)
    assert launcher.returncode == 0, stderr[-3000:]
    assert len(killed) >= 2, f'the run ended before the faults: {killed}'
    # A kill that lands on a worker already being restarted (its siblings going down, its new nodes coming up)
    # is absorbed by that restart: under load 5 kills gave 3 restarts. Every restart answers a kill.
    assert 1 <= stderr.count('restarting worker') <= len(killed), stderr[-3000:]
    assert metrics(out) == uninterrupted
    summary = json.loads(out.with_suffix('.summary.json').read_text())
    assert summary['this_run']['restarts'] >= 1


@pytest.mark.slow   # fault injection on whole evaluations; fast: test_eval (resume, Ctrl-C), test_integrity (resend), test_sim_node (restart)
def test_a_killed_launcher_leaves_no_node_and_the_same_command_resumes(checkpoint, uninterrupted, tmp_path):
    out = tmp_path / 'r.jsonl'
    launcher = subprocess.Popen(command(checkpoint, out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 600
    while not (out.exists() and results(out)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert out.exists(), 'no episode finished'
    nodes = children(launcher.pid)
    assert nodes
    launcher.kill()
    launcher.wait()
    deadline = time.monotonic() + 20
    while any(alive(p) for p in nodes) and time.monotonic() < deadline:
        time.sleep(0.2)
    left = {p: cmdline(p) for p in nodes if alive(p)}
    assert not left, f'nodes outlived their launcher by 20 s: {left}'
    first = len(results(out))
    assert first < TASKS
    proc = subprocess.run(command(checkpoint, out), capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert metrics(out) == uninterrupted


@pytest.mark.slow   # fault injection on whole evaluations; fast: test_eval (resume, Ctrl-C), test_integrity (resend), test_sim_node (restart)
def test_a_results_file_cut_mid_line_is_reported_and_its_episode_replayed(checkpoint, uninterrupted, tmp_path):
    uninterrupted_lines = uninterrupted_run
    out = tmp_path / 'r.jsonl'
    lines = uninterrupted_lines.lines                     # 3 results of the base run, the third cut mid-line
    out.write_text('\n'.join(lines[:2]) + '\n' + lines[2][:40])
    proc = subprocess.run(command(checkpoint, out), capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert 'warning:' in proc.stderr, proc.stderr[-2000:]
    assert metrics(out) == uninterrupted


@pytest.mark.slow   # fault injection on whole evaluations; fast: test_eval (resume, Ctrl-C), test_integrity (resend), test_sim_node (restart)
def test_a_node_that_dies_at_every_start_is_given_up_on(tmp_path):
    from dialfred_bringup.workers import Supervisor
    from dialfred_bringup.graph import Graph, NodeDied, NodeProcess
    # a performer node with a bad parameter dies while it starts, every time
    nodes_of = {'/dying': [NodeProcess('dialfred_performer', {'record_format': 'gif'}, namespace='/dying')]}
    logged = []
    with Graph(nodes_of['/dying']) as graph:
        def make_worker(ns):
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline:
                graph.spin_until_any([], 0.2)                 # raises NodeDied once the node is dead
            raise AssertionError('the node did not die')

        supervisor = Supervisor(graph, nodes_of, make_worker, max_restarts=2, log=logged.append)
        t0 = time.monotonic()
        with pytest.raises(NodeDied, match='restarted 2 times in a row without finishing an episode; giving up') as err:
            supervisor.start(['/dying'])
    assert 'record_format must be one of' in str(err.value)          # the node's own last words
    assert len(logged) == 2 and supervisor.restarts == 2
    assert time.monotonic() - t0 < 120
