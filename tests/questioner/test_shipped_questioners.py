"""The questioner checkpoints shipped in the package (dialfred_questioner/checkpoints/).

Claims: every shipped name has its file, each is small, loads, records the command that made it (the
pre-training or a fine-tuning with the settings its name says: timing, gap, rewards, perturbation,
input) and a commit, names the shipped performer as the holder of its frozen frame encoder (with the
encoder's digest), and decides the same
question twice on the same input (greedy).
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dialfred_performer.model import SHIPPED_CHECKPOINT, state_digest, visual_state
from dialfred_questioner.policy import SHIPPED_LEARNED, learned_checkpoint
from dialfred_questioner.questioners import make_questioner
from dialfred_sim.tasks import load_split

MAX_BYTES = 4 * 1024 * 1024
# name -> (words its command must hold, timing mode, gap, reads the dialogue)
EXPECTED = {
    'pretrained': (('dialfred_questioner.pretrain', '--split train'), 'begin', None, True),
    'rl-begin': (('dialfred_questioner.finetune', '--timing begin', '--rewards paper'), 'begin', None, True),
    'rl-anytime': (('--timing anytime', '--gap 5', '--rewards paper', "--perturb-type ''"), 'anytime', 5, True),
    'rl-anytime-1': (('--timing anytime', '--gap 1', '--rewards fixed_1'), 'anytime', 1, True),
    'rl-anytime-10': (('--timing anytime', '--gap 10', '--rewards paper'), 'anytime', 10, True),
    'rl-mc': (('--timing confusion', '--epsilon 0.5'), 'confusion', None, True),
    'rl-anytime-withhold-location': (('--perturb-type location', '--perturb-probability 0.5'), 'anytime', 5, True),
    'rl-anytime-withhold-appearance': (('--perturb-type appearance',), 'anytime', 5, True),
    'rl-anytime-withhold-direction': (('--perturb-type direction',), 'anytime', 5, True),
    'rl-anytime-no-dialogue': (('--no-dialogue',), 'anytime', 5, False),
    'map-rl-anytime': (('--timing anytime', '--gap 5', '--model map'), 'anytime', 5, True),
    'rl-anytime-chained': (('--timing anytime', '--gap 5', '--protocol chained'), 'anytime', 5, True),
    'map-rl-anytime-chained': (('--timing anytime', '--gap 5', '--model map', '--protocol chained'), 'anytime', 5, True),
}


def test_every_shipped_name_is_expected_here():
    assert set(EXPECTED) == set(SHIPPED_LEARNED)


@pytest.mark.parametrize('name', sorted(EXPECTED))
def test_a_shipped_questioner_is_small_says_how_it_was_made_and_decides_the_same_twice(name):
    path = learned_checkpoint(name)
    assert path.is_file(), f'{path} is not shipped'
    assert path.stat().st_size <= MAX_BYTES
    state = torch.load(path, map_location='cpu', weights_only=True)
    words, mode, gap, reads = EXPECTED[name]
    for w in words:
        assert w in state['command'], (w, state['command'])
    assert state['git_commit'] not in ('', 'unknown')
    # The frame encoder is kept once, in the shipped performer: the questioner names it and its digest.
    assert 'visual' not in state
    source = state['visual_source']
    assert (path.parent / source['performer']).resolve() == SHIPPED_CHECKPOINT.resolve()
    assert state_digest(visual_state(SHIPPED_CHECKPOINT)) == source['sha256']
    q = make_questioner(name)
    assert q.timing.mode == mode and (gap is None or q.timing.gap == gap) and q.reads_dialogue == reads
    task = load_split('valid_unseen')[3]
    rgb = np.random.default_rng(0).integers(0, 255, (64, 64, 3), dtype=np.uint8)
    a = q.decide(rgb, task.instruction, [], 0)[0]
    b = q.decide(rgb, task.instruction, [], 0)[0]
    assert a == b
