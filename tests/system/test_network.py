"""The graph stays on the machine unless asked: a local run's sockets all bind to loopback, and a run
whose discovery reaches other hosts opts in by its environment and says so."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys

import pytest

from dialfred_bringup.graph import Graph, NodeProcess, network_environment
from dialfred_bringup.paths import REPO


@pytest.mark.parametrize('caller, across', [({}, False), ({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}, False),
                                            ({'ROS_STATIC_PEERS': '127.0.0.1'}, False),
                                            ({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET'}, True),
                                            ({'ROS_STATIC_PEERS': '10.0.0.11;10.0.0.12'}, True)])
def test_the_network_settings_follow_the_callers_choice(caller, across):
    env = network_environment(caller, REPO)
    if across:
        assert env == {'DIALFRED_NETWORK': 'hosts',
                       'FASTRTPS_DEFAULT_PROFILES_FILE': str(REPO / 'config' / 'fastdds_profiles_hosts.xml')}
    else:
        assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'SYSTEM_DEFAULT' and env['DIALFRED_NETWORK'] == 'local'
        assert env['FASTRTPS_DEFAULT_PROFILES_FILE'] == str(REPO / 'config' / 'fastdds_profiles.xml')
    own = {'FASTRTPS_DEFAULT_PROFILES_FILE': '/etc/mine.xml', **caller}
    assert network_environment(own, REPO)['FASTRTPS_DEFAULT_PROFILES_FILE'] == '/etc/mine.xml'


def udp_sockets(pids: set) -> list[tuple[str, int]]:
    """(local address, pid) of every UDP socket of `pids` (ss -lunp)."""
    out = subprocess.run(['ss', '-H', '-lunp'], capture_output=True, text=True, check=True).stdout
    found = []
    for line in out.splitlines():
        fields = line.split()
        for pid in map(int, re.findall(r'pid=(\d+)', line)):
            if pid in pids:
                found.append((fields[3].rsplit(':', 1)[0], pid))
    return found


@pytest.mark.skipif(shutil.which('ss') is None, reason='needs ss (iproute2)')
def test_no_socket_of_a_local_run_listens_outside_loopback():
    nodes = [NodeProcess('dialfred_sim', {'resolution': 32}, namespace='/net'),
             NodeProcess('dialfred_oracle', namespace='/net'),
             NodeProcess('dialfred_questioner', {'questioner': 'all'}, namespace='/net'),
             NodeProcess('dialfred_performer', {'questioner': True}, namespace='/net')]
    from dialfred_msgs.srv import OracleAnswer, SimReset
    with Graph(nodes) as graph:
        graph.client(SimReset, '/net/sim/reset')
        graph.client(OracleAnswer, '/net/oracle/answer')          # discovery worked: the graph talks
        pids = {n.proc.pid for n in nodes} | {os.getpid()}
        sockets = udp_sockets(pids)
        assert len({pid for _, pid in sockets}) >= 3            # the processes have their sockets ...
        outside = [(a, p) for a, p in sockets if not a.startswith('127.')]
        assert outside == [], outside                           # ... and none listens off loopback


def test_a_run_across_hosts_says_so():
    env = {k: v for k, v in os.environ.items() if not k.startswith(('ROS_AUTOMATIC', 'ROS_STATIC', 'FASTRTPS',
                                                                      'DIALFRED_SAID', 'DIALFRED_NETWORK'))}
    done = subprocess.run([sys.executable, '-c', 'import dialfred_bringup.graph, os; '
                           'print(os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"])'],
                          env={**env, 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET'}, capture_output=True, text=True)
    assert 'DDS discovery reaches other hosts' in done.stderr and done.stdout.strip().endswith('fastdds_profiles_hosts.xml')
    local = subprocess.run([sys.executable, '-c', 'import dialfred_bringup.graph'], env=env, capture_output=True,
                           text=True)
    assert local.returncode == 0 and 'other hosts' not in local.stderr
