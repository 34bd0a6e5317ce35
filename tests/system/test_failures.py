"""dialfred_bringup.failures: a results file's failures sorted by how they ended and their last failed
action, with the out-of-reach distances; bad input gets a clear error."""

from __future__ import annotations

import json

import pytest

from dialfred_bringup.failures import breakdown, kind_of, main
from dialfred_sim.metrics import TruncatedResultsWarning


def row(task: str, success: bool, end: str, error: str = '', task_type: str = 'Pick') -> str:
    return json.dumps({'task_id': task, 'task_type': task_type, 'split': 'valid_unseen', 'success': success,
                       'goal_conditions_met': int(success), 'goal_conditions_total': 1, 'steps': 5,
                       'expert_length': 5, 'questions': 0, 'failed_actions': int(bool(error)),
                       'invalid_questions': 0, 'end_reason': end, 'error': error, 'agent': 'et-x', 'oracle': '',
                       'seed': 0, 'wall_s': 0.1, 'privileged': False, 'dialogue': []}) + '\n'


def test_object_ids_and_pixels_are_taken_out_of_the_kinds():
    assert kind_of('Mug_1 is out of reach (1.73 m away; reach is 1.5 m)') == 'X is out of reach'
    assert kind_of('MoveAhead blocked by DiningTable_0') == 'MoveAhead blocked by X'
    assert kind_of('no object at pixel (64, 12) (wall is there)') == 'no object at pixel (wall is there)'
    assert kind_of('') == ''


def test_failures_are_counted_by_end_and_last_error_with_the_reach_distances(tmp_path):
    path = tmp_path / 'r.jsonl'
    path.write_text(row('valid_unseen/000000', True, 'success')
                    + row('valid_unseen/000001', False, 'stop', 'Mug_1 is out of reach (1.60 m away; reach is 1.5 m)', 'Put')
                    + row('valid_unseen/000002', False, 'stop', 'Box_0 is out of reach (2.40 m away; reach is 1.5 m)', 'Put')
                    + row('valid_unseen/000003', False, 'max_failures', 'MoveAhead blocked by Sofa_0')
                    + '{"task_id": "valid_unseen/0000')                       # a cut-off last line is skipped
    with pytest.warns(TruncatedResultsWarning):
        report = breakdown(path)
    assert (report['episodes'], report['failed']) == (4, 3)
    first = report['by_end_and_last_error'][0]
    assert (first['end_reason'], first['last_error'], first['episodes']) == ('stop', 'X is out of reach', 2)
    assert first['examples'] == ['valid_unseen/000001', 'valid_unseen/000002']
    reach = report['out_of_reach_metres']
    assert reach['episodes'] == 2 and reach['p50'] == 2.0 and reach['within_0.25_m_of_reach'] == 0.5
    assert reach['task_types'] == {'Put': 2}


def test_a_missing_or_empty_file_is_a_clear_error(tmp_path, capsys):
    assert main([str(tmp_path / 'missing.jsonl')]) == 2
    (tmp_path / 'empty.jsonl').write_text('')
    assert main([str(tmp_path / 'empty.jsonl')]) == 2
    assert 'no results' in capsys.readouterr().err
