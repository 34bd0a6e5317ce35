"""DialFRED's metrics (no ROS): success, path-weighted success, goal conditions, questions, per-type
summaries in the paper's order, their 95% bootstrap intervals, and the JSON-lines results file an
evaluation resumes from."""

from __future__ import annotations

import json
import warnings

import pytest

from dialfred_sim.metrics import (END_REASONS, EpisodeResult, TruncatedResultsWarning, append_result, end_reason,
                                  failures, format_table, intervals, load_results, results_by_task, summarize)
from dialfred_sim.tasks.types import TASK_TYPES


def result(task_id='valid_unseen/000001', task_type='Pick', success=True, met=1, total=1, steps=10, expert=10,
           questions=0, end='success', **kw) -> EpisodeResult:
    return EpisodeResult(task_id=task_id, task_type=task_type, split='valid_unseen', success=success,
                         goal_conditions_met=met, goal_conditions_total=total, steps=steps, expert_length=expert,
                         questions=questions, end_reason=end, agent='expert', **kw)


# ---------------------------------------------------------------------------------------------- per episode

@pytest.mark.parametrize('success, steps, expert, expected', [
    pytest.param(True, 10, 10, 1.0, id='as-long-as-the-expert'),
    pytest.param(True, 4, 10, 1.0, id='shorter-than-the-expert-gives-s'),
    pytest.param(True, 20, 10, 0.5, id='twice-the-expert-halves-it'),
    pytest.param(True, 40, 10, 0.25, id='four-times-the-expert'),
    pytest.param(False, 10, 10, 0.0, id='failure-scores-zero'),
    pytest.param(False, 3, 10, 0.0, id='short-failure-scores-zero'),
    pytest.param(True, 0, 0, 1.0, id='zero-length-task'),
])
def test_path_weighted_success_is_s_times_expert_over_the_longer_path(success, steps, expert, expected):
    r = result(success=success, steps=steps, expert=expert, end='success' if success else 'stop')
    assert r.path_weighted_success == pytest.approx(expected)


def test_goal_condition_fraction_is_met_over_total():
    assert result(success=False, met=1, total=3, end='stop').gc == pytest.approx(1 / 3)
    assert result(met=2, total=2).gc == 1.0
    assert result(success=False, met=0, total=4, end='max_failures').gc == 0.0
    # An episode that never started (reset failed) has no conditions and no credit.
    assert result(success=False, met=0, total=0, end='error').gc == 0.0


def test_an_unknown_end_reason_is_rejected():
    with pytest.raises(ValueError, match='end_reason must be one of'):
        result(end='gave_up')


@pytest.mark.parametrize('success, last, failed, truncated, expected', [
    (True, 'Put', 0, False, 'success'),
    (True, 'Stop', 3, False, 'success'),       # success wins over everything else
    (False, 'Stop', 0, False, 'stop'),
    (False, 'Stop', 10, False, 'stop'),        # the agent's Stop wins over the failure count
    (False, 'Pickup', 10, False, 'max_failures'),
    (False, 'Pickup', 10, True, 'max_failures'),
    (False, 'MoveAhead', 2, True, 'max_steps'),
])
def test_the_end_reason_follows_the_last_step(success, last, failed, truncated, expected):
    assert end_reason(success, last, failed, truncated) == expected
    assert expected in END_REASONS


def test_an_episode_that_has_not_ended_has_no_end_reason():
    with pytest.raises(ValueError, match='has not ended'):
        end_reason(False, 'MoveAhead', 1, False)


def test_a_result_survives_a_json_round_trip():
    r = result(questions=3, failed_actions=2, error='', seed=7, wall_s=0.25)
    line = r.to_json()
    assert '\n' not in line
    assert EpisodeResult.from_json(line) == r


@pytest.mark.parametrize('line, message', [
    pytest.param('{"task_id": "valid_unseen/0', 'not a JSON episode result', id='truncated'),
    pytest.param('[1, 2]', 'must be a JSON object', id='not-an-object'),
    pytest.param('{"task_id": "x"}', 'missing fields', id='missing-fields'),
])
def test_a_malformed_line_raises_a_clear_value_error(line, message):
    with pytest.raises(ValueError, match=message):
        EpisodeResult.from_json(line)


def test_a_result_written_before_dialogues_were_recorded_loads_with_none():
    good = json.loads(result(questions=2).to_json())
    del good['dialogue']
    old = EpisodeResult.from_json(json.dumps(good))
    assert old.dialogue == [] and old.questions == 2 and old.question_types == {}


