"""The node graph as processes: start node executables as `ros2 run` resolves them, supervise them,
and talk to them from a client node of this process (no `ros2 launch` here: this does its job).

`NodeProcess` is one node executable run as a child process in a session of its own (it gets SIGTERM
when its parent dies; its last output is kept for error reports); `Graph` starts a list of them, waits
for their services and gives a client node and executor to call them; a node that dies is reported
with its exit code and last lines. Used by `dialfred_bringup/launch.py` (the jobs) and `dialfred_bringup/evaluation.py` (the
evaluation), and by the tests and benchmarks.
"""

from __future__ import annotations

import collections
import ctypes
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import rclpy
from rclpy.signals import SignalHandlerOptions

from dialfred_sim import ros_util
from dialfred_sim.ros_util import LAUNCHER_ENV, SERVICE_QOS, SETTLE_S

from .paths import REPO


def _spans_hosts(env) -> bool:
    if env.get('DIALFRED_NETWORK') in ('local', 'hosts'):      # decided already, by a parent process
        return env['DIALFRED_NETWORK'] == 'hosts'
    reach = env.get('ROS_AUTOMATIC_DISCOVERY_RANGE', '').strip().upper()
    peers = [p.strip() for p in env.get('ROS_STATIC_PEERS', '').split(';') if p.strip()]
    return reach not in ('', 'LOCALHOST', 'OFF') or any(not (p.startswith('127.') or p == 'localhost') for p in peers)


def network_environment(env, repo: Path) -> dict:
    """The DDS settings the graph's processes run with, given the caller's environment `env`.

    On one machine (the default; also a caller's LOCALHOST): config/fastdds_profiles.xml, which keeps
    UDP on the loopback interface and discovers by unicast to 127.0.0.1, with the discovery range
    SYSTEM_DEFAULT so that ROS leaves discovery to that file: no socket listens outside 127.0.0.0/8
    (Jazzy's LOCALHOST range opens sockets on every interface). Across hosts (a caller's SUBNET or
    SYSTEM_DEFAULT range, or static peers on other hosts: docs/scaling.md):
    config/fastdds_profiles_hosts.xml, UDP on every interface. A profile file the caller chose is
    kept. DIALFRED_NETWORK records the choice for the processes this one starts."""
    config = Path(repo) / 'config'
    if _spans_hosts(env):
        return {'DIALFRED_NETWORK': 'hosts', 'FASTRTPS_DEFAULT_PROFILES_FILE': env.get('FASTRTPS_DEFAULT_PROFILES_FILE')
                or str(config / 'fastdds_profiles_hosts.xml')}
    return {'DIALFRED_NETWORK': 'local', 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SYSTEM_DEFAULT',
            'FASTRTPS_DEFAULT_PROFILES_FILE': env.get('FASTRTPS_DEFAULT_PROFILES_FILE')
            or str(config / 'fastdds_profiles.xml')}


def use_project_environment(repo: Path) -> None:
    """Apply `network_environment` to this process (and so to the nodes it starts). A run whose
    discovery reaches other hosts says so once, on stderr."""
    os.environ.update(network_environment(os.environ, repo))
    if discovery_spans_hosts() and not os.environ.get('DIALFRED_SAID_HOSTS'):
        os.environ['DIALFRED_SAID_HOSTS'] = '1'
        print(f'dialfred: DDS discovery reaches other hosts (ROS_AUTOMATIC_DISCOVERY_RANGE='
              f'{os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "")!r}, ROS_STATIC_PEERS='
              f'{os.environ.get("ROS_STATIC_PEERS", "")!r}): the nodes listen on every interface', file=sys.stderr)


def discovery_spans_hosts() -> bool:
    """Whether this process's DDS discovery reaches other hosts: a range other than LOCALHOST or OFF
    (Jazzy's default when unset is SUBNET), or static peers off this host (docs/scaling.md)."""
    env = dict(os.environ)
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'SUBNET')      # Jazzy's default
    return _spans_hosts(env)


use_project_environment(REPO)      # this process, the nodes it starts, and what they start


def host_token() -> str:
    """This host's name as a ROS name token (letters, digits, single underscores)."""
    token = re.sub(r'_+', '_', re.sub(r'[^A-Za-z0-9_]', '_', socket.gethostname())).strip('_')
    return token or 'host'


def use_private_ros_domain() -> int:
    """Put this process (and the nodes it starts) in a ROS domain of its own, unless the caller chose
    one: benchmarks must not be answered, or slowed, by another graph on this machine."""
    if 'ROS_DOMAIN_ID' not in os.environ:
        os.environ['ROS_DOMAIN_ID'] = str(1 + os.getpid() % 101)   # 1-101: safe on Linux
    return int(os.environ['ROS_DOMAIN_ID'])


