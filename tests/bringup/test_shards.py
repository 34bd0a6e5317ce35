"""An evaluation in shards, without ROS: which tasks a shard plays, and `./dialfred merge`.

Claims: the shards of a split are disjoint, cover it, keep each task's index in the split (its
episode seed) and do not move with --limit; a bad K/N is refused before anything starts; each
shard has a results file of its own; merging the shards' files gives the results (in split order)
and the summary of one run of all the tasks; files of different runs, a shard given twice, a task
twice or in the wrong shard's file, a cut-off or corrupt line and missing tasks are errors that
write nothing (missing tasks are written with --partial, listed).
(tests/bringup/test_eval_shards.py plays real shards through simulator nodes.)
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import re
from pathlib import Path

import pytest

from dialfred_sim.metrics import EpisodeResult, ResultsFileError, append_result, load_results, summarize
from dialfred_bringup.shards import default_out, main, merge_shards, parse_shard, shard_suffix, shard_tasks
from dialfred_sim.tasks import load_split

from dialfred_bringup.evaluation import EvalConfig, EvalReport, EvalRun, add_eval_parser, eval_config, run_eval

REPO = Path(__file__).resolve().parents[2]
SPLIT = 'valid_unseen'
LIMIT = 7


# ---------------------------------------------------------------------------------------------- selection

def test_the_shards_are_disjoint_cover_the_tasks_and_keep_their_index_in_the_split():
    tasks = list('abcdefg')
    shards = [shard_tasks(tasks, (k, 3)) for k in range(3)]
    assert shards[0] == [(0, 'a'), (3, 'd'), (6, 'g')] and shards[1] == [(1, 'b'), (4, 'e')]
    assert sorted(p for s in shards for p in s) == list(enumerate(tasks))
    assert shard_tasks(tasks, None) == list(enumerate(tasks))
    # a task's shard does not depend on --limit: a longer limit only adds tasks to each shard
    assert shard_tasks(tasks[:4], (1, 3)) == shards[1][:1] and shard_tasks(tasks, (1, 3))[:1] == shards[1][:1]


@pytest.mark.parametrize('text', ['2/2', '-1/2', '0/0', 'a/b', '1', '1/2/3', ''])
def test_a_bad_shard_is_refused_with_what_a_shard_is(text, capsys):
    with pytest.raises(ValueError, match='a shard is K/N with integers 0 <= K < N'):
        parse_shard(text)
    parser = argparse.ArgumentParser()
    add_eval_parser(parser.add_subparsers())
    with pytest.raises(SystemExit) as exit_info:
        parser.parse_args(['eval', f'--shard={text}'])
    assert exit_info.value.code == 2 and 'a shard is K/N' in capsys.readouterr().err


def test_a_bad_shard_fails_before_any_node_starts(tmp_path):
    out = tmp_path / 'x.jsonl'
    with pytest.raises(ValueError, match='0 <= K < N'):
        run_eval(EvalConfig(split=SPLIT, agent='random', shard=(3, 2), out=out), progress=False)
    assert not out.exists() and not list(tmp_path.iterdir())


def test_each_shard_has_a_results_file_of_its_own():
    parser = argparse.ArgumentParser()
    add_eval_parser(parser.add_subparsers())
    config = eval_config(parser.parse_args(['eval', '--agent', 'random', '--shard', '1/3']))
    assert config.shard == (1, 3)
    run, whole = EvalRun(config), EvalRun(EvalConfig(split=SPLIT, agent='random'))
    assert run.results_path.name == 'valid_unseen_random_shard1of3.jsonl'
    assert run.summary_path.name == 'valid_unseen_random_shard1of3.summary.json'
    assert whole.results_path.name == 'valid_unseen_random.jsonl'
    assert default_out(run.results_path) == whole.results_path
    assert shard_suffix(None) == ''


# ---------------------------------------------------------------------------------------------- merging

def fake_results(seed: int = 0) -> list[EpisodeResult]:
    """Results of the first LIMIT tasks, as a random agent's run would record them (varied outcomes)."""
    out = []
    for k, t in enumerate(load_split(SPLIT)[:LIMIT]):
        ok = k % 3 == 0
        out.append(EpisodeResult(task_id=t.task_id, task_type=t.task_type, split=SPLIT, success=ok,
                                 goal_conditions_met=1 if ok else k % 2, goal_conditions_total=2, steps=3 + k,
                                 expert_length=t.expert_length, failed_actions=0 if ok else 10,
                                 end_reason='success' if ok else 'max_failures', error='' if ok else 'blocked',
                                 agent='random', seed=seed, wall_s=0.1 * k))
    return out


