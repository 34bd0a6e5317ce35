"""A crafted checkpoint never runs its pickled code: every loader reads with weights_only=True and
refuses such a file with a clear error (the marker file its payload would write never appears)."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
import torch

from dialfred_bringup.paths import REPO


class Payload:
    """Pickled as a call to os.system: loading the file unsafely would run the command."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return os.system, (f'touch {self.marker}',)


@pytest.fixture
def crafted(tmp_path):
    marker = tmp_path / 'payload_ran'
    path = tmp_path / 'crafted.pt'
    torch.save({'format': 'dialfred-performer/1', 'state_dict': {'w': Payload(marker)}, 'extra': Payload(marker)}, path)
    return path, marker


def loaders():
    from dialfred_bringup.compare_runs import compare_weights
    from dialfred_bringup.reproduce.plan import weights_sha256
    from dialfred_performer.agent import PerformerAgent
    from dialfred_performer.checkpoint_header import read_header
    from dialfred_performer.mapper.agent import MapAgent
    from dialfred_performer.model import load_checkpoint, read_state
    from dialfred_performer.model_registry import camera_resolution
    from dialfred_performer.perception import load_perception
    from dialfred_questioner.policy import LearnedQuestioner

    def compare(path):
        for run in ('a', 'b'):
            (path.parent / run / 'performer').mkdir(parents=True, exist_ok=True)
            (path.parent / run / 'performer' / 'best.pt').write_bytes(path.read_bytes())
        return compare_weights(path.parent / 'a', path.parent / 'b', 3)

    return {'performer checkpoint': load_checkpoint, 'performer agent': PerformerAgent.from_checkpoint,
            'map performer': MapAgent.from_checkpoint,
            'training state (pretrain/finetune/perception --resume)': read_state, 'perception': load_perception,
            'questioner': LearnedQuestioner.from_checkpoint, 'reproduce weights digest': weights_sha256,
            'compare_runs --parts weights': compare, 'checkpoint header (no torch)': read_header,
            'camera of an et checkpoint (EvalConfig)': lambda path: camera_resolution('et', path)}


@pytest.mark.parametrize('name', list(loaders()))
def test_each_loader_refuses_a_crafted_file_without_running_it(crafted, name):
    path, marker = crafted
    with pytest.raises(Exception) as info:
        loaders()[name](path)
    assert not marker.exists(), f'{name} ran the payload'
    assert 'weights_only' in str(info.value) or 'Unsupported' in str(info.value) or 'not' in str(info.value), info.value
    assert torch.load.__module__ == 'torch.serialization'


def test_no_code_in_the_repository_loads_a_checkpoint_unsafely():
    calls = []
    for path in sorted((REPO / 'src').rglob('*.py')) + sorted((REPO / 'scripts').rglob('*.py')) + \
            sorted((REPO / 'benchmarks').rglob('*.py')):
        for number, line in enumerate(path.read_text().splitlines(), start=1):
            if re.search(r'torch\.load\(', line) and 'weights_only=True' not in line:
                calls.append(f'{path.relative_to(REPO)}:{number}: {line.strip()}')
    assert calls == []


def test_the_crafted_file_does_run_its_payload_when_loaded_unsafely(crafted):
    """The control: without weights_only the same file runs its command (so the tests above can fail)."""
    path, marker = crafted
    torch.load(path, weights_only=False)  # noqa: S614 - the point of this test
    assert marker.exists()
