"""A copied or moved checkout sets itself up again: its .venv (scripts with the old absolute path), build/
(CMake caches of the old source directory) and install/ are made anew, with one line saying why, and the
copy then works. Slow: a whole setup (pip from its cache, the colcon build), minutes."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.slow


def test_a_moved_checkout_is_set_up_again_and_works(tmp_path):
    copy = tmp_path / 'moved'
    subprocess.run(['git', 'clone', '-q', str(REPO), str(copy)], check=True, timeout=120)
    # the old tree's environment, as a copy (`cp -a`) or a move would bring it (hard links: no second 1.8 GB)
    for part in ('.venv', 'build', 'install'):
        subprocess.run(['cp', '-al', str(REPO / part), str(copy / part)], check=True, timeout=300)
    setup = subprocess.run([str(copy / 'dialfred'), 'setup'], cwd=copy, capture_output=True, text=True, timeout=1500,
                           stdin=subprocess.DEVNULL)
    assert setup.returncode == 0, setup.stderr[-3000:]
    assert f'this checkout was set up in {REPO} and has moved to {copy}' in setup.stderr
    done = subprocess.run([str(copy / 'dialfred'), 'env', 'python', '-c',
                           'import dialfred_sim.env, rclpy, dialfred_msgs.srv; print(dialfred_sim.env.__file__)'],
                          cwd=copy, capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip().startswith(str(copy))        # the copy's own packages, not the old tree's
    assert (copy / '.venv' / '.dialfred-root').read_text().strip() == str(copy)
    assert (REPO / '.venv' / '.dialfred-root').read_text().strip() == str(REPO)    # the old tree untouched
    again = subprocess.run([str(copy / 'dialfred'), 'setup'], cwd=copy, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0 and 'moved' not in again.stderr and 'up to date' in again.stderr
