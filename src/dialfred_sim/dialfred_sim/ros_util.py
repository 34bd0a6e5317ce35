"""Small ROS helpers shared by the nodes and the launcher (imports rclpy; the core never does)."""

from __future__ import annotations

import functools
import math
import os
import sys
import traceback
from dataclasses import dataclass
from typing import Any, Callable, Optional, Union

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import InvalidParameterValueException
from rclpy.executors import ExternalShutdownException
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from .processes import watch_parent

# Services that never drop a request. ROS's default service QoS keeps the last 10 requests: of 500
# sent at once, 12 were executed and the rest vanished without a reply (measured on /sim/step). With
# KEEP_ALL the server's reader holds every request until the node takes it, so a flood is served in
# order; tests/test_service_flood.py floods /sim/step and /oracle/answer to check it. Clients use it
# too, so that many replies arriving at once are not dropped on their side either.
# A reset or a question unanswered this long is sent again (a request sent before DDS matched the reply path,
# or to a node being restarted, is lost; both may be repeated). Steps are never repeated: they change the world.
RESEND_AFTER_S = 5.0
# After a service first appears, its reply path may match a moment later.
SETTLE_S = 0.2
SERVICE_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE, depth=1)


def refused_request(srv_type):
    """A request of `srv_type` that its dialfred server refuses without changing anything (an empty
    action, an unknown scene or object id), or None for other types."""
    from dialfred_msgs.msg import Action  # lazy: the ROS messages, which the rest of this module does without
    # lazy: the ROS messages, which the rest of this module does without
    from dialfred_msgs.srv import GroundTruth, SimReset, SimStep
    probes = {SimStep: lambda: SimStep.Request(action=Action(action=''), with_depth=False, with_segmentation=False),
              SimReset: lambda: SimReset.Request(scene='-', with_depth=False, with_segmentation=False),
              GroundTruth: lambda: GroundTruth.Request(appearance_of=['-'])}
    # (No OracleAnswer probe: the oracle logs every question it is asked, and its callers resend.)
    make = probes.get(srv_type)
    return make() if make else None


def make_executor():
    """The EventsExecutor (measured about 4x lower service latency here), else single-threaded."""
    try:
        # lazy: experimental in rclpy; one without it gets the single-threaded executor below
        from rclpy.experimental.events_executor import EventsExecutor
        return EventsExecutor()
    except ImportError:  # pragma: no cover - older rclpy
        from rclpy.executors import SingleThreadedExecutor  # lazy: needed only without the EventsExecutor
        return SingleThreadedExecutor()


def spin_forever(executor) -> None:
    """Serve callbacks until shutdown.

    A loop of spin_once rather than spin(): with the Jazzy wheels' EventsExecutor (rclpy 7.1.6),
    spin() never dispatched service requests here, while spin_once() does (tested in
    tests/sim/test_sim_node.py through the real node). Other executors spin().
    """
    if type(executor).__name__ != 'EventsExecutor':
        executor.spin()
        return
    while rclpy.ok():
        executor.spin_once(timeout_sec=0.5)


def error_reply(field: str = 'error', flag: str = 'ok'):
    """Decorate a service callback `(self, request, response) -> response` so that no exception
    escapes it: an unexpected one is logged with its traceback and answered with `flag`=False and
    `field`='internal error: <type>: <message>' (a fresh response, so no half-filled reply goes
    out). An exception in an rclpy callback would otherwise end the node's spin and the process."""
    def wrap(callback):
        @functools.wraps(callback)
        def serve(self, request, response):
            try:
                return callback(self, request, response)
            except Exception as exc:   # the node must keep serving whatever a request does
                self.get_logger().error(f'{callback.__name__} failed: {exc!r}\n{traceback.format_exc()}')
                fresh = type(response)()
                setattr(fresh, flag, False)
                setattr(fresh, field, f'internal error: {type(exc).__name__}: {str(exc)[:200]}')
                return fresh
        return serve
    return wrap


# The launcher (dialfred_bringup.graph) names itself in its nodes' environment. A node it started ends
# within LAUNCHER_GRACE_S of the launcher's death even if a callback never returns: the SIGTERM the
# launcher's death sends (PR_SET_PDEATHSIG) reaches rclpy only when the executor gets control back, and a
# callback waiting on a peer that died with the launcher may never give it back (measured: a node stuck
# in a callback outlived SIGTERM indefinitely). A node started by hand does not watch its parent.
LAUNCHER_ENV = 'DIALFRED_LAUNCHER_PID'
LAUNCHER_GRACE_S = 5.0


