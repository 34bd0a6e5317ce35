"""dialfred_bringup/compare_runs.py on two small synthetic run folders (made here, not by a real run).

Claims: two copies of a run differ nowhere, whatever their folders' names; a run whose wall times,
timings in a cache's meta.json and checkpoint file names alone differ is the same; one changed episode field, one changed tensor, one
changed table line or one changed cache file is found and named; a missing run folder or results.md
is a clear error (exit status 2), a difference exit status 1.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import torch


import dialfred_bringup.compare_runs as compare_runs

ROOT = Path(__file__).resolve().parents[2]
EPISODE = {'task_id': 'valid_unseen/000001', 'success': True, 'steps': 12, 'questions': 1,
           'dialogue': [{'type': 'location', 'noun': 'apple', 'valid': True, 'answer': 'left'}]}


def make_run(run: Path, cache: Path) -> Path:
    """A synthetic run folder: results.md, one results file, three checkpoints, stamps naming a cache."""
    (run / 'eval').mkdir(parents=True)
    (run / 'stamps').mkdir()
    doc = (f'# Results\n\n- performer: `{run}/performer/best.pt` (sha256 `{hash(str(run)) & 0xffff:x}`)\n\n'
           f'## Table II: baselines\n\n| RL anytime | 22.0 |\n| All QAs | 26.1 |\n\nfrom `{run}/eval`\n\n'
           f'## Run times\n\n- rl: {len(str(run))} s\n')
    (run / 'results.md').write_text(doc)
    episodes = [dict(EPISODE, wall_s=0.1 * len(str(run)), agent=f'et-{len(str(run))}+all'),
                dict(EPISODE, task_id='valid_unseen/000002', success=False, wall_s=0.2, agent='x')]
    (run / 'eval' / 'valid_unseen_all_qas.jsonl').write_text(''.join(json.dumps(e) + '\n' for e in episodes))
    (run / 'eval' / 'valid_unseen_all_qas.runs.jsonl').write_text(json.dumps({'wall_s': len(str(run))}) + '\n')
    g = torch.Generator().manual_seed(0)
    for rel in ('performer/best.pt', 'questioner/pretrain/best.pt', 'questioner/rl_anytime/final.pt'):
        (run / rel).parent.mkdir(parents=True, exist_ok=True)
        torch.save({'format': 'synthetic/1', 'config': {'hidden': 4}, 'vocab': ['a', 'b'],
                    'state_dict': {'w': torch.randn(3, 4, generator=g)}, 'command': f'train --out {run}'},
                   run / rel)
    (cache / 'demos').mkdir(parents=True)
    (cache / 'demos' / 'frames.npy').write_bytes(bytes(range(256)))
    (cache / 'demos' / 'meta.json').write_text(json.dumps({'tasks': 2, 'seconds_this_run': len(str(run)) / 7}))
    (cache / 'dialogues.jsonl.gz').write_bytes(b'dialogues')
    (cache / 'first.npz').write_bytes(b'frames')
    stamps = {'demos': {'inputs': {'config': {'out': str(cache / 'demos')}}},
              'dialogues': {'report': {'path': str(cache / 'dialogues.jsonl.gz')}},
              'frames': {'report': {'path': str(cache / 'first.npz')}}}
    for stage, stamp in stamps.items():
        (run / 'stamps' / f'{stage}.json').write_text(json.dumps(stamp))
    return run


@pytest.fixture
def runs(tmp_path):
    return (make_run(tmp_path / 'first', tmp_path / 'cache_a'),
            make_run(tmp_path / 'a_second_run_folder', tmp_path / 'cache_b'))


def test_two_runs_with_the_same_outputs_are_the_same(runs):
    a, b = runs
    report = compare_runs.compare(a, b, parts=compare_runs.PARTS)
    assert report['same'], report
    assert report['episodes'] == {'same': True, 'files': 1, 'episodes': 2, 'differing': 0, 'only_in_one': [],
                                  'differing_files': {}}
    assert set(report['weights']['models']) == {'performer', 'pretrain', 'rl_anytime'}
    assert all(c['same'] for c in report['caches']['caches'].values())
    assert compare_runs.main([str(a), str(b)]) == 0


def test_a_changed_episode_is_found_with_its_fields(runs):
    a, b = runs
    path = b / 'eval' / 'valid_unseen_all_qas.jsonl'
    lines = path.read_text().splitlines()
    second = json.loads(lines[1])
    second['steps'] += 1
    path.write_text(lines[0] + '\n' + json.dumps(second) + '\n')
    report = compare_runs.compare(a, b)
    assert not report['same'] and report['tables']['same'] and report['weights']['same']
    assert report['episodes']['differing'] == 1
    assert report['episodes']['differing_files']['eval/valid_unseen_all_qas.jsonl'] == {
        'episodes': 2, 'differing': 1, 'first': ['valid_unseen/000002'], 'fields_of_first': ['steps']}
    assert compare_runs.main([str(a), str(b)]) == 1


def test_a_results_file_in_one_run_only_is_a_difference(runs):
    a, b = runs
    shutil.copy(a / 'eval' / 'valid_unseen_all_qas.jsonl', a / 'eval' / 'valid_seen_all_qas.jsonl')
    report = compare_runs.compare(a, b)
    assert report['episodes']['only_in_one'] == ['eval/valid_seen_all_qas.jsonl'] and not report['same']


def test_a_changed_tensor_is_found(runs):
    a, b = runs
    path = b / 'questioner' / 'rl_anytime' / 'final.pt'
    ckpt = torch.load(path, weights_only=True)
    ckpt['state_dict']['w'][0, 0] += 1e-6
    torch.save(ckpt, path)
    report = compare_runs.compare(a, b)
    assert not report['weights']['same']
    assert report['weights']['models']['rl_anytime'] == {'same': False, 'differing': ['state_dict'],
                                                         'first_tensors': ['w']}
    assert report['weights']['models']['performer']['same']


def test_a_changed_table_line_is_shown(runs):
    a, b = runs
    doc = b / 'results.md'
    doc.write_text(doc.read_text().replace('| All QAs | 26.1 |', '| All QAs | 26.2 |'))
    report = compare_runs.compare(a, b)
    assert report['tables']['differing_lines'] == 1
    assert report['tables']['first'] == [{'a': '| All QAs | 26.1 |', 'b': '| All QAs | 26.2 |'}]


def test_a_changed_cache_file_is_named(runs, tmp_path):
    a, b = runs
    (tmp_path / 'cache_b' / 'demos' / 'frames.npy').write_bytes(b'other')
    report = compare_runs.compare(a, b, parts=compare_runs.PARTS)
    assert report['caches']['caches']['demonstrations'] == {'same': False, 'files': 2, 'differing': ['frames.npy']}
    (tmp_path / 'cache_b' / 'demos' / 'frames.npy').write_bytes(bytes(range(256)))
    (tmp_path / 'cache_b' / 'demos' / 'meta.json').write_text(json.dumps({'tasks': 3, 'seconds_this_run': 1.0}))
    assert compare_runs.compare(a, b, parts=('caches',))['caches']['caches']['demonstrations']['differing'] == ['meta.json']
    assert report['caches']['caches']['dialogues']['same'] and not report['same']


def test_missing_folders_and_unfinished_runs_are_clear_errors(runs, tmp_path, capsys):
    a, b = runs
    assert compare_runs.main([str(a), str(tmp_path / 'nowhere')]) == 2
    assert 'is not a run folder' in capsys.readouterr().err
    (b / 'results.md').write_text('# Results\n\n## Table II\n')
    assert compare_runs.main([str(a), str(b)]) == 2
    assert 'an unfinished run?' in capsys.readouterr().err
    assert compare_runs.main([str(a), str(b), '--parts', 'weights,caches']) == 0     # what an unfinished run has
    assert compare_runs.main([str(a), str(b), '--parts', 'weights,nope']) == 2
    assert 'parts are some of' in capsys.readouterr().err
