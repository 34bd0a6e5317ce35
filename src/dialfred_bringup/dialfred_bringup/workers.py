"""The workers of an evaluation through the graph, and what keeps them alive.

`SimWorker` plays the episode loop (`dialfred_sim.episode.play`) of an agent in this process against one
worker's simulator and oracle nodes, one asynchronous request in flight; `PerformerWorker` sends one
worker's performer node a RunTask goal per task and records its result. `play_episodes` keeps every
worker busy from one executor; `Supervisor` restarts a worker whose node died or stopped answering and
plays its episode again from the start. `worker_nodes` says which nodes a worker runs; `LiveHook` and
`start_live_view` feed the Foxglove live view.
"""

from __future__ import annotations

import collections
import sys
import time
from pathlib import Path
from types import SimpleNamespace

from rclpy.action import ActionClient
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from dialfred_oracle.answerers import resolved_spec
from dialfred_sim.agents import task_view
from dialfred_sim.bag import RecordingObserver
from dialfred_sim.chained import ChainedEpisode, expert_reference, reference_length
from dialfred_sim.episode import Ask, EpisodeObserver, Failed, Reset, play
from dialfred_sim.metrics import OUTCOME_FIELDS, dialogue_entry, episode_result
from dialfred_sim.protocol import MapPainter, episode_seed, heard_by, image_array
from dialfred_sim.ros_util import RESEND_AFTER_S, SETTLE_S
from dialfred_sim.traces import make_trace

from .graph import Graph, NodeDied, NodeProcess, oracle_node, sim_node, sim_service
from .local import state_result


