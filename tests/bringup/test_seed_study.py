"""scripts/seed_study.py end to end on a tiny budget: RL fine-tuned with another seed, the shipped
checkpoint and Random QA evaluated on the same tasks, the spread written as JSON and markdown."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow   # RL fine-tuning and evaluations over seeds; fast: test_questioner_finetune, test_eval_local
def test_seed_study_fine_tunes_evaluates_and_reports_the_spread(tmp_path):
    out = tmp_path / 'study'
    args = ['--runs', 'rl_anytime', '--seeds', '1', '--random-seeds', '0', '3', '--limit', '4', '--updates', '1',
            '--episodes-per-update', '4', '--max-steps', '10', '--out', str(out), '--no-progress']
    proc = subprocess.run([sys.executable, str(REPO / 'scripts' / 'seed_study.py'), *args], cwd=REPO,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout[proc.stdout.index('{'):])
    assert set(report['draws']) == {'rl_anytime', 'random_qa'}
    assert set(report['draws']['rl_anytime']) == {'shipped', 'seed 1'}
    assert set(report['draws']['random_qa']) == {'eval seed 0', 'eval seed 3'}
    for draws in report['draws'].values():
        for row in draws.values():
            assert row['n'] == 4 and 0 <= row['SR'] <= 100 and row['NQ'] >= 0
    assert report['spread']['random_qa']['NQ']['draws'] == 2
    assert (out / 'rl_anytime_s1' / 'final.pt').exists()
    assert json.loads((out / 'summary.json').read_text()) == report
    assert '| rl_anytime | seed 1 |' in (out / 'seeds.md').read_text()


def test_seed_study_rejects_a_perturbed_run_and_negative_seeds():
    for bad in (['--runs', 'rl_anytime_withhold_location'], ['--seeds', '-1']):
        proc = subprocess.run([sys.executable, str(REPO / 'scripts' / 'seed_study.py'), *bad], cwd=REPO,
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2 and 'error' in proc.stderr
