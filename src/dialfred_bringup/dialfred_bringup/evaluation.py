#!/usr/bin/env python3
"""Evaluation through the node graph: an agent plays (a part of) a split on simulator nodes.

`./dialfred launch eval ...` runs `--workers` simulator nodes, each in its own namespace
(/eval_<pid>/w0/sim/step, /eval_<pid>/w1/sim/step, ...), drives them all from this process with
asynchronous calls, appends each episode's result to the JSON-lines file as it ends (a rerun skips
the tasks already there), and prints SR / PWSR / GC / NQ overall and per task type; the summary also
goes to <out without .jsonl>.summary.json.

With `--questioner`, each worker also gets an oracle node in its namespace (.../w0/oracle/answer
answers from .../w0/sim/ground_truth). Before every action the agent may ask it questions, which
are counted (NQ, NQ_invalid).

With `--tasks PATH` (a split file of your own, such as a sealed test split) instead of `--split`,
every simulator node reads that file (its `tasks_file` parameter), and <out without .jsonl>.tasks.json
records the file's path and sha256: results of another file are refused, never mixed in.

With `--shard K/N`, only the tasks whose index in the split is K modulo N are played (seeded by that
index, as in a whole run) into <out>_shardKofN.jsonl; `./dialfred merge` joins the shards' files
(dialfred_bringup/shards.py, docs/scaling.md).
"""

from __future__ import annotations

import collections
import contextlib
import functools
import json
import os
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from dialfred_sim.metrics import ResultsFileError
from dialfred_sim.protocol import QUESTION_TYPES

from dialfred_sim.episode import EpisodeObserver

from .graph import Graph, NodeDied, NodeProcess, oracle_node, sim_node, sim_service, use_project_environment
from .paths import REPO
from .shards import check_shard, shard_suffix, shard_tasks

use_project_environment(REPO)

@dataclass
class EvalConfig:
    """One evaluation run: an agent over (the first `limit` tasks of) a split."""

    split: str = 'valid_unseen'
    agent: str = 'expert'
    questioner: str = ''                # '' = the agent asks nothing; else a dialfred_questioner.questioners name
    perturb_type: str = ''              # the paper's ablation: the oracle withholds answers of this type ...
    perturb_probability: float = 0.5    # ... with this probability
    limit: Optional[int] = None
    workers: int = 2
    out: Optional[Path] = None          # default: out/eval/<split>_<agent>.jsonl
    seed: int = 0
    resolution: int = 128
    request_timeout: float = 120.0      # seconds one reset or step may take before the run gives up
    tasks_file: Optional[Path] = None   # a split file of your own (a test_unseen split) instead of `split`
    performer: str = ''                 # 'et': a performer node per worker plays each task (RunTask goals);
                                        # '' = the agent is a Python object of this process (the in-process path)
    checkpoint: Optional[Path] = None   # the `et` performer's checkpoint (default the one shipped in the package, dialfred_performer/checkpoints/et.pt)
    episode_timeout: float = 1800.0     # seconds one RunTask goal may take before it is cancelled
    record: Optional[Path] = None       # write each episode as a rosbag2/MCAP bag into this folder
    record_format: str = 'raw'          # the bags' camera frames: raw, png or jpeg (dialfred_sim.bag)
    foxglove: Optional[int] = None      # a port: stream the workers live to Foxglove (dialfred_bringup.live)
    max_restarts: int = 3               # a worker whose node dies is restarted (its episode replayed) this many
                                        # times in a row at most; 0 = a dead node ends the run
    shard: Optional[tuple] = None       # (K, N): only shard K of N of the selected tasks (see dialfred_bringup.shards.shard_tasks)
    local: bool = False                 # no ROS: worker processes with a simulator, the oracle's rules and the agent
                                        # each (dialfred_bringup.local: the same episodes as through the graph, faster)

    @functools.cached_property
    def tasks_source(self):
        """The tasks file read once (dialfred_sim.tasks.splits.TasksFile), or None for a shipped split."""
        from dialfred_sim.tasks.splits import read_tasks_file
        return read_tasks_file(self.tasks_file) if self.tasks_file else None

    @property
    def checkpoint_path(self) -> Path:
        if self.checkpoint:
            return Path(self.checkpoint)
        from dialfred_performer.model import SHIPPED_CHECKPOINT
        return SHIPPED_CHECKPOINT

    @functools.cached_property
    def checkpoint_sha256(self) -> str:
        import hashlib
        try:
            return hashlib.sha256(self.checkpoint_path.read_bytes()).hexdigest()
        except OSError:
            raise ValueError(f'no performer checkpoint at {self.checkpoint_path} (--checkpoint PATH)') from None

    @property
    def learned_questioner_path(self) -> Optional[Path]:
        """The checkpoint file of a questioner given as learned:PATH, else None."""
        if ':' not in self.questioner:
            return None
        from dialfred_questioner.policy import LEARNED_PREFIX
        return Path(self.questioner[len(LEARNED_PREFIX):]).expanduser() \
            if self.questioner.startswith(LEARNED_PREFIX) else None

    @functools.cached_property
    def questioner_label(self) -> str:
        """The questioner's name as results carry it: learned:PATH as learned-<file stem>-<its sha256[:8]>
        (no slashes in a file name), a shipped learned one as <name>-<its sha256[:8]> (results of two
        checkpoints never mix, as the performer's), any other as given."""
        from dialfred_questioner.policy import SHIPPED_LEARNED, learned_checkpoint
        path = self.learned_questioner_path
        if path is None and self.questioner not in SHIPPED_LEARNED:
            return self.questioner
        import hashlib
        path = path if path is not None else learned_checkpoint(self.questioner)
        try:
            digest = hashlib.sha256(path.read_bytes()).hexdigest()[:8]
        except OSError:
            raise ValueError(f'no questioner checkpoint at {path}') from None
        return f'learned-{path.stem}-{digest}' if self.learned_questioner_path is not None else f'{self.questioner}-{digest}'

    @property
    def agent_name(self) -> str:
        """The name results carry: the agent's (the `et` performer's with its checkpoint's sha256, so that
        results of two checkpoints never mix), with its questioner's (`questioner_label`) after a '+'."""
        agent = f'et-{self.checkpoint_sha256[:8]}' if self.agent == 'et' else self.agent
        return f'{agent}+{self.questioner_label}' if self.questioner else agent

    @property
    def oracle(self) -> str:
        """How the oracle answers, as results record it: '' exactly, 'location:0.5' perturbed."""
        return f'{self.perturb_type}:{self.perturb_probability:g}' if self.perturb_type else ''

    @property
    def results_path(self) -> Path:
        if self.out:
            return Path(self.out)
        perturbed = f'_withhold-{self.perturb_type}-{self.perturb_probability:g}' if self.perturb_type else ''
        source = self.tasks_source
        tasks = f'{source.split}-{source.sha256[:8]}' if source else self.split   # a file: named by its content
        return REPO / 'out' / 'eval' / f'{tasks}_{self.agent_name}{perturbed}{shard_suffix(self.shard)}.jsonl'

    @property
    def tasks_record_path(self) -> Path:
        """Where a run on a tasks file records which file (path, sha256) its results came from."""
        return self.results_path.with_suffix('.tasks.json')

    def make_performer(self):
        """The acting agent alone: the `et` performer from its checkpoint, or a dialfred_sim.agents one."""
        if self.agent == 'et':
            from dialfred_performer.agent import PerformerAgent
            from dialfred_performer.model import CheckpointError
            try:
                return PerformerAgent.from_checkpoint(self.checkpoint_path)
            except (FileNotFoundError, CheckpointError) as exc:
                raise ValueError(str(exc)) from None
        from dialfred_sim.agents import make_agent
        return make_agent(self.agent, self.resolution)

    def make_agent(self):
        """A new agent as configured (ValueError for an unknown agent or questioner)."""
        from dialfred_questioner.baselines import with_questioner
        from dialfred_questioner.questioners import make_questioner
        return with_questioner(self.make_performer(), make_questioner(self.questioner) if self.questioner else None)

    def check(self) -> None:
        """ValueError for settings that cannot run together, or an agent or questioner that cannot be made."""
        check_shard(self.shard)
        from dialfred_sim.bag import IMAGE_FORMATS
        if self.max_restarts < 0:
            raise ValueError(f'--max-restarts must be 0 or more, got {self.max_restarts}')
        if self.record_format not in IMAGE_FORMATS:
            raise ValueError(f'--record-format must be one of {", ".join(IMAGE_FORMATS)}, got {self.record_format!r}')
        if self.record is not None and Path(self.record).exists() and not Path(self.record).is_dir():
            raise ValueError(f'--record {self.record} exists and is not a folder')
        if self.local and (self.performer or self.record is not None or self.foxglove is not None):
            raise ValueError('--local plays without ROS: it cannot go with --performer, --record or --foxglove')
        if self.performer:
            if self.performer != 'et':
                raise ValueError(f'--performer must be et (the Episodic-Transformer performer node), got {self.performer!r}')
            self.agent = 'et'
        self.make_agent()     # the node path too: a bad checkpoint or questioner fails before any node starts
        if self.tasks_file:
            try:
                self.split = self.tasks_source.split      # the split played is the file's
            except FileNotFoundError as exc:
                raise ValueError(str(exc)) from None
        if self.perturb_type:
            if not self.questioner:
                raise ValueError('a perturbed oracle needs a questioner (--questioner)')
            if self.perturb_type not in QUESTION_TYPES:
                raise ValueError(f'--perturb-type must be one of {", ".join(QUESTION_TYPES)}, '
                                 f'got {self.perturb_type!r}')
            if not 0.0 <= self.perturb_probability <= 1.0:
                raise ValueError(f'--perturb-probability must be in [0, 1], got {self.perturb_probability}')

    @property
    def summary_path(self) -> Path:
        return self.results_path.with_suffix('.summary.json')


