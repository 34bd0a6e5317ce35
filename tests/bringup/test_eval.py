"""The evaluation: the expert and random agents (no ROS), then `dialfred_bringup/launch.py eval` through real
simulator nodes, two workers in their own namespaces driven from one client.

Claims: the expert succeeds on every task it is run on; a run is a pure function of split, agent and
seed; a results file resumes (a longer --limit, or a run interrupted by Ctrl-C) without redoing or
losing an episode; with a questioner, the agent's questions reach an oracle node of its own worker
and are counted; nodes never outlive a launcher that is killed.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from dialfred_sim.agents import ExpertAgent, RandomAgent, make_agent
from dialfred_sim.protocol import ACTIONS, episode_seed, scale_pixel
from dialfred_sim.metrics import EpisodeResult, append_result, load_results
from dialfred_sim.tasks import ExpertAction

from dialfred_bringup.evaluation import EvalConfig, EvalRun, print_report, run_eval
from dialfred_bringup.graph import Graph, NodeProcess, sim_service
from helpers import interrupt_after

REPO = Path(__file__).resolve().parents[2]
SPLIT = 'valid_unseen'


def fake_task(actions, resolution=128):
    return SimpleNamespace(expert_actions=actions, resolution=resolution)


# ---------------------------------------------------------------------------------------------- agents (no ROS)

def test_the_expert_replays_its_demonstration_then_stops():
    actions = [ExpertAction('MoveAhead'), ExpertAction('Pickup', 40, 90, 'Apple_1'), ExpertAction('RotateLeft')]
    agent = ExpertAgent(resolution=128)
    agent.reset(fake_task(actions), seed=0)
    assert [agent.act(None) for _ in range(5)] == [('MoveAhead', -1, -1), ('Pickup', 40, 90), ('RotateLeft', -1, -1),
                                                   ('Stop', -1, -1), ('Stop', -1, -1)]
    agent.reset(fake_task(actions[:1]), seed=0)      # a new episode starts from its first action again
    assert agent.act(None) == ('MoveAhead', -1, -1)


def test_the_expert_scales_its_pixels_to_the_simulators_frame():
    agent = ExpertAgent(resolution=300)
    agent.reset(fake_task([ExpertAction('Open', 0, 127, 'Fridge_1'), ExpertAction('Close', 64, 10, 'Fridge_1')]))
    assert agent.act(None) == ('Open', 1, 298)
    assert agent.act(None) == ('Close', 151, 24)
    assert scale_pixel(-1, -1, 128, 64) == (-1, -1)
    assert scale_pixel(127, 0, 128, 64) == (63, 0)
    assert scale_pixel(5, 6, 128, 128) == (5, 6)


def test_the_random_agent_draws_all_13_actions_and_pixels_in_the_frame():
    agent = RandomAgent(resolution=64)
    agent.reset(None, seed=episode_seed(0, 0))
    decisions = [agent.act(None) for _ in range(2000)]
    assert {a for a, _, _ in decisions} == set(ACTIONS) and len(ACTIONS) == 13
    assert all(0 <= x < 64 and 0 <= y < 64 for _, x, y in decisions)


def test_the_random_agent_repeats_itself_for_the_same_episode_seed():
    def play(seed):
        agent = make_agent('random')
        agent.reset(None, seed=seed)
        return [agent.act(None) for _ in range(50)]

    assert play(episode_seed(0, 7)) == play(episode_seed(0, 7))
    assert play(episode_seed(0, 7)) != play(episode_seed(0, 8))
    assert play(episode_seed(0, 7)) != play(episode_seed(1, 7))


def test_an_unknown_agent_is_named_in_the_error():
    with pytest.raises(ValueError, match="unknown agent 'oracle'"):
        make_agent('oracle')


# ---------------------------------------------------------------------------------------------- through the nodes

def evaluate(out: Path, agent: str = 'random', limit: int = 6, workers: int = 2, **kw):
    return run_eval(EvalConfig(split=SPLIT, agent=agent, limit=limit, workers=workers, out=out, **kw), progress=False)


def without_wall_time(results):
    return [dataclasses.replace(r, wall_s=0.0) for r in results]


def test_a_worker_node_gets_its_own_namespace():
    node = NodeProcess('dialfred_sim', {'resolution': 64}, namespace='/w1')
    assert node.command()[1:] == ['--ros-args', '-p', 'resolution:=64', '-r', '__ns:=/w1']
    assert node.label == 'dialfred_sim [/w1]'
    assert sim_service('/w1', 'step') == '/w1/sim/step' and sim_service('', 'reset') == '/sim/reset'


@pytest.fixture(scope='module')
def expert_run(tmp_path_factory):
    return evaluate(tmp_path_factory.mktemp('expert') / 'expert.jsonl', agent='expert', limit=8)


def test_the_expert_succeeds_on_the_first_valid_unseen_tasks(expert_run):
    results = expert_run.results
    assert len(results) == 8 and expert_run.ran == 8
    from dialfred_sim.tasks import load_split
    tasks = load_split(SPLIT)[:8]
    assert [r.task_id for r in results] == [t.task_id for t in tasks]
    failed = [(r.task_id, r.task_type, r.end_reason, r.error) for r in results if not r.success]
    assert failed == []
    for r, t in zip(results, tasks):
        assert r.end_reason == 'success' and r.task_type == t.task_type and r.agent == 'expert'
        # success ends the episode as soon as the goal holds: at the latest on the expert's last action
        assert 1 <= r.steps <= t.expert_length == r.expert_length
        assert r.goal_conditions_met == r.goal_conditions_total > 0
    overall = expert_run.summary['overall']
    assert (overall['n'], overall['SR'], overall['PWSR'], overall['GC'], overall['NQ']) == (8, 100.0, 100.0, 100.0, 0.0)


def test_the_run_writes_its_results_and_a_summary_next_to_them(expert_run):
    run = expert_run.run
    in_file = load_results(run.results_path)          # in the order the episodes ended
    assert sorted(in_file, key=lambda r: r.task_id) == expert_run.results
    assert run.summary_path == run.results_path.with_name('expert.summary.json')
    summary = json.loads(run.summary_path.read_text())
    assert summary['tasks'] == 8 and summary['failures'] == []
    assert summary['summary']['overall']['SR'] == 100.0
    assert list(summary['summary']['per_type']) == list(expert_run.summary['per_type'])
    # the code the episodes were played at: this checkout's commit (+dirty when edited)
    head = subprocess.run(['git', 'rev-parse', 'HEAD'], capture_output=True, text=True).stdout.strip()
    assert summary['this_run']['code'].split('+')[0] == head and len(head) == 40
    assert {r.code for r in in_file} == {summary['this_run']['code']}          # every row says it too
    assert summary['played_at'] == {summary['this_run']['code']: 8}


def test_a_resumed_file_of_another_commit_keeps_its_episodes_and_says_so(tmp_path, capfd):
    path = tmp_path / 'resume.jsonl'
    first = evaluate(path, limit=3, local=True, workers=1)   # the results file's rules: the same without ROS
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    old = [dict(row, code='0123456789abcdef' * 2 + '01234567') for row in lines[:2]] + [dict(lines[2], code='')]
    path.write_text(''.join(json.dumps(row) + '\n' for row in old))   # two from another commit, one from before rows said
    capfd.readouterr()
    second = evaluate(path, limit=5, local=True, workers=1)
    assert second.ran == 2
    err = capfd.readouterr().err
    assert 'holds 3 episodes played at other commits (0123456789ab: 2, unrecorded: 1)' in err, err
    summary = json.loads(second.run.summary_path.read_text())
    code = summary['this_run']['code']
    assert summary['played_at'] == {'0123456789abcdef' * 2 + '01234567': 2, code: 2, 'unrecorded': 1}
    from dialfred_sim.metrics import same_episode
    assert all(same_episode(a, b) for a, b in zip(first.results, second.results[:3]))
    assert [r.code for r in first.results] != [r.code for r in second.results[:3]]


@pytest.fixture(scope='module')
def random_run(tmp_path_factory):
    return evaluate(tmp_path_factory.mktemp('random') / 'a.jsonl')


def test_the_random_agent_gives_a_result_for_every_task(random_run):
    results = random_run.results
    assert len(results) == 6
    for r in results:
        assert r.agent == 'random' and r.seed == 0 and r.end_reason in ('success', 'stop', 'max_failures', 'max_steps')
        assert r.steps >= 1 and r.goal_conditions_total > 0
        assert r.end_reason != 'max_failures' or r.failed_actions >= 10


def test_the_same_split_and_seed_give_the_same_episodes(random_run, tmp_path):
    again = evaluate(tmp_path / 'b.jsonl', workers=1)       # another worker count, another order of play
    assert without_wall_time(again.results) == without_wall_time(random_run.results)
    other_seed = evaluate(tmp_path / 'c.jsonl', seed=1, local=True, workers=1)   # local plays the graph's episodes
    assert without_wall_time(other_seed.results) != without_wall_time(random_run.results)


@pytest.mark.slow   # fast: test_eval_local's resume test and the resume refusals below
def test_a_longer_limit_resumes_without_redoing_or_losing_episodes(random_run, tmp_path):
    path = tmp_path / 'resume.jsonl'
    first = evaluate(path, limit=3)
    lines = path.read_text().splitlines()
    assert first.ran == 3 and len(lines) == 3
    second = evaluate(path, limit=6)
    assert second.ran == 3
    now = path.read_text().splitlines()
    assert now[:3] == lines and len(now) == 6
    assert without_wall_time(second.results) == without_wall_time(random_run.results)
    assert evaluate(path, limit=6).ran == 0                   # nothing left to do


@pytest.mark.slow   # a launcher process interrupted mid-run; resuming has fast tests of its own (test_eval_options.py)
def test_a_run_interrupted_by_ctrl_c_resumes_where_it_stopped(tmp_path):
    path = tmp_path / 'interrupted.jsonl'
    cmd = [sys.executable, '-m', 'dialfred_bringup.launch', 'eval', '--split', SPLIT, '--agent', 'expert',
           '--limit', '40', '--out', str(path), '--no-progress']
    code, out = interrupt_after(cmd, path, lines=2, within_s=30)
    assert code == 130, out
    assert 'the same command resumes' in out
    before = path.read_text().splitlines()
    assert 2 <= len(before) < 40
    report = evaluate(path, agent='expert', limit=40)
    after = path.read_text().splitlines()
    assert after[:len(before)] == before
    assert report.ran == 40 - len(before) and len(after) == 40
    ids = [EpisodeResult.from_json(line).task_id for line in after]
    assert sorted(ids) == sorted(r.task_id for r in report.results) and len(set(ids)) == 40


def test_a_task_the_node_cannot_load_is_recorded_as_an_error_and_the_run_goes_on(tmp_path, monkeypatch):
    import dialfred_sim.tasks
    good = dialfred_sim.tasks.load_split(SPLIT)[:2]
    unknown = dataclasses.replace(good[0], task_id='valid_unseen/999999')
    monkeypatch.setattr(dialfred_sim.tasks, 'load_split', lambda split: [unknown, good[1]])
    report = evaluate(tmp_path / 'errors.jsonl', agent='expert', workers=1)
    error, ok = report.results
    assert (error.task_id, error.end_reason, error.success, error.steps) == (unknown.task_id, 'error', False, 0)
    assert 'unknown task_id' in error.error
    assert ok.success and report.summary['end_reasons'] == {'success': 1, 'error': 1}
    with contextlib.redirect_stdout(io.StringIO()) as printed:     # the expert's failures are listed
        print_report(report)
    out = printed.getvalue()
    assert 'expert failures: 1' in out
    line = next(line for line in out.splitlines() if unknown.task_id in line)
    assert unknown.task_type in line and ' error ' in line and 'unknown task_id' in line


def test_a_results_file_of_another_agent_is_not_mixed_in(tmp_path, random_run):
    path = tmp_path / 'mixed.jsonl'
    append_result(path, dataclasses.replace(random_run.results[0], agent='expert'))
    with pytest.raises(ValueError, match="agent 'expert'.*choose another --out"):
        evaluate(path)


def test_the_eval_command_prints_the_table_and_the_experts_failures(expert_run, capsys):
    import dialfred_bringup.launch
    code = dialfred_bringup.launch.main(['eval', '--split', SPLIT, '--agent', 'expert', '--limit', '8',
                                 '--out', str(expert_run.run.results_path), '--no-progress'])
    out = capsys.readouterr().out
    assert code == 0
    assert '8 tasks (0 played now' in out                      # all resumed from the file
    assert out.splitlines()[1].split()[:3] == ['task', 'type', 'n']
    assert 'overall' in out and 'expert failures: 0' in out
    assert os.path.exists(expert_run.run.summary_path)


def test_a_graph_inside_another_shares_the_process_ros_context():
    import rclpy

    was_up = rclpy.ok()
    with Graph([]) as outer:
        assert outer.owns_context == (not was_up)
        with Graph([]) as inner:
            assert not inner.owns_context and inner.client_node is not outer.client_node
        assert rclpy.ok()                                    # the inner graph left the context up
    assert rclpy.ok() == was_up


def test_a_graph_that_fails_to_start_stops_the_nodes_it_started(monkeypatch):
    import dialfred_sim.ros_util

    def broken_executor():
        raise RuntimeError('no executor')

    monkeypatch.setattr(dialfred_sim.ros_util, 'make_executor', broken_executor)
    node = NodeProcess('dialfred_sim', {'resolution': 16}, namespace='/broken')
    with pytest.raises(RuntimeError, match='no executor'):
        with Graph([node]):
            pass
    assert node.proc is not None and node.proc.poll() is not None


# ---------------------------------------------------------------------------------------------- with a questioner

def test_an_eval_with_a_questioner_asks_each_workers_oracle_and_counts_the_questions(tmp_path):
    from dialfred_questioner.baselines import task_nouns
    from dialfred_sim.tasks import load_split
    report = evaluate(tmp_path / 'asking.jsonl', agent='expert', questioner='all', limit=6)
    tasks = load_split(SPLIT)[:6]
    asked = [2 * len(task_nouns(t)) + 1 for t in tasks]
    assert [(r.task_id, r.success, r.agent) for r in report.results] == [(t.task_id, True, 'expert+all') for t in tasks]
    # Every question reached an oracle that answered from its own simulator's state.
    assert [(r.questions, r.invalid_questions) for r in report.results] == [(n, 0) for n in asked]
    assert report.summary['overall']['NQ'] == pytest.approx(sum(asked) / 6)
    assert report.summary['overall']['NQ_invalid'] == 0.0


def test_the_default_results_file_names_the_questioner():
    run = EvalRun(EvalConfig(split=SPLIT, agent='random', questioner='random'))
    assert run.agent_name == 'random+random'
    assert run.results_path.name == 'valid_unseen_random+random.jsonl'
    assert EvalRun(EvalConfig(split=SPLIT, agent='random')).results_path.name == 'valid_unseen_random.jsonl'


def test_questioner_none_on_the_command_line_means_no_questions():
    from dialfred_bringup.evaluation import add_eval_parser, eval_config
    import argparse
    parser = argparse.ArgumentParser()
    add_eval_parser(parser.add_subparsers())
    for argv in (['eval'], ['eval', '--questioner', 'none']):
        config = eval_config(parser.parse_args(argv))
        assert config.questioner == '' and EvalRun(config).agent_name == 'expert'
    assert eval_config(parser.parse_args(['eval', '--questioner', 'all'])).questioner == 'all'


def test_an_agent_that_never_stops_asking_is_cut_off_with_an_error(tmp_path, monkeypatch):
    from dialfred_questioner import baselines
    from dialfred_sim.protocol import MAX_QUESTIONS, Question

    class Chatty(baselines.AllQuestioner):
        name = 'chatty'

        def ask(self, observation, step):
            return Question('direction')

    monkeypatch.setitem(baselines.QUESTIONERS, 'chatty', Chatty)
    report = evaluate(tmp_path / 'chatty.jsonl', agent='expert', questioner='chatty', limit=2, workers=1)
    for r in report.results:
        assert (r.end_reason, r.questions, r.steps) == ('error', MAX_QUESTIONS, 0)
        assert f'more than {MAX_QUESTIONS} questions without acting' in r.error


def test_an_unknown_questioner_fails_before_any_node_starts(tmp_path):
    with pytest.raises(ValueError, match="unknown questioner 'oracle'"):
        evaluate(tmp_path / 'x.jsonl', questioner='oracle')
    assert not (tmp_path / 'x.jsonl').exists()


def test_each_run_has_a_namespace_of_its_own():
    from dialfred_bringup.evaluation import run_namespace
    assert run_namespace() == f'/eval_{os.getpid()}'


# ---------------------------------------------------------------------------------------------- orphans

def _running(pid: int) -> bool:
    try:
        with open(f'/proc/{pid}/stat') as f:
            return f.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except FileNotFoundError:
        return False


def test_a_node_does_not_outlive_a_launcher_that_is_killed(tmp_path):
    script = tmp_path / 'start_and_wait.py'
    script.write_text(
        'import time\n'
        'from dialfred_bringup.graph import NodeProcess\n'
        "node = NodeProcess('dialfred_sim', {'resolution': 16}, namespace='/orphan_test')\n"
        'node.start()\n'
        'print(node.proc.pid, flush=True)\n'
        'time.sleep(600)\n')
    launcher = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        pid = int(launcher.stdout.readline())
        assert _running(pid)
        launcher.kill()                                   # SIGKILL: no cleanup code runs in the launcher
        launcher.wait(10)
        deadline = time.monotonic() + 30
        while _running(pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _running(pid), 'the node outlived its launcher'
    finally:
        launcher.kill()


def test_a_perturbed_oracle_withholds_one_type_and_the_results_say_so(tmp_path, monkeypatch):
    from dialfred_questioner import baselines
    heard = []
    real_hear = baselines.QuestioningAgent.hear
    monkeypatch.setattr(baselines.QuestioningAgent, 'hear', lambda self, qa: (heard.append(qa), real_hear(self, qa)))
    path = tmp_path / 'withheld.jsonl'
    report = evaluate(path, agent='expert', questioner='all', limit=3, perturb_type='location', perturb_probability=1.0)
    assert all(r.success and r.oracle == 'location:1' and r.invalid_questions == 0 for r in report.results)
    kinds = {q.question.question_type for q in heard}
    assert kinds == {'location', 'appearance', 'direction'}
    for qa in heard:
        assert qa.valid and (qa.answer == "I don't know.") == (qa.question.question_type == 'location'), qa
    with pytest.raises(ValueError, match="oracle 'location:1'.*choose another --out"):
        evaluate(path, agent='expert', questioner='all', limit=3)       # the exact oracle: another run


def test_a_perturbed_oracle_needs_a_questioner_and_a_known_type():
    for bad, match in (({'perturb_type': 'location'}, 'needs a questioner'),
                       ({'perturb_type': 'colour', 'questioner': 'all'}, 'must be one of'),
                       ({'perturb_type': 'location', 'questioner': 'all', 'perturb_probability': 2.0}, r'\[0, 1\]')):
        with pytest.raises(ValueError, match=match):
            EvalRun(EvalConfig(split=SPLIT, agent='random', **bad))
    run = EvalRun(EvalConfig(split=SPLIT, agent='random', questioner='all', perturb_type='direction'))
    assert run.oracle == 'direction:0.5'
    assert run.results_path.name == 'valid_unseen_random+all_withhold-direction-0.5.jsonl'


# ---------------------------------------------------------------------------------------------- your own agent

MY_AGENTS = '''
from dialfred_sim.protocol import Question


class WalkThenStop:
    """Two steps ahead, then Stop."""

    name = 'walker'

    def __init__(self, resolution=128):
        self.resolution = resolution

    def reset(self, task, seed):
        self.steps = 0

    def act(self, observation):
        self.steps += 1
        return ('MoveAhead', -1, -1) if self.steps <= 2 else ('Stop', -1, -1)


class AskForDirections:
    name = 'directions'

    def reset(self, task, seed):
        self.asked = False

    def ask(self, observation, step):
        return Question('direction') if step == 0 and not self.asked else None

    def hear(self, qa):
        self.asked = True


class NotAnAgent:
    pass
'''


def test_your_own_agent_and_questioner_run_by_module_and_class_name(tmp_path, monkeypatch):
    (tmp_path / 'my_agents.py').write_text(MY_AGENTS)
    monkeypatch.syspath_prepend(str(tmp_path))
    report = evaluate(tmp_path / 'mine.jsonl', agent='my_agents:WalkThenStop', questioner='my_agents:AskForDirections',
                      limit=3, workers=1)
    for r in report.results:
        assert r.agent == 'my_agents:WalkThenStop+my_agents:AskForDirections' and r.questions == 1
        assert r.end_reason in ('stop', 'success') and r.steps <= 3
    # The same run resumes from its file (the agent's name in the results is the one it was run by).
    assert evaluate(tmp_path / 'mine.jsonl', agent='my_agents:WalkThenStop', questioner='my_agents:AskForDirections',
                    limit=3, workers=1).ran == 0


@pytest.mark.parametrize('agent, message', [
    ('no_such_module_here:Agent', "cannot import 'no_such_module_here'"),
    ('my_agents:Missing', "has no class 'Missing'"),
    ('my_agents:NotAnAgent', 'lacks reset, act'),
    ('walker', "unknown agent 'walker'"),
])
def test_an_agent_that_cannot_be_made_is_refused_before_any_node_starts(tmp_path, monkeypatch, agent, message):
    (tmp_path / 'my_agents.py').write_text(MY_AGENTS)
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ValueError, match=message):
        evaluate(tmp_path / 'bad.jsonl', agent=agent)
    assert not (tmp_path / 'bad.jsonl').exists()


def test_the_confusion_questioner_asks_before_every_action_of_the_always_unsure_random_agent(tmp_path):
    report = evaluate(tmp_path / 'confused.jsonl', agent='random', questioner='confusion', limit=4, workers=1)
    for r in report.results:
        assert r.agent == 'random+confusion' and r.invalid_questions == 0
        assert r.questions == r.steps > 0                     # one question before each action


def test_the_example_agent_reaches_most_move_goals_by_following_the_oracles_directions(tmp_path, monkeypatch):
    import dialfred_sim.tasks
    moves = [t for t in dialfred_sim.tasks.load_split(SPLIT)[:200] if t.task_type == 'Move'][:8]
    monkeypatch.setattr(dialfred_sim.tasks, 'load_split', lambda split: moves)
    report = evaluate(tmp_path / 'follower.jsonl', agent='examples.direction_follower:DirectionFollower',
                      questioner='examples.direction_follower:AskForDirections', limit=8, workers=1)
    assert len(report.results) == 8
    assert sum(r.success for r in report.results) >= 5          # 126 of 169 (74.6%) on all of valid_unseen
    for r in report.results:
        assert r.questions == r.steps and r.invalid_questions == 0   # it asks before every action
    # Without ROS the agent reads the same observation fields (last_action_success) and plays the same
    local = evaluate(tmp_path / 'local.jsonl', agent='examples.direction_follower:DirectionFollower',
                     questioner='examples.direction_follower:AskForDirections', limit=8, workers=1, local=True)
    key = lambda r: (r.task_id, r.success, r.steps, r.questions, r.failed_actions, r.end_reason, r.dialogue)  # noqa: E731 - a sort key
    assert [key(r) for r in local.results] == [key(r) for r in report.results]
    # The same agent asking by itself (its own ask(): a DialogueAgent), with no questioner: the run starts the
    # oracle for it and plays the same episodes, through the graph and without ROS.
    for path, limit in (('graph', 2), ('local', 6)):
        asker = evaluate(tmp_path / f'asker_{path}.jsonl', agent='examples.direction_follower:DirectionAsker',
                         limit=limit, workers=1, local=path == 'local')
        assert [key(r) for r in asker.results] == [key(r) for r in report.results[:limit]], path


def test_the_et_performer_is_evaluated_at_its_training_resolution_unless_told_otherwise(tmp_path):
    import argparse

    from dialfred_bringup.evaluation import add_eval_parser, eval_config
    from helpers import tiny_checkpoint
    checkpoint = tiny_checkpoint(tmp_path / 'r48.pt', resolution=48)
    parser = argparse.ArgumentParser()
    add_eval_parser(parser.add_subparsers(dest='command'))
    config = lambda *a: eval_config(parser.parse_args(['eval', *a]))
    assert config('--agent', 'et').resolution == 64                           # the shipped checkpoint's
    assert config('--performer', 'et', '--checkpoint', str(checkpoint)).resolution == 48
    assert config('--agent', 'et', '--resolution', '128').resolution == 128
    assert config('--agent', 'expert').resolution == 128
    assert config('--agent', 'et', '--checkpoint', '/nonexistent.pt').resolution == 128   # check() reports it


def test_a_second_run_into_the_same_results_file_is_refused_naming_the_first(tmp_path):
    from dialfred_sim.metrics import ResultsFileError, results_lock
    out = tmp_path / 'shared.jsonl'
    with results_lock(out):                       # a run of this process owns the file
        with pytest.raises(ResultsFileError, match=f'being written by another run .*"pid": {os.getpid()}'):
            with results_lock(out):
                pass
        done = subprocess.run([sys.executable, '-m', 'dialfred_bringup.launch', 'eval', '--split', SPLIT, '--agent',
                               'random', '--limit', '2', '--local', '--workers', '1', '--out', str(out),
                               '--no-progress'], capture_output=True, text=True, timeout=120)
        assert done.returncode == 2 and 'is being written by another run' in done.stderr, done.stderr
        assert not out.exists()
    report = run_eval(EvalConfig(split=SPLIT, agent='random', limit=2, workers=1, local=True, out=out), progress=False)
    assert report.ran == 2 and len(out.read_text().splitlines()) == 2       # free again once the owner is done
