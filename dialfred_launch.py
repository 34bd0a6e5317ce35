#!/usr/bin/env python3
"""DialFRED launcher: starts the node graph as separate processes and runs scripted jobs on it.

There is no `ros2 launch` here, so this script does its job: it resolves each node executable the
way `ros2 run <pkg> node` does (ament index prefix + lib/<pkg>/node), starts it, waits until its
services answer, runs a job, and shuts everything down on exit or Ctrl-C. A node that dies is
reported with its exit code and the last lines it printed.

    python dialfred_launch.py demo [--scene FloorPlan1] [--seed 0] [--steps 40] [--out out/demo]
    python dialfred_launch.py nodes              # start the graph and keep it up until Ctrl-C
    python dialfred_launch.py eval --split valid_unseen --agent expert|random [--limit N] [--workers 2]
                                   [--out out/eval/<split>_<agent>.jsonl] [--seed 0] [--resolution 128]

`eval` runs `--workers` simulator nodes, each in its own namespace (/w0/sim/step, /w1/sim/step, ...),
drives them all from this process with asynchronous calls, appends each episode's result to the
JSON-lines file as it ends (a rerun skips the tasks already there), and prints SR / PWSR / GC / NQ
overall and per task type; the summary also goes to <out without .jsonl>.summary.json.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import signal
import subprocess
import sys
import threading
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

REPO = Path(__file__).resolve().parent
# Every process of the graph (this one and its children) uses the project's Fast DDS profile: a
# shared-memory segment large enough for whole observations (see config/fastdds_profiles.xml).
os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(REPO / 'config' / 'fastdds_profiles.xml'))
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')


def resolve_executable(package: str, executable: str = 'node') -> Path:
    """<prefix>/lib/<package>/<executable> of an installed package, as `ros2 run` finds it."""
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


@dataclass
class NodeProcess:
    """One node executable running as a child process, its output kept for error reports."""

    package: str
    parameters: dict = field(default_factory=dict)
    executable: str = 'node'
    namespace: str = ''          # e.g. '/w0': the node's relative names (sim/step) become /w0/sim/step
    proc: Optional[subprocess.Popen] = None
    tail: collections.deque = field(default_factory=lambda: collections.deque(maxlen=40))

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
        self.proc = subprocess.Popen(self.command(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     start_new_session=True)
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
        for sig, wait in ((signal.SIGINT, timeout), (signal.SIGTERM, 2.0), (signal.SIGKILL, 2.0)):
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
    """The running node graph plus a client node in this process to talk to it."""

    def __init__(self, nodes: list[NodeProcess]):
        self.nodes = nodes
        self.client_node = None
        self.executor = None
        self.owns_context = False    # False inside another Graph of this process: share its rclpy context

    def __enter__(self) -> 'Graph':
        try:
            self._start()
        except BaseException:
            self.__exit__()         # never leave started nodes behind (they run in their own sessions)
            raise
        return self

    def _start(self) -> None:
        import rclpy
        from rclpy.signals import SignalHandlerOptions

        from dialfred_sim.ros_util import make_executor
        for n in self.nodes:
            n.start()
        if not rclpy.ok():
            # Ctrl-C is this process's KeyboardInterrupt (unwinding through __exit__), not rclpy's
            # handler, which would shut the context down under a running spin (ExternalShutdownException).
            rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
            self.owns_context = True
        self.client_node = rclpy.create_node('dialfred_launcher')
        self.executor = make_executor()
        self.executor.add_node(self.client_node)

    def __exit__(self, *exc) -> None:
        import rclpy
        if self.executor is not None:
            self.executor.shutdown()
        if self.client_node is not None:
            self.client_node.destroy_node()
        if self.owns_context:
            rclpy.try_shutdown()
        for n in self.nodes:
            code = n.stop()
            if code not in (None, 0, -signal.SIGINT, 130):
                print(f'{n.label} node exited with code {code}', file=sys.stderr)

    def check(self) -> None:
        for n in self.nodes:
            n.check()

    def client(self, srv_type, name: str, timeout: float = 30.0):
        """A client for service `name`, once it is available; NodeDied if a node dies meanwhile."""
        cli = self.client_node.create_client(srv_type, name)
        deadline = time.monotonic() + timeout
        while not cli.wait_for_service(timeout_sec=0.1):
            self.check()
            if time.monotonic() > deadline:
                raise TimeoutError(f'service {name} not available after {timeout:.0f} s')
        return cli

    def spin_until_any(self, futures: list, timeout: float = 0.5) -> None:
        """Serve callbacks until one of `futures` is done or `timeout` passes; NodeDied if a node dies."""
        deadline = time.monotonic() + timeout
        while not any(f.done() for f in futures) and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
        self.check()

    def call(self, cli, request, timeout: float = 30.0):
        """Call a service and wait for the reply, watching the nodes for crashes."""
        future = cli.call_async(request)
        deadline = time.monotonic() + timeout
        while not future.done():
            self.executor.spin_until_future_complete(future, timeout_sec=0.5)
            self.check()
            if time.monotonic() > deadline:
                raise TimeoutError(f'no reply from {cli.srv_name} after {timeout:.0f} s')
        return future.result()


def sim_node(resolution: int = 128, namespace: str = '', **params) -> NodeProcess:
    return NodeProcess('dialfred_sim', {'resolution': resolution, **params}, namespace=namespace)


def sim_service(namespace: str, name: str) -> str:
    """The full name of the sim node's service `name` ('reset', 'step') in `namespace` ('' or '/w0')."""
    return f'{namespace.rstrip("/")}/sim/{name}'