@dataclass
class EvalReport:
    """What a run came to: the results of every selected task (in split order), and this run's share."""

    config: EvalConfig
    results: list
    ran: int                # episodes played by this run (the others were in the file already)
    startup_s: float        # loading the tasks and the results file, starting the nodes until they answer
    wall_s: float           # the whole run, start-up included
    summary: dict
    restarts: int = 0       # workers restarted after a node died or hung (their episodes replayed)

    def to_json(self) -> dict:
        from dialfred_sim.metrics import failures
        c = self.config
        loop_s = self.wall_s - self.startup_s
        return {
            'split': c.split, 'tasks_file': c.tasks_source.describe() if c.tasks_source else None,
            'agent': c.agent_name, 'privileged': any(r.privileged for r in self.results),
            'oracle': c.oracle, 'seed': c.seed, 'resolution': c.resolution,
            'workers': c.workers,
            'through': 'performer node' if c.performer else ('local processes (no ROS)' if c.local else 'in-process agent'),
            'checkpoint': ({'path': str(c.checkpoint_path), 'sha256': c.checkpoint_sha256} if c.agent == 'et' else None),
            'limit': c.limit, 'shard': {'index': c.shard[0], 'count': c.shard[1]} if c.shard else None,
            'results_file': str(c.results_path), 'tasks': len(self.results),
            'this_run': {'episodes': self.ran, 'startup_s': round(self.startup_s, 3), 'wall_s': round(self.wall_s, 3),
                         'episodes_per_s': round(self.ran / loop_s, 3) if self.ran and loop_s > 0 else None,
                         'restarts': self.restarts},
            'summary': self.summary,
            'failures': [{'task_id': r.task_id, 'task_type': r.task_type, 'end_reason': r.end_reason,
                          'error': r.error} for r in failures(self.results)],
        }


RESEND_AFTER_S = 10.0  # a reset or question unanswered this long is sent again (see SimWorker.resend_if_lost)


