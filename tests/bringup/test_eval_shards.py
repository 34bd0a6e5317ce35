"""An evaluation in shards through real simulator nodes, merged into one run's results.

Claims: the shards of a run, played by the in-process evaluation one after the other, merge into the
very episodes and the summary of the unsharded run (the random agent: every episode depends on its
seed, so a shard that seeded by its own task count would differ); and so do two launcher processes
started side by side in one ROS domain, with static peers set as on hosts, each with its own nodes in
its own namespace (/eval_<host>_<pid> where discovery reaches other hosts): the multi-host recipe of
docs/scaling.md, as far as one machine goes.
(tests/bringup/test_shards.py checks the selection and the merge's refusals without ROS.)
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dialfred_sim.metrics import load_results
from dialfred_bringup.shards import main as merge

from dialfred_bringup.evaluation import EvalConfig, run_eval

REPO = Path(__file__).resolve().parents[2]
SPLIT, LIMIT, RESOLUTION = 'valid_unseen', 6, 64
# Starting simulator nodes is most of these tests' time; on a loaded machine it takes minutes.
pytestmark = pytest.mark.timeout(1800)


def run(out: Path, shard=None, workers: int = 1):
    return run_eval(EvalConfig(split=SPLIT, agent='random', limit=LIMIT, workers=workers, resolution=RESOLUTION,
                               out=out, shard=shard), progress=False)


def without_wall_time(results):
    return [dataclasses.replace(r, wall_s=0.0) for r in results]


@pytest.fixture(scope='module')
def whole_run(tmp_path_factory):
    return run(tmp_path_factory.mktemp('whole') / 'run.jsonl')


def check_merge_is_the_whole_run(folder: Path, whole_run) -> None:
    shards = sorted(folder.glob('run_shard*of2.jsonl'))
    assert len(shards) == 2
    assert merge([str(p) for p in shards]) == 0
    merged = folder / 'run.jsonl'
    assert without_wall_time(load_results(merged)) == without_wall_time(whole_run.results)   # split order
    summary = json.loads(merged.with_suffix('.summary.json').read_text())
    single = json.loads(whole_run.run.summary_path.read_text())
    assert summary['summary'] == single['summary'] == whole_run.summary
    assert summary['failures'] == single['failures'] and summary['missing'] == []


def test_shards_played_one_after_the_other_merge_into_the_whole_run(whole_run, tmp_path):
    reports = [run(tmp_path / f'run_shard{k}of2.jsonl', shard=(k, 2)) for k in range(2)]
    assert [[r.task_id[-1] for r in rep.results] for rep in reports] == [['0', '2', '4'], ['1', '3', '5']]
    assert len({r.steps for r in whole_run.results}) > 1       # the random agent: the seeds matter
    check_merge_is_the_whole_run(tmp_path, whole_run)
    assert run(tmp_path / 'run_shard1of2.jsonl', shard=(1, 2)).ran == 0       # a shard resumes its own file


def test_a_run_namespace_names_the_host_where_discovery_reaches_other_hosts(monkeypatch):
    from rclpy.validate_namespace import validate_namespace

    from dialfred_bringup.evaluation import run_namespace
    from dialfred_bringup.graph import host_token
    monkeypatch.setattr('socket.gethostname', lambda: 'gpu-07.lab.example')
    assert host_token() == 'gpu_07_lab_example'
    monkeypatch.delenv('DIALFRED_NETWORK', raising=False)       # as in a process the caller starts afresh
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    monkeypatch.delenv('ROS_STATIC_PEERS', raising=False)
    assert run_namespace() == f'/eval_{os.getpid()}'          # pids are unique on this host
    for env in ({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET'}, {'ROS_STATIC_PEERS': '10.0.0.2;10.0.0.3'}):
        with monkeypatch.context() as m:
            for k, v in env.items():
                m.setenv(k, v)
            assert run_namespace() == f'/eval_gpu_07_lab_example_{os.getpid()}'
            validate_namespace(run_namespace())              # raises for a name ROS refuses
    monkeypatch.setattr('socket.gethostname', lambda: '--')
    assert host_token() == 'host'


@pytest.mark.slow
def test_two_launchers_in_one_ros_domain_play_the_shards_side_by_side(whole_run, tmp_path):
    # one domain (conftest's) and static peers, as on hosts; discovery stays on this host (LOCALHOST)
    env = {**os.environ, 'ROS_DOMAIN_ID': os.environ['ROS_DOMAIN_ID'], 'ROS_STATIC_PEERS': '127.0.0.1'}
    procs = [subprocess.Popen([sys.executable, '-m', 'dialfred_bringup.launch', 'eval', '--split', SPLIT,
                               '--agent', 'random', '--limit', str(LIMIT), '--workers', '1',
                               '--resolution', str(RESOLUTION), '--shard', f'{k}/2',
                               '--out', str(tmp_path / f'run_shard{k}of2.jsonl'), '--no-progress'],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
             for k in range(2)]
    try:
        deadline = time.monotonic() + 1500
        while any(p.poll() is None for p in procs) and time.monotonic() < deadline:
            time.sleep(0.5)
        outputs = [p.communicate(timeout=10)[0] if p.poll() is not None else '(still running)' for p in procs]
        assert [p.returncode for p in procs] == [0, 0], outputs
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
    for k, out in enumerate(outputs):
        assert f'{SPLIT}, shard {k}/2, random agent, seed 0: 3 tasks (3 played now' in out, out
    summaries = [json.loads((tmp_path / f'run_shard{k}of2.summary.json').read_text()) for k in range(2)]
    assert [s['shard'] for s in summaries] == [{'index': 0, 'count': 2}, {'index': 1, 'count': 2}]
    check_merge_is_the_whole_run(tmp_path, whole_run)