# ---------------------------------------------------------------------------------------- jobs

def image_array(msg):
    import numpy as np
    dtype = {'rgb8': np.uint8, '32FC1': np.float32, '32SC1': np.int32}[msg.encoding]
    arr = np.frombuffer(bytes(msg.data), dtype=dtype)
    channels = 3 if msg.encoding == 'rgb8' else 1
    return arr.reshape(msg.height, msg.width, channels) if channels > 1 else arr.reshape(msg.height, msg.width)


def run_demo(args) -> int:
    """Start the simulator node, play a scripted exploring episode through ROS, save its frames."""
    from dialfred_msgs.msg import Action
    from dialfred_msgs.srv import SimReset, SimStep

    from dialfred_sim.scripted import ExplorerPolicy

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with Graph([sim_node(args.resolution)]) as graph:
        t0 = time.monotonic()
        reset_cli = graph.client(SimReset, '/sim/reset')
        step_cli = graph.client(SimStep, '/sim/step')
        print(f'graph ready in {time.monotonic() - t0:.1f} s')
        reply = graph.call(reset_cli, SimReset.Request(scene=args.scene, seed=args.seed))
        if not reply.ok:
            print(f'reset failed: {reply.error}', file=sys.stderr)
            return 1
        obs = reply.observation
        policy = ExplorerPolicy(seed=args.seed)
        frames = []
        print(f'{reply.task.scene}, seed {args.seed}')
        print(f'{"step":>4}  {"action":<10} {"target px":<10} {"ok":<3} {"held":<16} error')
        for step in range(args.steps):
            rgb = image_array(obs.rgb)
            frames.append(rgb)
            decision = policy.act(rgb=rgb, depth=image_array(obs.depth), segmentation=image_array(obs.segmentation),
                                  instances=dict(zip(obs.instance_ids, obs.instance_object_ids)),
                                  held=obs.held_object, last_success=obs.last_action_success)
            req = SimStep.Request(action=Action(action=decision.action, x=decision.pixel[0], y=decision.pixel[1]))
            reply = graph.call(step_cli, req)
            if not reply.ok:
                print(f'step rejected: {reply.error}', file=sys.stderr)
                return 1
            obs = reply.observation
            px = f'{decision.pixel[0]},{decision.pixel[1]}' if decision.pixel[0] >= 0 else ''
            print(f'{step + 1:>4}  {decision.action:<10} {px:<10} {"y" if obs.last_action_success else "n":<3} '
                  f'{obs.held_object or "-":<16} {obs.last_action_error}')
            if obs.done:
                break
        frames.append(image_array(obs.rgb))
    paths = save_frames(frames, out)
    print(f'saved {len(frames)} frames and {paths["gif"]} (contact sheet {paths["sheet"]})')
    return 0


