"""Small ROS helpers shared by the nodes and the launcher (imports rclpy; the core never does)."""

from __future__ import annotations

import functools
import traceback

from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

# Services that never drop a request. ROS's default service QoS keeps the last 10 requests: of 500
# sent at once, 12 were executed and the rest vanished without a reply (measured on /sim/step). With
# KEEP_ALL the server's reader holds every request until the node takes it, so a flood is served in
# order; tests/test_service_flood.py floods /sim/step and /oracle/answer to check it. Clients use it
# too, so that many replies arriving at once are not dropped on their side either.
SERVICE_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE, depth=1)


def refused_request(srv_type):
    """A request of `srv_type` that its dialfred server refuses without changing anything (an empty
    action, an unknown scene or object id), or None for other types."""
    from dialfred_msgs.msg import Action
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
        from rclpy.experimental.events_executor import EventsExecutor
        return EventsExecutor()
    except ImportError:  # pragma: no cover - older rclpy
        from rclpy.executors import SingleThreadedExecutor
        return SingleThreadedExecutor()


def spin_forever(executor) -> None:
    """Serve callbacks until shutdown.

    A loop of spin_once rather than spin(): with the Jazzy wheels' EventsExecutor (rclpy 7.1.6),
    spin() never dispatched service requests here, while spin_once() does (tested in
    tests/test_sim_node.py through the real node). Other executors spin().
    """
    import rclpy
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


def run_node(make_node, args=None, executor_factory=None) -> None:
    """The whole life of a node process: init, build the node (`make_node()`), serve until Ctrl-C
    or shutdown, then tear down in Jazzy's order. `executor_factory`: default `make_executor`."""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    rclpy.init(args=args)
    node = None
    executor = (executor_factory or make_executor)()
    try:
        node = make_node()
        executor.add_node(node)
        spin_forever(executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