class SimWorker(EpisodeObserver):
    """One simulator node (in its own namespace) playing one episode at a time with its own agent, one
    request in flight: the episode loop (`dialfred_sim.episode.play`) driven by asynchronous service
    calls. `begin` starts an episode; `advance` hands the reply that arrived to the loop and either sends
    its next request or returns the episode's EpisodeResult. With `oracle`, the agent's questions go to
    the oracle node of the same namespace before it acts. `begin_chain` plays a chained episode
    (dialfred_sim.chained): its tasks one after the other on the same simulator, each later one going on
    from the world the last left (`carry_on` in /sim/reset); `advance` returns each task's result as it
    ends, and the worker stays busy until the episode's last has."""

    def __init__(self, graph: Graph, namespace: str, agent, run, oracle: bool = False):
        # lazy: the ROS messages, which the rest of this module does without
        from dialfred_msgs.srv import OracleAnswer, SimReset, SimStep
        self.reset_cli = graph.client(SimReset, sim_service(namespace, 'reset'))
        self.step_cli = graph.client(SimStep, sim_service(namespace, 'step'))
        self.ask_cli = graph.client(OracleAnswer, f'{namespace.rstrip("/")}/oracle/answer') if oracle else None
        self.graph, self.namespace, self.agent, self.run = graph, namespace, agent, run
        self.future = None
        self.job = None
        self.live = None       # a LiveHook, with --foxglove
        self.sent_at = 0.0
        self.task = None
        self.pending = ''      # what the request in flight is: 'reset', 'step' or 'question'
        self.chain, self.link = None, 0     # a chained episode being played, and the task of it now
        self.traces = collections.defaultdict(list)   # task id -> the actions sent, (name, x, y)

    @property
    def busy(self) -> bool:
        return self.future is not None

    def begin(self, index: int, task) -> None:
        self.job, self.chain = (index, task), None
        self._start(index, task, task, carry_on=False)

    def begin_chain(self, episode) -> None:
        """Play the tasks of a chained episode (dialfred_sim.chained.ChainedEpisode) in order."""
        self.job, self.chain = episode, episode
        self._start_link(0)

    def _start_link(self, k: int) -> None:
        tasks = [t for _, t in self.chain.tasks]
        self.link = k
        index, task = self.chain.tasks[k]
        self._start(index, task, expert_reference(tasks, k), carry_on=k > 0)

    def _start(self, index: int, task, reference, carry_on: bool) -> None:
        """Start the episode loop of `task`; the expert is told `reference` (its chained stretch)."""
        self.task = task
        self.started_at = time.monotonic()
        observers = [self]
        if not carry_on:        # a chained episode's tasks share one recorder: the episode is one bag
            self.recorder = None
            if self.run.options.record is not None:
                self.recorder = RecordingObserver(
                    self.run.options.record, self.run.options.record_format,
                    picture=self.agent.picture if isinstance(self.agent, MapPainter) else None,
                    chained=self.chain is not None, heard=lambda qa: heard_by(self.agent, qa))
        if self.recorder is not None:
            observers.append(self.recorder)
        if self.live is not None:
            self.live.begin(task)
        self.episode = play(self.agent, seed=episode_seed(self.run.options.seed, index),
                            told=task_view(self.agent, reference),      # the public view, unless privileged
                            asks=self.ask_cli is not None, max_questions=self.run.options.max_questions,
                            observers=observers, carry_on=carry_on)
        self._request(next(self.episode))

    def overdue(self) -> bool:
        if self.pending == 'question' and self.run.options.human:
            return False          # a person answers at their own pace (the oracle's human_timeout bounds it)
        return self.busy and time.monotonic() - self.sent_at > self.run.options.request_timeout

    def close(self) -> None:
        """Abandon the episode in flight (this worker's nodes are being restarted). Its clients stay with
        the client node: destroying an entity the executor may be waiting on can crash rclpy."""
        self.future, self.recorder = None, None

    def advance(self):
        """Hand the finished request's reply to the episode: its next request is sent, or its result returned."""
        reply, self.future = self.future.result(), None
        if reply is None:
            reply = Failed('the service call returned no reply')
        elif self.pending == 'question':
            # lazy: the ROS messages, which the rest of this module does without
            from dialfred_sim.messages import qa_from_answer
            reply = qa_from_answer(self.asking, reply, self.task.task_id)
        else:
            # lazy: the ROS messages, which the rest of this module does without
            from dialfred_sim.messages import sim_reply
            reply = sim_reply(reply)
        try:
            self._request(self.episode.send(reply))
        except StopIteration as stop:
            result = self._result(stop.value)
            if self.chain is not None and self.link + 1 < len(self.chain.tasks):
                self._start_link(self.link + 1)      # still busy: the episode's next task
            return result
        return None

    def _request(self, request) -> None:
        """Send the episode's request to the simulator or the oracle node."""
        from dialfred_msgs.msg import Action  # lazy: the ROS messages, which the rest of this module does without
        # lazy: the ROS messages, which the rest of this module does without
        from dialfred_msgs.srv import OracleAnswer, SimReset, SimStep
        if isinstance(request, Reset):
            chained = {'protocol': 'chained', 'carry_on': self.link > 0} if self.chain is not None else {}
            self._send(self.reset_cli, SimReset.Request(task_id=self.task.task_id, with_depth=False,
                                                        with_segmentation=False, **chained), 'reset')
        elif isinstance(request, Ask):
            self.asking = request.question
            self._send(self.ask_cli, OracleAnswer.Request(question_type=request.question.question_type,
                                                          object_noun=request.question.object_noun), 'question')
        else:
            self._send(self.step_cli, SimStep.Request(action=Action(action=request.action, x=request.x, y=request.y),
                                                      with_depth=False, with_segmentation=False), 'step')

    # EpisodeObserver: the live view and the traces of the actions sent (the bag: a RecordingObserver beside it)
    def on_question(self, state, qa, step: int) -> None:
        if self.live is not None:
            self.live.qa(qa.question.question_type, qa.question.object_noun, qa.answer, qa.valid)
        heard = heard_by(self.agent, qa)
        if heard and self.run.options.human:      # the person sees what the robot took from their words
            print(f'[robot] heard: {heard}', file=sys.stderr, flush=True)

    def on_action(self, state, action: str, x: int, y: int) -> None:
        self.traces[self.task.task_id].append((action, x, y))
        if isinstance(self.agent, MapPainter) and self.live is not None:     # a performer that keeps a map
            self.live.belief(self.agent.picture())

    def on_stepped(self, state, reply, action: str, x: int, y: int) -> None:
        obs = reply.raw.observation
        if self.live is not None:
            self.live.action(int(obs.step_count), action, obs.last_action_success)

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
        length = reference_length([t for _, t in self.chain.tasks], self.link) if self.chain is not None else None
        return state_result(self.run, self.task, self.agent, state, time.monotonic() - self.started_at,
                            expert_length=length)


