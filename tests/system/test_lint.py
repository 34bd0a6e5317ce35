"""The linter's rules (pyproject.toml's [tool.ruff]) hold over the whole repository."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_ruff_finds_nothing():
    ruff = shutil.which('ruff', path=str(Path(sys.executable).parent)) or shutil.which('ruff')
    assert ruff, 'ruff is not installed (it is pinned in requirements.txt)'
    proc = subprocess.run([ruff, 'check', '--no-cache', '--output-format', 'concise', '.'], cwd=REPO,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]


def test_every_noqa_says_why():
    """A suppression names its rule and gives a reason after it (`# noqa: E402  (why)`)."""
    proc = subprocess.run(['git', 'grep', '-n', '-E', r'noqa(:\s*[A-Z]+[0-9]+(,\s*[A-Z]+[0-9]+)*)?\s*$', '--', '*.py'],
                          cwd=REPO, capture_output=True, text=True)
    assert proc.stdout == '', 'noqa without a reason:\n' + proc.stdout
