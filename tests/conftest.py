"""Shared set-up of the test suite: ROS isolation and a small simulator.

ROS isolation happens at import time, before any test module imports rclpy or starts a node: every
pytest session picks its own ROS_DOMAIN_ID (derived from its pid, and locked so that no concurrent
session on this machine takes the same one) and keeps discovery on this host, so two test runs on
one machine never see each other's /sim/* services.
The value is chosen afresh even if the calling shell set one: a fixed CI value would make parallel
jobs cross-talk, which is exactly what this prevents. Child processes (the node under test) inherit
it through os.environ.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest


def claim_ros_domain_id():
    """A ROS domain id in 1-101 that no other pytest session on this machine holds.

    Ids 0-101 are safe on Linux with the default participant limits; 0 is everyone's default, so
    use 1-101. Start from one derived from the pid and take the first whose lock file we can lock;
    the lock (not inherited by child processes) is held until this process exits.
    """
    import fcntl
    import tempfile
    start = os.getpid() % 101
    for k in range(101):
        domain = 1 + (start + k) % 101
        lock = open(os.path.join(tempfile.gettempdir(), f'dialfred-test-ros-domain-{domain}.lock'), 'a')
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            continue
        return domain, lock
    return 1 + start, None


ROS_DOMAIN_ID, _DOMAIN_LOCK = claim_ros_domain_id()
os.environ['ROS_DOMAIN_ID'] = str(ROS_DOMAIN_ID)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_STATIC_PEERS', None)
os.environ.pop('ROS_LOCALHOST_ONLY', None)   # deprecated in Jazzy; would warn next to the above

TESTS = Path(__file__).resolve().parent

SMALL_RESOLUTION = 64


@pytest.fixture(scope='session')
def ros_domain_id() -> int:
    return int(os.environ['ROS_DOMAIN_ID'])


@pytest.fixture(scope='session')
def spare_ros_domain_id():
    """A second domain id of this session's own, for nodes that must stay out of the main graph."""
    domain, lock = claim_ros_domain_id()
    yield domain
    if lock is not None:
        lock.close()


@pytest.fixture(scope='module')
def checkpoint(tmp_path_factory) -> Path:
    """A tiny random-init performer checkpoint (helpers.tiny_checkpoint), made once per test module."""
    from helpers import tiny_checkpoint
    return tiny_checkpoint(tmp_path_factory.mktemp('ckpt') / 'tiny.pt')


@pytest.fixture
def restore_torch_globals():
    """Put torch's global settings (deterministic algorithms, threads) back after a test that changes
    them; a module opts in with `pytestmark = pytest.mark.usefixtures('restore_torch_globals')`."""
    import torch
    deterministic, threads = torch.are_deterministic_algorithms_enabled(), torch.get_num_threads()
    yield
    torch.use_deterministic_algorithms(deterministic)
    torch.set_num_threads(threads)


@pytest.fixture(scope='module')
def env():
    """A 64x64 DialfredEnv shared by a test module; each test resets it to the situation it needs."""
    from dialfred_sim.env import DialfredEnv
    e = DialfredEnv(resolution=SMALL_RESOLUTION)
    yield e
    e.close()


@pytest.fixture
def make_env():
    """Factory for extra environments (other limits, a second copy); all are closed afterwards."""
    from dialfred_sim.env import DialfredEnv
    made = []

    def make(**kwargs):
        kwargs.setdefault('resolution', SMALL_RESOLUTION)
        e = DialfredEnv(**kwargs)
        made.append(e)
        return e

    yield make
    for e in made:
        e.close()
