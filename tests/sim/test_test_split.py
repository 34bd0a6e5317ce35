"""A sealed test split: `python -m dialfred_sim.tasks.splits test_unseen --seed S --size N --out PATH`,
evaluated with `launch eval --tasks PATH`.

Claims: a test split plays only in ALFRED's held-out test rooms, which no shipped split uses; it comes
from the generator of the other splits, and the expert solves every task of it, in one process and
through real simulator nodes (SR 100%); the same seed gives the same bytes with any number of
workers and at any path, another seed other tasks; bad input is refused with a clear error and
writes nothing; results on a tasks file record that file (path and sha256) and are never mixed
with results of another file or of a shipped split.
"""

from __future__ import annotations

import gzip
import json
import subprocess
import sys
from pathlib import Path

import pytest

from dialfred_sim.env import DialfredEnv
from dialfred_sim.tasks import get_task, load_split, split_scenes
from dialfred_sim.tasks.splits import (TEST_SPLIT, TEST_UNSEEN_SCENES, read_tasks_file, resolve_task,
                                       write_split)

import dialfred_bringup.launch
from dialfred_bringup.evaluation import EvalConfig, ResultsFileError, run_eval
from dialfred_bringup.graph import Graph, NodeDied, NodeProcess

REPO = Path(__file__).resolve().parents[2]
SIZE = 16          # tasks: about four episodes


def make_split(*args: str) -> subprocess.CompletedProcess:
    """The command line a user types, in a process of its own."""
    return subprocess.run([sys.executable, '-m', 'dialfred_sim.tasks.splits', *args],
                          capture_output=True, text=True, timeout=300)