class SimWorker(EpisodeObserver):
    """One simulator node (in its own namespace) playing one episode at a time with its own agent, one
    request in flight: the episode loop (`dialfred_sim.episode.play`) driven by asynchronous service
    calls. `begin` starts an episode; `advance` hands the reply that arrived to the loop and either sends
    its next request or returns the episode's EpisodeResult. With `oracle`, the agent's questions go to
    the oracle node of the same namespace before it acts."""

    def __init__(self, graph: Graph, namespace: str, agent, config: EvalConfig, oracle: bool = False):
        from dialfred_msgs.srv import OracleAnswer, SimReset, SimStep
        self.reset_cli = graph.client(SimReset, sim_service(namespace, 'reset'))
        self.step_cli = graph.client(SimStep, sim_service(namespace, 'step'))
        self.ask_cli = graph.client(OracleAnswer, f'{namespace.rstrip("/")}/oracle/answer') if oracle else None
        self.graph, self.namespace, self.agent, self.config = graph, namespace, agent, config
        self.future = None
        self.job = None
        self.live = None       # a LiveHook, with --foxglove
        self.sent_at = 0.0
        self.task = None
        self.pending = ''      # what the request in flight is: 'reset', 'step' or 'question'
        self.traces = collections.defaultdict(list)   # task id -> the actions sent, (name, x, y)

    @property
    def busy(self) -> bool:
        return self.future is not None

    def begin(self, index: int, task) -> None:
        from dialfred_sim.agents import task_view
        from dialfred_sim.episode import play
        from dialfred_sim.protocol import episode_seed
        self.job = (index, task)
        self.task = task
        self.started_at = time.monotonic()
        self.recorder = None
        if self.live is not None:
            self.live.begin(task)
        self.episode = play(self.agent, seed=episode_seed(self.config.seed, index),
                            told=task_view(self.agent, task),      # the public view, unless privileged
                            asks=self.ask_cli is not None, observers=[self])
        self._request(next(self.episode))

    def overdue(self) -> bool:
        return self.busy and time.monotonic() - self.sent_at > self.config.request_timeout

    def close(self) -> None:
        """Abandon the episode in flight (this worker's nodes are being restarted). Its clients stay with
        the client node: destroying an entity the executor may be waiting on can crash rclpy."""
        self.future, self.recorder = None, None

    def advance(self):
        """Hand the finished request's reply to the episode: its next request is sent, or its result returned."""
        from dialfred_sim.episode import Failed
        reply, self.future = self.future.result(), None
        if reply is None:
            reply = Failed('the service call returned no reply')
        elif self.pending == 'question':
            from dialfred_sim.protocol import QA
            reply = QA(self.asking, bool(reply.valid), reply.answer, reply.reason)
        else:
            from dialfred_sim.messages import sim_reply
            reply = sim_reply(reply)
        try:
            self._request(self.episode.send(reply))
        except StopIteration as stop:
            return self._result(stop.value)
        return None

    def _request(self, request) -> None:
        """Send the episode's request to the simulator or the oracle node."""
        from dialfred_msgs.msg import Action
        from dialfred_msgs.srv import OracleAnswer, SimReset, SimStep
        from dialfred_sim.episode import Ask, Reset
        if isinstance(request, Reset):
            self._send(self.reset_cli, SimReset.Request(task_id=self.task.task_id, with_depth=False,
                                                        with_segmentation=False), 'reset')
        elif isinstance(request, Ask):
            self.asking = request.question     # (not `question`: the observer method)
            self._send(self.ask_cli, OracleAnswer.Request(question_type=request.question.question_type,
                                                          object_noun=request.question.object_noun), 'question')
        else:
            self._send(self.step_cli, SimStep.Request(action=Action(action=request.action, x=request.x, y=request.y),
                                                      with_depth=False, with_segmentation=False), 'step')

    # EpisodeObserver: the recorder, the live view and the traces of the actions sent
    def started(self, state, reply) -> None:
        if self.config.record is not None:
            from dialfred_sim.bag import EpisodeRecorder
            t = reply.raw.task       # what the agent is told
            self.recorder = EpisodeRecorder(t.task_id, t.scene, t.split, t.instruction, t.object_nouns,
                                            image_format=self.config.record_format)
            self.recorder.observation_msg(reply.raw.observation)

    def question(self, state, qa, step: int) -> None:
        if self.recorder is not None:
            from dialfred_sim.messages import qa_msg
            self.recorder.question_msg(step, qa_msg(qa))
        if self.live is not None:
            self.live.qa(qa.question.question_type, qa.question.object_noun, qa.answer, qa.valid)

    def action(self, state, action: str, x: int, y: int) -> None:
        self.traces[self.task.task_id].append((action, x, y))

    def stepped(self, state, reply, action: str, x: int, y: int) -> None:
        obs = reply.raw.observation
        if self.recorder is not None:
            self.recorder.action(int(obs.step_count), action, x, y, obs.last_action_success, state.questions)
            self.recorder.observation_msg(obs)
        if self.live is not None:
            self.live.action(int(obs.step_count), action, obs.last_action_success)

    def ended(self, state) -> None:
        if self.recorder is not None:
            self.recorder.result(success=state.success, steps=state.steps, goal_conditions_met=state.goal_conditions_met,
                                 goal_conditions_total=state.goal_conditions_total,
                                 failed_actions=state.failed_actions, questions=state.questions,
                                 invalid_questions=state.invalid_questions, end_reason=state.end_reason,
                                 error=state.error, last_action=state.last_action)
            self.recorder.save(Path(self.config.record))
            self.recorder = None

    def _send(self, cli, request, pending: str) -> None:
        self.sent_at = self.last_sent = time.monotonic()
        self.pending = pending
        self.request, self.cli = request, cli
        self.future = cli.call_async(request)

    def resend_if_lost(self) -> bool:
        """Send a reset or question again that got no reply in RESEND_AFTER_S (a request sent while a
        restarted node is not yet discovered is lost; both may be repeated: a reset starts the same
        episode, a question gets the same answer). Steps are never repeated: they change the world."""
        if self.pending not in ('reset', 'question') or time.monotonic() - self.last_sent < RESEND_AFTER_S:
            return False
        self.cli.remove_pending_request(self.future)
        self.last_sent = time.monotonic()
        self.future = self.cli.call_async(self.request)
        return True

    def _result(self, state):
        from .local import episode_result
        return episode_result(self.config, self.task, self.agent, state, time.monotonic() - self.started_at)