def exit_with_launcher(grace_s: float = LAUNCHER_GRACE_S) -> bool:
    """In a node process started by the launcher (LAUNCHER_ENV names its parent): end the process
    `grace_s` seconds after the launcher dies. Whether the watch started."""
    if os.environ.get(LAUNCHER_ENV) != str(os.getppid()):
        return False
    watch_parent(grace_s=grace_s)
    return True


def run_node(make_node, args=None, executor_factory=None) -> None:
    """The whole life of a node process: init, build the node (`make_node()`), serve until Ctrl-C
    or shutdown, then tear down in Jazzy's order. `executor_factory`: default `make_executor`. A node
    the launcher started ends soon after the launcher does (`exit_with_launcher`)."""
    exit_with_launcher()
    rclpy.init(args=args)
    node, refused = None, None
    executor = (executor_factory or make_executor)()
    try:
        try:
            node = make_node()
        except ValueError as exc:     # a parameter out of range, an unknown name: one line, not a traceback
            refused = f'{getattr(make_node, "__name__", "node")}: {exc}'
        else:
            executor.add_node(node)
            spin_forever(executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    if refused:
        print(refused, file=sys.stderr)
        sys.exit(1)


# ---------------------------------------------------------------------- parameters

MAX_SEED = 2 ** 31 - 1


@dataclass(frozen=True)
class Param:
    """A node parameter: its default, what it means, the values it takes (an inclusive `span` for a
    number, `choices` for a string: a tuple, or a function giving it when asked, for values read from a
    registry) and whether it may change while the node runs."""

    name: str
    default: Any
    description: str
    span: Optional[tuple] = None
    choices: Optional[Union[tuple, Callable[[], tuple]]] = None
    dynamic: bool = False

    def allowed(self) -> Optional[tuple]:
        """The values a string parameter takes now (None: any)."""
        return self.choices() if callable(self.choices) else self.choices

    def problem(self, value) -> Optional[str]:
        """Why `value` is not acceptable, or None."""
        if isinstance(self.default, bool) != isinstance(value, bool) or (
                isinstance(self.default, (int, float)) and not isinstance(value, (int, float))) or (
                isinstance(self.default, str) and not isinstance(value, str)):
            return f'{self.name} takes a {type(self.default).__name__}, got {value!r}'
        if isinstance(value, float) and not math.isfinite(value):
            return f'{self.name} must be a finite number, got {value}'
        if self.span is not None and not self.span[0] <= value <= self.span[1]:
            return f'{self.name} must be in [{self.span[0]}, {self.span[1]}], got {value}'
        allowed = self.allowed()
        if allowed is not None and value not in allowed:
            return f'{self.name} must be one of {", ".join(repr(c) for c in allowed)}, got {value!r}'
        return None

    def descriptor(self):
        text = self.description + ('' if self.dynamic else ' (read only: set when the node starts)')
        d = ParameterDescriptor(description=text, read_only=not self.dynamic)
        if self.span is not None and isinstance(self.default, float):
            d.floating_point_range = [FloatingPointRange(from_value=float(self.span[0]), to_value=float(self.span[1]))]
        elif self.span is not None and isinstance(self.default, int) and not isinstance(self.default, bool):
            d.integer_range = [IntegerRange(from_value=int(self.span[0]), to_value=int(self.span[1]), step=1)]
        return d


def declare_parameters(node, params) -> None:
    """Declare `params` (each with its description, range and read_only flag), check the values the
    node was started with (ValueError naming the parameter: the node does not start), and refuse a
    later change that breaks a Param's rules with the reason (NaN and infinity included, which
    ROS's own range check lets through)."""
    by_name = {p.name: p for p in params}
    for p in params:
        try:
            node.declare_parameter(p.name, p.default, p.descriptor())
        except InvalidParameterValueException as exc:
            raise ValueError(f'parameter {p.name}: {exc}') from None
        problem = p.problem(node.get_parameter(p.name).value)
        if problem:
            raise ValueError(f'parameter {problem}')

    def check(changes):
        for change in changes:
            rule = by_name.get(change.name)
            problem = rule.problem(change.value) if rule is not None else None
            if problem:
                return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(check)