def resolve_executable(package: str, executable: str = 'node') -> Path:
    """<prefix>/lib/<package>/<executable> of an installed package, as `ros2 run` finds it."""
    # lazy: ament, which the rest of this module does without
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix
    try:
        prefix = get_package_prefix(package)
    except PackageNotFoundError:
        raise FileNotFoundError(f'package {package!r} is not in the ament index '
                                f'(AMENT_PREFIX_PATH={os.environ.get("AMENT_PREFIX_PATH", "")!r}); '
                                'run ./dialfred setup') from None
    path = Path(prefix) / 'lib' / package / executable
    if not os.access(path, os.X_OK):
        raise FileNotFoundError(f'{path} is missing or not executable')
    return path


class NodeDied(RuntimeError):
    pass


def _libc_prctl():
    try:
        return ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):   # pragma: no cover - not Linux
        return None


_PRCTL = _libc_prctl()
_PR_SET_PDEATHSIG = 1


def _die_with_parent() -> None:
    """In a new child (before exec): get SIGTERM when the launcher dies, however it dies, so that a
    killed launcher or benchmark never leaves nodes running (they live in sessions of their own)."""
    if _PRCTL is not None:
        _PRCTL(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)


@dataclass
class NodeProcess:
    """One node executable running as a child process, its output kept for error reports."""

    package: str
    parameters: dict = field(default_factory=dict)
    executable: str = 'node'
    namespace: str = ''          # e.g. '/w0': the node's relative names (sim/step) become /w0/sim/step
    stdin: Optional[int] = None  # subprocess.PIPE to feed it text (tests of the oracle's human mode)
    capture_output: bool = True  # False: it talks to this terminal (the oracle asking a person)
    proc: Optional[subprocess.Popen] = None
    tail: collections.deque = field(default_factory=lambda: collections.deque(maxlen=40))
    forced: bool = False         # the last stop() had to go past SIGINT (the node did not end in time)

    @property
    def label(self) -> str:
        return f'{self.package} [{self.namespace}]' if self.namespace else self.package

    def command(self) -> list[str]:
        ros_args = [a for k, v in self.parameters.items() for a in ('-p', f'{k}:={v}')]
        if self.namespace:
            ros_args += ['-r', f'__ns:={self.namespace}']
        cmd = [str(resolve_executable(self.package, self.executable))]
        return cmd + ['--ros-args'] + ros_args if ros_args else cmd

    def start(self) -> None:
        out = subprocess.PIPE if self.capture_output else None
        self.proc = subprocess.Popen(self.command(), stdin=self.stdin, stdout=out,
                                     stderr=subprocess.STDOUT if self.capture_output else None, text=True,
                                     start_new_session=True, preexec_fn=_die_with_parent,
                                     env={**os.environ, LAUNCHER_ENV: str(os.getpid())})
        if self.capture_output:
            threading.Thread(target=self._drain, daemon=True).start()

    def _drain(self) -> None:
        for line in self.proc.stdout:
            self.tail.append(line.rstrip())
            if os.environ.get('DIALFRED_VERBOSE'):
                print(f'[{self.label}] {line.rstrip()}', file=sys.stderr)

    def check(self) -> None:
        if self.proc is not None and self.proc.poll() is not None:
            out = '\n    '.join(list(self.tail)[-15:]) or '(no output)'
            raise NodeDied(f'{self.label} node died with exit code {self.proc.returncode}; last output:\n    {out}')

    def stop(self, timeout: float = 5.0) -> Optional[int]:
        if self.proc is None or self.proc.poll() is not None:
            return None if self.proc is None else self.proc.returncode
        self.forced = False
        for sig, wait in ((signal.SIGINT, timeout), (signal.SIGTERM, 2.0), (signal.SIGKILL, 2.0)):
            self.forced = sig != signal.SIGINT
            try:
                os.killpg(self.proc.pid, sig)
            except ProcessLookupError:
                break
            try:
                return self.proc.wait(wait)
            except subprocess.TimeoutExpired:
                continue
        return self.proc.poll()