class PerformerWorker:
    """One worker's performer node (in its own namespace, with its simulator, oracle and questioner
    nodes beside it) playing one task at a time as a RunTask goal: a commander that only sends goals
    and records results. `begin` sends the goal; `advance` handles the reply that arrived (the goal
    accepted: wait for its result; the result: the episode's EpisodeResult). A goal running longer
    than `episode_timeout` is cancelled, and its episode recorded as an error."""

    def __init__(self, graph: Graph, namespace: str, config: EvalConfig, on_feedback=None):
        from rclpy.action import ActionClient

        from dialfred_msgs.action import RunTask
        self.name = f'{namespace.rstrip("/")}/performer/run_task'
        self.client = ActionClient(graph.client_node, RunTask, self.name)
        deadline = time.monotonic() + 60.0
        while not self.client.wait_for_server(timeout_sec=0.1):
            graph.check()
            if time.monotonic() > deadline:
                raise TimeoutError(f'action server {self.name} not available after 60 s')
        self.graph, self.namespace, self.config = graph, namespace, config
        self._prove_paths(deadline)
        self.on_feedback = on_feedback    # called with (task, RunTask.Feedback) as each step's feedback comes
        self.future = self.goal_handle = self.cancel_future = None
        self.task = self.job = None
        self.live = None       # a LiveHook, with --foxglove
        self.pending = ''       # 'goal' (waiting for acceptance) or 'result'
        self.traces = collections.defaultdict(list)   # task id -> the actions of its feedback, (name, x, y)

    def _prove_paths(self, deadline: float) -> None:
        """Wait until a goal's reply paths work. "Server available" means the goal request reader
        matched; the replies (goal response, result) may not have, and a reply sent before they match
        is lost: a goal then waits for its acceptance until request_timeout (the hang once seen in an
        evaluation, and after every node restart under load). So: a goal the node refuses to play (a
        negative seed: aborted before it touches the simulator) is sent until its result comes back."""
        from dialfred_msgs.action import RunTask
        while True:
            if time.monotonic() > deadline:
                raise TimeoutError(f'action server {self.name} gave no reply to a probe goal in 60 s')
            sent = self.client.send_goal_async(RunTask.Goal(task_id='', seed=-1))
            self.graph.spin_until_any([sent], 1.0)
            if not sent.done() or not sent.result().accepted:      # lost, or the previous probe still running
                continue
            result = sent.result().get_result_async()
            self.graph.spin_until_any([result], 2.0)
            if result.done():
                self.graph.spin_until_any([], SETTLE_S)
                return

    @property
    def busy(self) -> bool:
        return self.future is not None

    def begin(self, index: int, task) -> None:
        from dialfred_msgs.action import RunTask

        from dialfred_sim.protocol import episode_seed
        self.job = (index, task)
        self.task, self.started = task, time.monotonic()
        self.sent_at, self.cancel_future, self.goal_handle = self.started, None, None
        trace = self.traces[task.task_id]
        trace.clear()

        if self.live is not None:
            self.live.begin(task)

        def feedback(msg) -> None:
            a = msg.feedback.action
            trace.append((a.action, int(a.x), int(a.y)))
            if self.live is not None:
                self.live.action(int(msg.feedback.step), a.action, bool(msg.feedback.action_success))
            if self.on_feedback is not None:
                self.on_feedback(task, msg.feedback)

        goal = RunTask.Goal(task_id=task.task_id, seed=episode_seed(self.config.seed, index))
        self.future = self.client.send_goal_async(goal, feedback_callback=feedback)
        self.pending = 'goal'

    def advance(self):
        reply, self.future = self.future.result(), None
        if self.pending == 'goal':
            if reply is None or not reply.accepted:
                return self._result(None, error=f'{self.name} rejected the goal (is another goal running there?)')
            self.goal_handle, self.pending = reply, 'result'
            self.future = reply.get_result_async()
            return None
        from action_msgs.msg import GoalStatus
        result = reply.result
        if reply.status == GoalStatus.STATUS_CANCELED:
            return self._result(result, error=f'cancelled after {self.config.episode_timeout:g} s (episode_timeout)')
        return self._result(result)

    def overdue(self) -> bool:
        """Cancel a goal past episode_timeout (once); True only if even the cancel got no result in 60 s."""
        late = time.monotonic() - self.started - self.config.episode_timeout
        if late < 0 or self.pending != 'result':
            return self.pending == 'goal' and time.monotonic() - self.sent_at > self.config.request_timeout
        if self.cancel_future is None:
            self.cancel_future = self.goal_handle.cancel_goal_async()
        return late > 60.0

    def resend_if_lost(self) -> bool:
        return False         # a goal is never sent twice: the node refuses a second one while the first runs

    def close(self) -> None:
        """Abandon the goal in flight (this worker's nodes are being restarted). The action client stays
        with the client node: destroying an entity the executor may be waiting on can crash rclpy."""
        self.future = None

    def _result(self, result, error: str = ''):
        from dialfred_sim.metrics import EpisodeResult, dialogue_entry
        task, r = self.task, result
        reason = 'error' if error or r is None or r.end_reason in ('error', 'canceled') else r.end_reason
        success = bool(r.success) if r is not None and reason != 'error' else False
        return EpisodeResult(
            task_id=task.task_id, task_type=task.task_type, split=task.split, success=success,
            goal_conditions_met=int(r.goal_conditions_met) if r else 0,
            goal_conditions_total=int(r.goal_conditions_total) if r else 0,
            steps=int(r.steps) if r else 0, expert_length=int(task.expert_length),
            questions=int(r.questions) if r else 0, invalid_questions=int(r.invalid_questions) if r else 0,
            failed_actions=int(r.failed_actions) if r else 0, end_reason=reason,
            error='' if success else (error or (r.error if r else '')), agent=self.config.agent_name,
            oracle=self.config.oracle, seed=self.config.seed, wall_s=round(time.monotonic() - self.started, 4),
            privileged=False, dialogue=[dialogue_entry(m.question_type, m.object_noun, m.valid, m.answer)
                                        for m in r.dialogue] if r else [])


SETTLE_S = 0.2


