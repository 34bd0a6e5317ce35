"""`./dialfred run PKG EXECUTABLE` starts a node as `ros2 run` does (there is no ros2 CLI on PyPI), and
`./dialfred graph` lists the running graph's nodes, topics, services and actions as `ros2 node list`,
`topic list -t`, `service list -t` and `action list` would."""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DIALFRED = str(REPO / 'dialfred')


def test_run_names_what_a_package_has_when_the_executable_is_not_there():
    done = subprocess.run([DIALFRED, 'run', 'dialfred_sim', 'nope'], capture_output=True, text=True, timeout=60)
    assert done.returncode != 0 and "package 'dialfred_sim' has no executable 'nope' (it has: node" in done.stderr
    done = subprocess.run([DIALFRED, 'run', 'no_such_pkg', 'node'], capture_output=True, text=True, timeout=60)
    assert done.returncode != 0 and "no package 'no_such_pkg'" in done.stderr and 'dialfred_oracle' in done.stderr


def test_a_node_started_with_run_is_listed_by_graph_with_its_services_and_topics():
    node = subprocess.Popen([DIALFRED, 'run', 'dialfred_sim', 'node', '--ros-args', '-r', '__ns:=/runtest',
                             '-p', 'resolution:=32'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        graph = {}
        deadline = time.monotonic() + 120     # a few seconds on a quiet machine; far more beside training
        while time.monotonic() < deadline and node.poll() is None:
            done = subprocess.run([DIALFRED, 'graph', '--json', '--wait', '3'], capture_output=True, text=True,
                                  timeout=120)
            assert done.returncode == 0, done.stderr[-2000:]
            graph = json.loads(done.stdout)
            if '/runtest/sim/reset' in graph['services']:
                break
        assert node.poll() is None, f'the node exited with {node.returncode}: {node.stdout.read()[-2000:]}'
        assert '/runtest/dialfred_sim' in graph['nodes']
        assert graph['services']['/runtest/sim/reset'] == ['dialfred_msgs/srv/SimReset']
        assert graph['services']['/runtest/sim/step'] == ['dialfred_msgs/srv/SimStep']
        assert '/runtest/sim/observation' in graph['topics']
        assert not any(name.endswith('/get_parameters') for name in graph['services'])
        lists = subprocess.run([DIALFRED, 'graph', '--wait', '3'], capture_output=True, text=True, timeout=120)
        assert lists.stdout.startswith('nodes (') and '  /runtest/sim/reset [dialfred_msgs/srv/SimReset]' in lists.stdout
    finally:
        node.send_signal(signal.SIGINT)
        try:
            node.wait(timeout=20)
        except subprocess.TimeoutExpired:
            node.kill()


@pytest.mark.slow   # two more nodes and three graph reads; fast: the graph test above
def test_graph_flags_a_node_name_taken_twice_and_all_shows_what_ros_lists():
    nodes = [subprocess.Popen([DIALFRED, 'run', 'dialfred_oracle', 'node', '--ros-args', '-r', '__ns:=/duptest'],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(2)]
    try:
        graph = {}
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            done = subprocess.run([DIALFRED, 'graph', '--json', '--all'], capture_output=True, text=True, timeout=120)
            assert done.returncode == 0, done.stderr[-2000:]
            graph = json.loads(done.stdout)
            if '/duptest/dialfred_oracle' in graph['duplicates']:    # (another graph read may be running: its
                break                                                # launcher node is a duplicate too)
        assert '/duptest/dialfred_oracle' in graph['duplicates'] and graph['settled']
        assert '/rosout' in graph['topics'] and '/duptest/dialfred_oracle/get_parameters' in graph['services']
        lists = subprocess.run([DIALFRED, 'graph'], capture_output=True, text=True, timeout=120)
        line = next(x for x in lists.stdout.splitlines() if x.startswith('  /duptest/dialfred_oracle'))
        assert 'WARNING: more than one node has this name' in line
        assert '/rosout' not in lists.stdout          # without --all, as before
    finally:
        for node in nodes:
            node.send_signal(signal.SIGINT)
        for node in nodes:
            try:
                node.wait(timeout=20)
            except subprocess.TimeoutExpired:
                node.kill()