def write_run(path: Path, results: list, shard=None, order=None, **config) -> Path:
    """A results file and its summary as run_eval writes them (the episodes appended in `order`)."""
    c = EvalRun(EvalConfig(**{'split': SPLIT, 'agent': 'random', 'limit': LIMIT, 'resolution': 64, 'out': path,
                              'shard': shard, 'workers': 2, **config}))
    selected = {t.task_id for _, t in shard_tasks(load_split(SPLIT)[:LIMIT], shard)}
    mine = [r for r in results if r.task_id in selected]
    for r in (mine if order is None else [mine[k] for k in order]):
        append_result(path, r)
    report = EvalReport(c, mine, len(mine), 1.0, 2.0, summarize(mine))
    c.summary_path.write_text(json.dumps(report.to_json(), indent=1) + '\n')
    return path


@pytest.fixture
def shards(tmp_path):
    results = fake_results()
    whole = write_run(tmp_path / 'whole' / 'run.jsonl', results)
    parts = [write_run(tmp_path / 'a' / f'run_shard{k}of3.jsonl', results, (k, 3), order=[1, 0] if k else None)
             for k in range(3)]
    return whole, parts


def summary_of(path: Path) -> dict:
    return json.loads(path.with_suffix('.summary.json').read_text())


def test_merged_shards_are_the_results_and_summary_of_one_run(shards, tmp_path, capsys):
    whole, parts = shards
    out = tmp_path / 'merged.jsonl'
    assert main([str(p) for p in reversed(parts)] + ['--out', str(out)]) == 0
    assert 'overall' in capsys.readouterr().out
    assert out.read_text() == whole.read_text()              # the same lines, in the split's order
    merged, single = summary_of(out), summary_of(whole)
    assert merged['summary'] == single['summary'] and merged['failures'] == single['failures']
    assert json.dumps(merged['summary']) == json.dumps(single['summary'])     # the same order of keys too
    assert list(merged) == list(single) + ['shards', 'missing']
    for key in set(single) - {'workers', 'this_run', 'results_file'}:
        assert merged[key] == single[key], key
    assert merged['results_file'] == str(out) and merged['workers'] == 6 and merged['missing'] == []
    assert [(s['index'], s['count'], s['tasks']) for s in merged['shards']] == [(0, 3, 3), (1, 3, 2), (2, 3, 2)]


def test_the_default_merged_file_is_the_one_a_whole_run_writes(shards, tmp_path):
    _, parts = shards
    assert main([str(p) for p in parts]) == 0
    assert (tmp_path / 'a' / 'run.jsonl').read_text() == shards[0].read_text()
    assert main([str(p) for p in parts]) == 0                 # a merged file may be merged again over
    (tmp_path / 'a' / 'run.summary.json').write_text(json.dumps({'summary': {}, 'agent': 'random'}))
    assert main([str(p) for p in parts]) == 2                 # ... but never a run's own results


def check_refused(paths, match, tmp_path, capsys, *extra):
    out = tmp_path / 'refused.jsonl'
    assert main([str(p) for p in paths] + ['--out', str(out), *extra]) == 2
    assert re.search(match, capsys.readouterr().err), match
    assert not out.exists() and not out.with_suffix('.summary.json').exists()


def test_shards_of_different_runs_are_refused(shards, tmp_path, capsys):
    _, parts = shards
    other = write_run(tmp_path / 'b' / 'run_shard1of3.jsonl', fake_results(seed=1), (1, 3), seed=1)
    check_refused([parts[0], other, parts[2]], r'not shards of one run; they differ in seed \(0 vs 1\)', tmp_path,
                  capsys)
    hi_res = write_run(tmp_path / 'c' / 'run_shard1of3.jsonl', fake_results(), (1, 3), resolution=128)
    check_refused([parts[0], hi_res, parts[2]], r'differ in resolution \(64 vs 128\)', tmp_path, capsys)
    halves = write_run(tmp_path / 'd' / 'run_shard1of2.jsonl', fake_results(), (1, 2))
    check_refused([parts[0], halves], r'shard_count \(3 vs 2\)', tmp_path, capsys)


def test_a_shard_given_twice_or_a_task_twice_is_refused(shards, tmp_path, capsys):
    _, parts = shards
    copy = tmp_path / 'copy' / parts[1].name
    copy.parent.mkdir()
    copy.write_text(parts[1].read_text())
    copy.with_suffix('.summary.json').write_text(parts[1].with_suffix('.summary.json').read_text())
    check_refused([parts[0], parts[1], copy, parts[2]], 'shard 1/3 is given twice', tmp_path, capsys)
    line = parts[2].read_text().splitlines()[0]
    with open(parts[2], 'a') as f:
        f.write(line + '\n')
    check_refused(parts, r'task valid_unseen/000005 appears twice$', tmp_path, capsys)
    first = EpisodeResult.from_json(line)
    parts[2].write_text(line + '\n' + dataclasses.replace(first, steps=first.steps + 1).to_json() + '\n')
    check_refused(parts, 'appears twice, with different results', tmp_path, capsys)


def test_a_task_in_another_shards_file_is_refused(shards, tmp_path, capsys):
    _, parts = shards
    with open(parts[0], 'a') as f:
        f.write(parts[1].read_text())          # shard 1 was run with shard 0's --out
    check_refused(parts, r'valid_unseen/00000[14] \(index [14]\) belongs to shard 1/3, not 0/3', tmp_path, capsys)


