"""`./dialfred demo` (what the README's first command runs), end to end: the learned performer plays a
valid_unseen task through the sim, oracle, questioner and performer nodes, each its own process.

Claims: the demo prints the task's instruction, every question and answer the performer heard on
`dialogue/qa`, every action with its pixel, and the outcome; it saves a captioned GIF of more than one
frame per task and a contact sheet; without a checkpoint it says where one should be and how to make
one. A tiny untrained checkpoint that always turns left stands in for a trained performer.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from helpers import tiny_checkpoint

REPO = Path(__file__).resolve().parents[2]


def demo(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'dialfred_bringup.launch', 'demo', *args], cwd=REPO,
                          capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL)


def test_the_demo_prints_the_dialogue_the_actions_and_the_outcome_and_saves_captioned_gifs(tmp_path):
    from PIL import Image

    from dialfred_sim.tasks import load_split
    # The first task that turning in place cannot finish (no Move in its type), so the episode runs
    # its 4 steps and fails: a Move task may be done by the first RotateLeft.
    first, task = next((k, t) for k, t in enumerate(load_split('valid_unseen')) if 'Move' not in t.task_type)
    checkpoint = tiny_checkpoint(tmp_path / 'left.pt', favour='RotateLeft')
    out = tmp_path / 'demo'
    proc = demo('--tasks', '1', '--first', str(first), '--checkpoint', str(checkpoint), '--max-steps', '4',
                '--out', str(out))
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    lines = proc.stdout.splitlines()
    assert f'{task.task_id} ({task.task_type}) in {task.scene}: "{task.instruction}"' in lines
    questions = [line for line in lines if line.startswith('  Q: ')]
    answers = [line for line in lines if line.startswith('  A: ')]
    assert questions and len(questions) == len(answers)        # the `all` questioner asks at the start
    assert [line.split()[1:] for line in lines if line.startswith('  step ')] == [
        [str(k), 'RotateLeft'] for k in range(1, 5)]
    outcome = next(line for line in lines if line.startswith('  -> '))
    assert 'failure: 4 steps, goal conditions 0/' in outcome and 'end reason max_steps' in outcome
    assert f'{len(questions)} questions' in outcome
    gif = out / f'{task.task_id.replace("/", "_")}.gif'
    with Image.open(gif) as im:
        # start, one frame per answer, one per action
        assert im.n_frames == 1 + len(questions) + 4 and im.size[0] == 320
    with Image.open(out / 'contact_sheet.png') as sheet:
        sheet.verify()
        assert sheet.format == 'PNG'
    # the closing line: how many succeeded, and (a checkpoint not shipped) how to measure it on the whole split
    assert lines[-1].startswith('0 of 1 succeeded; ') and 'launch eval --local --split valid_unseen' in lines[-1]
    # and one success to show, whatever the performer did: the expert's path on the same task, labelled as such
    assert lines[-1].endswith(f"The expert's reference path on {task.task_id}: goal reached.")
    assert any(line.startswith(f"For reference, the expert's path on {task.task_id}") and 'not the performer' in line
               for line in lines)
    with Image.open(out / f'{task.task_id.replace("/", "_")}_expert_reference.gif') as im:
        n = len(task.expert_actions)
        assert im.n_frames in (1 + n, 2 + n)       # the start, each expert action (and a Stop, if it needs one)


def test_the_demos_tasks_are_one_of_each_family_by_type_and_its_reference_is_the_shipped_results_table(tmp_path):
    from dialfred_bringup.demo import DEMO_TYPES, DemoConfig, demo_tasks, reference_line
    from dialfred_sim.tasks import load_split
    tasks = load_split('valid_unseen')
    chosen = demo_tasks(tasks, 6)
    firsts = [next(k for k, t in enumerate(tasks) if t.task_type == name) for name in DEMO_TYPES]
    assert [k for k, _ in chosen[:3]] == firsts                  # the first of each type, in DEMO_TYPES' order
    assert [t.task_type for _, t in chosen] == list(DEMO_TYPES) * 2
    assert demo_tasks(tasks, 2, first=5) == [(5, tasks[5]), (6, tasks[6])]
    doc = tmp_path / 'results.md'
    doc.write_text('| # | setting | split | n | SR [95%] |\n|---|---|---|---|---|\n'
                   '| 2 | All QAs | valid_seen | 1296 | 46.7 [44.0, 49.5] |\n'
                   '| 2 | All QAs | valid_unseen | 1363 | 41.9 [39.3, 44.5] |\n')
    config = DemoConfig().eval_config()
    assert reference_line(config, doc) == 'on all 1363 valid_unseen tasks this performer with All QAs succeeds on 41.9% (docs/results.md)'
    other = DemoConfig(checkpoint=tmp_path / 'mine.pt').eval_config()
    assert 'launch eval --local' in reference_line(other, doc)


def test_without_a_checkpoint_the_demo_says_where_one_should_be_and_how_to_make_one(tmp_path):
    missing = tmp_path / 'none.pt'
    proc = demo('--tasks', '1', '--checkpoint', str(missing), '--out', str(tmp_path / 'demo'), timeout=60)
    assert proc.returncode == 2
    assert f'no performer checkpoint at {missing}' in proc.stderr and 'train-performer' in proc.stderr
    assert not (tmp_path / 'demo').exists()


def test_the_demo_plays_the_performer_model_it_is_told_and_refuses_others(capsys):
    import pytest

    from dialfred_bringup.demo import DemoConfig
    from dialfred_sim.dataclass_cli import parse
    assert parse(DemoConfig, []).eval_config().performer == 'et'
    config = parse(DemoConfig, ['--performer', 'map']).eval_config()
    assert config.performer == 'map' and config.questioner == 'all' and config.workers == 1
    with pytest.raises(SystemExit):
        parse(DemoConfig, ['--performer', 'film'])
    assert 'film' in capsys.readouterr().err
