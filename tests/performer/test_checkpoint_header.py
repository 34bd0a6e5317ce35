"""A checkpoint's header (dialfred_performer/checkpoint_header.py): every plain value of the saved dict, read
without torch, the same as the full load's; the tensors left as None; a damaged file is refused, and a config
settles its camera from the header without importing torch."""

from __future__ import annotations

import subprocess
import sys

import pytest

from dialfred_bringup.paths import REPO
from dialfred_performer.checkpoint_header import HeaderError, read_header
from dialfred_performer.model import CheckpointError, SHIPPED_CHECKPOINT, read_state
from dialfred_performer.model_registry import camera_resolution


def test_the_header_is_the_saved_dict_but_its_tensors():
    header, state = read_header(SHIPPED_CHECKPOINT), read_state(SHIPPED_CHECKPOINT)
    assert sorted(header) == sorted(state)
    assert {k: v for k, v in header.items() if k != 'state_dict'} == {k: v for k, v in state.items() if k != 'state_dict'}
    assert list(header['state_dict']) == list(state['state_dict'])
    assert set(header['state_dict'].values()) == {None}


def test_a_damaged_or_missing_file_is_refused(tmp_path):
    cut = tmp_path / 'cut.pt'
    cut.write_bytes(SHIPPED_CHECKPOINT.read_bytes()[:5000])
    with pytest.raises(HeaderError):
        read_header(cut)
    with pytest.raises(CheckpointError):        # the camera falls back to the full load, which says why
        camera_resolution('et', cut)
    with pytest.raises(FileNotFoundError):
        read_header(tmp_path / 'none.pt')


def test_an_eval_config_settles_its_camera_without_torch():
    code = ('import sys\nfrom dialfred_bringup.eval_config import EvalConfig\n'
            "c = EvalConfig(agent='et')\nprint(c.resolution, 'torch' in sys.modules)")
    proc = subprocess.run([sys.executable, '-c', code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    resolution = read_state(SHIPPED_CHECKPOINT)['config']['resolution']
    assert proc.stdout.split() == [str(resolution), 'False']