def play_episodes(graph: Graph, workers: list, jobs: list, on_result, supervisor=None) -> None:
    """Play every (index, task) of `jobs` on the workers, each keeping one request in flight, and
    call `on_result(result)` as each episode ends (in the order they end).

    With a `supervisor` (a Supervisor), a worker whose node died or stopped answering has its nodes
    restarted and its episode played again from the start; without one, NodeDied or TimeoutError ends
    the run."""
    queue = collections.deque(jobs)
    for w in workers:
        if queue:
            w.begin(*queue.popleft())
    while any(w.busy for w in workers) or (supervisor is not None and queue):
        for w in workers:
            if not w.busy and queue:
                w.begin(*queue.popleft())
        try:
            graph.spin_until_any([w.future for w in workers if w.busy])
        except NodeDied:
            if supervisor is None:
                raise
            supervisor.recover(workers, queue, supervisor.dead_namespaces())
            continue
        for w in workers:
            if w.busy and w.future.done():
                result = w.advance()
                if result is not None:
                    on_result(result)
                    if getattr(w, 'live', None) is not None:
                        w.live.result(result)
                    if supervisor is not None:
                        supervisor.finished(w.namespace)
                    if queue:
                        w.begin(*queue.popleft())
            elif w.busy and w.resend_if_lost():
                continue
            elif w.busy and w.overdue():
                node = {'question': 'oracle', 'goal': 'performer', 'result': 'performer'}.get(w.pending, 'sim')
                message = (f'no reply from {w.namespace or "/"} {node} node after {w.config.request_timeout:.0f} s '
                           f'(task {w.task.task_id})')
                if supervisor is None:
                    raise TimeoutError(message)
                supervisor.recover(workers, queue, {w.namespace}, reason=message)
                break


class Supervisor:
    """Keeps an evaluation's workers alive: when a node of a worker dies (or stops answering), every
    node of that worker is stopped and started again, a new worker object is made for them, and the
    episode it was playing goes back to the front of the queue, to be played again from its start
    (episodes are seeded by their index, and no node carries state from one episode to the next, so
    the replay is the episode an uninterrupted run plays). A worker restarted more than
    `max_restarts` times in a row without finishing an episode is given up on: NodeDied, with the
    last output of the node that keeps dying."""

    def __init__(self, graph: Graph, nodes_of: dict, make_worker, max_restarts: int = 3, log=None):
        self.graph, self.nodes_of, self.make_worker = graph, nodes_of, make_worker
        self.max_restarts = max_restarts
        self.strikes = collections.Counter()     # namespace -> restarts since its last finished episode
        self.restarts = 0                        # all restarts of this run
        self.log = log or (lambda text: print(f'[eval] {text}', file=sys.stderr, flush=True))

    def start(self, namespaces: list) -> list:
        """A worker for each namespace, restarting the nodes of any that die while they start."""
        made: dict = {}
        while len(made) < len(namespaces):
            try:
                for ns in namespaces:
                    if ns not in made:
                        made[ns] = self.make_worker(ns)
            except NodeDied:
                for ns in self.dead_namespaces():
                    if ns in made:
                        made.pop(ns).close()
                    self._restart(ns, '')
        return [made[ns] for ns in namespaces]

    def dead_namespaces(self) -> set:
        return {n.namespace for ns, nodes in self.nodes_of.items() for n in nodes
                if n.proc is not None and n.proc.poll() is not None}

    def finished(self, namespace: str) -> None:
        self.strikes[namespace] = 0

    def recover(self, workers: list, queue: collections.deque, namespaces: set, reason: str = '') -> None:
        """Restart the nodes of the workers in `namespaces` (and of any other whose node died meanwhile),
        requeue their episodes, make new workers for them and give every idle worker a job."""
        pending = set(namespaces)
        while pending:
            for w in workers:
                if w.namespace not in pending:
                    continue
                if w.job is not None and w.busy:
                    queue.appendleft(w.job)
                    w.traces.pop(w.job[1].task_id, None)      # the replay traces it afresh
                w.close()
                self._restart(w.namespace, reason)
            try:
                for k, w in enumerate(workers):
                    if w.namespace in pending:
                        workers[k] = self.make_worker(w.namespace)
                        workers[k].traces.update(w.traces)      # the actions of the episodes it finished
                pending = set()
            except NodeDied:                      # a node died while the new workers waited for their services
                pending = self.dead_namespaces()
                reason = ''
        for w in workers:
            if not w.busy and queue:
                w.begin(*queue.popleft())

    def _restart(self, namespace: str, reason: str) -> None:
        nodes = self.nodes_of[namespace]
        dead = [n for n in nodes if n.proc is not None and n.proc.poll() is not None]
        self.strikes[namespace] += 1
        if self.strikes[namespace] > self.max_restarts:
            culprit = dead[0] if dead else nodes[0]
            out = '\n    '.join(list(culprit.tail)[-15:]) or '(no output)'
            raise NodeDied(f'worker {namespace}: restarted {self.max_restarts} times in a row without finishing an '
                           f'episode; giving up. {reason or culprit.label + " node died with exit code " + str(culprit.proc.returncode)}'
                           f'; its last output:\n    {out}')
        what = reason or ', '.join(f'{n.label} node died (exit code {n.proc.returncode})' for n in dead)
        self.log(f'{what}; restarting worker {namespace} ({self.strikes[namespace]}/{self.max_restarts}) and '
                 'replaying its episode')
        for n in nodes:
            n.stop(timeout=1.0)
        for n in nodes:
            n.tail.clear()
            n.start()
        self.restarts += 1


