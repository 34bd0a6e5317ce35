"""The front door: `./dialfred CMD --help` needs no set-up and never mixes set-up lines into the help; the
help files a checkout without set-up prints are the commands' own help; `./dialfred run --help` is a usage."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from helpers import interrupt_after

REPO = Path(__file__).resolve().parents[2]


def dialfred(*args, root: Path = REPO, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([str(root / 'dialfred'), *args], capture_output=True, text=True, timeout=120,
                          stdin=subprocess.DEVNULL, env={**os.environ, 'COLUMNS': '100'}, **kw)


def test_the_help_files_are_the_commands_own_help():
    done = subprocess.run([str(REPO / '.venv' / 'bin' / 'python'), str(REPO / 'scripts' / 'cli_help.py'), '--check'],
                          capture_output=True, text=True, timeout=300, env={**os.environ})
    assert done.returncode == 0, done.stderr


@pytest.mark.parametrize('args, key', [(('demo', '--help'), 'demo'), (('launch', 'eval', '-h'), 'launch-eval'),
                                       (('score', '--help'), 'score')])
def test_help_on_a_checkout_without_set_up_prints_at_once_and_sets_nothing_up(tmp_path, args, key):
    shutil.copy2(REPO / 'dialfred', tmp_path / 'dialfred')
    shutil.copytree(REPO / 'docs' / 'cli', tmp_path / 'docs' / 'cli')
    done = dialfred(*args, root=tmp_path)
    assert done.returncode == 0 and done.stderr == ''
    assert done.stdout == (REPO / 'docs' / 'cli' / f'{key}.txt').read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ['dialfred', 'docs']     # no .venv, no build


def test_help_on_a_set_up_checkout_has_no_set_up_lines():
    done = dialfred('demo', '--help')
    assert done.returncode == 0 and '[dialfred]' not in done.stdout + done.stderr
    assert done.stdout == (REPO / 'docs' / 'cli' / 'demo.txt').read_text()


def test_run_help_is_a_usage_and_a_missing_executable_an_error_of_status_2():
    done = dialfred('run', '--help')
    assert done.returncode == 0 and done.stdout.startswith('usage: ./dialfred run PACKAGE EXECUTABLE')
    assert 'error' not in done.stdout + done.stderr
    done = dialfred('run', 'dialfred_oracle')
    assert done.returncode == 2 and done.stderr.startswith('usage: ./dialfred run')


def launch(*args) -> subprocess.CompletedProcess:
    return subprocess.run([str(REPO / '.venv' / 'bin' / 'python'), '-m', 'dialfred_bringup.launch', *args],
                          capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL, cwd=REPO)


@pytest.mark.parametrize('args, says', [
    (('eval', '--questoner', 'all'), './dialfred launch eval: error: unrecognized arguments: --questoner all '
                                     '(did you mean --questioner?)'),
    (('evl',), "./dialfred launch: error: argument command: invalid choice: 'evl'"),
    (('eval', '--split', 'valid_unsen'), "'valid_unsen' is not one of train, valid_seen, valid_unseen "
                                          '(did you mean valid_unseen?)'),
    (('demo', '--max-stpes', '5'), './dialfred launch demo: error: unrecognized arguments: --max-stpes 5 (did you mean '
                                  '--max-steps?)'),
])
def test_a_misspelled_option_or_value_is_one_line_at_its_subcommand_with_a_suggestion_and_status_2(args, says):
    done = launch(*args)
    assert done.returncode == 2 and done.stdout == ''
    assert len(done.stderr.splitlines()) == 1 and says in done.stderr, done.stderr
    if args[0] == 'evl':
        assert '(did you mean eval?)' in done.stderr


def test_an_unknown_questioner_is_refused_with_the_nearest_name():
    done = launch('eval', '--questioner', 'rl-anytme', '--local', '--limit', '1')
    assert done.returncode == 2 and "unknown questioner 'rl-anytme' (did you mean rl-anytime?)" in done.stderr


@pytest.mark.slow   # two launcher processes; fast: the exit statuses of misspelled options above
def test_a_results_file_of_another_seed_is_a_usage_error_of_status_2(tmp_path):
    out = tmp_path / 'r.jsonl'
    common = ('eval', '--agent', 'random', '--limit', '1', '--local', '--workers', '1', '--resolution', '64',
              '--no-progress', '--out', str(out))
    assert launch(*common).returncode == 0
    done = launch(*common, '--seed', '7')
    assert done.returncode == 2 and done.stderr.startswith('error: '), done.stderr


@pytest.mark.slow   # a graph run of performer nodes interrupted mid-episode
def test_ctrl_c_through_performer_nodes_ends_with_a_clean_message(tmp_path):
    out = tmp_path / 'r.jsonl'
    code, text = interrupt_after([str(REPO / '.venv' / 'bin' / 'python'), '-m', 'dialfred_bringup.launch', 'eval',
                                  '--performer', 'map', '--questioner', 'all', '--limit', '40', '--workers', '1',
                                  '--out', str(out), '--no-progress'], out, lines=1, within_s=240, settle_s=1.0,
                                 cwd=REPO, stdin=subprocess.DEVNULL)   # Ctrl-C inside the next episode
    assert code == 130, text
    assert 'exited with code' not in text and 'did not end' not in text, text
    assert 'the same command resumes' in text


def test_local_with_performer_is_local_with_that_agent_and_a_run_that_plays_nothing_keeps_the_summary(tmp_path):
    import json

    from dialfred_bringup.eval_run import EvalRun
    from dialfred_bringup.evaluation import EvalConfig, run_eval
    a = EvalRun(EvalConfig(split='valid_unseen', local=True, performer='map', limit=2))
    b = EvalRun(EvalConfig(split='valid_unseen', local=True, agent='map', limit=2))
    assert (a.options.agent, a.options.performer, a.results_path) == ('map', '', b.results_path)
    out = tmp_path / 'r.jsonl'
    report = run_eval(EvalConfig(split='valid_unseen', local=True, agent='random', limit=2, resolution=64, out=out),
                      progress=False)
    summary = json.loads(report.run.summary_path.read_text())
    assert summary['through'] == 'local processes (no ROS)'
    summary['through'] = 'performer node'           # as if the graph had played them
    report.run.summary_path.write_text(json.dumps(summary))
    again = run_eval(EvalConfig(split='valid_unseen', local=True, agent='random', limit=2, resolution=64, out=out),
                     progress=False)
    assert again.ran == 0 and json.loads(again.run.summary_path.read_text())['through'] == 'performer node'
    # every line says how it was played; a file played two ways says both, whatever its summary claims
    lines = out.read_text().splitlines()
    assert all(json.loads(line)['played'] == 'local processes (no ROS)' for line in lines)
    out.write_text(lines[0] + '\n' + lines[1].replace('local processes (no ROS)', 'performer node') + '\n')
    third = run_eval(EvalConfig(split='valid_unseen', local=True, agent='random', limit=3, resolution=64, out=out),
                     progress=False)
    assert third.ran == 1 and third.to_json()['through'] == 'local processes (no ROS): 2, performer node: 1'
    from dialfred_bringup.report import run_settings
    settings = dict(run_settings(third.results, {'through': 'performer node'})[0])
    assert settings['played'] == 'local processes (no ROS): 2, performer node: 1'


def test_a_users_module_beside_the_project_leaves_runs_clean_and_names_hold_no_colon():
    from dialfred_bringup.eval_run import EvalRun
    from dialfred_bringup.evaluation import EvalConfig
    from dialfred_sim.metrics import changes_code
    assert not changes_code(['?? my_questioner.py', '?? mine/agents.py', ''])
    assert changes_code(['?? src/dialfred_sim/dialfred_sim/new_rule.py'])
    assert changes_code([' M src/dialfred_sim/dialfred_sim/env.py']) and changes_code(['M  README.md'])
    run = EvalRun(EvalConfig(split='valid_unseen', local=True, agent='examples.direction_follower:DirectionFollower',
                             questioner='examples.direction_follower:AskForDirections', limit=1))
    assert run.results_path.name == ('valid_unseen_examples.direction_follower.DirectionFollower+'
                                     'examples.direction_follower.AskForDirections.jsonl')
    assert ':' in run.agent_name          # the results lines still name the classes as given
