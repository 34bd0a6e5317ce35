"""`dialfred_performer node`: the performer as a ROS 2 node, serving the action `performer/run_task`.

A goal (dialfred_msgs/action/RunTask: a task id and the episode's seed) is played to its end through
the graph: `sim/reset` (the public TaskDescription and RGB only), then before each action, when the
`questioner` parameter is on, `questioner/ask` (with the policy's top-2 action-probability gap) and
`oracle/answer` for each question it asks, and `sim/step` with the policy's decision. Every QA is
published on `dialogue/qa` (dialfred_msgs/QAPair) and every action command on `performer/action`
(dialfred_msgs/Action); feedback after each step. A policy that keeps a map (`model:=map`) publishes a
picture of its belief with each action on `performer/map` (sensor_msgs/Image, rgb8) while anything
subscribes or records. The result comes from the simulator's step
replies (the simulator is the checker). All names are relative: in a namespace /w0 they are
/w0/sim/reset, /w0/performer/run_task, ...

The decisions come from a policy object of the core (`agent.PerformerAgent`: reset/hear/act/
action_probabilities); this node only converts messages. The server has the shape of ros2/demos'
fibonacci_action_server: one goal at a time (a goal sent while one runs is rejected), cancel checked
before every question and action. Its clients live in a reentrant callback group on a multi-threaded
executor and wait for replies with a timeout (never spin inside a callback); a reset or question
that got no reply is sent again, a step never is. A bad goal (unknown task, missing or corrupt
checkpoint, negative seed) ends aborted with end_reason 'error' and the reason; the node keeps serving.

With the `record_dir` parameter set, each goal's episode is also written as a ROS 2 bag (rosbag2,
MCAP storage; `dialfred_sim.bag`): `<record_dir>/<split>_<number>/`, from the messages this node
sent and received (the task, every frame and pose, QA, action, its feedback and the result). The goals
of a chained episode (protocol 'chained', its first goal then carry_on ones) are one bag,
`<record_dir>/<split>_<first number>_chained/`, that holds its tasks in order.
"""

from __future__ import annotations

import os
import threading
import time
import traceback
from pathlib import Path
from typing import Optional

import torch
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import Image

from dialfred_msgs.action import RunTask
from dialfred_msgs.msg import Action, QAPair
from dialfred_msgs.srv import OracleAnswer, QuestionerAsk, SimReset, SimStep
from dialfred_sim.episode import Ask, EpisodeObserver, EpisodeState, Reset, play, run
from dialfred_sim.messages import qa_from_answer, qa_msg, sim_reply, task_description_msg
from dialfred_sim.protocol import (MAX_QUESTIONS, PROTOCOLS, QA, ConfusionSource, Continuing, MapPainter, Question,
                                  heard_by, top2_gap)
from dialfred_sim.bag import IMAGE_FORMATS, RecordingObserver
from dialfred_sim.ros_util import (RESEND_AFTER_S, SERVICE_QOS, SETTLE_S, Param, declare_parameters, refused_request,
                                   run_node)

from .model import SHIPPED_CHECKPOINT, CheckpointError
from .model_registry import PERFORMER_MODELS, camera_resolution, load_policy



class GoalFailed(RuntimeError):
    """The goal cannot be played on: its result says why (end_reason 'error')."""


class GoalCanceled(Exception):
    pass


