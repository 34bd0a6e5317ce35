"""The launcher's scripted jobs end to end (integration): `explore` (a scripted explorer through
the simulator node) and `dialogue`, each as a separate process that starts the real node executables.

conftest.py gives this pytest session its own ROS_DOMAIN_ID, which the launcher's child processes
inherit, so their nodes answer no other session.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip('rclpy')

REPO = Path(__file__).resolve().parents[2]


def launch(*args: str, timeout: float = 180) -> str:
    proc = subprocess.run([sys.executable, '-m', 'dialfred_bringup.launch', *args], cwd=REPO,
                          capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc.stdout


def test_the_explorer_plays_an_episode_and_saves_its_frames(tmp_path):
    out = launch('explore', '--steps', '6', '--resolution', '48', '--out', str(tmp_path))
    frames = sorted(tmp_path.glob('frame_*.png'))
    assert 2 <= len(frames) <= 7
    assert (tmp_path / 'episode.gif').stat().st_size > 0 and (tmp_path / 'contact_sheet.png').exists()
    assert f'saved {len(frames)} frames' in out


def test_the_dialogue_run_asks_every_question_type_and_saves_a_captioned_gif(tmp_path):
    from PIL import Image

    from dialfred_sim.tasks import load_split
    # The first valid_unseen task whose expert walks before it ends with a Put (the pixel to scale).
    first, task = next((k, t) for k, t in enumerate(load_split('valid_unseen'))
                       if len(t.expert_actions) > 1 and t.expert_actions[-1].action == 'Put')
    n = len(task.expert_actions)
    gif = tmp_path / 'dialogue.gif'
    out = launch('dialogue', '--tasks', '1', '--first', str(first), '--resolution', '96', '--gif', str(gif))
    lines = out.splitlines()
    asked = [line for line in lines if line.strip().startswith('agent')]
    # location, appearance, direction, an unknown object, an unknown type, directions near the end
    assert len(asked) == 6
    assert sum('(invalid:' in line for line in asked) == 2
    assert "there is no unicorn here" in out and "unknown question type 'colour'" in out
    # The expert's pixels are scaled from the task's 128x128 frames to this node's 96x96.
    assert "the expert's last action, Put: goal reached" in out
    with Image.open(gif) as im:
        # start, 5 answers, the expert's n actions, the last answer
        assert (im.n_frames, im.size[0]) == (1 + 5 + n + 1, 320)
    assert lines[-1] == f'saved {1 + 5 + n + 1} captioned frames to {gif}'
