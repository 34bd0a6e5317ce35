"""Worker pools end with the process that started them, however it dies (dialfred_sim.processes)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

PARENT = textwrap.dedent('''
    import os, sys, time
    from pathlib import Path
    from dialfred_sim.processes import worker_pool, worker_executor

    def linger(path):
        Path(path).write_text(str(os.getpid()))
        time.sleep(120)

    if __name__ == '__main__':
        kind, path = sys.argv[1], sys.argv[2]
        if kind == 'pool':
            pool = worker_pool(1)
            pool.apply_async(linger, (path,))
        else:
            pool = worker_executor(1)
            pool.submit(linger, path)
        time.sleep(120)
''')


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f'/proc/{pid}/stat') as f:            # a zombie is gone but for its parent's wait
        return f.read().split(')')[1].split()[0] != 'Z'


@pytest.mark.parametrize('kind', ['pool', 'executor'])
@pytest.mark.parametrize('sig', [signal.SIGKILL, signal.SIGTERM])
def test_a_killed_parent_leaves_no_worker_running(tmp_path: Path, kind: str, sig: int):
    script, pid_file = tmp_path / 'parent.py', tmp_path / 'worker.pid'
    script.write_text(PARENT)
    parent = subprocess.Popen([sys.executable, str(script), kind, str(pid_file)])
    try:
        deadline = time.monotonic() + 60
        while not (pid_file.exists() and pid_file.read_text()) and time.monotonic() < deadline:
            time.sleep(0.1)
        worker = int(pid_file.read_text())
        assert alive(worker)
        parent.send_signal(sig)
        parent.wait(timeout=10)
        deadline = time.monotonic() + 10
        while alive(worker) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not alive(worker), f'the worker outlived its parent ({signal.Signals(sig).name})'
    finally:
        parent.kill()
        parent.wait()