# The node's parameters (ros_util.Param): declared with their ranges; docs tables are made from them.
PARAMETERS = (
    Param('checkpoint', str(SHIPPED_CHECKPOINT), "the policy (default: the shipped et.pt; '' = none); a goal may "
          'name another; each file is loaded once, and again if it changes'),
    Param('model', 'et', 'how the checkpoint decides (dialfred_performer.model_registry): ' +
          '; '.join(f'{m.name}: {m.description}' for m in PERFORMER_MODELS.values()), choices=tuple(PERFORMER_MODELS)),
    Param('questioner', False, 'ask questioner/ask before every action (and oracle/answer what it asks)'),
    Param('request_timeout', 60.0, 'seconds one reset, step, question or answer may take before the goal '
          'fails', span=(0.1, 86_400.0), dynamic=True),
    Param('answer_timeout', 0.0, "seconds the oracle's answer may take (0: request_timeout); a person's pace: the "
          'launcher sets it with --human', span=(0.0, 1e9), dynamic=True),
    Param('max_questions', MAX_QUESTIONS, 'questions in a row without acting before the goal fails', span=(1, 1000),
          dynamic=True),
    Param('torch_threads', 1, 'torch intra-op threads (1: the simulators and other workers share the cores)',
          span=(1, 256)),
    Param('record_dir', '', "write each goal's episode as a rosbag2/MCAP bag into `<record_dir>/<split>_<number>/` "
          "('' = no recording)"),
    Param('record_format', 'raw', 'camera frames in the bags: raw (sensor_msgs/Image), png or jpeg '
          '(CompressedImage)', choices=IMAGE_FORMATS))