def test_a_cut_off_last_line_is_reported_not_read(shards, tmp_path, capsys):
    _, parts = shards
    text = parts[1].read_text()
    parts[1].write_text(text[:-20])
    check_refused(parts, r'run_shard1of3.jsonl:2: skipped 1 truncated final line .*Run that shard again', tmp_path,
                  capsys)
    assert parts[1].read_text() == text[:-20]          # the merge changes no shard file
    parts[1].write_text('{"task_id": 3}\n' + text)
    check_refused(parts, r'run_shard1of3.jsonl:1: corrupt result line', tmp_path, capsys)


def test_missing_tasks_are_reported_and_written_only_with_partial(shards, tmp_path, capsys):
    _, parts = shards
    lines = parts[1].read_text().splitlines()
    parts[1].write_text(lines[0] + '\n')                 # an interrupted shard: one of its two tasks (000004)
    check_refused(parts[:2], r'3 task\(s\) are in no shard file:\n  shard 1/3: 1 missing from .*\n'
                             r'  shard 2/3: no file of shard 2/3 was given', tmp_path, capsys)
    out = tmp_path / 'partial.jsonl'
    assert main([str(p) for p in parts[:2]] + ['--out', str(out), '--partial']) == 0
    merged = summary_of(out)
    assert merged['missing'] == ['valid_unseen/000001', 'valid_unseen/000002', 'valid_unseen/000005']
    assert merged['tasks'] == 4 and len(load_results(out)) == 4


def test_a_shard_without_its_summary_is_refused(shards, tmp_path, capsys):
    _, parts = shards
    parts[2].with_suffix('.summary.json').unlink()
    check_refused(parts, r'no summary beside run_shard2of3.jsonl; .*run that shard to its end', tmp_path, capsys)
    with pytest.raises(ResultsFileError, match='no shard files'):
        merge_shards([], tmp_path / 'x.jsonl')


def test_results_of_another_agent_in_a_shard_file_are_refused(shards, tmp_path, capsys):
    _, parts = shards
    r = EpisodeResult.from_json(parts[0].read_text().splitlines()[0])
    append_result(parts[0], dataclasses.replace(r, agent='expert'))
    check_refused(parts, r"result 4 \(valid_unseen/000000\) is of split, agent, oracle, seed .*'expert'.* the file "
                         'mixes runs', tmp_path, capsys)


def test_a_result_of_a_task_not_in_the_split_is_refused_and_one_beyond_the_limit_ignored(shards, tmp_path, capsys):
    _, parts = shards
    r = EpisodeResult.from_json(parts[0].read_text().splitlines()[0])
    beyond = load_split(SPLIT)[LIMIT + 2]           # shard 0 of 3 run earlier with a longer --limit
    append_result(parts[0], dataclasses.replace(r, task_id=beyond.task_id))
    out = tmp_path / 'beyond.jsonl'
    assert main([str(p) for p in parts] + ['--out', str(out)]) == 0
    assert 'ignored 1 result(s) of tasks beyond --limit 7' in capsys.readouterr().out
    assert len(load_results(out)) == LIMIT
    append_result(parts[0], dataclasses.replace(r, task_id='valid_unseen/999999'))
    check_refused(parts, 'task valid_unseen/999999 is not a task of valid_unseen', tmp_path, capsys)


def test_shards_of_a_tasks_file_merge_with_that_file_found_by_its_sha256(tmp_path, capsys):
    import gzip

    from dialfred_sim.tasks.split_files import split_path
    rows = gzip.decompress(split_path(SPLIT).read_bytes()).splitlines(keepends=True)
    tasks_file = tmp_path / 'mine.jsonl.gz'
    tasks_file.write_bytes(gzip.compress(b''.join(rows[:LIMIT + 1])))
    results = fake_results()
    parts = [write_run(tmp_path / 'runs' / f'run_shard{k}of2.jsonl', results, (k, 2), tasks_file=tasks_file)
             for k in range(2)]
    assert summary_of(parts[0])['tasks_file']['path'] == str(tasks_file)
    moved = tmp_path / 'elsewhere' / 'copy.jsonl.gz'
    moved.parent.mkdir()
    tasks_file.rename(moved)                           # as on the host where the shards are merged
    check_refused(parts, r'the shards were run on a tasks file: .* does not exist.*--tasks PATH', tmp_path, capsys)
    other = tmp_path / 'other.jsonl.gz'
    other.write_bytes(gzip.compress(b''.join(rows[:LIMIT + 2])))
    check_refused(parts, r'other.jsonl.gz is not the tasks file the shards were run on', tmp_path, capsys,
                  '--tasks', str(other))
    out = tmp_path / 'merged.jsonl'
    assert main([str(p) for p in parts] + ['--out', str(out), '--tasks', str(moved)]) == 0
    assert [r.task_id for r in load_results(out)] == [r.task_id for r in results]
    assert summary_of(out)['summary'] == summarize(results)