class PerformerWorker:
    """One worker's performer node (in its own namespace, with its simulator, oracle and questioner
    nodes beside it) playing one task at a time as a RunTask goal: a commander that only sends goals
    and records results. `begin` sends the goal; `advance` handles the reply that arrived (the goal
    accepted: wait for its result; the result: the episode's EpisodeResult). A goal running longer
    than `episode_timeout` is cancelled, and its episode recorded as an error."""

    def __init__(self, graph: Graph, namespace: str, run, on_feedback=None):
        from dialfred_msgs.action import RunTask  # lazy: the ROS messages, which the rest of this module does without
        self.name = f'{namespace.rstrip("/")}/performer/run_task'
        self.client = ActionClient(graph.client_node, RunTask, self.name)
        deadline = time.monotonic() + 60.0
        while not self.client.wait_for_server(timeout_sec=0.1):
            graph.check()
            if time.monotonic() > deadline:
                raise TimeoutError(f'action server {self.name} not available after 60 s')
        self.graph, self.namespace, self.run = graph, namespace, run
        if run.options.human:      # the person sees what the robot took from their words (QAPair.heard)
            from dialfred_msgs.msg import QAPair  # lazy: the ROS messages, which the rest of this module does without
            self.heard_sub = graph.client_node.create_subscription(
                QAPair, f'{namespace.rstrip("/")}/dialogue/qa',
                lambda m: print(f'[robot] heard: {m.heard}', file=sys.stderr, flush=True) if m.heard else None, 100)
        self._prove_paths(deadline)
        self.on_feedback = on_feedback    # called with (task, RunTask.Feedback) as each step's feedback comes
        self.future = self.goal_handle = self.cancel_future = None
        self.task = self.job = None
        self.live = None       # a LiveHook, with --foxglove
        self.pending = ''       # 'goal' (waiting for acceptance) or 'result'
        self.chain, self.link = None, 0     # a chained episode being played (a goal a task), and its task now
        self.traces = collections.defaultdict(list)   # task id -> the actions of its feedback, (name, x, y)

    def _prove_paths(self, deadline: float) -> None:
        """Wait until a goal's reply paths work. "Server available" means the goal request reader
        matched; the replies (goal response, result) may not have, and a reply sent before they match
        is lost: a goal then waits for its acceptance until request_timeout (the hang once seen in an
        evaluation, and after every node restart under load). So: a goal the node refuses to play (a
        negative seed: aborted before it touches the simulator) is sent until its result comes back."""
        from dialfred_msgs.action import RunTask  # lazy: the ROS messages, which the rest of this module does without
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
        self.job, self.chain = (index, task), None
        self._send_goal(index, task)

    def begin_chain(self, episode) -> None:
        """Play the tasks of a chained episode (dialfred_sim.chained.ChainedEpisode) in order, a goal each: the
        first resets the simulator to its start, every later one goes on (`carry_on`)."""
        self.job, self.chain, self.link = episode, episode, 0
        self._send_goal(*episode.tasks[0])

    def _send_goal(self, index: int, task) -> None:
        from dialfred_msgs.action import RunTask  # lazy: the ROS messages, which the rest of this module does without

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

        chained = {'protocol': 'chained', 'carry_on': self.link > 0} if self.chain is not None else {}
        goal = RunTask.Goal(task_id=task.task_id, seed=episode_seed(self.run.options.seed, index), **chained)
        self.future = self.client.send_goal_async(goal, feedback_callback=feedback)
        self.pending = 'goal'

    def advance(self):
        reply, self.future = self.future.result(), None
        if self.pending == 'goal':
            if reply is None or not reply.accepted:
                return self._go_on(self._result(None, error=f'{self.name} rejected the goal (is another goal running '
                                                            'there?)'))
            self.goal_handle, self.pending = reply, 'result'
            self.future = reply.get_result_async()
            return None
        from action_msgs.msg import GoalStatus  # lazy: the ROS messages, which the rest of this module does without
        result = reply.result
        if reply.status == GoalStatus.STATUS_CANCELED:
            return self._go_on(self._result(result, error=f'cancelled after {self.run.options.episode_timeout:g} s '
                                                          '(episode_timeout)'))
        return self._go_on(self._result(result))

    def _go_on(self, line):
        """`line`, a task's results line; in a chained episode the next task's goal is sent first (still busy)."""
        if self.chain is not None and self.link + 1 < len(self.chain.tasks):
            self.link += 1
            self._send_goal(*self.chain.tasks[self.link])
        return line

    def overdue(self) -> bool:
        """Cancel a goal past episode_timeout (once); True only if even the cancel got no result in 60 s."""
        late = time.monotonic() - self.started - self.run.options.episode_timeout
        if late < 0 or self.pending != 'result':
            return self.pending == 'goal' and time.monotonic() - self.sent_at > self.run.options.request_timeout
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
        """The results line of the goal's RunTask `result` (None: no result came), or of an error."""
        r = result
        reason = 'error' if error or r is None or r.end_reason in ('error', 'canceled') else r.end_reason
        outcome = SimpleNamespace(**{k: getattr(r, k) if r is not None else 0 for k in OUTCOME_FIELDS})
        outcome.success = bool(r.success) if r is not None and reason != 'error' else False
        outcome.end_reason = reason
        outcome.error = '' if outcome.success else (error or (r.error if r is not None else ''))
        dialogue = [dialogue_entry(m.question_type, m.object_noun, m.valid, m.answer) for m in r.dialogue] if r else []
        length = reference_length([t for _, t in self.chain.tasks], self.link) if self.chain is not None else None
        # the trace: the actions the node sent and its questions' steps, as its result says (no result: none)
        trace = make_trace([(a.action, a.x, a.y) for a in r.actions], r.asked_at) if r is not None else \
            make_trace([], [])
        return episode_result(self.task, outcome, dialogue, wall_s=time.monotonic() - self.started,
                              expert_length=length, trace=trace, **self.run.identity)