class PerformerNode(Node):
    def __init__(self):
        super().__init__('dialfred_performer')
        declare_parameters(self, PARAMETERS)
        p = self.get_parameter
        self.record_dir = str(p('record_dir').value)
        self.record_format = str(p('record_format').value)
        self.recorder = None       # the running goal's RecordingObserver, when recording
        self.chain_recorder = None  # the chained episode's RecordingObserver, kept for its next task's goal
        torch.set_num_threads(max(1, int(p('torch_threads').value)))
        self.checkpoint = p('checkpoint').value
        self.model = str(p('model').value)
        self.use_questioner = bool(p('questioner').value)
        group = ReentrantCallbackGroup()
        self.reset_cli = self.create_client(SimReset, 'sim/reset', qos_profile=SERVICE_QOS, callback_group=group)
        self.step_cli = self.create_client(SimStep, 'sim/step', qos_profile=SERVICE_QOS, callback_group=group)
        self.oracle_cli = self.create_client(OracleAnswer, 'oracle/answer', qos_profile=SERVICE_QOS,
                                             callback_group=group)
        self.questioner_cli = self.create_client(QuestionerAsk, 'questioner/ask', qos_profile=SERVICE_QOS,
                                                 callback_group=group)
        self.qa_pub = self.create_publisher(QAPair, 'dialogue/qa', 100)
        self.action_pub = self.create_publisher(Action, 'performer/action', 100)
        self.map_pub = self.create_publisher(Image, 'performer/map', 10)
        self._policies: dict = {}     # checkpoint path -> ((mtime, size), policy of self.model, its camera pixels)
        self._camera_warned: set = set()   # (checkpoint path, width, height) already warned of
        self._busy = False
        self._lock = threading.Lock()
        self._settled: set = set()
        self.server = ActionServer(self, RunTask, 'performer/run_task', execute_callback=self.execute,
                                   goal_callback=self.on_goal, cancel_callback=self.on_cancel,
                                   callback_group=group)
        if self.checkpoint:
            try:
                self.policy(self.checkpoint)
            except (FileNotFoundError, CheckpointError, ValueError) as exc:   # goals will say it too
                self.get_logger().error(f'checkpoint: {exc}')
        self.get_logger().info(f'serving performer/run_task (model {self.model}, checkpoint {self.checkpoint or "none"}, '
                               f'questioner {"on" if self.use_questioner else "off"})')

    # ------------------------------------------------------------------ action server

    def on_goal(self, goal: RunTask.Goal) -> GoalResponse:
        with self._lock:
            if self._busy:
                self.get_logger().warning(f'goal {goal.task_id!r} rejected: a goal is running')
                return GoalResponse.REJECT
            self._busy = True
        return GoalResponse.ACCEPT

    def on_cancel(self, goal_handle) -> CancelResponse:
        return CancelResponse.ACCEPT

    def execute(self, goal_handle) -> RunTask.Result:
        result = RunTask.Result()
        try:
            self.play(goal_handle, result)
            goal_handle.succeed()
        except GoalCanceled:
            result.end_reason = 'canceled'
            goal_handle.canceled()
        except GoalFailed as exc:
            result.end_reason, result.error = 'error', str(exc)
            goal_handle.abort()
        except Exception as exc:   # the node keeps serving whatever a goal does
            self.get_logger().error(f'goal {goal_handle.request.task_id!r} failed: {exc!r}\n{traceback.format_exc()}')
            result.end_reason, result.error = 'error', f'internal error: {type(exc).__name__}: {str(exc)[:200]}'
            goal_handle.abort()
        finally:
            self.save_recording(result)
            with self._lock:
                self._busy = False
        return result

    def save_recording(self, result: RunTask.Result) -> None:
        """Write the goal's bag (when recording); a failure to write is logged, the goal's result stands."""
        recorder, self.recorder = self.recorder, None
        if recorder is None or recorder.recorder is None:
            return
        task_id = recorder.recorder.task_id
        try:
            recorder.finish(result)
        except Exception as exc:  # noqa: BLE001 - a full disk must not take the node down
            self.get_logger().error(f'recording {task_id}: {type(exc).__name__}: {exc}')

    def play(self, goal_handle, result: RunTask.Result) -> None:
        """Play the goal's task to its end (the episode loop, `dialfred_sim.episode.play`, its requests
        served by this node's clients), filling `result` as it goes."""
        goal = goal_handle.request
        if not goal.task_id.strip():
            # An empty id would reset the simulator into free exploration: no instruction to follow.
            raise GoalFailed('task_id is empty: a goal names a task of the simulator\'s splits, e.g. '
                             'valid_unseen/000012')
        if goal.seed < 0:
            raise GoalFailed(f'seed must be a non-negative integer, got {goal.seed}')
        if goal.protocol not in ('', *PROTOCOLS):
            raise GoalFailed(f'protocol must be one of {", ".join(PROTOCOLS)} (or empty), got {goal.protocol!r}')
        if goal.carry_on and goal.protocol != 'chained':
            raise GoalFailed("carry_on goes on to the next task of a chained episode: protocol 'chained'")
        try:
            policy = self.policy(goal.checkpoint or self.checkpoint)
        except (FileNotFoundError, CheckpointError, ValueError) as exc:
            raise GoalFailed(f'checkpoint: {exc}') from None
        goal_run = GoalRun(self, goal_handle, policy, result, goal.checkpoint or self.checkpoint)
        observers = [goal_run]
        if self.record_dir:     # the bag is written with the goal's result, however the goal ends (save_recording)
            chained = goal.protocol == 'chained'
            if chained and goal.carry_on and self.chain_recorder is not None:
                self.recorder = self.chain_recorder     # the episode's next task, in the episode's bag
            else:
                self.recorder = RecordingObserver(Path(self.record_dir), self.record_format,
                                                  picture=policy.picture if isinstance(policy, MapPainter) else None,
                                                  save_on_end=False, chained=chained,
                                                  heard=lambda qa, policy=policy: heard_by(policy, qa))
            self.chain_recorder = self.recorder if chained else None
            observers.append(self.recorder)
        episode = play(goal_run, seed=int(goal.seed), asks=self.use_questioner,
                       max_questions=int(self.get_parameter('max_questions').value), asker='questioner',
                       observers=observers, carry_on=bool(goal.carry_on))
        run(episode, goal_run.serve)

    # ------------------------------------------------------------------ helpers

    def policy(self, path: str):
        """The policy of checkpoint `path` (a PerformerAgent, or a MapAgent with model:=map), loaded once (again
        if the file changed)."""
        if not path:
            raise FileNotFoundError('no checkpoint: set the node\'s `checkpoint` parameter or the goal\'s')
        path = str(Path(path).expanduser())
        try:
            st = os.stat(path)
        except OSError:
            raise FileNotFoundError(f'no performer checkpoint at {path}') from None
        stamp = (st.st_mtime_ns, st.st_size)
        cached = self._policies.get(path)
        if cached is None or cached[0] != stamp:
            self._policies[path] = (stamp, load_policy(self.model, Path(path)), camera_resolution(self.model, Path(path)))
        return self._policies[path][1]

    def check_camera(self, path: str, width: int, height: int) -> None:
        """Warn (once per checkpoint and frame size) when the simulator's frames are not the size the policy
        of checkpoint `path` plays at: they are area-averaged to it, and it plays otherwise than in its evaluation."""
        path = str(Path(path).expanduser())
        want = self._policies[path][2]
        if (width, height) == (want, want) or (path, width, height) in self._camera_warned:
            return
        self._camera_warned.add((path, width, height))
        self.get_logger().warning(
            f'the simulator sends {width}x{height} px frames, but the {self.model} performer of {path} plays at '
            f'{want}x{want}: its frames are resized and it plays otherwise than in its evaluation; start the '
            f'simulator with resolution:={want}')

    def call(self, client, request, resend: bool, timeout: Optional[float] = None):
        """The reply to `request`, waited for (this thread blocks; the executor's other threads
        deliver it); GoalFailed after `timeout` s (none: request_timeout). `resend`: send again after
        RESEND_AFTER_S without a reply (only for requests that may be repeated)."""
        timeout = timeout or float(self.get_parameter('request_timeout').value)
        deadline = time.monotonic() + timeout
        if client.srv_name not in self._settled:
            appear = min(timeout, float(self.get_parameter('request_timeout').value))   # a service, not a person
            if not client.wait_for_service(timeout_sec=appear):
                raise GoalFailed(f'no {client.srv_name} service after {appear:g} s')
            self._settled.add(client.srv_name)
            # The reply path may match a moment after the service appears: a request the server
            # refuses without changing anything, resent until answered, proves it (as Graph.client).
            probe = refused_request(client.srv_type)
            if probe is not None:
                self.call(client, probe, resend=True)
            else:
                time.sleep(SETTLE_S)
        while True:
            done = threading.Event()
            future = client.call_async(request)
            future.add_done_callback(lambda _, done=done: done.set())   # this request's own event
            wait = min(RESEND_AFTER_S, deadline - time.monotonic()) if resend else deadline - time.monotonic()
            if done.wait(max(0.0, wait)):
                reply = future.result()
                if reply is None:
                    raise GoalFailed(f'{client.srv_name} returned no reply')
                return reply
            client.remove_pending_request(future)
            if time.monotonic() >= deadline:
                raise GoalFailed(f'no reply from {client.srv_name} after {timeout:g} s')