@pytest.fixture(scope='module')
def test_split(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp('test_split') / 'test_s7.jsonl.gz'
    report = write_split(TEST_SPLIT, path, SIZE, split_seed=7, progress=False)
    assert report['tasks'] == SIZE and report['path'] == str(path)
    return path


# ---------------------------------------------------------------------------------------------- the split (no ROS)

def test_a_test_split_plays_only_in_the_held_out_test_rooms(test_split):
    tasks = read_tasks_file(test_split).tasks
    rooms = {t.scene for t in tasks}
    assert rooms <= {f'FloorPlan{n}' for n in TEST_UNSEEN_SCENES} and len(rooms) >= 3
    shipped = set(split_scenes('train')) | {t.scene for s in ('valid_seen', 'valid_unseen') for t in load_split(s)}
    assert not set(split_scenes(TEST_SPLIT)) & shipped
    assert [t.task_id for t in tasks] == [f'{TEST_SPLIT}/{k:06d}' for k in range(SIZE)]
    assert {t.split for t in tasks} == {TEST_SPLIT}


def test_the_expert_solves_every_task_of_a_test_split(test_split):
    env = DialfredEnv()
    try:
        for task in read_tasks_file(test_split).tasks:
            obs, info = env.reset(options={'task': task})
            assert not info['success'], f'{task.task_id}: its goal holds before the expert acts'
            for a in task.expert_actions:
                obs, reward, terminated, truncated, info = env.step({'action': a.action, 'pixel': (a.x, a.y)})
                if terminated or truncated:
                    break
            assert info['success'], f'{task.task_id} ({task.task_type}): the expert did not reach the goal'
    finally:
        env.close()


def test_the_same_seed_gives_the_same_bytes_with_two_workers_and_another_seed_other_tasks(test_split, tmp_path):
    again = tmp_path / 'elsewhere' / 'same_seed.jsonl.gz'
    done = make_split(TEST_SPLIT, '--seed', '7', '--size', str(SIZE), '--out', str(again), '--workers', '2')
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert again.read_bytes() == test_split.read_bytes()          # another path, two processes: same bytes
    assert report['sha256'] == read_tasks_file(test_split).sha256 and report['workers'] == 2
    other = tmp_path / 'seed8.jsonl.gz'
    write_split(TEST_SPLIT, other, SIZE, split_seed=8, progress=False)
    first = [(t.scene, t.episode.seed, t.instruction) for t in read_tasks_file(test_split).tasks]
    second = [(t.scene, t.episode.seed, t.instruction) for t in read_tasks_file(other).tasks]
    assert not {seed for _, seed, _ in first} & {seed for _, seed, _ in second}
    assert first != second


@pytest.mark.parametrize('args, message', [
    (['--size', '4'], 'needs a seed of your own'),
    (['--seed', '-1'], 'an integer >= 0'),
    (['--seed', '1', '--size', '0'], '--size must be a number of tasks >= 1'),
    (['--seed', '1', '--workers', '0'], '--workers must be >= 1'),
    (['--seed', '1', '--out', 'OUT.json'], 'must name a .jsonl.gz file'),
    (['--seed', '1', '--out', 'EXISTING'], 'exists; pass --force'),
    (['--seed', '1', '--out', ''], 'needs --out PATH'),
])
def test_bad_arguments_are_refused_and_nothing_is_written(tmp_path, args, message):
    existing = tmp_path / 'existing.jsonl.gz'
    existing.write_bytes(b'a split of an earlier day')
    out = str(tmp_path / 'new.jsonl.gz')
    args = [{'OUT.json': str(tmp_path / 'new.json'), 'EXISTING': str(existing)}.get(a, a) for a in args]
    if '--out' not in args:
        args += ['--out', out]
    done = make_split(TEST_SPLIT, *args)
    assert done.returncode == 2 and message in done.stderr, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ['existing.jsonl.gz']
    assert existing.read_bytes() == b'a split of an earlier day'


def test_a_shipped_split_takes_no_seed_of_your_own(tmp_path):
    done = make_split('valid_unseen', '--seed', '3', '--out', str(tmp_path / 'v.jsonl.gz'))
    assert done.returncode == 2 and 'defined by its fixed seeds' in done.stderr
    assert not list(tmp_path.iterdir())


def test_a_part_of_a_shipped_split_is_never_written_over_the_shipped_file():
    from dialfred_sim.tasks.splits import split_path
    before = split_path('train').read_bytes()
    done = make_split('train', '--size', '3')
    assert done.returncode == 2 and '--size 3 of train needs --out' in done.stderr
    assert split_path('train').read_bytes() == before


def test_force_replaces_an_existing_file_with_the_new_split(test_split, tmp_path):
    out = tmp_path / 'replaced.jsonl.gz'
    out.write_bytes(b'old')
    done = make_split(TEST_SPLIT, '--seed', '7', '--size', str(SIZE), '--out', str(out), '--force', '--no-progress')
    assert done.returncode == 0, done.stderr
    assert out.read_bytes() == test_split.read_bytes()
    assert [p.name for p in tmp_path.iterdir()] == ['replaced.jsonl.gz']      # no temporary file left


def test_test_split_ids_are_known_only_with_their_file(test_split, tmp_path):
    with pytest.raises(ValueError, match='lives in the file you made'):
        get_task(f'{TEST_SPLIT}/000000')
    tasks_file = read_tasks_file(test_split)
    assert resolve_task(f'{TEST_SPLIT}/000003', tasks_file) is tasks_file.tasks[3]
    assert resolve_task('valid_unseen/000003', tasks_file).task_id == 'valid_unseen/000003'   # shipped ids still work
    with pytest.raises(ValueError, match=f'unknown task_id .{TEST_SPLIT}/000999. in .*{test_split.name}'):
        resolve_task(f'{TEST_SPLIT}/000999', tasks_file)


def test_a_file_that_is_not_a_split_is_a_clear_error(tmp_path, test_split):
    with pytest.raises(FileNotFoundError, match='does not exist'):
        read_tasks_file(tmp_path / 'missing.jsonl.gz')
    (tmp_path / 'plain.jsonl.gz').write_text('not gzip')
    with pytest.raises(ValueError, match='not a complete gzipped split file'):
        read_tasks_file(tmp_path / 'plain.jsonl.gz')
    (tmp_path / 'cut.jsonl.gz').write_bytes(test_split.read_bytes()[:-20])
    with pytest.raises(ValueError, match='not a complete gzipped split file'):
        read_tasks_file(tmp_path / 'cut.jsonl.gz')
    rows = gzip.decompress(test_split.read_bytes()).splitlines(keepends=True)
    mixed = rows[0] + rows[1].replace(TEST_SPLIT.encode(), b'valid_unseen')
    (tmp_path / 'mixed.jsonl.gz').write_bytes(gzip.compress(mixed))
    with pytest.raises(ValueError, match='mixes the splits'):
        read_tasks_file(tmp_path / 'mixed.jsonl.gz')


# ---------------------------------------------------------------------------------------------- through the nodes

@pytest.fixture(scope='module')
def expert_on_test_split(test_split, tmp_path_factory):
    out = tmp_path_factory.mktemp('test_eval') / 'expert.jsonl'
    code = dialfred_bringup.launch.main(['eval', '--tasks', str(test_split), '--agent', 'expert', '--workers', '2',
                                 '--out', str(out), '--no-progress'])
    assert code == 0
    return out


def test_the_expert_succeeds_on_every_task_of_a_test_split_through_launch_eval(expert_on_test_split, test_split):
    summary = json.loads(expert_on_test_split.with_suffix('.summary.json').read_text())
    assert summary['summary']['overall']['SR'] == 100.0 and summary['tasks'] == SIZE
    assert summary['split'] == TEST_SPLIT and summary['failures'] == []
    source = read_tasks_file(test_split)
    assert summary['tasks_file'] == source.describe()
    record = json.loads(expert_on_test_split.with_suffix('.tasks.json').read_text())
    assert record == {'path': str(test_split), 'sha256': source.sha256, 'split': TEST_SPLIT, 'tasks': SIZE}
    lines = [json.loads(line) for line in expert_on_test_split.read_text().splitlines()]
    assert sorted(r['task_id'] for r in lines) == [t.task_id for t in source.tasks]
    assert all(r['success'] and r['split'] == TEST_SPLIT for r in lines)


def test_results_of_one_tasks_file_are_never_mixed_with_another(expert_on_test_split, test_split, tmp_path):
    other = tmp_path / 'seed9.jsonl.gz'
    write_split(TEST_SPLIT, other, 4, split_seed=9, progress=False)
    before = expert_on_test_split.read_bytes()
    with pytest.raises(ResultsFileError, match=r'holds results of tasks file .*test_s7.*, not of tasks file .*seed9'):
        run_eval(EvalConfig(tasks_file=other, agent='expert', out=expert_on_test_split), progress=False)
    assert expert_on_test_split.read_bytes() == before
    # The same tasks, copied elsewhere, are the same file: the run resumes and plays nothing.
    copy = tmp_path / 'copy.jsonl.gz'
    copy.write_bytes(test_split.read_bytes())
    report = run_eval(EvalConfig(tasks_file=copy, agent='expert', out=expert_on_test_split), progress=False)
    assert report.ran == 0 and len(report.results) == SIZE


def test_results_of_a_shipped_split_are_not_resumed_with_a_tasks_file(tmp_path, test_split):
    out = tmp_path / 'shipped.jsonl'
    run_eval(EvalConfig(split='valid_unseen', agent='expert', limit=1, workers=1, out=out), progress=False)
    with pytest.raises(ResultsFileError, match="split 'valid_unseen'.*not 'test_unseen'"):
        run_eval(EvalConfig(tasks_file=test_split, agent='expert', out=out), progress=False)


def test_the_eval_command_takes_a_split_or_a_tasks_file_not_both(test_split, capsys):
    with pytest.raises(SystemExit) as exit_info:
        dialfred_bringup.launch.main(['eval', '--split', 'valid_unseen', '--tasks', str(test_split)])
    assert exit_info.value.code == 2 and 'not allowed with argument' in capsys.readouterr().err
    assert dialfred_bringup.launch.main(['eval', '--tasks', str(test_split.with_name('missing.jsonl.gz'))]) == 2
    assert 'does not exist' in capsys.readouterr().err


def test_a_sim_node_given_a_missing_tasks_file_stops_and_says_why(tmp_path):
    node = NodeProcess('dialfred_sim', {'resolution': 16, 'tasks_file': str(tmp_path / 'missing.jsonl.gz')},
                       namespace='/no_tasks')
    with pytest.raises(NodeDied, match=r'(?s)exit code 1.*missing.jsonl.gz does not exist'):
        with Graph([node]) as graph:
            from dialfred_msgs.srv import SimReset
            graph.client(SimReset, '/no_tasks/sim/reset', timeout=30.0)
