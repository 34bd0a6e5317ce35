"""The rclpy client of docs/operations.md ("Your own client in rclpy"), run as written against a graph of a
simulator, an oracle and a performer node: it prints the task's instruction, a feedback line per step
and the result. (A small checkpoint that stops at once stands in for the shipped performer.)"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from dialfred_bringup.graph import Graph, NodeProcess, oracle_node, sim_node
from dialfred_sim.tasks import get_task
from helpers import tiny_checkpoint

REPO = Path(__file__).resolve().parents[2]


def snippet() -> str:
    text = (REPO / 'docs' / 'operations.md').read_text()
    return re.search(r'<!-- snippet: rclpy client -->\n```python\n(.*?)```', text, re.S).group(1)


def test_the_documented_rclpy_client_resets_sends_a_goal_and_prints_feedback_and_result(tmp_path):
    code = snippet()
    assert len(code.strip().splitlines()) <= 30
    task = re.search(r"TASK = '([^']+)'", code).group(1)
    stopping = tiny_checkpoint(tmp_path / 'stop.pt', favour='Stop')
    nodes = [sim_node(64, publish_observations=False), oracle_node(),
             NodeProcess('dialfred_performer', {'checkpoint': str(stopping)})]
    with Graph(nodes):
        (tmp_path / 'client.py').write_text(code)
        done = subprocess.run([sys.executable, str(tmp_path / 'client.py')], capture_output=True, text=True,
                              timeout=120, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    assert lines[0] == f'task: {get_task(task).instruction}'
    assert lines[1] == 'step 1 Stop'
    assert lines[-1] == 'failure 1 steps 0 questions stop'
