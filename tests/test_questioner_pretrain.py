"""Pre-training of the learned questioner (dialfred_questioner.pretrain, no ROS) on the shipped
(SYNTHETIC) valid_unseen dialogues and a few rendered first frames.

Claims: every annotation of a rendered task becomes an example (a noun outside the catalogue or a
task without frames is skipped and counted); a tiny run writes last.pt, best.pt and a metrics line
per epoch and its loss falls; a run stopped after one epoch and resumed ends with the weights of an
uninterrupted run; a changed config is refused on resume.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from dialfred_oracle.annotator import load_dialogues
from dialfred_questioner.data import catalog_nouns, pretraining_examples
from dialfred_questioner.model import QuestionerConfig
from dialfred_questioner.pretrain import PretrainConfig, pretrain
from dialfred_sim.tasks.demonstrations import build_demonstrations, load_demonstrations
from helpers import tiny_checkpoint

TASKS = 16


@pytest.fixture(scope='module')
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp('qpre')
    build_demonstrations('valid_unseen', 64, root / 'demo', workers=1, limit=TASKS, progress=False)
    return root / 'demo', tiny_checkpoint(root / 'performer.pt')


def config(setup, out, **changes) -> PretrainConfig:
    demo, performer = setup
    base = dict(split='valid_unseen', demonstrations=str(demo), performer=str(performer), out=str(out),
                model=QuestionerConfig(embedding=16, hidden=32, image=32, dropout=0.0), epochs=3, batch_size=8,
                lr=3e-3, val_fraction=0.2, limit=TASKS, threads=1, progress=False)
    return PretrainConfig(**{**base, **changes})


def test_each_annotation_of_a_rendered_task_is_an_example(setup):
    demo = load_demonstrations(setup[0])
    rows = load_dialogues('valid_unseen')[:TASKS + 4]
    examples, skipped = pretraining_examples(rows, demo, catalog_nouns())
    assert len(examples) + skipped == sum(len(r.annotations) for r in rows)
    assert skipped >= 4 * 2                          # the 4 tasks without frames
    assert {e.task_id for e in examples} <= {t['task_id'] for t in demo.tasks}


def test_a_tiny_run_learns_and_a_resumed_run_ends_with_the_same_weights(setup, tmp_path):
    report = pretrain(config(setup, tmp_path / 'full'))
    lines = [json.loads(l) for l in (tmp_path / 'full' / 'metrics.jsonl').read_text().splitlines()]
    assert [l['epoch'] for l in lines] == [1, 2, 3] and lines[-1]['train_loss'] < lines[0]['train_loss']
    assert report['examples']['train'] > 0 and report['examples']['val'] > 0
    assert (tmp_path / 'full' / 'best.pt').is_file()
    pretrain(config(setup, tmp_path / 'split', epochs=1))
    pretrain(config(setup, tmp_path / 'split', resume=True))
    a = torch.load(tmp_path / 'full' / 'last.pt', weights_only=False)['state_dict']
    b = torch.load(tmp_path / 'split' / 'last.pt', weights_only=False)['state_dict']
    assert all(torch.equal(a[k], b[k]) for k in a)
    with pytest.raises(ValueError, match='batch_size'):
        pretrain(config(setup, tmp_path / 'split', resume=True, batch_size=4))