def worker_nodes(config: EvalConfig, namespace: str, **sim_params) -> list:
    """The nodes of one worker in `namespace`: its simulator; with a questioner, its oracle; with the
    performer node, also the questioner node and the performer node (a RunTask server). `sim_params`:
    more parameters of the simulator node (default: it publishes no observations)."""
    from_file = {'tasks_file': str(config.tasks_source.path)} if config.tasks_file else {}
    nodes = [sim_node(config.resolution, namespace, **{'publish_observations': False, **from_file, **sim_params})]
    if config.questioner:
        withhold = {'perturb_type': config.perturb_type, 'perturb_probability': config.perturb_probability,
                    'seed': config.seed} if config.perturb_type else {}
        nodes.append(oracle_node(namespace, **withhold))
    if config.performer:
        if config.questioner:
            learned = config.learned_questioner_path     # the node may run elsewhere: an absolute path
            name = f'learned:{learned.resolve()}' if learned is not None else config.questioner
            nodes.append(NodeProcess('dialfred_questioner', {'questioner': name}, namespace=namespace))
        record = {'record_dir': str(Path(config.record).resolve()),
                  'record_format': config.record_format} if config.record is not None else {}
        nodes.append(NodeProcess('dialfred_performer', {'checkpoint': str(config.checkpoint_path.resolve()),
                                                        'questioner': bool(config.questioner),
                                                        'request_timeout': config.request_timeout, **record},
                                 namespace=namespace))
    return nodes


def parse_shard(text: str) -> tuple:
    """--shard K/N -> (K, N); argparse's usage error unless 0 <= K < N."""
    import argparse

    from dialfred_bringup.shards import parse_shard as parse
    try:
        return parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


class LiveHook:
    """What one worker tells the Foxglove live view (dialfred_bringup.live.LiveView) as its episodes go."""

    def __init__(self, view, worker: str):
        self.view, self.worker = view, worker

    def begin(self, task) -> None:
        self.view.task(self.worker, task.task_id, task.scene, task.instruction)

    def qa(self, question_type: str, object_noun: str, answer: str, valid: bool) -> None:
        self.view.qa(self.worker, question_type, object_noun, answer, valid)

    def action(self, step: int, name: str, success: bool) -> None:
        self.view.action(self.worker, step, name, success)

    def result(self, r) -> None:
        self.view.result(self.worker, r.task_id, r.success, r.end_reason, r.steps, r.questions)


def start_live_view(config: EvalConfig, graph: Graph, namespaces: list, total: int):
    """The Foxglove server of --foxglove, fed from each worker's sim/observation (camera, pose) and,
    for performer nodes, dialogue/qa; the workers' LiveHooks tell it the rest."""
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

    from dialfred_msgs.msg import Observation, QAPair
    from dialfred_sim.protocol import image_array
    from dialfred_bringup.live import LiveView, describe
    view = LiveView(len(namespaces), port=config.foxglove, total=total)
    print(describe(view), file=sys.stderr, flush=True)
    qos = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=1)
    for k, ns in enumerate(namespaces):
        w, base = f'w{k}', ns.rstrip('/')

        def seen(obs, w=w) -> None:
            p = obs.pose
            view.frame(w, image_array(obs.rgb), (p.x, p.y, p.rotation_deg, p.horizon_deg), p.camera_height,
                       int(obs.step_count))

        graph.client_node.create_subscription(Observation, f'{base}/sim/observation', seen, qos)
        if config.performer:
            graph.client_node.create_subscription(
                QAPair, f'{base}/dialogue/qa',
                lambda m, w=w: view.qa(w, m.question_type, m.object_noun, m.answer, m.valid), 100)
    return view


def run_namespace() -> str:
    """The namespace of this run's nodes (/eval_<pid>): no other run, even in the same ROS domain,
    can reach them or be reached by this one. Where discovery reaches other hosts (a shard per host,
    docs/scaling.md), the host's name goes in too (/eval_<host>_<pid>): a pid is unique on one host only."""
    from dialfred_bringup.graph import discovery_spans_hosts, host_token
    return f'/eval_{host_token()}_{os.getpid()}' if discovery_spans_hosts() else f'/eval_{os.getpid()}'


def resumable_results(config: EvalConfig, task_ids: list) -> dict:
    """{task_id: result} already in the results file for the selected tasks (a cut-off last line is
    dropped from the file); ResultsFileError if the file is corrupt or holds another split, agent or seed."""
    from dialfred_sim.metrics import load_results, results_by_task
    path = config.results_path
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        try:
            existing = load_results(path, drop_truncated=True)
        except ValueError as exc:
            raise ResultsFileError(str(exc)) from None
    for w in caught:
        print(f'warning: {w.message}', file=sys.stderr)
    for r in existing:
        if (r.split, r.agent, r.oracle, r.seed) != (config.split, config.agent_name, config.oracle, config.seed):
            raise ResultsFileError(f'{path} holds results of split {r.split!r}, agent {r.agent!r}, '
                                   f'oracle {r.oracle!r}, seed {r.seed}, not {config.split!r}, {config.agent_name!r}, '
                                   f'{config.oracle!r}, '
                                   f'{config.seed}: choose another --out')
    check_tasks_record(config, bool(existing))
    return results_by_task(existing, task_ids)


def check_tasks_record(config: EvalConfig, has_results: bool) -> None:
    """Results of a tasks file are kept with a record of that file (<results>.tasks.json: path, sha256):
    ResultsFileError if the results file holds results of another tasks file, or of a shipped split
    while a tasks file is given (or the other way round). Writes the record for a new results file."""
    record_path, source = config.tasks_record_path, config.tasks_source
    record = _read_tasks_record(record_path)
    if has_results and (record or {}).get('sha256') != (source.sha256 if source else None):
        held = (f"tasks file {record['path']} (sha256 {record['sha256'][:12]}...)" if record
                else f'tasks of the shipped split {config.split!r}')
        wanted = f'tasks file {source.path} (sha256 {source.sha256[:12]}...)' if source else \
            f'the shipped split {config.split!r}'
        raise ResultsFileError(f'{config.results_path} holds results of {held}, not of {wanted}: '
                               'choose another --out')
    if not has_results:
        if source:
            from dialfred_sim.metrics import write_text_atomically
            record_path.parent.mkdir(parents=True, exist_ok=True)
            write_text_atomically(record_path, json.dumps(source.describe(), indent=1) + '\n')
        elif record is not None:
            record_path.unlink()      # left from results that are gone


def _read_tasks_record(path: Path) -> Optional[dict]:
    if not path.exists():
        return None
    try:
        record = json.loads(path.read_text())
    except ValueError:
        record = None
    if not (isinstance(record, dict) and isinstance(record.get('path'), str) and isinstance(record.get('sha256'), str)):
        raise ResultsFileError(f'{path} is not a record of a tasks file: choose another --out')
    return record