def test_a_result_written_before_rows_carried_their_commit_loads_unrecorded_and_compares_the_same():
    from dialfred_sim.metrics import played_at, same_episode
    good = json.loads(result(code='abc+dirty', wall_s=1.0).to_json())
    del good['code']
    old = EpisodeResult.from_json(json.dumps(good))
    assert old.code == '' and played_at([old, result(code='abc'), result(code='abc')]) == {'abc': 2, 'unrecorded': 1}
    assert same_episode(old, result(code='abc', wall_s=2.0))        # how and where it was played aside
    assert not same_episode(old, result(code='abc', steps=11))
    with pytest.raises(ValueError, match="field 'code' should be str"):
        EpisodeResult.from_json(json.dumps({**good, 'code': 7}))


def test_a_field_of_the_wrong_type_or_unknown_is_rejected():
    good = json.loads(result().to_json())
    with pytest.raises(ValueError, match="field 'steps' should be int"):
        EpisodeResult.from_json(json.dumps({**good, 'steps': '10'}))
    with pytest.raises(ValueError, match="field 'success' should be bool"):
        EpisodeResult.from_json(json.dumps({**good, 'success': 1}))
    with pytest.raises(ValueError, match='unknown episode result fields'):
        EpisodeResult.from_json(json.dumps({**good, 'reward': 1.0}))


# ---------------------------------------------------------------------------------------------- summaries

def test_the_summary_averages_overall_in_percent_and_questions_as_a_count():
    results = [
        result('t/1', 'Pick', success=True, steps=10, expert=10, questions=2),               # p = 1
        result('t/2', 'Pick', success=True, steps=20, expert=10, questions=0),               # p = 0.5
        result('t/3', 'Open', success=False, met=1, total=2, end='stop', questions=1),       # GC 0.5
        result('t/4', 'Open', success=False, met=0, total=2, end='max_failures'),
    ]
    s = summarize(results)
    overall = s['overall']
    assert overall['n'] == 4
    assert overall['SR'] == pytest.approx(50.0)
    assert overall['PWSR'] == pytest.approx(100 * (1 + 0.5) / 4)
    assert overall['GC'] == pytest.approx(100 * (1 + 1 + 0.5 + 0) / 4)
    assert overall['NQ'] == pytest.approx(3 / 4)
    assert s['end_reasons'] == {'success': 2, 'stop': 1, 'max_failures': 1}


def test_the_summary_groups_by_task_type_in_the_papers_order():
    played = [('Pick & Move', True), ('Clean', True), ('Pick', True), ('Clean', False), ('Move & Heat', False),
              ('Pick', True)]
    results = [result(f't/{k}', t, success=ok, end='success' if ok else 'stop') for k, (t, ok) in enumerate(played)]
    per_type = summarize(results)['per_type']
    assert list(per_type) == ['Clean', 'Pick', 'Move & Heat', 'Pick & Move']
    assert list(per_type) == [t for t in TASK_TYPES if t in per_type]
    assert per_type['Clean']['n'] == 2 and per_type['Clean']['SR'] == pytest.approx(50.0)
    assert per_type['Pick']['n'] == 2 and per_type['Pick']['SR'] == pytest.approx(100.0)
    assert per_type['Pick & Move'] == {'n': 1, 'SR': 100.0, 'PWSR': 100.0, 'GC': 100.0, 'NQ': 0.0, 'NQ_invalid': 0.0}


def test_the_paper_lists_25_task_types():
    assert len(TASK_TYPES) == len(set(TASK_TYPES)) == 25
    assert TASK_TYPES[0] == 'Clean' and TASK_TYPES[-1] == 'Pick & Move & Slice'


def test_an_empty_summary_has_zero_episodes():
    s = summarize([])
    assert s['overall']['n'] == 0 and s['per_type'] == {}
    assert 'overall' in format_table(s)


def mixed(n, seed=0):
    """n episodes with every metric varying: ~40% successes, some long, 0-3 questions, partial GC."""
    import numpy as np
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        ok = bool(rng.random() < 0.4)
        out.append(result(task_id=f'valid_unseen/{k:06d}', success=ok, met=int(rng.integers(0, 3)) if not ok else 2,
                          total=2, steps=int(rng.integers(5, 40)), expert=10, questions=int(rng.integers(0, 4)),
                          end='success' if ok else 'stop'))
    return out


def test_the_bootstrap_interval_holds_the_point_estimate_in_the_summarys_units():
    results = mixed(300)
    point, ci = summarize(results)['overall'], intervals(results)
    assert set(ci) == {'SR', 'PWSR', 'GC', 'NQ'}
    for k, (lo, hi) in ci.items():
        assert lo < point[k] < hi, (k, lo, point[k], hi)
    assert 0 < ci['SR'][0] and ci['SR'][1] < 100 and ci['NQ'][1] < 3


def test_the_bootstrap_interval_narrows_as_episodes_grow():
    small, large = intervals(mixed(100)), intervals(mixed(1600))
    for k in small:
        assert large[k][1] - large[k][0] < 0.6 * (small[k][1] - small[k][0]), (k, small[k], large[k])


