"""`./dialfred reproduce --quick` (dialfred_bringup/reproduce/): the whole pipeline on tiny slices, in a
temporary run folder (each run from nothing takes about 3.5 minutes on a quiet 2-core machine, longer beside
other tests; two of them run here).

Claims: every stage runs (demos, performer, dialogues, frames, pretrain, rl, eval, check, doc) and writes
its stamp; the check stage plays a learned and a perturbed setting through the ROS graph and finds the
eval stage's (local) episodes; the document has Tables II, III and IV with every row, what holds, and the SR-NQ plot next to
it; the results record each episode's dialogue (question types); a rerun skips every stage (stamps
match); rerunning the doc stage alone writes the same bytes; the quick caches stay in the run folder;
a second run from nothing, in another folder with the same seed, gives the same tables and the same
weights of every model it trains, the same episodes and the same caches (`dialfred_bringup/compare_runs.py`).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

import dialfred_bringup.reproduce as reproduce
from dialfred_bringup.machine import speed_probe
from dialfred_sim.protocol import PAPER_QUESTION_TYPES

ROOT = Path(__file__).resolve().parents[2]
STAGES = reproduce.STAGES
# The first test builds the module's run (the fixture) and one test makes a second: each is a whole quick
# pipeline, longer than pytest.ini's 300 s bound for one test.
pytestmark = pytest.mark.timeout(1800)


def run(out: Path, *more: str) -> dict:
    done = subprocess.run([sys.executable, '-m', 'dialfred_bringup.reproduce', '--quick', '--out', str(out),
                           *more], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          timeout=1500)
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    summary['stderr'] = done.stderr
    return summary


@pytest.fixture(autouse=True)
def quick_speed_probe(monkeypatch):
    """The stages' speed probe (about half a second a call) as a stand-in that counts its calls, in this
    process; the probe itself is tested below, and the --quick runs in subprocesses use the real one."""
    from dialfred_bringup.reproduce import stages
    calls = []
    monkeypatch.setattr(stages, 'speed_probe', lambda: calls.append(1) or 0.05 + 0.01 * len(calls))
    return calls


def test_the_speed_probe_times_a_fixed_convolution():
    threads = torch.get_num_threads()
    assert 0 < speed_probe(repeats=1) < 10 and torch.get_num_threads() == threads     # threads restored


@pytest.fixture(scope='module')
def first(tmp_path_factory):
    out = tmp_path_factory.mktemp('reproduce') / 'run'
    return out, run(out)


@pytest.mark.slow   # the whole --quick pipeline (minutes); each stage has fast tests of its own
def test_every_stage_runs_and_stamps(first):
    out, summary = first
    assert list(summary['stages']) == list(STAGES)
    assert all(summary['stages'][s]['status'] == 'ran' for s in STAGES), summary['stages']
    for s in STAGES:
        stamp = json.loads((out / 'stamps' / f'{s}.json').read_text())
        assert stamp['status'] == 'done' and stamp['hash'] == summary['stages'][s]['hash']
        assert f'[reproduce] {s}: running' in summary['stderr']
    # the quick caches stay in the run folder
    assert (out / 'cache' / 'dialogues' / 'train.jsonl.gz').exists()
    assert (out / 'cache' / 'demonstrations' / 'train_64' / 'meta.json').exists()
    for name in reproduce.RL_RUNS:
        assert (out / 'questioner' / name / 'final.pt').exists()


@pytest.mark.slow   # the whole --quick pipeline (minutes); each stage has fast tests of its own
def test_the_check_stage_replays_a_learned_and_a_perturbed_setting_through_the_graph(first):
    out, summary = first
    report = json.loads((out / 'check' / 'report.json').read_text())
    assert report['eval_path'] == 'local' and report['tasks'] == 2
    assert set(report['settings']) == {'valid_seen/rl_begin', 'valid_unseen/rl_anytime_withhold_location'}
    assert all(r['episodes'] == 2 and r['differing'] == [] for r in report['settings'].values())
    assert summary['stages']['check']['report'] == {'episodes': 4, 'differing': 0}
    for name in ('valid_seen_rl_begin', 'valid_unseen_rl_anytime_withhold_location'):
        graph = (out / 'check' / f'{name}.summary.json').read_text()
        assert '"through": "performer node"' in graph
    assert '4 episodes: every one the same' in (out / 'results.md').read_text()


@pytest.mark.slow   # the whole --quick pipeline (minutes); each stage has fast tests of its own
def test_the_doc_has_every_table_row_and_the_plot(first):
    out, _ = first
    doc = (out / 'results.md').read_text()
    for title in ('## Table II', '## Table III', '## Table IV', '## What holds', '## Dialogues that turned'):
        assert title in doc
    for p in reproduce.PAPER_T2.values():
        for split in reproduce.SPLITS:
            assert f'| {p["number"]} | {p["name"]} | {split} | 8 |' in doc
    for name, *_ in reproduce.PAPER_T3.values():
        assert f'| {name} | 8 |' in doc
    for name, *_ in reproduce.PAPER_T4.values():
        assert f'| {name} | 8 |' in doc
    for name in reproduce.EXTRA.values():
        assert f'| {name} | 8 |' in doc
    assert '## Beyond the paper: the map-and-plan performer' in doc
    for name, *_ in reproduce.MAP_ROWS.values():
        assert f'\n| {name} | 8 |' in doc
    chained = doc[doc.index("## DialFRED's challenge test"):doc.index('## What RL optimizes')]
    rows = [line for line in chained.splitlines() if line.startswith(('| Episodic Transformer |', '| map-and-plan |'))]
    assert len([r for r in rows if r.split(' | ')[2] == '8']) == len(reproduce.chained_settings())
    assert '| overall |' in chained                                   # the tasks lost to chaining, per type
    assert 'no results' not in doc and 'not recorded' not in doc
    assert doc.count('**holds**') + doc.count('**does not hold**') >= 8
    png = out / 'sr_nq.png'
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and png.stat().st_size > 2000


@pytest.mark.slow   # the whole --quick pipeline (minutes); each stage has fast tests of its own
def test_results_record_the_questions_asked(first):
    out, _ = first
    lines = [json.loads(l) for l in (out / 'eval' / 'valid_unseen_all_qas.jsonl').read_text().splitlines()]
    assert all(len(l['dialogue']) == l['questions'] for l in lines)
    assert {qa['type'] for l in lines for qa in l['dialogue']} <= {'location', 'appearance', 'direction'}


@pytest.mark.slow   # the whole --quick pipeline (minutes); each stage has fast tests of its own
def test_a_rerun_skips_every_stage_and_the_doc_stage_writes_the_same_bytes(first):
    out, _ = first
    before = (out / 'results.md').read_bytes()
    again = run(out)
    assert all(again['stages'][s]['status'] == 'skipped' for s in STAGES), again['stages']
    assert all(f'[reproduce] {s}: skipped (stamp matches' in again['stderr'] for s in STAGES)
    forced = run(out, '--force', 'doc')
    assert forced['stages']['doc']['status'] == 'ran'
    assert all(forced['stages'][s]['status'] == 'skipped' for s in STAGES[:-1])
    assert (out / 'results.md').read_bytes() == before
    stamps = {p.name: p.read_bytes() for p in (out / 'stamps').glob('*.json')}
    (out / 'results.md').unlink()
    done = subprocess.run([sys.executable, '-m', 'dialfred_bringup.reproduce', '--quick', '--out', str(out), '--redoc'],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (out / 'results.md').read_bytes() == before          # the same document, from the results alone
    assert {p.name: p.read_bytes() for p in (out / 'stamps').glob('*.json')} == stamps   # no stage ran


@pytest.mark.slow   # the whole --quick pipeline (minutes); each stage has fast tests of its own
def test_a_second_run_with_the_same_seed_gives_the_same_tables_and_weights(first, tmp_path):
    import dialfred_bringup.compare_runs as compare_runs
    out, _ = first
    other = tmp_path / 'again'
    run(other)
    # dialfred_bringup/compare_runs.py: the tables (Table II to the run times, run folders taken out), every
    # episode of eval/ and check/ (wall time and the agent's checkpoint-file name aside), the weights of
    # every model trained, and the caches (the quick run keeps its own, in its folder)
    report = compare_runs.compare(out, other, parts=compare_runs.PARTS)
    assert report['same'], json.dumps(report, indent=1)[:3000]
    assert set(report['weights']['models']) == {'perception', 'performer', 'pretrain', *reproduce.RL_RUNS}
    assert report['episodes']['episodes'] > 0 and report['tables']['lines'] > 20
    assert all(c['same'] for c in report['caches']['caches'].values())
    # the doc names the performer by its weights, so both docs name the same one
    digest = [[l for l in (run_dir / 'results.md').read_text().splitlines() if 'weights sha256' in l][0].split('`')[3]
              for run_dir in (out, other)]
    assert digest[0] == digest[1] == reproduce.weights_sha256(out / 'performer' / 'best.pt')[:16]


@pytest.mark.slow   # the whole --quick pipeline (minutes); each stage has fast tests of its own
def test_a_runs_models_are_shipped_with_the_frame_encoder_kept_once(first, tmp_path):
    from dialfred_bringup.reproduce.ship import ShipConfig, ship
    from dialfred_questioner.policy import LearnedQuestioner
    run = first[0]
    with pytest.raises(ValueError, match='quick run'):
        ship(ShipConfig(run=str(run)))                        # never over the package's checkpoints
    report = ship(ShipConfig(run=str(run), into=str(tmp_path / 'ship')))
    assert len(report['files']) == 1 + 1 + len(reproduce.RL_RUNS)
    times = json.loads((tmp_path / 'ship' / 'shipped_run.json').read_text())['stages']
    # every finished stage's time (the training stages' for --shipped documents, all for --status's estimate)
    assert set(times) == set(STAGES[:-1])
    full = run / 'questioner' / 'rl_anytime' / 'final.pt'
    shipped = tmp_path / 'ship' / 'rl_anytime.pt'
    assert shipped.stat().st_size < full.stat().st_size
    assert LearnedQuestioner.from_checkpoint(shipped).visual.state_dict().keys() == \
        LearnedQuestioner.from_checkpoint(full).visual.state_dict().keys()
    (run / 'stamps' / 'rl.json').rename(run / 'stamps' / 'rl.json.away')
    try:
        with pytest.raises(ValueError, match='rl stage has no stamp'):
            ship(ShipConfig(run=str(run), into=str(tmp_path / 'again')))
        assert not (tmp_path / 'again').exists()
    finally:
        (run / 'stamps' / 'rl.json.away').rename(run / 'stamps' / 'rl.json')


def test_the_weights_digest_reads_tensors_not_provenance(tmp_path):
    import torch
    state = {'b.weight': torch.arange(6, dtype=torch.float32).reshape(2, 3), 'a.bias': torch.ones(3, dtype=torch.bfloat16),
             'steps': torch.tensor(7)}
    torch.save({'state_dict': state, 'command': 'run A', 'git_commit': 'aaa'}, tmp_path / 'a.pt')
    torch.save({'state_dict': dict(reversed(state.items())), 'command': 'run B', 'git_commit': 'bbb'}, tmp_path / 'b.pt')
    assert reproduce.weights_sha256(tmp_path / 'a.pt') == reproduce.weights_sha256(tmp_path / 'b.pt')
    changed = dict(state, **{'b.weight': state['b.weight'].clone()})
    changed['b.weight'][1, 2] = torch.nextafter(changed['b.weight'][1, 2], torch.tensor(99.0))
    torch.save({'state_dict': changed}, tmp_path / 'c.pt')
    assert reproduce.weights_sha256(tmp_path / 'c.pt') != reproduce.weights_sha256(tmp_path / 'a.pt')
    reshaped = dict(state, **{'b.weight': state['b.weight'].reshape(3, 2)})
    torch.save({'state_dict': reshaped}, tmp_path / 'd.pt')
    assert reproduce.weights_sha256(tmp_path / 'd.pt') != reproduce.weights_sha256(tmp_path / 'a.pt')
    (tmp_path / 'e.pt').write_bytes(b'not a checkpoint')
    with pytest.raises(ValueError, match='not a checkpoint'):
        reproduce.weights_sha256(tmp_path / 'e.pt')


def test_the_map_performers_settings_play_the_map_model_with_its_own_rl_questioner():
    plan = reproduce.Plan(reproduce.ReproduceConfig(out='/tmp/unused-run'))
    mapped = {s.key: s for s in reproduce.settings() if s.performer == 'map'}
    assert set(mapped) == set(reproduce.MAP_ROWS) and all(s.split == 'valid_unseen' for s in mapped.values())
    assert reproduce.RL_RUNS['map_rl_anytime']['model'] == 'map'
    local = plan.eval_config(mapped['map_rl_anytime'])
    assert local.agent == 'map' and local.questioner.endswith('map_rl_anytime/final.pt')
    graph = plan.eval_config(mapped['map_all_qas'], check=True)
    assert graph.performer == 'map' and graph.questioner == 'all'
    assert plan.eval_config(reproduce.settings()[0]).agent == 'et'
    # each performer plays at its own camera, in the evaluations, the graph check and the RL run
    assert local.resolution == graph.resolution == plan.rl_config('map_rl_anytime')['resolution'] == 128
    assert plan.eval_config(reproduce.settings()[0]).resolution == plan.rl_config('rl_anytime')['resolution'] == 64


def test_bad_settings_are_refused():
    with pytest.raises(ValueError):
        reproduce.ReproduceConfig(force='nope')
    with pytest.raises(ValueError):
        reproduce.ReproduceConfig(quick=True, shipped=True)
    with pytest.raises(ValueError, match='eval-path'):
        reproduce.ReproduceConfig(eval_path='ros')
    with pytest.raises(ValueError, match='check-tasks'):
        reproduce.ReproduceConfig(check_tasks=-1)


def test_a_stage_skipped_after_the_simulators_rules_changed_says_so(tmp_path, monkeypatch, capsys):
    from dialfred_bringup.reproduce import stages
    runner = reproduce.Runner(reproduce.ReproduceConfig(quick=True, out=str(tmp_path / 'run')))
    monkeypatch.setattr(runner, 'stage_inputs', lambda stage, raw=False: {'x': 1})
    runner.run_stage('frames', lambda resume: {}, [])
    assert json.loads((tmp_path / 'run' / 'stamps' / 'frames.json').read_text())['world_code'] == stages.world_code_hash()
    runner.run_stage('frames', lambda resume: pytest.fail('rerun'), [])
    assert 'warning' not in capsys.readouterr().err
    monkeypatch.setattr(stages, 'world_code_hash', lambda raw=False: 'another')
    runner.run_stage('frames', lambda resume: pytest.fail('rerun'), [])      # still skipped, with a warning
    assert "frames: warning: the simulator's rules" in capsys.readouterr().err


def test_the_code_hash_reads_what_python_does_not_how_it_is_written(tmp_path, monkeypatch):
    from dialfred_bringup.reproduce import stages
    monkeypatch.setattr(stages, 'REPO', tmp_path)
    f = tmp_path / 'm.py'

    def hashed(text):
        f.write_text(text)
        return stages.code_hash(('m.py',)), stages.code_hash(('m.py',), raw=True)

    base, base_raw = hashed('def f(x):\n    return x + 1\n')
    assert hashed('"""A module."""\n\n\ndef f(x):   # one more\n    """One more."""\n    return (x +\n            1)\n')[0] == base
    edited, edited_raw = hashed('def f(x):\n    return x + 2\n')
    assert edited != base and edited_raw != base_raw
    assert hashed('def f(x):\n    """Only a docstring."""\n')[0] == hashed('def f(x):\n    pass\n')[0]
    assert hashed('def f(x):\n    return x + 1\n') == (base, base_raw)
    f.write_text('def f(:\n')                              # not Python: its bytes
    assert stages.code_hash(('m.py',)) == stages.code_hash(('m.py',), raw=True)


def test_stamps_made_with_the_byte_hash_of_the_same_code_still_match(tmp_path, monkeypatch):
    from dialfred_bringup.reproduce import stages
    runner = reproduce.Runner(reproduce.ReproduceConfig(quick=True, out=str(tmp_path / 'run')))
    monkeypatch.setattr(stages, 'code_hash', lambda paths, raw=False: 'bytes')    # as stamps were made before
    runner.run_stage('frames', lambda resume: {}, [])
    assert runner.run_item('rl', 'a', {'lr': 1}, ('x.py',), [tmp_path / 'a'], lambda resume: {})['reused'] is False
    made = json.loads((tmp_path / 'run' / 'stamps' / 'frames.json').read_text())['hash']
    monkeypatch.setattr(stages, 'code_hash', lambda paths, raw=False: 'bytes' if raw else 'meaning')
    runner.run_stage('frames', lambda resume: pytest.fail('rerun'), [])          # matched by its byte hash
    assert runner.hashes['frames'] == made
    assert runner.run_item('rl', 'a', {'lr': 1}, ('x.py',), [tmp_path / 'a'], lambda resume: {})['reused'] is True
    monkeypatch.setattr(stages, 'code_hash', lambda paths, raw=False: 'new bytes' if raw else 'new meaning')
    ran = []
    runner.run_stage('frames', lambda resume: ran.append(resume), [])             # the code changed: rerun
    assert ran == [False] and runner.hashes['frames'] != made


def test_a_resumed_stage_counts_the_time_of_its_cut_off_run(tmp_path, monkeypatch):
    runner = reproduce.Runner(reproduce.ReproduceConfig(quick=True, out=str(tmp_path / 'run')))
    monkeypatch.setattr(runner, 'stage_inputs', lambda stage, raw=False: {'x': 1})
    out = tmp_path / 'run' / 'outputs'

    def cut_off(resume):
        out.mkdir(parents=True, exist_ok=True)
        (out / 'a').write_text('half')
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        runner.run_stage('frames', cut_off, [out])
    stamp = json.loads((tmp_path / 'run' / 'stamps' / 'frames.json').read_text())
    stamp['started_at'] -= 30.0                    # the cut-off run began 30 s before its last write
    (tmp_path / 'run' / 'stamps' / 'frames.json').write_text(json.dumps(stamp))
    runner.run_stage('frames', lambda resume: {'resumed': resume}, [out])
    done = json.loads((tmp_path / 'run' / 'stamps' / 'frames.json').read_text())
    assert done['runs'] == 2 and done['report'] == {'resumed': True}
    assert 30.0 <= done['seconds'] < 40.0 and done['seconds_this_run'] < 5.0
    # the machine's speed at the start of each run and at the end: the cut-off run's start kept
    assert done['speed_probe_s'] == pytest.approx([0.06, 0.07, 0.08])


def test_a_cache_stage_is_timed_by_the_files_it_writes_and_never_cleared(tmp_path, monkeypatch):
    runner = reproduce.Runner(reproduce.ReproduceConfig(quick=True, out=str(tmp_path / 'run')))
    assert runner.plan.stage_outputs('demos') == [runner.plan.demos] and runner.plan.stage_outputs('frames') == [runner.plan.frames]
    assert runner.plan.stage_outputs('dialogues') == [runner.plan.dialogue_dir / 'train.jsonl.gz']
    inputs = {'x': 1}
    monkeypatch.setattr(runner, 'stage_inputs', lambda stage, raw=False: dict(inputs))
    demos = runner.plan.demos

    def cut_off(resume):
        demos.mkdir(parents=True)
        (demos / 'frames.npy').write_text('half')
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        runner.run_stage('demos', cut_off, runner.plan.stage_outputs('demos'))
    stamp_path = tmp_path / 'run' / 'stamps' / 'demos.json'
    stamp = json.loads(stamp_path.read_text())
    stamp['started_at'] -= 30.0
    stamp_path.write_text(json.dumps(stamp))
    runner.run_stage('demos', lambda resume: {'resumed': resume}, runner.plan.stage_outputs('demos'))
    done = json.loads(stamp_path.read_text())
    assert done['runs'] == 2 and done['report'] == {'resumed': True} and done['seconds'] >= 30.0
    inputs['x'] = 2                                             # new inputs: rewritten in place, not cleared
    runner.run_stage('demos', lambda resume: {'resumed': resume}, runner.plan.stage_outputs('demos'))
    assert (demos / 'frames.npy').read_text() == 'half'


def test_the_frontier_plot_fits_its_legend_however_long_the_labels(tmp_path):
    from PIL import Image
    points = [(f'a setting with a rather long name number {k}', 10.0 + k, 0.2 * k) for k in range(24)]
    path = reproduce.draw_frontier(points, tmp_path / 'f.png')
    image = Image.open(path)
    assert image.size[1] >= 14 * 24 + 40
    import numpy as np
    edge = np.asarray(image.crop((image.size[0] - 16, 0, image.size[0], image.size[1])).convert('L'))
    assert edge.min() == 255                                 # nothing drawn in the last 16 px: no cut-off text
    legend_marks = np.asarray(image.convert('RGB'))[:, -int(image.size[0] - 520) - 1:, :]
    assert legend_marks.shape[1] > 300                       # the legend area grew with the longest label


def test_why_lines_price_a_question_and_read_the_sampled_mixes(tmp_path):
    """Synthetic rows and training logs: the worth of a question against the rewards' price of 5 SR points,
    the sampled mix of the last updates beside the greedy shares, and repeats under withheld answers."""
    def row(sr, nq, ret=0.0, shares=None, repeats=0.0):
        return {'n': 100, 'SR': sr, 'NQ': nq, 'return': ret, 'shares': shares, 'repeats': repeats}
    rows = {}
    for split in reproduce.SPLITS:
        rows[(split, 'instruction_only')] = row(20.0, 0.0, 0.1)
        rows[(split, 'all_qas')] = row(28.0, 4.0, 0.0)          # 2 points per question: below the price of 5
        rows[(split, 'pretrained')] = row(26.0, 0.5, 0.15)      # 12 points per question
    rows[('valid_unseen', 'rl_anytime')] = row(24.0, 0.3, shares={'location': 1.0, 'appearance': 0.0, 'direction': 0.0},
                                               repeats=0.01)
    rows[('valid_unseen', 'rl_anytime_withhold_location')] = row(22.0, 0.6, repeats=0.2)
    run = tmp_path / 'run'
    for name, mixes in (('rl_anytime', [(0.9, 0.1, 0.0)] * 10), ('rl_anytime_withhold_location', [(0.6, 0.3, 0.1)] * 10)):
        (run / 'questioner' / name).mkdir(parents=True)
        (run / 'questioner' / name / 'metrics.jsonl').write_text(''.join(
            json.dumps({'update': i, 'episodes': 64, 'nq': 1.0, 'mix': dict(zip(PAPER_QUESTION_TYPES, m))}) + '\n'
            for i, m in enumerate(mixes)))
    plan = reproduce.Plan(reproduce.ReproduceConfig(out=str(run)))
    lines = reproduce.why_lines(plan, rows)
    assert len(lines) == 4, lines
    assert '2.0 points per question' in lines[0] and 'more than 5.0 SR points' in lines[0] and 'loses return' in lines[0]
    assert 'buy 12.0 points each' in lines[0] and 'learns to ask few questions' in lines[0]
    assert 'greedy shares on valid_unseen are 1.00 / 0.00 / 0.00' in lines[2]
    assert 'it asked 0.90 / 0.10 / 0.00' in lines[2] and 'location withheld: 0.60 / 0.30 / 0.10 (its location share -0.30)' in lines[2]
    assert 'asks 0.60 questions per episode against 0.30' in lines[3] and 'until it is answered' in lines[3]
    rows[('valid_seen', 'all_qas')] = row(60.0, 4.0)            # 10 points per question: asking pays
    assert 'worth their price' in reproduce.why_lines(plan, rows)[0]
    shipped = reproduce.Plan(reproduce.ReproduceConfig(shipped=True))
    assert 'no sampled mixes' in reproduce.why_lines(shipped, rows)[2]


def test_a_doc_of_another_name_gets_its_own_plot(tmp_path):
    run, docs = tmp_path / 'run', tmp_path / 'docs'
    run.mkdir()
    docs.mkdir()
    (run / 'results.md').write_text('# Results\n\n![SR against NQ](sr_nq.png)\n')
    (run / 'sr_nq.png').write_bytes(b'png')
    reproduce.copy_doc(run, docs / 'results.md')
    reproduce.copy_doc(run, docs / 'results_shipped.md')
    assert (docs / 'results.md').read_text() == (run / 'results.md').read_text()
    assert '![SR against NQ](results_shipped_sr_nq.png)' in (docs / 'results_shipped.md').read_text()
    assert (docs / 'sr_nq.png').read_bytes() == (docs / 'results_shipped_sr_nq.png').read_bytes() == b'png'


def test_where_the_document_is_copied():
    docs = ROOT / 'docs'
    assert reproduce.ReproduceConfig().doc_target == docs / 'results.md'
    assert reproduce.ReproduceConfig(shipped=True).doc_target is None                     # the shipped ones are a full run's
    assert reproduce.ReproduceConfig(quick=True).doc_target is None
    assert reproduce.ReproduceConfig(out='out/reproduce_b').doc_target is None           # a second run
    assert reproduce.ReproduceConfig(out='out/reproduce_b', doc='x/r.md').doc_target == ROOT / 'x' / 'r.md'
    assert reproduce.ReproduceConfig(doc='none').doc_target is None


def test_the_full_runs_perception_recipe_is_the_network_the_shipped_performer_carries():
    from dialfred_performer.model import SHIPPED_CHECKPOINT, load_checkpoint
    from dialfred_performer.perception import PerceptionConfig
    shipped = load_checkpoint(SHIPPED_CHECKPOINT)[0].visual.net.config
    planned = PerceptionConfig(**reproduce.Plan(reproduce.ReproduceConfig()).perception_config())
    for field in ('c1', 'c2', 'c3', 'decoder'):
        assert getattr(planned, field) == getattr(shipped, field), field
    assert shipped.resolution == reproduce.plan.camera('et') == 64
    assert (planned.frames, planned.small_objects, planned.seed) == (400_000, 0.5, 0)


def test_the_rl_and_eval_stages_rerun_when_the_perception_code_changes():
    from dialfred_bringup.reproduce.stages import CODE
    for stage in ('rl', 'eval'):
        assert {'src/dialfred_performer/dialfred_performer/perception.py',
                'src/dialfred_performer/dialfred_performer/preprocess.py'} <= set(CODE[stage])


def package_closure(entries: tuple[str, ...], package: str) -> set:
    """The files of `package` that these files import, directly or through one another (any import
    statement, in a function too), as repository paths."""
    import ast
    from dialfred_bringup.paths import REPO
    root = f'src/{package}/{package}'
    todo, seen = list(entries), set()
    while todo:
        rel = todo.pop()
        if rel in seen or not (REPO / rel).exists():
            continue
        seen.add(rel)
        for node in ast.walk(ast.parse((REPO / rel).read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 1 and rel.startswith(root):
                todo.append(f'{root}/{node.module}.py')
            elif isinstance(node, ast.ImportFrom) and (node.module or '').startswith(f'{package}.'):
                todo.append(f'{root}/{node.module.split(".", 1)[1].replace(".", "/")}.py')
    return {rel for rel in seen if rel.startswith(root)}


def test_the_rl_and_eval_stages_hash_every_questioner_module_they_run():
    from dialfred_bringup.reproduce.stages import CODE
    ques = 'src/dialfred_questioner/dialfred_questioner'
    assert package_closure((f'{ques}/finetune.py',), 'dialfred_questioner') <= set(CODE['rl'])
    assert package_closure((f'{ques}/questioners.py',), 'dialfred_questioner') <= set(CODE['eval'])


def test_an_itemized_stage_reruns_only_the_items_whose_inputs_changed(tmp_path):
    runner = reproduce.Runner(reproduce.ReproduceConfig(quick=True, out=str(tmp_path / 'run')))
    ran = []
    code = ('pyproject.toml',)

    def item(name, inputs, fail=False):
        out = tmp_path / name
        def action(resume):
            ran.append((name, resume))
            out.mkdir(exist_ok=True)
            if fail:
                time.sleep(0.3)                                     # the cut-off run's time, up to its last output
            (out / 'part').write_text('x')
            if fail:
                raise KeyboardInterrupt
            return {'made': name}
        return runner.run_item('rl', name, inputs, code, [out], action)

    assert item('a', {'lr': 1})['reused'] is False and item('b', {'lr': 1})['reused'] is False
    again = item('a', {'lr': 1})
    assert again['reused'] is True and again['made'] == 'a' and ran == [('a', False), ('b', False)]
    (tmp_path / 'b' / 'stale').write_text('old')
    assert item('b', {'lr': 2})['reused'] is False              # its inputs changed: set aside and rerun
    assert not (tmp_path / 'b' / 'stale').exists() and ran[-1] == ('b', False)
    kept = tmp_path / 'run' / 'replaced' / 'rl' / 'b' / 'b'      # the finished run's outputs, until the next change
    assert (kept / 'stale').read_text() == 'old' and (kept / 'part').exists()
    assert item('b', {'lr': 3})['reused'] is False and not (kept / 'stale').exists() and (kept / 'part').exists()
    with pytest.raises(KeyboardInterrupt):
        item('c', {'lr': 1}, fail=True)
    resumed = item('c', {'lr': 1})
    assert resumed['reused'] is False and ran[-1] == ('c', True)   # cut off: resumed, not cleared
    with pytest.raises(KeyboardInterrupt):
        item('d', {'lr': 1}, fail=True)
    item('d', {'lr': 2})                                        # cut off, then other inputs: cleared, not kept
    assert not (tmp_path / 'run' / 'replaced' / 'rl' / 'd').exists()
    stamp = json.loads((tmp_path / 'run' / 'stamps' / 'rl' / 'c.json').read_text())
    assert stamp['runs'] == 2 and stamp['seconds'] >= 0.3 > stamp['seconds_this_run']   # the cut-off run counts
    assert resumed['seconds'] == stamp['seconds']
    code = ('pyproject.toml', 'README.md')                      # its code changed: rerun
    assert item('a', {'lr': 1})['reused'] is False and ran[-1] == ('a', False)


def test_the_map_performers_code_reruns_only_its_own_items():
    from dialfred_bringup.reproduce.stages import CODE, MODEL_CODE
    mapper = 'src/dialfred_performer/dialfred_performer/mapper/agent.py'
    assert mapper in MODEL_CODE['map'] and mapper not in MODEL_CODE['et']
    assert set(MODEL_CODE['et']) < set(MODEL_CODE['map'])
    for stage in ('rl', 'eval'):
        assert set(MODEL_CODE['map']) <= set(CODE[stage])


def test_the_run_times_count_the_reused_items_time(tmp_path):
    from dialfred_bringup.reproduce.document import run_times
    plan = reproduce.Plan(reproduce.ReproduceConfig(quick=True, out=str(tmp_path / 'run')))
    stamps = tmp_path / 'run' / 'stamps'
    stamps.mkdir(parents=True)
    (stamps / 'perception.json').write_text(json.dumps({'seconds': 100.0}))
    (stamps / 'rl.json').write_text(json.dumps({'seconds': 50.0, 'report': {'items': {
        'a': {'seconds': 40.0, 'reused': False}, 'b': {'seconds': 300.0, 'reused': True}}}}))
    times = run_times(plan)
    assert 'perception: 100 s' in times
    assert 'rl: 340 s (1 of its 2 items done by an earlier run of the same inputs, their time included)' in times
    # a resumed stage: the items it reuses ran in its own cut-off run, whose time its seconds already hold
    (stamps / 'rl.json').write_text(json.dumps({'seconds': 400.0, 'runs': 2, 'report': {'items': {
        'a': {'seconds': 40.0, 'reused': False}, 'b': {'seconds': 300.0, 'reused': True}}}}))
    assert 'rl: 340 s (over 2 runs: it was resumed; 1 of its 2 items' in '\n'.join(run_times(plan))
    assert 'demos: not run here' in times and times[-1] == 'total of the stages: 7.3 min'
    # the machine's speed probes beside a stage's time, and what they are
    (stamps / 'perception.json').write_text(json.dumps({'seconds': 100.0, 'speed_probe_s': [0.0212, 0.0405, 0.0233]}))
    times = run_times(plan)
    assert 'perception: 100 s (speed probe 21.2-40.5 ms)' in times and times[-1].startswith('speed probe: a fixed')


def test_the_shipped_runs_document_gives_the_training_times_of_the_run_that_made_the_models(tmp_path, monkeypatch):
    from dialfred_bringup.reproduce import document
    from dialfred_bringup.reproduce.document import run_times, stage_times
    made = tmp_path / 'made' / 'stamps'
    made.mkdir(parents=True)
    (made / 'performer.json').write_text(json.dumps({'seconds': 2900.0, 'runs': 2, 'machine': {'cpu': 'AMD EPYC'}}))
    (made / 'rl.json').write_text(json.dumps({'seconds': 1.0, 'report': {'items': {'a': {'seconds': 600.0}}}}))
    (made / 'eval.json').write_text(json.dumps({'seconds': 3000.0}))
    times = stage_times(tmp_path / 'made')
    assert times['performer']['seconds'] == 2900.0 and times['rl']['seconds'] == 600.0 and 'demos' not in times
    record = tmp_path / 'shipped_run.json'
    record.write_text(json.dumps({'stages': {k: v for k, v in times.items() if k != 'eval'}}))
    monkeypatch.setattr(document, 'SHIPPED_RUN', record)
    plan = reproduce.Plan(reproduce.ReproduceConfig(shipped=True, out=str(tmp_path / 'run')))
    (tmp_path / 'run' / 'stamps').mkdir(parents=True)
    (tmp_path / 'run' / 'stamps' / 'eval.json').write_text(json.dumps({'seconds': 1200.0}))
    lines = run_times(plan)
    assert 'performer: not run here (shipped; 2900 s in the run that made them, on AMD EPYC)' in lines
    assert 'demos: not run here (shipped)' in lines and 'eval: 1200 s' in lines
    assert lines[-2:] == ['total of the stages: 20.0 min', "with the shipped models' training stages: 78.3 min"]


def test_the_status_of_a_run_reads_its_stamps_and_runs_nothing(tmp_path):
    from dialfred_bringup.reproduce.status import run_status, status_lines
    stamps = tmp_path / 'run' / 'stamps'
    (stamps / 'rl').mkdir(parents=True)
    (stamps / 'perception.json').write_text(json.dumps({'status': 'done', 'seconds': 600.0}))
    (stamps / 'performer.json').write_text(json.dumps({'status': 'done', 'seconds': 1200.0, 'runs': 2}))
    (stamps / 'rl.json').write_text(json.dumps({'status': 'running', 'started_at': 1000.0, 'seconds_before': 60.0,
                                                'runs': 2}))
    (stamps / 'rl' / 'rl_begin.json').write_text(json.dumps({'status': 'done', 'seconds': 300.0}))
    (stamps / 'rl' / 'rl_anytime.json').write_text(json.dumps({'status': 'running', 'seconds_before': 10.0}))
    times = tmp_path / 'shipped_run.json'
    times.write_text(json.dumps({'stages': {'demos': {'seconds': 100.0}, 'rl': {'seconds': 3600.0},
                                            'perception': {'seconds': 500.0}}}))
    status = run_status(tmp_path / 'run', now=1240.0, shipped_run=times)
    rows = status['stages']
    assert rows['perception'] == {'status': 'done', 'seconds': 600.0, 'runs': 1}
    assert rows['rl']['status'] == 'running' and rows['rl']['seconds'] == 300.0 and rows['rl']['runs'] == 2
    assert rows['rl']['items'] == {'rl_anytime': {'status': 'running', 'seconds': 10.0},
                                   'rl_begin': {'status': 'done', 'seconds': 300.0}}
    assert rows['eval'] == {'status': 'not started'}
    assert status['left_s'] == 100.0 + 3300.0               # demos not started, rl 300 s of 3600 in
    text = '\n'.join(status_lines(status))
    assert '1 items done, rl_anytime running or cut off' in text and 'about 57 min' in text
    shipped = run_status(tmp_path / 'run', shipped=True, now=1240.0, shipped_run=times)
    assert shipped['stages']['performer'] == {'status': 'shipped'} and shipped['left_s'] is None
    assert not (tmp_path / 'run' / 'results.md').exists()


def test_a_running_stage_says_how_far_it_has_come_and_how_long_it_has_left(tmp_path):
    from dialfred_bringup.reproduce.status import run_status, status_lines
    run = tmp_path / 'run'
    stamps, perf, rl_a, rl_b = run / 'stamps', run / 'performer', run / 'questioner' / 'a', run / 'questioner' / 'b'
    for folder in (stamps, perf, rl_a, rl_b, run / 'eval'):
        folder.mkdir(parents=True)
    (stamps / 'performer.json').write_text(json.dumps({
        'status': 'running', 'started_at': 1000.0, 'seconds_before': 200.0,
        'inputs': {'config': {'out': str(perf), 'max_updates': 1000}}}))
    # a validation line after the last train line, and a torn line being written
    perf.joinpath('metrics.jsonl').write_text('{"kind": "train", "update": 100}\n{"kind": "train", "update": 250}\n'
                                              '{"kind": "val", "loss": 1.0}\n{"kind": "train", "upd')
    # two RL runs of 32 updates: one finished, one half way (48 of 64 in all)
    (stamps / 'rl.json').write_text(json.dumps({'status': 'running', 'started_at': 1000.0, 'inputs': {'config': {
        'a': {'out': str(rl_a), 'updates': 32}, 'b': {'out': str(rl_b), 'updates': 32}}}}))
    rl_a.joinpath('metrics.jsonl').write_text(''.join(json.dumps({'update': u}) + '\n' for u in range(1, 33)))
    rl_b.joinpath('metrics.jsonl').write_text(json.dumps({'update': 16}) + '\n')
    # eval: 2 settings of valid_seen's 1296 tasks (limit 0: all), 648 episodes played in all
    (stamps / 'eval.json').write_text(json.dumps({'status': 'running', 'started_at': 1000.0, 'inputs': {'config': {
        'limit': 0, 'settings': [{'split': 'valid_seen', 'key': 'x'}, {'split': 'valid_seen', 'key': 'y'}]}}}))
    (run / 'eval' / 'valid_seen_x.jsonl').write_text('{}\n' * 648)
    times = tmp_path / 'shipped_run.json'
    times.write_text(json.dumps({'stages': {'performer': {'seconds': 9000.0}, 'rl': {'seconds': 9000.0},
                                            'eval': {'seconds': 9000.0}}}))
    status = run_status(run, now=1100.0, shipped_run=times)
    rows = status['stages']
    # 300 s for a quarter of the updates: 900 s more at that rate, not the shipped run's 9000 - 300
    assert rows['performer']['progress'] == {'done': 250, 'total': 1000, 'unit': 'updates', 'left_s': 900.0}
    assert rows['rl']['progress'] == {'done': 48, 'total': 64, 'unit': 'RL updates', 'left_s': 33.3}
    assert rows['eval']['progress'] == {'done': 648, 'total': 2592, 'unit': 'episodes', 'left_s': 300.0}
    assert status['left_s'] == 900.0 + 33.3 + 300.0
    text = '\n'.join(status_lines(status))
    assert '250 of 1,000 updates (25%), about 15 min more at its rate so far' in text
    assert '648 of 2,592 episodes (25%), about 5 min more' in text
    # nothing written yet: 0 of the total, and no estimate of its own (the shipped run's time stands)
    perf.joinpath('metrics.jsonl').unlink()
    early = run_status(run, now=1100.0, shipped_run=times)
    assert early['stages']['performer']['progress'] == {'done': 0, 'total': 1000, 'unit': 'updates'}
    assert early['left_s'] == 9000.0 - 300.0 + 33.3 + 300.0


def test_the_status_marks_a_done_stage_stale_when_a_run_would_redo_it(tmp_path):
    from dialfred_bringup.reproduce.status import run_status, status_lines
    from dialfred_sim.dataclass_cli import parse
    cfg = parse(reproduce.ReproduceConfig, ['--quick', '--out', str(tmp_path / 'run')])
    planned = reproduce.Runner(cfg).planned_hashes()
    assert set(planned) == set(STAGES)
    stamps = tmp_path / 'run' / 'stamps'
    stamps.mkdir(parents=True)
    for stage in STAGES:
        (stamps / f'{stage}.json').write_text(json.dumps({'status': 'done', 'hash': planned[stage], 'seconds': 60.0}))
    assert reproduce.Runner(cfg).planned_hashes() == planned          # computing them wrote nothing
    status = run_status(tmp_path / 'run', planned=planned, shipped_run=tmp_path / 'none.json')
    assert {row['status'] for row in status['stages'].values()} == {'done'}
    (stamps / 'performer.json').write_text(json.dumps({'status': 'done', 'hash': 'made by other code', 'seconds': 60.0}))
    # another seed changes the inputs of the stages that read it, and through their hashes every stage after
    other = reproduce.Runner(parse(reproduce.ReproduceConfig, ['--quick', '--out', str(tmp_path / 'run'),
                                                               '--seed', '1'])).planned_hashes()
    status = run_status(tmp_path / 'run', planned=planned, shipped_run=tmp_path / 'none.json')
    assert [s for s, row in status['stages'].items() if row['status'] == 'stale'] == ['performer']
    assert 'a run redoes it' in '\n'.join(status_lines(status))
    moved = [s for s in STAGES if other[s] != planned[s]]
    assert moved == [s for s in STAGES if s not in ('demos', 'dialogues', 'frames')]   # the caches are not seeded
    assert sorted(p.name for p in stamps.iterdir()) == sorted(f'{s}.json' for s in STAGES)


def test_the_shipped_record_holds_every_finished_stage_so_status_counts_the_evaluations_left(tmp_path):
    from dialfred_bringup.reproduce.ship import finished_times
    from dialfred_bringup.reproduce.status import run_status
    made = tmp_path / 'made' / 'stamps'
    made.mkdir(parents=True)
    for stage, seconds in (('perception', 600.0), ('performer', 1200.0), ('eval', 900.0)):
        (made / f'{stage}.json').write_text(json.dumps({'status': 'done', 'seconds': seconds}))
    (made / 'check.json').write_text(json.dumps({'status': 'running', 'started_at': 0.0, 'seconds_before': 50.0}))
    (made / 'rl.json').write_text('{"status": "do')                     # torn: not a finished stage
    record = finished_times(tmp_path / 'made')
    assert set(record) == {'perception', 'performer', 'eval'} and record['eval']['seconds'] == 900.0
    times = tmp_path / 'shipped_run.json'
    times.write_text(json.dumps({'stages': record}))
    stamps = tmp_path / 'run' / 'stamps'
    stamps.mkdir(parents=True)
    (stamps / 'perception.json').write_text(json.dumps({'status': 'done', 'seconds': 500.0}))
    status = run_status(tmp_path / 'run', now=0.0, shipped_run=times)
    assert status['left_s'] == 1200.0 + 900.0       # the performer and the evaluations still to run


def test_redoc_refuses_a_run_without_results_and_writes_nothing(tmp_path, capsys):
    assert reproduce.main(['--out', str(tmp_path / 'run'), '--redoc']) == 2
    assert 'no results files' in capsys.readouterr().err
    assert not (tmp_path / 'run' / 'results.md').exists() and not (tmp_path / 'run' / 'stamps').exists()
    with pytest.raises((SystemExit, ValueError)):
        reproduce.main(['--out', str(tmp_path / 'run'), '--redoc', '--force', 'doc'])


def test_the_worth_of_a_question_is_read_by_family_and_type_and_the_swap_control_paired():
    """Synthetic results of 8 tasks: All QAs (2 questions each) turns 2 go-to tasks and 1 other into successes;
    Random QA's location episodes win 1 task with 2 questions; with swapped answers, 1 of All QAs' 3 gains stays."""
    from dialfred_bringup.reproduce.document import swap_lines, worth_rows
    from dialfred_sim.metrics import EpisodeResult

    def result(k, success, questions=0, types=()):
        return EpisodeResult(task_id=f'valid_unseen/{k:06d}', task_type='Move & Pick' if k < 4 else 'Put',
                             split='valid_unseen', success=success, goal_conditions_met=int(success),
                             goal_conditions_total=1, steps=10, expert_length=5, questions=questions,
                             invalid_questions=0, failed_actions=0, end_reason='stop', error='', agent='et',
                             oracle='', seed=0, wall_s=0.0,
                             dialogue=[{'type': t, 'noun': 'apple', 'valid': True, 'answer': 'x'} for t in types])

    def row(results):
        return {'n': len(results), 'SR': 100.0 * sum(r.success for r in results) / len(results), 'results': results}
    alone = [result(k, k == 7) for k in range(8)]
    allq = [result(k, k in (0, 1, 4, 7), 2, ('location', 'direction')) for k in range(8)]
    rnd = [result(k, k in (2, 7), 2, ('location', 'location')) if k < 3 else result(k, k == 7) for k in range(8)]
    swapped = [result(k, k in (0, 7), 2, ('location', 'direction')) for k in range(8)]
    rows = {('valid_unseen', k): {'n': 0} for k in ('map_instruction_only', 'map_all_qas', 'map_random_qa',
                                                     'map_all_qas_swapped')}
    rows.update({('valid_unseen', 'instruction_only'): row(alone), ('valid_unseen', 'all_qas'): row(allq),
                 ('valid_unseen', 'random_qa'): row(rnd), ('valid_unseen', 'all_qas_swapped'): row(swapped)})
    (et,) = worth_rows(rows)                           # the map performer has no results: no row
    assert et[:4] == ['Episodic Transformer', '+18.75 (8)', '+25.00 (4)', '+12.50 (4)']   # 3 of 16, 2 of 8, 1 of 8
    assert et[4:7] == ['+16.67 (3)', 'no questions', 'no questions']                  # 1 win, 6 questions
    assert et[7] == '25.0' and et[8].startswith('+25.0 [')
    (line,) = swap_lines(rows)
    assert 'SR 25.0 vs 50.0' in line and '6 of 8 episodes end with the same steps and outcome' in line
