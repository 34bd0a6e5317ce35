"""dialfred_bringup/baseline_runs.py: the paper's baselines 1-4 with a performer checkpoint, as JSON and docs/results.md.

Claims: on 3 valid_unseen tasks with a small (untrained) checkpoint, in process, every baseline gets a
results file and a JSON row (n, SR/PWSR/GC/NQ inside their 95% intervals, the distractor and
out-of-view splits adding up to n); the document names the command, the checkpoint's sha256 and
stored command and has every section; a rerun plays no new episode; --results-only only rewrites.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import dialfred_bringup.baseline_runs as baselines
from helpers import tiny_checkpoint

ROOT = Path(__file__).resolve().parents[2]




@pytest.fixture(scope='module')
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp('baselines')
    checkpoint = tiny_checkpoint(folder / 'tiny.pt')
    argv = ['--checkpoint', str(checkpoint), '--splits', 'valid_unseen', '--limit', '3', '--workers', '1',
            '--out', str(folder / 'out'), '--doc', str(folder / 'results.md'), '--resamples', '200',
            '--no-progress']
    return folder, argv


def call(capfd, argv) -> dict:
    assert baselines.main(argv) == 0
    return json.loads(capfd.readouterr().out)


def lines_of(folder: Path) -> dict:
    return {p.name: len(p.read_text().splitlines()) for p in sorted((folder / 'out').glob('*.jsonl'))}


@pytest.mark.slow   # the baselines script end to end; fast: test_eval_local, reproduce's document tests
def test_every_baseline_is_played_reported_and_documented_and_a_rerun_resumes(run, capfd):
    folder, argv = run
    report = call(capfd, argv)
    rows = report['results']['valid_unseen']
    assert list(rows) == ['instruction_only', 'all_qas', 'random_qa', 'random_mc']
    for key, row in rows.items():
        assert row['n'] == row['tasks'] == 3 and row['complete'], key
        for k in ('SR', 'PWSR', 'GC', 'NQ'):
            lo, hi = row['CI95'][k]
            assert lo <= row[k] <= hi, (key, k)
        assert row['distractor']['with']['n'] + row['distractor']['without']['n'] == 3
        assert row['target_at_start']['out_of_view']['n'] + row['target_at_start']['in_view']['n'] == 3
        assert row['eval_wall_s'] > 0 and row['runs'] == 1
    assert rows['instruction_only']['NQ'] == 0 and rows['all_qas']['NQ'] > 0
    assert len(report['checkpoint']['sha256']) == 64 and report['checkpoint']['command'] == 'tests/helpers.py tiny_checkpoint'

    doc = (folder / 'results.md').read_text()
    for section in ('## Checkpoint', '## Settings', '## Baselines (paper, Table II)', '### valid_unseen',
                    '## Same-class distractor and target out of view at the start', '## What holds'):
        assert section in doc, section
    assert './dialfred baselines --checkpoint' in doc and report['checkpoint']['sha256'][:16] in doc
    assert 'command stored in the checkpoint: `tests/helpers.py tiny_checkpoint`' in doc
    assert '| 2 | All QAs | all | 3 |' in doc and '| 32.0 |' in doc          # ours beside the paper's
    assert 'All QAs minus instruction only on valid_unseen:' in doc and '(paper +13.7)' in doc
    assert 'Instruction only on valid_unseen: SR' in doc and '>= 18.3 (paper)' in doc

    files = lines_of(folder)
    assert files == ({f'valid_unseen_{k}.jsonl': 3 for k in rows} | {f'valid_unseen_{k}.runs.jsonl': 1 for k in rows}
                     | {f'valid_unseen_{k}.trace.jsonl': 3 for k in rows})      # each episode's trace (score)
    again = call(capfd, argv)                                  # a rerun: nothing new is played
    assert lines_of(folder) == files
    assert again['results'] == report['results']
    (folder / 'results.md').unlink()
    only = call(capfd, argv + ['--results-only'])
    assert only['results'] == report['results'] and (folder / 'results.md').exists()


def test_unknown_baselines_or_splits_are_refused(capfd):
    with pytest.raises(SystemExit):
        baselines.main(['--baselines', 'all_qas,oracle'])
    assert 'baselines takes' in capfd.readouterr().err
    with pytest.raises(SystemExit):
        baselines.main(['--splits', 'train'])
