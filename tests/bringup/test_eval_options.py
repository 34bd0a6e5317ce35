"""`launch eval`'s options: a bad one exits 2 with one line before anything starts, a resumed run says
what it resumes, and a run leaves no lock file behind (no ROS needed for any of these)."""

from __future__ import annotations

import contextlib
import io
import os
from pathlib import Path

import pytest

import dialfred_bringup.launch
from dialfred_bringup.evaluation import EvalConfig, EvalRun, run_eval
from dialfred_sim.metrics import ResultsFileError, results_lock

REPO = Path(__file__).resolve().parents[2]


def launch_eval(*args: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = dialfred_bringup.launch.main(['eval', '--agent', 'random', '--no-progress', *args])
        except SystemExit as exc:       # argparse's own refusals
            code = exc.code
    return code, out.getvalue(), err.getvalue()


@pytest.mark.parametrize('args, says', [
    (('--limit', '-3'), '--limit must be at least 1'),
    (('--limit', '0'), '--limit must be at least 1'),
    (('--workers', '0'), '--workers must be at least 1'),
    (('--resolution', '0'), '--resolution must be 16 to 1024'),
    (('--local', '--resolution', '7'), '--resolution must be 16 to 1024'),
    (('--out', '/proc/x.jsonl'), 'no file can be made in /proc'),
    (('--out', 'README.md/x.jsonl'), 'README.md is a file, not a folder'),
    (('--out', 'docs'), 'is a folder'),
])
def test_a_bad_option_exits_2_with_one_line_and_writes_nothing(args, says, tmp_path, monkeypatch):
    monkeypatch.chdir(REPO)
    before = sorted(os.listdir(REPO))
    code, out, err = launch_eval(*args)
    assert code == 2, (out, err)
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and says in lines[0], err
    assert sorted(os.listdir(REPO)) == before
    assert not Path('/proc/x.jsonl.lock').exists()


def test_a_limit_of_0_leaves_an_existing_summary_alone(tmp_path):
    out = tmp_path / 'run.jsonl'
    summary = out.with_suffix('.summary.json')
    summary.write_text('{"kept": true}\n')
    code, _, err = launch_eval('--limit', '0', '--out', str(out))
    assert code == 2 and summary.read_text() == '{"kept": true}\n'


def test_a_run_leaves_no_lock_file_and_a_resumed_run_says_how_many_tasks_are_done(tmp_path):
    from dialfred_sim.metrics import EpisodeResult, append_result
    out = tmp_path / 'run.jsonl'
    config = EvalConfig(split='valid_unseen', agent='random', limit=2, workers=1, local=True, out=out)
    for k in range(2):       # a run cut off after both its episodes were written
        append_result(out, EpisodeResult(f'valid_unseen/{k:06d}', 'Move', 'valid_unseen', False, 0, 1, 3, 5,
                                         agent='random', goal_rule='dialfred'))
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        report = run_eval(config, progress=False)
    assert report.ran == 0 and 'resuming: 2 of 2 tasks are already in' in err.getvalue()
    assert report.run.summary_path.exists() and not Path(str(out) + '.lock').exists()


def test_the_lock_still_keeps_a_second_run_out_and_goes_with_the_first(tmp_path):
    path = tmp_path / 'r.jsonl'
    with results_lock(path):
        assert Path(str(path) + '.lock').exists()
        with pytest.raises(ResultsFileError, match='being written by another run'):
            with results_lock(path):
                pass
    assert not Path(str(path) + '.lock').exists()
    with results_lock(path):        # free again
        pass


def test_launch_nodes_starts_the_camera_the_shipped_performer_was_trained_at():
    from dialfred_bringup.launch import NodesConfig, nodes_resolution
    from dialfred_performer.model import SHIPPED_CHECKPOINT
    from dialfred_performer.model_registry import camera_resolution
    assert NodesConfig().resolution is None
    assert nodes_resolution(None) == camera_resolution('et', SHIPPED_CHECKPOINT) == 64
    assert nodes_resolution(128) == 128


def test_max_questions_ends_an_episode_whose_questioner_asks_more_in_a_row(tmp_path):
    """The option reaches the episode loop of the local path (the graph's reaches the performer node's
    max_questions parameter, in worker_nodes)."""
    from dialfred_bringup.local import play_state
    from dialfred_bringup.workers import worker_nodes
    from dialfred_sim.env import DialfredEnv
    from dialfred_sim.tasks import load_split
    run = EvalRun(EvalConfig(split='valid_unseen', agent='random', questioner='all', max_questions=2, performer='',
                             out=tmp_path / 'capped.jsonl'))
    env = DialfredEnv(resolution=run.options.resolution)
    try:
        state = play_state(run, env, run.make_agent(), None, 0, load_split('valid_unseen')[0])
    finally:
        env.close()
    assert state.end_reason == 'error' and 'asked more than 2 questions without acting' in state.error
    node = EvalRun(EvalConfig(split='valid_unseen', performer='et', questioner='all', max_questions=7))
    performer = next(n for n in worker_nodes(node, '/w0') if n.package == 'dialfred_performer')
    assert performer.parameters['max_questions'] == 7
    code, _, err = launch_eval('--max-questions', '0', '--out', str(tmp_path / 'x.jsonl'))
    assert code == 2 and '--max-questions must be 1 to 1000' in err


def test_ctrl_c_before_the_first_episode_says_nothing_was_written(tmp_path, monkeypatch):
    import dialfred_bringup.evaluation as evaluation

    def interrupted(config, progress=True):
        raise KeyboardInterrupt
    monkeypatch.setattr(evaluation, 'run_eval', interrupted)
    out = tmp_path / 'never.jsonl'
    err = io.StringIO()
    with contextlib.redirect_stderr(err), pytest.raises(KeyboardInterrupt):
        evaluation.run_eval_command(
            dialfred_bringup.launch.make_parser().parse_args(['eval', '--agent', 'random', '--out', str(out)]))
    assert 'before the first episode ended: nothing was written' in err.getvalue() and not out.exists()


@pytest.mark.slow   # three launcher subprocesses; fast: the oracle node's human mode (test_oracle_node)
def test_eval_with_human_puts_the_questions_to_a_person_on_standard_input(tmp_path):
    """`launch eval --human`: the oracle node asks a person in the terminal; what they type is the answer the
    agent hears and the results record (oracle 'human'). Not --local, and one worker."""
    import json
    import subprocess
    import sys
    out = tmp_path / 'human.jsonl'
    base = [sys.executable, '-m', 'dialfred_bringup.launch', 'eval', '--split', 'valid_unseen', '--agent', 'random',
            '--questioner', 'all', '--limit', '1', '--resolution', '64', '--out', str(out)]
    refused = subprocess.run(base + ['--human', '--local'], capture_output=True, text=True, timeout=120)
    assert refused.returncode == 2 and '--human answers through the graph' in refused.stderr
    refused = subprocess.run(base + ['--human', '--workers', '2'], capture_output=True, text=True, timeout=120)
    assert refused.returncode == 2 and 'one worker' in refused.stderr
    typed = ''.join(f'answer number {k}\n' for k in range(10))
    done = subprocess.run(base + ['--human', '--workers', '1'], input=typed, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    (result,) = [json.loads(line) for line in out.read_text().splitlines()]
    assert result['oracle'] == 'human' and result['questions'] >= 3
    assert [qa['answer'] for qa in result['dialogue']] == [f'answer number {k}' for k in range(result['questions'])]
    assert 'the simulator would say' in done.stdout
