"""Progress bars write plain lines where stderr is a log, and tqdm's redraws on a terminal."""

from __future__ import annotations

import io

from dialfred_sim import progress


class _Log(io.StringIO):
    def isatty(self) -> bool:
        return False


def test_a_progress_bar_into_a_log_writes_whole_lines_and_no_carriage_returns(monkeypatch):
    log = _Log()
    monkeypatch.setattr(progress.sys, 'stderr', log)
    monkeypatch.setattr(progress, 'LOG_INTERVAL_S', 0.0)
    with progress.progress_bar(total=5, unit='task', desc='valid_unseen') as bar:
        for _ in range(5):
            bar.update(1)
    text = log.getvalue()
    assert '\r' not in text
    lines = text.splitlines()
    assert len(lines) >= 2 and all(line.startswith('valid_unseen:') for line in lines)
    assert '5/5' in lines[-1]


def test_a_disabled_progress_bar_writes_nothing(monkeypatch):
    log = _Log()
    monkeypatch.setattr(progress.sys, 'stderr', log)
    with progress.progress_bar(total=3, disable=True) as bar:
        bar.update(3)
    assert log.getvalue() == ''


def test_importing_the_simulator_prints_no_pybullet_banner():
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, '-c', 'import dialfred_sim.env, dialfred_oracle.colours; print("ok")'],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and proc.stdout == 'ok\n'
    assert 'pybullet build time' not in proc.stderr, proc.stderr