def progress_bar(total: int, done: int, enabled: bool):
    from tqdm import tqdm
    return tqdm(total=total, initial=done, unit='ep', file=sys.stderr, disable=not enabled, dynamic_ncols=True,
                smoothing=0.05)


def run_eval(config: EvalConfig, progress: bool = True, traces: Optional[dict] = None) -> EvalReport:
    """Evaluate `config.agent` on the split's tasks through `config.workers` simulator nodes.

    Results go to the JSON-lines file as each episode ends; tasks already there are skipped (resume).
    Writes the summary JSON next to it and returns the report of every selected task. `traces`: a
    dict to fill with each played task's actions, {task_id: [(name, x, y), ...]} (the performer path
    takes them from the goals' feedback).
    """
    from dialfred_sim.metrics import append_result, summarize, write_text_atomically
    from dialfred_sim.tasks import load_split

    config.check()    # an unknown agent or questioner, or a bad setting, fails here before any node starts

    t0 = time.monotonic()
    tasks = (config.tasks_source.tasks if config.tasks_file else load_split(config.split))[:config.limit]
    selected = shard_tasks(tasks, config.shard)       # (index in the split, task): the index seeds the episode
    tasks = [t for _, t in selected]
    done = resumable_results(config, [t.task_id for t in tasks])
    jobs = [(k, t) for k, t in selected if t.task_id not in done]
    ran, startup_s, restarts = 0, 0.0, 0

    def recorder(bar):
        """on_result of either path: the result line written at once (resumable), counted, shown."""
        def record(result) -> None:
            nonlocal ran
            append_result(config.results_path, result)
            done[result.task_id] = result
            ran += 1
            bar.update(1)
        return record

    if jobs and config.local:
        from dialfred_bringup.local import play_local
        with progress_bar(len(tasks), len(done), progress) as bar:
            play_local(config, jobs, recorder(bar))
    elif jobs:
        n = max(1, min(config.workers, len(jobs)))
        namespaces = [f'{run_namespace()}/w{k}' for k in range(n)]
        live = {'publish_observations': True} if config.foxglove is not None else {}
        nodes_of = {ns: worker_nodes(config, ns, **live) for ns in namespaces}
        nodes = [node for ns in namespaces for node in nodes_of[ns]]
        with Graph(nodes) as graph, contextlib.ExitStack() as cleanup:
            view = start_live_view(config, graph, namespaces, len(tasks)) if config.foxglove is not None else None
            if view is not None:
                cleanup.callback(view.close)

            def make_worker(ns: str):
                if config.performer:
                    worker = PerformerWorker(graph, ns, config)
                else:
                    worker = SimWorker(graph, ns, config.make_agent(), config, oracle=bool(config.questioner))
                if view is not None:
                    worker.live = LiveHook(view, f'w{namespaces.index(ns)}')
                return worker

            supervisor = Supervisor(graph, nodes_of, make_worker, config.max_restarts) if config.max_restarts else None
            workers = supervisor.start(namespaces) if supervisor else [make_worker(ns) for ns in namespaces]
            startup_s = time.monotonic() - t0
            with progress_bar(len(tasks), len(done), progress) as bar:
                play_episodes(graph, workers, jobs, recorder(bar), supervisor)
            restarts = supervisor.restarts if supervisor else 0
            if traces is not None:
                if config.performer:
                    graph.spin_until_any([], 0.5)     # feedback of the last steps may come after the result
                for w in workers:
                    traces.update(w.traces)
    results = [done[t.task_id] for t in tasks]
    report = EvalReport(config, results, ran, startup_s, time.monotonic() - t0, summarize(results), restarts)
    write_text_atomically(config.summary_path, json.dumps(report.to_json(), indent=1) + '\n')
    return report


def print_report(report: EvalReport) -> None:
    from dialfred_sim.metrics import failures, format_table
    c, info = report.config, report.to_json()['this_run']
    rate = f', {info["episodes_per_s"]:.2f} episodes/s' if info['episodes_per_s'] else ''
    privileged = (' (PRIVILEGED: given the expert\'s plan; a reference, not a benchmark result)'
                  if any(r.privileged for r in report.results) else '')
    shard = f', shard {c.shard[0]}/{c.shard[1]}' if c.shard else ''
    print(f'{c.split}{shard}, {c.agent_name} agent{privileged}, seed {c.seed}: {len(report.results)} tasks '
          f'({report.ran} played now in {report.wall_s:.1f} s{rate})')
    print(format_table(report.summary))
    if c.agent == 'expert':
        failed = failures(report.results)
        print(f'expert failures: {len(failed)}')
        for r in failed:
            print(f'  {r.task_id}  {r.task_type:<20} {r.end_reason:<12} {r.error}')
    print(f'results: {c.results_path}\nsummary: {c.summary_path}')
    if c.tasks_source:
        print(f'tasks:   {c.tasks_source.path} (sha256 {c.tasks_source.sha256[:12]}..., recorded in '
              f'{c.tasks_record_path})')


def eval_config(args) -> EvalConfig:
    return EvalConfig(split=args.split or 'valid_unseen',
                      agent=args.agent, questioner='' if args.questioner in (None, 'none') else args.questioner,
                      limit=args.limit,
                      perturb_type=args.perturb_type or '', perturb_probability=args.perturb_probability,
                      workers=args.workers,
                      out=Path(args.out) if args.out else None, seed=args.seed,
                      resolution=args.resolution or default_resolution(args),
                      tasks_file=Path(args.tasks) if args.tasks else None,
                      performer=args.performer or '', checkpoint=Path(args.checkpoint) if args.checkpoint else None,
                      foxglove=args.foxglove, max_restarts=args.max_restarts, shard=getattr(args, 'shard', None),
                      local=bool(getattr(args, 'local', False)), **record_options(args))


