"""`./dialfred score RESULTS`: a results file played again from its trace in a fresh simulator and oracle. It
agrees with runs of either protocol, and refuses a file with one success flipped, one answer reworded, one
question dropped or one action removed, naming what differs and its task."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from dialfred_bringup.evaluation import EvalConfig, run_eval
from dialfred_bringup.score import main as score_main, score
from dialfred_sim.metrics import ResultsFileError
from dialfred_sim.traces import trace_path

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def runs(tmp_path_factory):
    """A chained run and an expert-protocol run of the random agent asking random questions (the oracle
    answers, some questions are invalid, actions fail), and the map performer asking at every step."""
    tmp = tmp_path_factory.mktemp('score')
    made = {}
    for name, settings in {
        'chained': dict(agent='random', questioner='random', protocol='chained', limit=16, resolution=64),
        'expert': dict(agent='random', questioner='all', limit=8, resolution=64, seed=4),
        'map': dict(agent='map', questioner='rl-anytime-1', limit=6),
    }.items():
        out = tmp / f'{name}.jsonl'
        run_eval(EvalConfig(split='valid_unseen', local=True, workers=2, out=out, **settings), progress=False)
        made[name] = out
    return made


@pytest.mark.parametrize('name', ['chained', 'expert', 'map'])
def test_a_run_replays_to_every_recorded_outcome_answer_and_count(runs, name):
    report = score(runs[name], workers=2, progress=False)
    assert report['refused'] is None, report['refused']
    assert report['tasks'] == len(runs[name].read_text().splitlines())
    assert sum(r.questions for r in report['results']) > 0
    if name == 'chained':
        assert report['episodes'] < report['tasks'] and 'episodes' in report['summary']


def tampered(src: Path, dst_dir: Path, edit_line=None, edit_trace=None) -> Path:
    """A copy of a results file (with its trace and run record) whose first line that `edit_line` changes
    (it returns the new dict, or None to leave the line) is changed, and likewise its trace."""
    dst = dst_dir / src.name
    for a, b in ((src, dst), (trace_path(src), trace_path(dst)), (src.with_suffix('.run.json'), dst.with_suffix('.run.json'))):
        lines = a.read_text().splitlines()
        edit = edit_line if a == src else (edit_trace if a == trace_path(src) else None)
        if edit is not None:
            for k, line in enumerate(lines):
                new = edit(json.loads(line))
                if new is not None:
                    lines[k] = json.dumps(new)
                    break
        b.write_text('\n'.join(lines) + '\n')
    return dst


def flip_success(d):
    return None if d['success'] else {**d, 'success': True, 'end_reason': 'success', 'error': ''}


def reword_answer(d):
    for k, q in enumerate(d['dialogue']):
        if q['valid']:
            dialogue = list(d['dialogue'])
            dialogue[k] = {**q, 'answer': q['answer'] + ' Probably.'}
            return {**d, 'dialogue': dialogue}
    return None


def drop_question(d):
    if not d['dialogue']:
        return None
    invalid = int(not d['dialogue'][-1]['valid'])
    return {**d, 'dialogue': d['dialogue'][:-1], 'questions': d['questions'] - 1,
            'invalid_questions': d['invalid_questions'] - invalid}


def remove_action(d):
    return {**d, 'actions': d['actions'][:-1]} if len(d['actions']) > 2 else None


CASES = {
    'one success flipped': (flip_success, None, 'recorded success True, the replay gives False'),
    'one answer reworded': (reword_answer, None, 'Probably.'),
    # from the results line: a question dropped from its trace as well leaves a file the world cannot tell
    # from one whose agent never asked it (a replay plays the recorded episode, not the agent)
    'one question dropped': (drop_question, None, 'the trace holds'),
    'one action removed': (None, remove_action, 'recorded steps'),
}


@pytest.mark.parametrize('name', ['chained', 'expert'])
@pytest.mark.parametrize('case', list(CASES))
def test_a_tampered_file_is_refused_naming_the_difference_and_its_task(runs, tmp_path, name, case):
    edit_line, edit_trace, says = CASES[case]
    bad = tampered(runs[name], tmp_path, edit_line, edit_trace)
    report = score(bad, workers=1, progress=False)
    assert report['refused'] is not None
    task_id, what = report['refused']
    assert says in what and task_id.startswith('valid_unseen/')


def test_the_command_prints_the_table_or_refuses_with_status_1_and_an_unscorable_file_with_2(runs, tmp_path, capsys):
    assert score_main([str(runs['expert']), '--no-progress', '--workers', '1']) == 0
    out = capsys.readouterr().out
    assert 'every outcome, answer, count and action agrees' in out and 'overall' in out
    bad = tampered(runs['expert'], tmp_path, flip_success)
    assert score_main([str(bad), '--no-progress', '--workers', '1']) == 1
    assert 'refused:' in capsys.readouterr().err
    trace_path(bad).unlink()
    assert score_main([str(bad), '--no-progress']) == 2
    assert 'no trace of' in capsys.readouterr().err
    with pytest.raises(ResultsFileError, match='no results file'):
        score(tmp_path / 'nothing.jsonl')
    proc = subprocess.run([str(REPO / 'dialfred'), 'score', str(tmp_path / 'nothing.jsonl')], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2 and 'no results file' in proc.stderr


def test_a_chained_file_that_starts_an_episode_in_its_middle_cannot_be_scored(runs, tmp_path):
    lines = runs['chained'].read_text().splitlines()
    first = json.loads(lines[0])['episode_id']
    rows = [json.loads(x) for x in lines]
    first_task = min(r['task_id'] for r in rows if r['episode_id'] == first)
    keep = [x for x, r in zip(lines, rows) if r['task_id'] != first_task]
    dst = tampered(runs['chained'], tmp_path)
    dst.write_text('\n'.join(keep) + '\n')
    with pytest.raises(ResultsFileError, match='scored from its start'):
        score(dst, workers=1, progress=False)


@pytest.mark.slow   # two chained runs of the map performer, one through performer nodes; fast: the local runs above
def test_a_run_through_performer_nodes_keeps_the_local_paths_trace_and_replays(tmp_path):
    """The performer node's RunTask result carries its goal's actions and question steps: the trace file of a
    graph run is the local run's, line for line, and `score` replays it."""
    settings = dict(split='valid_unseen', agent='map', questioner='all', protocol='chained', limit=17, workers=2)
    graph = tmp_path / 'graph.jsonl'
    run_eval(EvalConfig(performer='map', out=graph, **settings), progress=False)
    run_eval(EvalConfig(local=True, out=tmp_path / 'local.jsonl', **settings), progress=False)
    lines = lambda p: sorted(trace_path(p).read_text().splitlines())
    assert lines(graph) == lines(tmp_path / 'local.jsonl')
    report = score(graph, workers=2, progress=False)
    assert report['refused'] is None, report['refused']
    assert sum(r.questions for r in report['results']) > 0
