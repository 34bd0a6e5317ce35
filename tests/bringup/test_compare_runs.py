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


# ---------------------------------------------------------------------- --shipped

def shipped_run(run: Path) -> Path:
    """A run folder assembled from the shipped checkpoints and docs/results.md, as a run that trained the
    same models would hold them: the perception network on its own, each questioner with its encoder's copy."""
    from dialfred_bringup.reproduce.plan import SHIPPED_QUESTIONERS
    from dialfred_performer.model import visual_state
    from dialfred_performer.shipped import SHIPPED_CHECKPOINT
    et = torch.load(SHIPPED_CHECKPOINT, weights_only=True)
    (run / 'performer').mkdir(parents=True)
    shutil.copy(SHIPPED_CHECKPOINT, run / 'performer' / 'best.pt')
    (run / 'perception').mkdir()
    net = compare_runs.perception_of(et)
    torch.save({'format': 'dialfred-perception/1', 'extra': {'update': 1}, **net}, run / 'perception' / 'perception.pt')
    encoder = visual_state(Path(SHIPPED_CHECKPOINT))
    for name in ('pretrained', 'rl_anytime'):
        q = torch.load(SHIPPED_QUESTIONERS / f'{name}.pt', weights_only=True)
        q = {k: v for k, v in q.items() if k != 'visual_source'} | {'visual': encoder, 'command': f'train --out {run}'}
        rel = 'questioner/pretrain/best.pt' if name == 'pretrained' else f'questioner/{name}/final.pt'
        (run / rel).parent.mkdir(parents=True, exist_ok=True)
        torch.save(q, run / rel)
    (run / 'results.md').write_text((ROOT / 'docs' / 'results.md').read_text().replace('out/reproduce', str(run)))
    return run


def test_a_run_of_the_shipped_models_is_the_shipped_run(tmp_path):
    run = shipped_run(tmp_path / 'mine')
    report = compare_runs.compare_with_shipped(run)
    assert report['same'], report
    assert set(report['weights']['models']) == {'perception', 'performer', 'pretrain', 'rl_anytime'}
    assert 'rl_begin' in report['weights']['not_made'] and report['weights']['not_shipped'] == []
    assert report['tables']['lines'] > 50
    assert report['machines']['shipped'] and not report['machines']['same_cpu']     # the run has no stamps
    assert compare_runs.main([str(run), '--shipped']) == 0


def test_the_machines_of_the_run_and_of_the_shipped_run_are_named(tmp_path):
    (tmp_path / 'run' / 'stamps').mkdir(parents=True)
    for stage, cpu in (('perception', 'CPU A'), ('performer', 'CPU A')):
        (tmp_path / 'run' / 'stamps' / f'{stage}.json').write_text(json.dumps({'machine': {'cpu': cpu, 'cpus': 2}}))
    shipped = tmp_path / 'shipped_run.json'
    shipped.write_text(json.dumps({'stages': {'perception': {'machine': {'cpu': 'CPU A'}}}}))
    assert compare_runs.training_machines(tmp_path / 'run', shipped) == {'run': ['CPU A'], 'shipped': ['CPU A'],
                                                                          'same_cpu': True}
    shipped.write_text(json.dumps({'stages': {'perception': {'machine': {'cpu': 'CPU B'}}}}))
    other = compare_runs.training_machines(tmp_path / 'run', shipped)
    assert not other['same_cpu'] and 'another CPU' in other['note']


def test_a_changed_perception_tensor_encoder_or_table_line_differs_from_the_shipped(tmp_path, capsys):
    run = shipped_run(tmp_path / 'mine')
    path = run / 'perception' / 'perception.pt'
    state = torch.load(path, weights_only=True)
    state['state_dict']['stem.0.weight'][0, 0, 0, 0] += 1e-6
    torch.save(state, path)
    q = run / 'questioner' / 'rl_anytime' / 'final.pt'
    state = torch.load(q, weights_only=True)
    name = sorted(state['visual'])[0]
    state['visual'][name] = state['visual'][name] + 1e-6
    torch.save(state, q)
    doc = run / 'results.md'
    lines = doc.read_text().splitlines()
    row = next(i for i, line in enumerate(lines) if line.startswith('| 2 | All QAs | valid_unseen'))
    lines[row] = lines[row].replace('| 2 | All QAs', '| 2 | All  QAs')
    doc.write_text('\n'.join(lines) + '\n')
    report = compare_runs.compare_with_shipped(run)
    models = report['weights']['models']
    assert models['perception'] == {'same': False, 'differing': ['state_dict'], 'first_tensors': ['stem.0.weight']}
    assert models['rl_anytime']['differing'] == ['visual'] and models['performer']['same']
    assert report['tables']['differing_lines'] == 1 and not report['same']
    assert compare_runs.main([str(run), '--shipped', '--parts', 'weights']) == 1
    capsys.readouterr()
    assert compare_runs.main([str(run), str(run), '--shipped']) == 2
    assert 'one of them' in capsys.readouterr().err
    assert compare_runs.main([str(run), '--shipped', '--parts', 'episodes']) == 2
    assert compare_runs.main([str(tmp_path / 'empty'), '--shipped']) == 2


def test_runs_given_by_absolute_paths_compare_as_their_documents_name_them(tmp_path, monkeypatch):
    """A document names its run folder relative to the repository (out/reproduce_b); the folders given as
    absolute paths still compare on the tables alone."""
    monkeypatch.setattr(compare_runs, 'REPO', tmp_path)
    a = make_run(tmp_path / 'out' / 'reproduce', tmp_path / 'cache_a')
    b = make_run(tmp_path / 'out' / 'reproduce_b', tmp_path / 'cache_b')
    for run in (a, b):
        doc = run / 'results.md'
        doc.write_text(doc.read_text().replace(str(run), str(run.relative_to(tmp_path))))
    assert 'out/reproduce_b/eval' in (b / 'results.md').read_text()
    assert compare_runs.compare(a.resolve(), b.resolve(), parts=('tables',))['tables']['same']
