"""scripts/et_parts.py: the shipped checkpoint's perception network and vocabulary, as a fine-tune reads them."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import torch

from dialfred_performer.perception import load_perception
from dialfred_performer.preprocess import Vocabulary
from dialfred_performer.shipped import SHIPPED_CHECKPOINT
from dialfred_performer.train import load_checkpoint

REPO = Path(__file__).resolve().parents[2]


def test_the_parts_written_out_are_the_checkpoints_own_network_and_words(tmp_path):
    proc = subprocess.run([sys.executable, str(REPO / 'scripts' / 'et_parts.py'), '--out', str(tmp_path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    model, vocab, _ = load_checkpoint(SHIPPED_CHECKPOINT)
    net, _ = load_perception(tmp_path / 'perception.pt')
    inside = {k[len('visual.net.'):]: v for k, v in model.state_dict().items() if k.startswith('visual.net.')}
    assert inside and all(torch.equal(inside[k], v) for k, v in net.state_dict().items())
    assert Vocabulary.load(tmp_path / 'vocabulary.json') == vocab