def begin(worker, job) -> None:
    """Start `job` on `worker`: an (index, task), or a chained episode (SimWorker.begin_chain)."""
    if isinstance(job, ChainedEpisode):
        worker.begin_chain(job)
    else:
        worker.begin(*job)


def play_episodes(graph: Graph, workers: list, jobs: list, on_result, supervisor=None) -> None:
    """Play every (index, task) of `jobs` (or chained episode: SimWorker.begin_chain) on the workers, each
    keeping one request in flight, and call `on_result(result)` as each episode (or chained task) ends, in
    the order they end.

    With a `supervisor` (a Supervisor), a worker whose node died or stopped answering has its nodes
    restarted and its episode played again from the start; without one, NodeDied or TimeoutError ends
    the run."""
    queue = collections.deque(jobs)
    for w in workers:
        if queue:
            begin(w, queue.popleft())
    while any(w.busy for w in workers) or (supervisor is not None and queue):
        for w in workers:
            if not w.busy and queue:
                begin(w, queue.popleft())
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
                    if queue and not w.busy:        # (a chained episode goes on with its next task)
                        begin(w, queue.popleft())
            elif w.busy and w.resend_if_lost():
                continue
            elif w.busy and w.overdue():
                node = {'question': 'oracle', 'goal': 'performer', 'result': 'performer'}.get(w.pending, 'sim')
                message = (f'no reply from {w.namespace or "/"} {node} node after {w.run.options.request_timeout:.0f} s '
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
                    queue.appendleft(w.job)         # a chained episode is played again from its first task
                    for task_id in (w.job.task_ids if isinstance(w.job, ChainedEpisode) else [w.job[1].task_id]):
                        w.traces.pop(task_id, None)      # the replay traces it afresh
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
                begin(w, queue.popleft())

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


def worker_nodes(run, namespace: str, **sim_params) -> list:
    """The nodes of one worker in `namespace`: its simulator; with a questioner, its oracle; with the
    performer node, also the questioner node and the performer node (a RunTask server). `sim_params`:
    more parameters of the simulator node (default: it publishes no observations)."""
    from_file = {'tasks_file': str(run.tasks_source.path)} if run.options.tasks_file else {}
    nodes = [sim_node(run.options.resolution, namespace, **{'publish_observations': False, 'goal_rule': run.options.goal_rule,
                                                       **from_file, **sim_params})]
    if run.asks:
        withhold = {'perturb_type': run.options.perturb_type, 'perturb_probability': run.options.perturb_probability,
                    'seed': run.options.seed} if run.options.perturb_type else {}
        if run.options.answers == 'swapped':
            withhold.update(answers='swapped', swap_resolution=run.options.resolution, **from_file)
        elif run.answerer:       # the node may run elsewhere: a file by its absolute path
            withhold['answers'] = resolved_spec(run.answerer)
        if run.options.human and run.options.human_timeout:
            withhold['human_timeout'] = run.options.human_timeout
        nodes.append(oracle_node(namespace, human=run.options.human, **withhold))
    if run.options.performer:
        if run.options.questioner:
            learned = run.learned_questioner_path     # the node may run elsewhere: an absolute path
            name = f'learned:{learned.resolve()}' if learned is not None else run.options.questioner
            nodes.append(NodeProcess('dialfred_questioner', {'questioner': name}, namespace=namespace))
        record = {'record_dir': str(Path(run.options.record).resolve()),
                  'record_format': run.options.record_format} if run.options.record is not None else {}
        nodes.append(NodeProcess('dialfred_performer', {'checkpoint': str(run.checkpoint_path.resolve()),
                                                        'model': run.options.performer,
                                                        'questioner': bool(run.options.questioner),
                                                        'max_questions': run.options.max_questions,
                                                        'request_timeout': run.options.request_timeout,
                                                        **({'answer_timeout': 1e9} if run.options.human else {}),
                                                        **record},
                                 namespace=namespace))
    return nodes


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

    def belief(self, picture) -> None:
        self.view.belief(self.worker, picture)

    def result(self, r) -> None:
        self.view.result(self.worker, r.task_id, r.success, r.end_reason, r.steps, r.questions)


def start_live_view(run, graph: Graph, namespaces: list, total: int):
    """The Foxglove server of --foxglove, fed from each worker's sim/observation (camera, pose) and,
    for performer nodes, dialogue/qa and performer/map; the workers' LiveHooks tell it the rest."""
    from sensor_msgs.msg import Image  # lazy: the ROS messages, which the rest of this module does without

    # lazy: the ROS messages, which the rest of this module does without
    from dialfred_msgs.msg import Observation, QAPair
    from dialfred_bringup.live import LiveView, describe
    view = LiveView(len(namespaces), port=run.options.foxglove, total=total)
    print(describe(view), file=sys.stderr, flush=True)
    qos = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=1)
    for k, ns in enumerate(namespaces):
        w, base = f'w{k}', ns.rstrip('/')

        def seen(obs, w=w) -> None:
            p = obs.pose
            view.frame(w, image_array(obs.rgb), (p.x, p.y, p.rotation_deg, p.horizon_deg), p.camera_height,
                       int(obs.step_count))

        graph.client_node.create_subscription(Observation, f'{base}/sim/observation', seen, qos)
        if run.options.performer:
            graph.client_node.create_subscription(
                QAPair, f'{base}/dialogue/qa',
                lambda m, w=w: view.qa(w, m.question_type, m.object_noun, m.answer, m.valid), 100)
            graph.client_node.create_subscription(
                Image, f'{base}/performer/map', lambda m, w=w: view.belief(w, image_array(m)), qos)
    return view