def default_resolution(args) -> int:
    """The et performer's training resolution (its checkpoint's: a frame of another size would be
    resized by area averaging, which is not the rendering it learned from); 128 for other agents. An
    unreadable checkpoint: 128, and check() says why."""
    if args.agent != 'et' and args.performer != 'et':
        return 128
    from dialfred_performer.model import SHIPPED_CHECKPOINT, CheckpointError, load_checkpoint
    try:
        return int(load_checkpoint(Path(args.checkpoint) if args.checkpoint else SHIPPED_CHECKPOINT)[0].config.resolution)
    except (FileNotFoundError, CheckpointError):
        return 128


def add_record_options(parser) -> None:
    """--record / --record-format, for every job that plays episodes (eval, demo, dialogue)."""
    parser.add_argument('--record', default=None, metavar='DIR',
                        help='write each episode as a ROS 2 bag (rosbag2, MCAP storage) into DIR/<split>_<number>/: '
                             'task, camera, poses, QAs, actions and their results, the outcome; '
                             '`./dialfred replay DIR/<bag>` prints and renders one')
    parser.add_argument('--record-format', default='raw', choices=['raw', 'png', 'jpeg'],
                        help='camera frames in the bags: raw sensor_msgs/Image (default) or CompressedImage')


def record_options(args) -> dict:
    return {'record': Path(args.record) if args.record else None, 'record_format': args.record_format}


def run_eval_command(args) -> int:
    config = eval_config(args)
    try:
        config.check()
    except ValueError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    try:
        report = run_eval(config, progress=not args.no_progress)
    except KeyboardInterrupt:
        print(f'interrupted: finished episodes are in {config.results_path}; the same command resumes',
              file=sys.stderr)
        raise
    print_report(report)
    return 0


def add_eval_parser(sub) -> None:
    ev = sub.add_parser('eval', help='evaluate an agent on a split; resumable JSON-lines results and a metrics table')
    tasks = ev.add_mutually_exclusive_group()
    tasks.add_argument('--split', default=None, choices=['train', 'valid_seen', 'valid_unseen'],
                       help='a shipped split (default valid_unseen)')
    tasks.add_argument('--tasks', default=None, metavar='PATH',
                       help='a split file of your own instead of --split, e.g. a sealed test split made with '
                            '`python -m dialfred_sim.tasks.splits test_unseen --seed S --size N --out PATH`; '
                            'results record its path and sha256 and are never mixed with another file\'s')
    ev.add_argument('--agent', default='expert',
                    help='expert, random, et (the performer of --checkpoint, in this process), or your own class '
                         'as package.module:ClassName (on the Python path; '
                         'made as ClassName(resolution=R), with reset(task, seed) and act(observation))')
    ev.add_argument('--performer', default=None, choices=['et'],
                    help='et: a performer node per worker plays each task as a RunTask goal (with sim, oracle '
                         'and questioner nodes in its namespace); this process only sends goals and records '
                         'results. (--agent et plays the same performer in this process.)')
    ev.add_argument('--checkpoint', default=None, metavar='PATH',
                    help='the et performer\'s checkpoint (default the one shipped in the package, dialfred_performer/checkpoints/et.pt)')
    ev.add_argument('--questioner', default=None,
                    help='ask the oracle (one oracle node per worker): none (the default) = no questions; '
                         'random = the paper\'s Random QA: at the start, a type drawn with 25%% each for '
                         'location, appearance, direction and no question, then every question of that type '
                         '(one per instruction object, or one direction question); '
                         'all = location + appearance of every instruction object, then direction; '
                         'confusion = a random question whenever the agent is unsure (needs action_probabilities); '
                         'a learned questioner (greedy, asking at the chances of the timing it was trained with): '
                         'pretrained, rl-begin, rl-anytime (every 5 steps), rl-anytime-1, rl-anytime-10, '
                         'rl-mc (when the performer is unsure), rl-anytime-withhold-location|appearance|direction, rl-anytime-no-dialogue '
                         '(the checkpoints shipped in dialfred_questioner/checkpoints), or learned:PATH (any '
                         'questioner checkpoint; results are named learned-<file stem>-<sha256[:8]>); '
                         'or package.module:ClassName (reset(task, seed), ask(observation, step), hear(qa))')
    ev.add_argument('--perturb-type', default=None, choices=['location', 'appearance', 'direction'],
                    help="the paper's ablation: the oracle withholds answers of this type (\"I don't know.\")")
    ev.add_argument('--perturb-probability', type=float, default=0.5,
                    help='how often it withholds them (default 0.5, as in the paper)')
    ev.add_argument('--limit', type=int, default=None, help='only the first N tasks of the split')
    ev.add_argument('--shard', type=parse_shard, default=None, metavar='K/N',
                    help='only shard K of N (0 <= K < N) of the selected tasks (after --limit): those whose index '
                         'in the split is K modulo N, seeded as in a whole run; results go to '
                         '<default name>_shardKofN.jsonl. Join the shards\' files with `./dialfred merge` '
                         '(docs/scaling.md)')
    ev.add_argument('--workers', type=int, default=2, help='simulator nodes playing episodes in parallel')
    ev.add_argument('--local', action='store_true',
                    help='no ROS: each worker is a process with its own simulator, the oracle\'s rules and the agent '
                         '(the same episodes as through the graph, faster; not with --performer, --record, '
                         '--foxglove; dialfred_bringup/local.py)')
    ev.add_argument('--out', default=None,
                    help='results file (default out/eval/<split>_<agent>[+<questioner>].jsonl)')
    ev.add_argument('--seed', type=int, default=0)
    ev.add_argument('--resolution', type=int, default=None,
                    help='camera pixels (default: for the et performer, the resolution its checkpoint was trained '
                         'at, 64 for the shipped one; else 128)')
    ev.add_argument('--no-progress', action='store_true', help='no progress bar on stderr')
    ev.add_argument('--foxglove', type=int, nargs='?', const=8765, default=None, metavar='PORT',
                    help='watch the workers live in the Foxglove app: a Foxglove WebSocket server on PORT (default '
                         '8765) streams each camera, a top-down map with the agent, the dialogue and the progress')
    ev.add_argument('--max-restarts', type=int, default=3,
                    help='a worker whose node dies or stops answering has its nodes restarted and its episode '
                         'replayed from the start, at most this many times in a row (default 3; 0 = stop the run)')
    add_record_options(ev)


