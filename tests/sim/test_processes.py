"""Worker pools and launched nodes end with the process that started them, however it dies (dialfred_sim.processes)."""

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


NODE = textwrap.dedent('''
    import os, signal, sys, time
    from pathlib import Path
    from dialfred_sim.ros_util import exit_with_launcher

    signal.signal(signal.SIGTERM, signal.SIG_IGN)     # deaf to SIGTERM, as a node stuck in a callback is
    watching = exit_with_launcher(grace_s=1.0)
    Path(sys.argv[1]).write_text(f'{os.getpid()} {int(watching)}')
    time.sleep(120)
''')

LAUNCHER = textwrap.dedent('''
    import os, subprocess, sys, time
    from dialfred_sim.ros_util import LAUNCHER_ENV

    node, path, how = sys.argv[1:4]
    env = dict(os.environ)
    env.pop(LAUNCHER_ENV, None)
    if how == 'launched':
        env[LAUNCHER_ENV] = str(os.getpid())
    subprocess.Popen([sys.executable, node, path], env=env, start_new_session=True)
    time.sleep(120)
''')


@pytest.mark.parametrize('how', ['launched', 'by-hand'])
def test_a_node_deaf_to_sigterm_ends_soon_after_its_launcher_dies_unless_started_by_hand(tmp_path: Path, how: str):
    node_script, launcher_script, pid_file = tmp_path / 'node.py', tmp_path / 'launcher.py', tmp_path / 'node.pid'
    node_script.write_text(NODE)
    launcher_script.write_text(LAUNCHER)
    launcher = subprocess.Popen([sys.executable, str(launcher_script), str(node_script), str(pid_file), how])
    node = None
    try:
        deadline = time.monotonic() + 60
        while not (pid_file.exists() and pid_file.read_text()) and time.monotonic() < deadline:
            time.sleep(0.1)
        node, watching = map(int, pid_file.read_text().split())
        assert watching == (how == 'launched')
        launcher.kill()
        launcher.wait(timeout=10)
        time.sleep(0.4)
        assert alive(node), 'the node was given no grace to end in its own way'
        deadline = time.monotonic() + (10 if how == 'launched' else 3)    # the grace is 1 s
        while alive(node) and time.monotonic() < deadline:
            time.sleep(0.1)
        if how == 'launched':
            assert not alive(node), 'the node outlived its launcher'
        else:
            assert alive(node), 'a node started by hand ended with the process that started it'
    finally:
        launcher.kill()
        launcher.wait()
        if node is not None and alive(node):
            os.kill(node, signal.SIGKILL)