class Graph:
    """The running node graph plus a client node in this process to talk to it.

    Ctrl-C: while the graph runs, SIGINT only sets a flag, and `check()` (called by every waiting
    loop here, at least every 0.5 s) raises KeyboardInterrupt from Python. A KeyboardInterrupt raised
    by the default handler inside a callback that the C++ EventsExecutor happens to be running can be
    swallowed there (a Ctrl-C lost once in a loaded test run); a flag cannot be."""

    def __init__(self, nodes: list[NodeProcess]):
        self.nodes = nodes
        self.client_node = None
        self.executor = None
        self.owns_context = False    # False inside another Graph of this process: share its rclpy context
        self._interrupted = threading.Event()
        self._previous_sigint = None

    def __enter__(self) -> 'Graph':
        try:
            self._start()
        except BaseException:
            self.__exit__()         # never leave started nodes behind (they run in their own sessions)
            raise
        return self

    def _start(self) -> None:
        for n in self.nodes:
            n.start()
        if not rclpy.ok():
            # Ctrl-C is this process's KeyboardInterrupt (unwinding through __exit__), not rclpy's
            # handler, which would shut the context down under a running spin (ExternalShutdownException).
            rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
            self.owns_context = True
            if threading.current_thread() is threading.main_thread():
                self._previous_sigint = signal.signal(signal.SIGINT, lambda *_: self._interrupted.set())
        self.client_node = rclpy.create_node('dialfred_launcher')
        self.executor = ros_util.make_executor()      # looked up when called (a test replaces it)
        self.executor.add_node(self.client_node)

    def __exit__(self, *exc) -> None:
        if self._previous_sigint is not None:
            signal.signal(signal.SIGINT, self._previous_sigint)
            self._previous_sigint = None
        if self.executor is not None:
            self.executor.shutdown()
        if self.client_node is not None:
            self.client_node.destroy_node()
        if self.owns_context:
            rclpy.try_shutdown()
        interrupted = bool(exc) and exc[0] is not None and issubclass(exc[0], KeyboardInterrupt)
        for n in self.nodes:
            code = n.stop()
            if code in (None, 0, -signal.SIGINT, 130):
                continue
            if code in (-signal.SIGTERM, -signal.SIGKILL) and n.forced:
                if not interrupted:      # after Ctrl-C, stopping what was running is what was asked for
                    print(f'{n.label} node did not end within 5 s of the stop signal; it was stopped '
                          f'({signal.Signals(-code).name})', file=sys.stderr)
            else:
                print(f'{n.label} node exited with code {code}', file=sys.stderr)

    def check(self) -> None:
        """KeyboardInterrupt after a Ctrl-C; NodeDied if a node died."""
        if self._interrupted.is_set():
            self._interrupted.clear()
            raise KeyboardInterrupt
        for n in self.nodes:
            n.check()

    def client(self, srv_type, name: str, timeout: float = 30.0):
        """A client for service `name`, once it is available; NodeDied if a node dies meanwhile."""
        cli = self.client_node.create_client(srv_type, name, qos_profile=SERVICE_QOS)
        deadline = time.monotonic() + timeout
        while not cli.wait_for_service(timeout_sec=0.1):
            self.check()
            if time.monotonic() > deadline:
                raise TimeoutError(f'service {name} not available after {timeout:.0f} s')
        # "Available" means the server's request reader matched; its reply writer may not have
        # matched our reply reader yet, and a reply sent before that is lost (a known DDS service
        # discovery race, ros2/rmw_fastrtps#390; under load it outlasted a fixed 0.2 s wait).
        # A request the server refuses without changing anything, sent until one reply comes
        # back, proves the reply path; services without such a request get a moment of discovery.
        from dialfred_sim.ros_util import refused_request
        probe = refused_request(srv_type)
        if probe is not None:
            self.call(cli, probe, timeout=max(1.0, deadline - time.monotonic()), retry_after=0.5)
            return cli
        settle = time.monotonic() + SETTLE_S
        while time.monotonic() < settle:
            self.executor.spin_once(timeout_sec=0.02)
        return cli

    def spin_until_any(self, futures: list, timeout: float = 0.5) -> None:
        """Serve callbacks until one of `futures` is done or `timeout` passes; NodeDied if a node dies."""
        deadline = time.monotonic() + timeout
        while not any(f.done() for f in futures) and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
        self.check()

    def call(self, cli, request, timeout: float = 30.0, retry_after: Optional[float] = None):
        """Call a service and wait for the reply, watching the nodes for crashes; TimeoutError after
        `timeout` s. `retry_after`: for requests that may be repeated (a reset, a question), send
        the request again when no reply came in that many seconds: a request sent while a restarted
        server is not yet discovered, or a reply sent before the server's reply path matched ours
        (see `client`), is lost, and waiting longer would not bring it."""
        deadline = time.monotonic() + timeout
        while True:
            future = cli.call_async(request)
            resend = time.monotonic() + retry_after if retry_after else deadline
            while not future.done() and time.monotonic() < min(resend, deadline):
                self.executor.spin_until_future_complete(future, timeout_sec=min(0.5, retry_after or 0.5))
                self.check()
            if future.done():
                return future.result()
            cli.remove_pending_request(future)
            if time.monotonic() >= deadline:
                raise TimeoutError(f'no reply from {cli.srv_name} after {timeout:.0f} s')
            cli.wait_for_service(timeout_sec=max(0.0, min(1.0, deadline - time.monotonic())))


def sim_node(resolution: int = 128, namespace: str = '', **params) -> NodeProcess:
    return NodeProcess('dialfred_sim', {'resolution': resolution, **params}, namespace=namespace)


def oracle_node(namespace: str = '', human: bool = False, **params) -> NodeProcess:
    """The oracle; `human` makes it ask a person in this terminal (its output is then not captured)."""
    if human:
        params['human'] = True
    return NodeProcess('dialfred_oracle', dict(params), namespace=namespace, capture_output=not human)


def sim_service(namespace: str, name: str) -> str:
    """The full name of the sim node's service `name` ('reset', 'step') in `namespace` ('' or '/w0')."""
    return f'{namespace.rstrip("/")}/sim/{name}'
