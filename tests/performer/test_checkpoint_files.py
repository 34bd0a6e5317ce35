"""Checkpoints on disk: written atomically, and a cut-off file refused with a clear message.

Claims: a performer or questioner checkpoint cut in half (a copy interrupted, a full disk) is
refused with an error that names the file and says it is not a readable checkpoint, never half
loaded; a save interrupted mid-write leaves the previous checkpoint intact and no partial file
under its name.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from dialfred_performer.model import CheckpointError, load_checkpoint, save_checkpoint
from dialfred_questioner.questioners import make_questioner

SHIPPED_QUESTIONER = (Path(__file__).resolve().parents[2] / 'src' / 'dialfred_questioner' / 'dialfred_questioner'
                      / 'checkpoints' / 'pretrained.pt')


def cut(source: Path, target: Path) -> Path:
    data = source.read_bytes()
    target.write_bytes(data[:len(data) // 2])
    return target


def test_a_cut_performer_checkpoint_is_refused(checkpoint, tmp_path):
    with pytest.raises(CheckpointError, match=r'cut\.pt is not a readable checkpoint'):
        load_checkpoint(cut(checkpoint, tmp_path / 'cut.pt'))


def test_a_cut_questioner_checkpoint_is_refused(tmp_path):
    with pytest.raises(ValueError, match=r'cut\.pt is not a questioner checkpoint'):
        make_questioner(f'learned:{cut(SHIPPED_QUESTIONER, tmp_path / "cut.pt")}')


def test_an_interrupted_save_leaves_the_previous_checkpoint(checkpoint, tmp_path, monkeypatch):
    path = tmp_path / 'model.pt'
    path.write_bytes(checkpoint.read_bytes())
    model, vocab, _ = load_checkpoint(path)
    real_save = torch.save

    def dies_midway(state, target):
        real_save(state, target)
        Path(target).write_bytes(Path(target).read_bytes()[:1000])     # half written when the power goes
        raise KeyboardInterrupt

    monkeypatch.setattr(torch, 'save', dies_midway)
    with pytest.raises(KeyboardInterrupt):
        save_checkpoint(path, model, vocab, command='test')
    assert path.read_bytes() == checkpoint.read_bytes()                   # the old one, whole
    load_checkpoint(path)