class GoalRun(EpisodeObserver):
    """One RunTask goal as the episode loop sees it: the agent (the policy, and the questioner node when
    the node's `questioner` parameter is on), the transport (this node's service clients) and an
    observer that fills the result, publishes QAs, actions and feedback, and records the bag."""

    def __init__(self, node: PerformerNode, goal_handle, policy, result: RunTask.Result, checkpoint: str):
        self.node, self.goal_handle, self.policy, self.result = node, goal_handle, policy, result
        self.checkpoint = checkpoint
        self.task, self.dialogue = None, []
        self.frame_msg = None          # the latest frame (sensor_msgs/Image) as the simulator sent it

    # the agent
    def reset(self, task, seed: int) -> None:
        self.task, self.seed = task, seed
        self.policy.reset(task, seed)

    def carry_on(self, task, seed: int) -> None:
        """A chained goal after the first of its episode: a policy that is protocol.Continuing keeps what it
        knows (the map performer its map), any other starts afresh."""
        self.task, self.seed = task, seed
        if isinstance(self.policy, Continuing):
            self.policy.carry_on(task, seed)
        else:
            self.policy.reset(task, seed)

    def ask(self, observation):
        """What the questioner node asks before this action (with the policy's top-2 action-probability gap)."""
        if self.goal_handle.is_cancel_requested:
            raise GoalCanceled
        gap = top2_gap(self.policy.action_probabilities(observation)) if isinstance(self.policy, ConfusionSource) \
            else -1.0
        reply = self.node.call(self.node.questioner_cli, QuestionerAsk.Request(
            task=task_description_msg(self.task), seed=int(self.seed), step=self.result.steps, rgb=self.frame_msg,
            dialogue=[qa_msg(qa) for qa in self.dialogue], confusion_gap=gap,
            episode=bytes(self.goal_handle.goal_id.uuid).hex()), resend=True)
        if not reply.ok:
            raise GoalFailed(f'questioner: {reply.error}')
        return Question(reply.question_type, reply.object_noun) if reply.ask else None

    def hear(self, qa: QA) -> None:
        self.dialogue.append(qa)
        self.policy.hear(qa)

    def act(self, observation):
        if self.goal_handle.is_cancel_requested:
            raise GoalCanceled
        return self.policy.act(observation)

    # the transport
    def serve(self, request):
        node = self.node
        if isinstance(request, Reset):
            goal = self.goal_handle.request
            reply = node.call(node.reset_cli, SimReset.Request(task_id=goal.task_id, with_depth=False,
                                                               with_segmentation=False, protocol=goal.protocol,
                                                               carry_on=goal.carry_on), resend=True)
            if not reply.ok:
                raise GoalFailed(f'reset: {reply.error}')
            return sim_reply(reply)
        if isinstance(request, Ask):
            q = request.question
            answer = node.call(node.oracle_cli, OracleAnswer.Request(question_type=q.question_type,
                                                                     object_noun=q.object_noun), resend=True,
                               timeout=float(node.get_parameter('answer_timeout').value) or None)
            return qa_from_answer(q, answer, self.goal_handle.request.task_id)
        reply = node.call(node.step_cli, SimStep.Request(action=Action(action=request.action, x=request.x, y=request.y),
                                                         with_depth=False, with_segmentation=False), resend=False)
        if not reply.ok:
            raise GoalFailed(f'step {self.result.steps + 1} ({request.action}): {reply.error}')
        return sim_reply(reply)

    # the observer
    def on_started(self, state: EpisodeState, reply) -> None:
        rgb = self.frame_msg = reply.raw.observation.rgb      # the frame as the simulator sent it, for the questioner
        self.node.check_camera(self.checkpoint, int(rgb.width), int(rgb.height))
        self.result.goal_conditions_total = int(reply.goal_conditions_total)

    def on_question(self, state: EpisodeState, qa: QA, step: int) -> None:
        self.result.questions += 1
        self.result.invalid_questions += not qa.valid
        msg = qa_msg(qa, heard_by(self.policy, qa))     # with what the performer took from it
        self.result.dialogue.append(msg)
        self.result.asked_at.append(int(step))
        self.node.qa_pub.publish(msg)

    def on_action(self, state: EpisodeState, action: str, x: int, y: int) -> None:
        node = self.node
        if isinstance(self.policy, MapPainter) and node.map_pub.get_subscription_count() > 0:
            img = self.policy.picture()
            h, w = img.shape[:2]
            node.map_pub.publish(Image(height=h, width=w, encoding='rgb8', step=w * 3, data=img.tobytes()))
        node.action_pub.publish(Action(action=action, x=x, y=y))
        self.result.actions.append(Action(action=action, x=x, y=y))     # sent: the trace keeps it, whatever comes back

    def on_stepped(self, state: EpisodeState, reply, action: str, x: int, y: int) -> None:
        result, observation = self.result, reply.raw.observation
        self.frame_msg = observation.rgb
        result.steps, result.failed_actions = int(observation.step_count), int(observation.failed_actions)
        result.goal_conditions_met = int(reply.goal_conditions_met)
        result.goal_conditions_total = int(reply.goal_conditions_total)
        result.last_action = action
        self.goal_handle.publish_feedback(RunTask.Feedback(step=result.steps, action=Action(action=action, x=x, y=y),
                                                           action_success=observation.last_action_success,
                                                           questions=result.questions))

    def on_ended(self, state: EpisodeState) -> None:
        if state.end_reason == 'error':          # too many questions in a row: the goal fails
            raise GoalFailed(state.error)
        self.result.success = state.success
        self.result.end_reason = state.end_reason
        self.result.error = state.error



def main(args=None):
    run_node(PerformerNode, args, executor_factory=lambda: MultiThreadedExecutor(num_threads=4))


if __name__ == '__main__':
    main()