def save_frames(frames, out: Path) -> dict:
    from PIL import Image
    for k, f in enumerate(frames):
        Image.fromarray(f).save(out / f'frame_{k:03d}.png')
    imgs = [Image.fromarray(f).resize((256, 256), Image.NEAREST) for f in frames]
    gif = out / 'episode.gif'
    imgs[0].save(gif, save_all=True, append_images=imgs[1:], duration=250, loop=0)
    cols = 8
    rows = (len(frames) + cols - 1) // cols
    h, w = frames[0].shape[:2]
    sheet = Image.new('RGB', (cols * w, rows * h), (255, 255, 255))
    for k, f in enumerate(frames):
        sheet.paste(Image.fromarray(f), ((k % cols) * w, (k // cols) * h))
    sheet.save(out / 'contact_sheet.png')
    return {'gif': gif, 'sheet': out / 'contact_sheet.png'}


def run_nodes(args) -> int:
    """Start the graph and keep it up until Ctrl-C, reporting any node that dies."""
    from dialfred_msgs.srv import SimReset
    with Graph([sim_node(args.resolution)]) as graph:
        graph.client(SimReset, '/sim/reset')
        print('graph up: /sim/reset, /sim/step, /sim/observation. Ctrl-C to stop.')
        while True:
            graph.check()
            time.sleep(0.5)


# ---------------------------------------------------------------------------------------- eval

@dataclass
class EvalConfig:
    """One evaluation run: an agent over (the first `limit` tasks of) a split."""

    split: str = 'valid_unseen'
    agent: str = 'expert'
    limit: Optional[int] = None
    workers: int = 2
    out: Optional[Path] = None          # default: out/eval/<split>_<agent>.jsonl
    seed: int = 0
    resolution: int = 128
    request_timeout: float = 120.0      # seconds one reset or step may take before the run gives up

    @property
    def results_path(self) -> Path:
        return Path(self.out) if self.out else REPO / 'out' / 'eval' / f'{self.split}_{self.agent}.jsonl'

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

    def to_json(self) -> dict:
        from dialfred_sim.metrics import failures
        c = self.config
        loop_s = self.wall_s - self.startup_s
        return {
            'split': c.split, 'agent': c.agent, 'seed': c.seed, 'resolution': c.resolution, 'workers': c.workers,
            'limit': c.limit, 'results_file': str(c.results_path), 'tasks': len(self.results),
            'this_run': {'episodes': self.ran, 'startup_s': round(self.startup_s, 3), 'wall_s': round(self.wall_s, 3),
                         'episodes_per_s': round(self.ran / loop_s, 3) if self.ran and loop_s > 0 else None},
            'summary': self.summary,
            'failures': [{'task_id': r.task_id, 'task_type': r.task_type, 'end_reason': r.end_reason,
                          'error': r.error} for r in failures(self.results)],
        }


class SimWorker:
    """One simulator node (in its own namespace) playing one episode at a time with its own agent,
    one request in flight. `begin` starts an episode; `advance` handles the reply that arrived and
    either sends the next request or returns the episode's EpisodeResult."""

    def __init__(self, graph: Graph, namespace: str, agent, config: EvalConfig):
        from dialfred_msgs.srv import SimReset, SimStep
        self.reset_cli = graph.client(SimReset, sim_service(namespace, 'reset'))
        self.step_cli = graph.client(SimStep, sim_service(namespace, 'step'))
        self.namespace, self.agent, self.config = namespace, agent, config
        self.future = None
        self.sent_at = 0.0
        self.task = None

    @property
    def busy(self) -> bool:
        return self.future is not None

    def begin(self, index: int, task) -> None:
        from dialfred_msgs.srv import SimReset

        from dialfred_sim.agents import episode_seed
        self.task, self.episode_seed = task, episode_seed(self.config.seed, index)
        self.started = time.monotonic()
        self.last_action, self.last_error = '', ''
        self.goal_conditions = (0, 0)
        self.resetting = True
        self._send(self.reset_cli, SimReset.Request(task_id=task.task_id, with_depth=False, with_segmentation=False))

    def overdue(self) -> bool:
        return self.busy and time.monotonic() - self.sent_at > self.config.request_timeout

    def advance(self):
        """Handle the finished request: the next request is sent, or the episode's result returned."""
        reply, self.future = self.future.result(), None
        if reply is None:
            return self._result('error', error='the service call returned no reply')
        if self.resetting:
            self.resetting = False
            if not reply.ok:
                return self._result('error', error=reply.error)
            self.goal_conditions = (0, reply.task.goal_conditions_total)
            self.agent.reset(self.task, self.episode_seed)
            return self._act(reply.observation)
        return self._after_step(reply)

    def _after_step(self, reply):
        from dialfred_sim.metrics import end_reason
        obs = reply.observation
        if not reply.ok:
            return self._result('error', obs, error=reply.error)
        self.goal_conditions = (reply.goal_conditions_met, reply.goal_conditions_total)
        if not obs.last_action_success:
            self.last_error = obs.last_action_error
        if reply.terminated or reply.truncated:
            reason = end_reason(reply.success, self.last_action, obs.failed_actions, reply.truncated)
            return self._result(reason, obs, success=reply.success)
        return self._act(obs)

    def _act(self, obs):
        from dialfred_msgs.msg import Action
        from dialfred_msgs.srv import SimStep
        name, x, y = self.agent.act(obs)
        self.last_action = name
        self._send(self.step_cli, SimStep.Request(action=Action(action=name, x=int(x), y=int(y)),
                                                  with_depth=False, with_segmentation=False))
        return None

    def _send(self, cli, request) -> None:
        self.sent_at = time.monotonic()
        self.future = cli.call_async(request)

    def _result(self, reason: str, obs=None, success: bool = False, error: str = ''):
        from dialfred_sim.metrics import EpisodeResult
        task = self.task
        met, total = self.goal_conditions
        return EpisodeResult(
            task_id=task.task_id, task_type=task.task_type, split=task.split, success=bool(success),
            goal_conditions_met=int(met), goal_conditions_total=int(total),
            steps=int(obs.step_count) if obs is not None else 0, expert_length=int(task.expert_length),
            questions=0, failed_actions=int(obs.failed_actions) if obs is not None else 0, end_reason=reason,
            error='' if success else (error or self.last_error), agent=self.agent.name, seed=self.config.seed,
            wall_s=round(time.monotonic() - self.started, 4))


def play_episodes(graph: Graph, workers: list, jobs: list, on_result) -> None:
    """Play every (index, task) of `jobs` on the workers, each keeping one request in flight, and
    call `on_result(result)` as each episode ends (in the order they end)."""
    queue = collections.deque(jobs)
    for w in workers:
        if queue:
            w.begin(*queue.popleft())
    while any(w.busy for w in workers):
        graph.spin_until_any([w.future for w in workers if w.busy])
        for w in workers:
            if w.busy and w.future.done():
                result = w.advance()
                if result is not None:
                    on_result(result)
                    if queue:
                        w.begin(*queue.popleft())
            elif w.overdue():
                raise TimeoutError(f'no reply from {w.namespace or "/"} sim node after '
                                   f'{w.config.request_timeout:.0f} s (task {w.task.task_id})')


class ResultsFileError(ValueError):
    """The results file cannot be resumed: corrupt, or written by another split, agent or seed."""


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
        if (r.split, r.agent, r.seed) != (config.split, config.agent, config.seed):
            raise ResultsFileError(f'{path} holds results of split {r.split!r}, agent {r.agent!r}, seed {r.seed}, not '
                             f'{config.split!r}, {config.agent!r}, {config.seed}: choose another --out')
    return results_by_task(existing, task_ids)


def progress_bar(total: int, done: int, enabled: bool):
    from tqdm import tqdm
    return tqdm(total=total, initial=done, unit='ep', file=sys.stderr, disable=not enabled, dynamic_ncols=True,
                smoothing=0.05)


def run_eval(config: EvalConfig, progress: bool = True) -> EvalReport:
    """Evaluate `config.agent` on the split's tasks through `config.workers` simulator nodes.

    Results go to the JSON-lines file as each episode ends; tasks already there are skipped (resume).
    Writes the summary JSON next to it and returns the report of every selected task.
    """
    from dialfred_sim.agents import make_agent
    from dialfred_sim.metrics import append_result, summarize
    from dialfred_sim.tasks import load_split

    t0 = time.monotonic()
    tasks = load_split(config.split)[:config.limit]
    done = resumable_results(config, [t.task_id for t in tasks])
    jobs = [(k, t) for k, t in enumerate(tasks) if t.task_id not in done]
    ran, startup_s = 0, 0.0
    if jobs:
        n = max(1, min(config.workers, len(jobs)))
        namespaces = [f'/w{k}' for k in range(n)]
        with Graph([sim_node(config.resolution, ns, publish_observations=False) for ns in namespaces]) as graph:
            workers = [SimWorker(graph, ns, make_agent(config.agent, config.resolution), config) for ns in namespaces]
            startup_s = time.monotonic() - t0
            with progress_bar(len(tasks), len(done), progress) as bar:
                def record(result) -> None:
                    nonlocal ran
                    append_result(config.results_path, result)
                    done[result.task_id] = result
                    ran += 1
                    bar.update(1)

                play_episodes(graph, workers, jobs, record)
    results = [done[t.task_id] for t in tasks]
    report = EvalReport(config, results, ran, startup_s, time.monotonic() - t0, summarize(results))
    config.summary_path.write_text(json.dumps(report.to_json(), indent=1) + '\n')
    return report


def print_report(report: EvalReport) -> None:
    from dialfred_sim.metrics import failures, format_table
    c, info = report.config, report.to_json()['this_run']
    rate = f', {info["episodes_per_s"]:.2f} episodes/s' if info['episodes_per_s'] else ''
    print(f'{c.split}, {c.agent} agent, seed {c.seed}: {len(report.results)} tasks '
          f'({report.ran} played now in {report.wall_s:.1f} s{rate})')
    print(format_table(report.summary))
    if c.agent == 'expert':
        failed = failures(report.results)
        print(f'expert failures: {len(failed)}')
        for r in failed:
            print(f'  {r.task_id}  {r.task_type:<20} {r.end_reason:<12} {r.error}')
    print(f'results: {c.results_path}\nsummary: {c.summary_path}')


def eval_config(args) -> EvalConfig:
    return EvalConfig(split=args.split, agent=args.agent, limit=args.limit, workers=args.workers,
                      out=Path(args.out) if args.out else None, seed=args.seed, resolution=args.resolution)


def run_eval_command(args) -> int:
    config = eval_config(args)
    try:
        report = run_eval(config, progress=not args.no_progress)
    except KeyboardInterrupt:
        print(f'interrupted: finished episodes are in {config.results_path}; the same command resumes',
              file=sys.stderr)
        raise
    print_report(report)
    return 0


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def add_eval_parser(sub) -> None:
    ev = sub.add_parser('eval', help='evaluate an agent on a split; resumable JSON-lines results and a metrics table')
    ev.add_argument('--split', default='valid_unseen', choices=['train', 'valid_seen', 'valid_unseen'])
    ev.add_argument('--agent', default='expert', choices=['expert', 'random'])
    ev.add_argument('--limit', type=int, default=None, help='only the first N tasks of the split')
    ev.add_argument('--workers', type=int, default=2, help='simulator nodes playing episodes in parallel')
    ev.add_argument('--out', default=None, help='results file (default out/eval/<split>_<agent>.jsonl)')
    ev.add_argument('--seed', type=int, default=0)
    ev.add_argument('--resolution', type=int, default=128)
    ev.add_argument('--no-progress', action='store_true', help='no progress bar on stderr')


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='command', required=True)
    demo = sub.add_parser('demo', help='scripted episode through the simulator node; saves frames')
    demo.add_argument('--scene', default='FloorPlan1')
    demo.add_argument('--seed', type=int, default=0)
    demo.add_argument('--steps', type=int, default=40)
    demo.add_argument('--resolution', type=int, default=128)
    demo.add_argument('--out', default=str(REPO / 'out' / 'demo'))
    nodes = sub.add_parser('nodes', help='start the node graph and keep it running')
    nodes.add_argument('--resolution', type=int, default=128)
    add_eval_parser(sub)
    args = parser.parse_args(argv)
    # Ctrl-C and SIGTERM both unwind through the Graph context, which stops every child.
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        return {'demo': run_demo, 'nodes': run_nodes, 'eval': run_eval_command}[args.command](args)
    except KeyboardInterrupt:
        print('interrupted; nodes stopped', file=sys.stderr)
        return 130
    except (NodeDied, TimeoutError, FileNotFoundError, ResultsFileError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
