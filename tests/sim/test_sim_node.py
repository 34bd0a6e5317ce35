"""The simulator as a ROS 2 node (integration): the real `dialfred_sim node` executable, started in
its own process by the project launcher (`dialfred_bringup.launch.NodeProcess` inside a `Graph`), driven
through /sim/reset and /sim/step and watched on /sim/observation.

conftest.py gives this pytest session its own ROS_DOMAIN_ID, so the node under test is the only
/sim/* server this client can see. Nodes that must not answer the module's services (the SIGINT and
crash tests) are started in a second domain of this session's own.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from ament_index_python.packages import get_package_prefix
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from dialfred_msgs.msg import Action, Observation
from dialfred_msgs.srv import SimReset, SimStep
from dialfred_bringup.graph import Graph, NodeDied, NodeProcess, resolve_executable
from dialfred_sim.protocol import image_array

REPO = Path(__file__).resolve().parents[2]
RES = 64


class Sim:
    """The running graph, its service clients and what the node answered to its very first request."""

    def __init__(self, graph, node, reset_cli, step_cli, first_reply):
        self.graph, self.node = graph, node
        self.reset_cli, self.step_cli = reset_cli, step_cli
        self.first_reply = first_reply

    def reset(self, scene: str = 'FloorPlan1', seed: int = 0, task_id: str = ''):
        return self.graph.call(self.reset_cli, SimReset.Request(scene=scene, seed=seed, task_id=task_id))

    def step(self, action: str, x: int = 0, y: int = 0):
        return self.graph.call(self.step_cli, SimStep.Request(action=Action(action=action, x=x, y=y)))


@pytest.fixture(scope='module')
def sim():
    node = NodeProcess('dialfred_sim', {'resolution': RES})
    with Graph([node]) as graph:
        reset_cli = graph.client(SimReset, '/sim/reset')
        step_cli = graph.client(SimStep, '/sim/step')
        # The node's first request is a step, before any reset (test_step_before_reset_is_rejected).
        first = graph.call(step_cli, SimStep.Request(action=Action(action='MoveAhead')))
        yield Sim(graph, node, reset_cli, step_cli, first)


@pytest.fixture
def other_ros_domain(spare_ros_domain_id):
    """Start processes in a spare ROS domain of this session, so they never answer the main graph."""

    @contextlib.contextmanager
    def switch():
        mine = os.environ['ROS_DOMAIN_ID']
        os.environ['ROS_DOMAIN_ID'] = str(spare_ros_domain_id)
        try:
            yield
        finally:
            os.environ['ROS_DOMAIN_ID'] = mine

    return switch


def wait_for_output(node: NodeProcess, text: str, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while not any(text in line for line in list(node.tail)):
        assert node.proc.poll() is None, f'node exited early with {node.proc.returncode}: {list(node.tail)}'
        assert time.monotonic() < deadline, f'no "{text}" from the node in {timeout} s: {list(node.tail)}'
        time.sleep(0.05)


def wait_for_exit(node: NodeProcess, timeout: float = 30.0) -> int:
    try:
        return node.proc.wait(timeout)
    except subprocess.TimeoutExpired:
        node.stop()
        pytest.fail(f'node still running after {timeout} s')


def assert_valid_observation(obs: Observation) -> None:
    assert obs.header.frame_id == 'agent_camera'
    assert (obs.rgb.encoding, obs.rgb.height, obs.rgb.width, obs.rgb.step) == ('rgb8', RES, RES, RES * 3)
    assert (obs.depth.encoding, obs.depth.height, obs.depth.width, obs.depth.step) == ('32FC1', RES, RES, RES * 4)
    assert (obs.segmentation.encoding, obs.segmentation.height, obs.segmentation.width) == ('32SC1', RES, RES)
    assert len(obs.rgb.data) == RES * RES * 3 and len(obs.depth.data) == len(obs.segmentation.data) == RES * RES * 4
    depth = image_array(obs.depth)
    assert np.isfinite(depth).all() and (depth > 0).all()
    seg = image_array(obs.segmentation)
    assert len(obs.instance_ids) == len(obs.instance_object_ids) > 0
    # Every id in the image is listed (-1 would mark pixels where nothing was rendered).
    assert set(np.unique(seg).tolist()) - {-1} <= set(obs.instance_ids)
    p = obs.pose
    assert p.camera_height == pytest.approx(1.5)
    assert p.rotation_deg in (0.0, 90.0, 180.0, 270.0)
    assert -30.0 <= p.horizon_deg <= 60.0 and p.horizon_deg % 15 == 0
    assert (p.x / 0.25) == pytest.approx(round(p.x / 0.25)) and (p.y / 0.25) == pytest.approx(round(p.y / 0.25))


def pose_of(obs: Observation) -> tuple:
    p = obs.pose
    return (p.x, p.y, p.rotation_deg, p.horizon_deg)


# ---------------------------------------------------------------------------------------------- start-up

def test_the_executable_is_resolved_like_ros2_run(sim):
    expected = Path(get_package_prefix('dialfred_sim')) / 'lib' / 'dialfred_sim' / 'node'
    assert resolve_executable('dialfred_sim') == expected
    assert os.access(expected, os.X_OK)
    assert sim.node.proc.args[0] == str(expected)
    assert sim.node.proc.args[1:] == ['--ros-args', '-p', f'resolution:={RES}']
    assert sim.node.proc.poll() is None
    sim.graph.check()


def test_the_node_runs_in_this_sessions_own_ros_domain(sim, ros_domain_id):
    assert 1 <= ros_domain_id <= 101
    environ = Path(f'/proc/{sim.node.proc.pid}/environ').read_bytes().split(b'\0')
    assert f'ROS_DOMAIN_ID={ros_domain_id}'.encode() in environ
    assert b'DIALFRED_NETWORK=local' in environ and b'ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT' in environ
    assert any(e.startswith(b'FASTRTPS_DEFAULT_PROFILES_FILE=') and e.endswith(b'config/fastdds_profiles.xml')
               for e in environ)                    # the loopback-only profile (tests/system/test_network.py)


def test_an_unknown_package_is_reported_clearly():
    with pytest.raises(FileNotFoundError, match="'no_such_pkg' is not in the ament index"):
        resolve_executable('no_such_pkg')


def test_step_before_reset_is_rejected(sim):
    reply = sim.first_reply
    assert not reply.ok
    assert 'step before reset' in reply.error
    assert sim.reset().ok        # and the node serves on


# ---------------------------------------------------------------------------------------------- reset / step

def test_reset_returns_the_first_observation(sim):
    reply = sim.reset('FloorPlan1', seed=3)
    assert reply.ok and reply.error == ''
    assert reply.task.scene == 'FloorPlan1'
    obs = reply.observation
    assert_valid_observation(obs)
    assert obs.pose.horizon_deg == 30.0
    assert (obs.step_count, obs.failed_actions, obs.done, obs.held_object) == (0, 0, False, '')
    assert obs.last_action_success and obs.last_action_error == ''


def test_the_node_shows_exactly_what_the_env_computes(sim, env):
    reply = sim.reset('FloorPlan205', seed=9)
    assert reply.ok
    expected, info = env.reset(seed=9, options={'scene': 'FloorPlan205'})
    obs = reply.observation
    assert np.array_equal(image_array(obs.rgb), expected['rgb'])
    assert np.array_equal(image_array(obs.depth), expected['depth'])
    assert np.array_equal(image_array(obs.segmentation), expected['segmentation'])
    assert pose_of(obs) == tuple(float(v) for v in expected['pose'])
    ids, names = info['instances']
    assert list(obs.instance_ids) == ids and list(obs.instance_object_ids) == names
    # Steps too: the node hands the frames' own buffers to rclpy (no copy), byte for byte.
    for action in ('RotateLeft', 'MoveAhead', 'LookDown'):
        obs = sim.step(action).observation
        expected = env.step({'action': action, 'pixel': (0, 0)})[0]
        for name in ('rgb', 'depth', 'segmentation'):
            assert np.array_equal(image_array(getattr(obs, name)), expected[name]), (action, name)


def test_rotate_and_move_ahead_change_the_pose(sim):
    obs = sim.reset('FloorPlan1', seed=0).observation
    reply = sim.step('RotateLeft')
    assert reply.ok and reply.observation.last_action_success
    assert reply.observation.pose.rotation_deg == (obs.pose.rotation_deg + 90) % 360
    assert reply.observation.step_count == 1
    assert_valid_observation(reply.observation)
    for _ in range(4):        # find a heading with free floor ahead
        before = reply.observation.pose
        reply = sim.step('MoveAhead')
        assert reply.ok
        if reply.observation.last_action_success:
            after = reply.observation.pose
            assert abs(after.x - before.x) + abs(after.y - before.y) == pytest.approx(0.25)
            return
        assert 'MoveAhead blocked' in reply.observation.last_action_error
        assert pose_of(reply.observation) == (before.x, before.y, before.rotation_deg, before.horizon_deg)
        reply = sim.step('RotateLeft')
    pytest.fail('MoveAhead blocked in every direction')


def test_a_step_can_leave_depth_and_segmentation_out_of_the_reply(sim):
    sim.reset('FloorPlan1', seed=0)
    request = SimStep.Request(action=Action(action='RotateLeft'), with_depth=False, with_segmentation=False)
    reply = sim.graph.call(sim.step_cli, request)
    assert reply.ok and reply.observation.last_action_success
    obs = reply.observation
    assert (obs.rgb.height, obs.rgb.width, len(obs.rgb.data)) == (RES, RES, RES * RES * 3)
    assert len(obs.depth.data) == 0 and len(obs.segmentation.data) == 0
    assert len(obs.instance_ids) == 0   # the id table travels with the segmentation it explains
    # By default every channel comes back.
    assert_valid_observation(sim.step('RotateRight').observation)


def test_a_failed_action_is_ok_but_unsuccessful(sim):
    sim.reset('FloorPlan1', seed=0)
    for _ in range(4):
        sim.step('LookUp')
    reply = sim.step('LookUp')
    assert reply.ok                                   # the request was fine ...
    obs = reply.observation
    assert not obs.last_action_success                # ... the action failed in the world
    assert 'cannot look up further' in obs.last_action_error
    assert obs.failed_actions == 1 and obs.step_count == 5
    assert not reply.terminated and not reply.truncated and not obs.done


# ---------------------------------------------------------------------------------------------- bad requests

BAD_STEPS = [
    pytest.param('Jump', 0, 0, "unknown action 'Jump'", id='unknown-action'),
    pytest.param('', 0, 0, 'unknown action', id='empty-action'),
    pytest.param('Pickup', RES, 10, f'outside the {RES}x{RES} frame', id='pixel-right-of-frame'),
    pytest.param('Open', 10, -1, f'outside the {RES}x{RES} frame', id='pixel-above-frame'),
]


@pytest.mark.parametrize('action, x, y, error', BAD_STEPS)
def test_a_bad_step_is_rejected_and_the_node_serves_on(sim, action, x, y, error):
    start = sim.reset('FloorPlan1', seed=0).observation
    reply = sim.step(action, x, y)
    assert not reply.ok and error in reply.error
    sim.graph.check()
    reply = sim.step('RotateRight')                   # nothing was counted or changed by the bad request
    assert reply.ok and reply.observation.step_count == 1 and reply.observation.failed_actions == 0
    assert reply.observation.pose.x == start.pose.x and reply.observation.pose.y == start.pose.y


@pytest.mark.parametrize('scene, task_id, error', [
    pytest.param('FloorPlan999', '', "unknown scene 'FloorPlan999'", id='unknown-scene'),
    pytest.param('Kitchen', '', "unknown scene 'Kitchen'", id='not-a-floor-plan'),
    pytest.param('FloorPlan1', 'trial_T20190909_000000', 'unknown task_id', id='unknown-task'),
])
def test_a_bad_reset_is_rejected_and_the_node_serves_on(sim, scene, task_id, error):
    sim.reset('FloorPlan2', seed=1)
    sim.step('RotateLeft')
    reply = sim.reset(scene, seed=0, task_id=task_id)
    assert not reply.ok and error in reply.error
    sim.graph.check()
    # The running episode goes on untouched ...
    reply = sim.step('RotateLeft')
    assert reply.ok and reply.observation.step_count == 2
    # ... and a valid reset still works.
    reply = sim.reset('FloorPlan3', seed=0)
    assert reply.ok and reply.task.scene == 'FloorPlan3'


def test_a_negative_seed_is_refused_and_the_node_serves_on(sim):
    # gymnasium raises a non-ValueError for it, which used to end the node's process.
    reply = sim.reset('FloorPlan1', seed=-1)
    assert not reply.ok and 'seed must be a non-negative integer, got -1' in reply.error
    sim.graph.check()
    assert sim.reset('FloorPlan1', seed=2 ** 63 - 1).ok


def test_a_fuzz_of_malformed_requests_gets_a_reply_each_and_the_node_serves_on(sim):
    rng = np.random.default_rng(7)
    words = ['', ' ', 'FloorPlan', 'FloorPlan0', 'FloorPlan-1', 'FloorPlan1 ', 'floorplan1', 'valid_unseen/',
             'valid_unseen/999999', 'valid_unseen/-1', '../../etc/passwd', 'x' * 5000, 'é\u00e9\u4e2d', '\x00',
             'Pickup', 'pickup', 'Stop ', 'MoveAhead\n', 'Teleport']
    extremes = [0, -1, 1, 2 ** 31 - 1, -2 ** 31, 64, 65, 10 ** 6]
    replies = 0
    for k in range(120):
        if k % 2:
            request = SimReset.Request(scene=str(rng.choice(words)), task_id=str(rng.choice(words)) if k % 3 else '',
                                       seed=int(rng.choice([0, -1, -2 ** 63, 2 ** 63 - 1, 5])))
            reply = sim.graph.call(sim.reset_cli, request)
        else:
            action = Action(action=str(rng.choice(words)), x=int(rng.choice(extremes)), y=int(rng.choice(extremes)))
            reply = sim.graph.call(sim.step_cli, SimStep.Request(action=action))
        assert reply.ok or reply.error          # an answer, and a reason when it is a refusal
        assert 'internal error' not in reply.error, reply.error
        replies += 1
    sim.graph.check()
    assert replies == 120
    assert sim.reset('FloorPlan1', seed=0).ok and sim.step('RotateLeft').ok


def test_a_flood_of_500_concurrent_steps_is_answered_in_order(sim):
    """ROS's default service queue kept 10 requests: of 500 sent at once, 12 were executed and the
    rest never got a reply. Every request must be answered."""
    assert sim.reset('FloorPlan1', seed=0).ok
    request = SimStep.Request(action=Action(action='RotateLeft'), with_depth=False, with_segmentation=False)
    futures = [sim.step_cli.call_async(request) for _ in range(500)]
    deadline = time.monotonic() + 120
    while not all(f.done() for f in futures) and time.monotonic() < deadline:
        sim.graph.spin_until_any([f for f in futures if not f.done()][:1], timeout=0.5)
    replies = [f.result() for f in futures if f.done()]
    assert len(replies) == 500
    assert all(r.ok for r in replies)
    assert sorted(r.observation.step_count for r in replies) == list(range(1, 501))


def test_an_exception_in_a_callback_becomes_an_error_reply():
    from dialfred_sim.ros_util import error_reply

    class Logger:
        def __init__(self):
            self.lines = []

        def error(self, text):
            self.lines.append(text)

    class FakeNode:
        logger = Logger()

        def get_logger(self):
            return self.logger

        @error_reply()
        def on_step(self, request, response):
            response.ok = True
            return {}['missing']     # any bug

    reply = FakeNode().on_step(SimStep.Request(), SimStep.Response())
    assert not reply.ok and reply.error.startswith("internal error: KeyError: 'missing'")
    assert 'Traceback' in FakeNode.logger.lines[0]


def test_stepping_after_the_episode_ended_is_rejected(sim):
    sim.reset('FloorPlan1', seed=0)
    reply = sim.step('Stop')
    assert reply.ok and reply.terminated and not reply.truncated and reply.observation.done
    reply = sim.step('RotateLeft')
    assert not reply.ok and 'episode is over' in reply.error
    assert sim.reset('FloorPlan1', seed=0).ok


def test_a_reset_with_an_empty_scene_keeps_the_current_scene(sim):
    assert sim.reset('FloorPlan5', seed=0).task.scene == 'FloorPlan5'
    reply = sim.reset('', seed=1)
    assert reply.ok
    assert reply.task.scene == 'FloorPlan5'


# ---------------------------------------------------------------------------------------------- topic

def test_an_observation_is_published_after_a_step(sim):
    graph = sim.graph
    qos = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=1)
    received = []
    sub = graph.client_node.create_subscription(Observation, '/sim/observation', received.append, qos)
    try:
        deadline = time.monotonic() + 15
        while graph.client_node.count_publishers('/sim/observation') < 1:
            assert time.monotonic() < deadline, 'no publisher on /sim/observation'
            graph.executor.spin_once(timeout_sec=0.1)
        sim.reset('FloorPlan1', seed=0)
        for _attempt in range(5):        # the node publishes once it has matched this subscriber
            received.clear()
            reply = sim.step('RotateLeft')
            assert reply.ok
            deadline = time.monotonic() + 2
            while not any(m.step_count == reply.observation.step_count for m in received) \
                    and time.monotonic() < deadline:
                graph.executor.spin_once(timeout_sec=0.05)
            mine = [m for m in received if m.step_count == reply.observation.step_count]
            if mine:
                msg = mine[-1]
                assert pose_of(msg) == pose_of(reply.observation)
                assert bytes(msg.rgb.data) == bytes(reply.observation.rgb.data)
                assert_valid_observation(msg)
                return
        pytest.fail('no observation on /sim/observation after 5 steps')
    finally:
        graph.client_node.destroy_subscription(sub)


# ---------------------------------------------------------------------------------------------- lifecycle

def test_sigint_shuts_the_node_down_cleanly(other_ros_domain):
    node = NodeProcess('dialfred_sim', {'resolution': 16})
    with other_ros_domain():
        node.start()
    try:
        wait_for_output(node, 'serving /sim/reset')
        time.sleep(0.3)
        t0 = time.monotonic()
        os.killpg(node.proc.pid, signal.SIGINT)
        code = wait_for_exit(node, timeout=5)
        assert code in (0, -signal.SIGINT), list(node.tail)
        assert time.monotonic() - t0 < 5
    finally:
        node.stop()


def test_a_node_that_dies_at_start_is_reported_with_its_exit_code(other_ros_domain):
    node = NodeProcess('dialfred_sim', {'resolution': 5})      # the env rejects it: ValueError
    graph = Graph([node])
    with other_ros_domain():
        node.start()
    try:
        code = wait_for_exit(node)
        assert code != 0
        with pytest.raises(NodeDied, match=rf'dialfred_sim node died with exit code {code}') as err:
            graph.check()
        time.sleep(0.2)      # let the output thread read the last lines
        with pytest.raises(NodeDied, match='parameter resolution: .*out of range. Min: 16, Max: 1024'):
            graph.check()
        assert 'last output' in str(err.value)
    finally:
        node.stop()


def test_after_a_restart_of_the_simulator_a_reset_is_answered():
    """A request sent while the restarted node is not yet discovered is lost: the client sends a
    reset again (it may be repeated) instead of waiting for a reply that will never come. (In this
    session's own domain: a Graph in this process shares the context of any other one alive.)"""
    node = NodeProcess('dialfred_sim', {'resolution': 32}, namespace='/restart')
    with Graph([node]) as graph:
        cli = graph.client(SimReset, '/restart/sim/reset')
        request = SimReset.Request(scene='FloorPlan1', seed=0, with_depth=False, with_segmentation=False)
        first = graph.call(cli, request)
        node.stop()
        node.start()
        t0 = time.monotonic()
        reply = graph.call(cli, request, timeout=30.0, retry_after=1.0)
        assert reply.ok and time.monotonic() - t0 < 30.0
        assert bytes(reply.observation.rgb.data) == bytes(first.observation.rgb.data)
        nobody = graph.client_node.create_client(SimReset, '/nobody/sim/reset')
        with pytest.raises(TimeoutError, match='no reply from /nobody/sim/reset after 2 s'):
            graph.call(nobody, request, timeout=2.0, retry_after=0.5)      # a clear timeout, not a hang


def test_a_node_killed_while_running_is_reported_with_its_exit_code(other_ros_domain):
    node = NodeProcess('dialfred_sim', {'resolution': 16})
    graph = Graph([node])
    with other_ros_domain():
        node.start()
    try:
        wait_for_output(node, 'serving /sim/reset')
        graph.check()                          # alive: nothing to report
        node.proc.kill()
        assert wait_for_exit(node, timeout=5) == -signal.SIGKILL
        with pytest.raises(NodeDied, match=rf'exit code {-signal.SIGKILL}'):
            graph.check()
    finally:
        node.stop()


# ---------------------------------------------------------------------- tasks through the node

@pytest.fixture(scope='module')
def task_sim():
    """A second node at the tasks' own resolution, in a namespace of its own."""
    node = NodeProcess('dialfred_sim', {'resolution': 128}, namespace='/tasks')
    with Graph([node]) as graph:
        yield graph, graph.client(SimReset, '/tasks/sim/reset'), graph.client(SimStep, '/tasks/sim/step')


def test_a_task_reset_tells_only_the_public_task_and_the_expert_reaches_its_goal(task_sim):
    from dialfred_msgs.srv import GroundTruth
    from dialfred_sim.tasks import get_task
    graph, reset_cli, step_cli = task_sim
    task = get_task('valid_unseen/000003')
    reply = graph.call(reset_cli, SimReset.Request(task_id=task.task_id))
    assert reply.ok, reply.error
    t = reply.task
    assert (t.task_id, t.scene, t.split, t.instruction) == (task.task_id, task.scene, 'valid_unseen', task.instruction)
    assert list(t.object_nouns) == task.object_nouns
    # Whoever resets learns nothing of the solution: no type, step plan, expert length or end pose.
    assert not {'task_type', 'step_instructions', 'expert_length', 'expert_end_pose'} & set(t.get_fields_and_field_types())
    assert reply.goal_conditions_total > 0
    # The oracle's privileged channel has them.
    truth = graph.call(graph.client(GroundTruth, '/tasks/sim/ground_truth'), GroundTruth.Request())
    key = truth.answer_key
    assert (key.task_type, list(key.step_instructions)) == (task.task_type, task.step_instructions)
    # GC's total: the goal conditions that do not hold at the start (a go-to may begin within reach of its pose)
    assert key.expert_length == task.expert_length
    assert key.goal_conditions_total == reply.goal_conditions_total <= len(task.goal)
    assert key.expert_end_pose.x == task.expert_end_pose[0] * 0.25
    for a in task.expert_actions:
        step = graph.call(step_cli, SimStep.Request(action=Action(action=a.action, x=a.x, y=a.y)))
        assert step.ok and step.observation.last_action_success, step.observation.last_action_error
        if step.terminated:
            break
    assert step.success and step.terminated and step.reward == 1.0
    assert step.goal_conditions_met == step.goal_conditions_total == reply.goal_conditions_total


def test_a_task_counts_only_the_goal_conditions_left_to_do_at_its_start(task_sim):
    """A Heat task's goal is hot + in hand + microwave closed; the last two hold at the start, so the
    reset and every step report 1 condition to achieve, and stopping at once achieves none."""
    from dialfred_sim.tasks import load_split
    graph, reset_cli, step_cli = task_sim
    task = next(t for t in load_split('valid_unseen') if t.task_type == 'Heat')
    reply = graph.call(reset_cli, SimReset.Request(task_id=task.task_id))
    assert reply.ok, reply.error
    assert len(task.goal) == 3 and reply.goal_conditions_total == 1
    step = graph.call(step_cli, SimStep.Request(action=Action(action='Stop')))
    assert step.ok and step.terminated and not step.success
    assert (step.goal_conditions_met, step.goal_conditions_total) == (0, 1)


def test_free_exploration_has_no_goal(task_sim):
    graph, reset_cli, step_cli = task_sim
    assert graph.call(reset_cli, SimReset.Request(scene='FloorPlan1', seed=0)).ok
    step = graph.call(step_cli, SimStep.Request(action=Action(action='RotateLeft')))
    assert step.ok and not step.success and step.goal_conditions_total == 0