def test_the_bootstrap_interval_repeats_itself_for_a_seed():
    results = mixed(200)
    assert intervals(results, seed=3) == intervals(results, seed=3)
    assert intervals(results, seed=3) != intervals(results, seed=4)


def test_all_successes_give_a_degenerate_interval_and_no_results_give_zeros():
    ci = intervals([result(task_id=f'valid_unseen/{k:06d}') for k in range(50)])
    assert ci['SR'] == (100.0, 100.0) and ci['PWSR'] == (100.0, 100.0) and ci['NQ'] == (0.0, 0.0)
    assert intervals([]) == {k: (0.0, 0.0) for k in ('SR', 'PWSR', 'GC', 'NQ')}
    with pytest.raises(ValueError, match='resamples'):
        intervals(mixed(5), resamples=0)


def test_the_table_has_a_line_per_type_and_an_overall_line():
    results = [result('t/1', 'Open & Put & Close'), result('t/2', 'Heat', success=False, met=1, total=2, end='stop')]
    table = format_table(summarize(results))
    lines = table.splitlines()
    assert lines[0].split() == ['task', 'type', 'n', 'SR', 'PWSR', 'GC', 'NQ']
    assert lines[2].split()[0] == 'Heat' and lines[2].split()[1:] == ['1', '0.0', '0.0', '50.0', '0.00']
    assert lines[3].startswith('Open & Put & Close') and lines[3].split()[-4:] == ['100.0', '100.0', '100.0', '0.00']
    assert lines[-1].split() == ['overall', '2', '50.0', '50.0', '75.0', '0.00']
    assert len({len(line) for line in lines}) == 1      # fixed width


def test_failures_and_first_results_by_task():
    results = [result('t/2', success=False, end='stop'), result('t/1'), result('t/2', success=True)]
    assert [r.task_id for r in failures(results)] == ['t/2']
    by_task = results_by_task(results, ['t/2'])
    assert list(by_task) == ['t/2'] and not by_task['t/2'].success


# ---------------------------------------------------------------------------------------------- results file

def test_results_are_appended_one_line_each_and_read_back(tmp_path):
    path = tmp_path / 'sub' / 'results.jsonl'
    assert load_results(path) == []
    written = [result(f't/{k}', steps=k) for k in range(3)]
    for r in written:
        append_result(path, r)
    assert path.read_text().count('\n') == 3
    assert load_results(path) == written


def test_a_truncated_last_line_is_skipped_with_a_warning(tmp_path):
    path = tmp_path / 'results.jsonl'
    written = [result('t/1'), result('t/2')]
    for r in written:
        append_result(path, r)
    with open(path, 'a') as f:
        f.write(result('t/3').to_json()[:37])          # a write cut off by a crash
    with pytest.warns(TruncatedResultsWarning, match='skipped 1 truncated final line'):
        assert load_results(path) == written
    assert path.read_text().count('\n') == 2           # reading alone leaves the file as it is


def test_dropping_a_truncated_last_line_lets_appending_go_on(tmp_path):
    path = tmp_path / 'results.jsonl'
    append_result(path, result('t/1'))
    with open(path, 'a') as f:
        f.write('{"task_id": "t/2", "task_ty')
    with pytest.warns(TruncatedResultsWarning):
        load_results(path, drop_truncated=True)
    append_result(path, result('t/2'))
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        assert [r.task_id for r in load_results(path)] == ['t/1', 't/2']


def test_a_malformed_line_in_the_middle_raises(tmp_path):
    path = tmp_path / 'results.jsonl'
    append_result(path, result('t/1'))
    with open(path, 'a') as f:
        f.write('{"task_id": "t/2", garbage\n')
    append_result(path, result('t/3'))
    with pytest.raises(ValueError, match=r'results.jsonl:2: corrupt result line'):
        load_results(path)


def test_blank_lines_are_ignored_and_a_line_without_newline_is_not_glued_to(tmp_path):
    path = tmp_path / 'results.jsonl'
    path.write_text('\n' + result('t/1').to_json())    # a complete last line that lacks its newline
    append_result(path, result('t/2'))
    assert [r.task_id for r in load_results(path)] == ['t/1', 't/2']


def test_a_file_written_atomically_is_whole_and_leaves_nothing_beside_it(tmp_path, monkeypatch):
    import os

    from dialfred_sim.metrics import write_text_atomically
    path = tmp_path / 'summary.json'
    write_text_atomically(path, 'old\n')
    real_replace = os.replace

    def power_cut(src, dst):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, 'replace', power_cut)
    with pytest.raises(KeyboardInterrupt):
        write_text_atomically(path, 'new\n' * 1000)
    monkeypatch.setattr(os, 'replace', real_replace)
    assert path.read_text() == 'old\n' and sorted(p.name for p in tmp_path.iterdir()) == ['summary.json']
    write_text_atomically(path, 'new\n')
    assert path.read_text() == 'new\n' and sorted(p.name for p in tmp_path.iterdir()) == ['summary.json']
