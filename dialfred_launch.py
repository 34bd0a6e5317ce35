#!/usr/bin/env python3
"""DialFRED launcher: starts the node graph as separate processes and runs scripted jobs on it.

There is no `ros2 launch` here, so this script does its job: it resolves each node executable the
way `ros2 run <pkg> node` does (ament index prefix + lib/<pkg>/node), starts it, waits until its
services answer, runs a job, and shuts everything down on exit or Ctrl-C. A node that dies is
reported with its exit code and the last lines it printed.

    python dialfred_launch.py demo [--scene FloorPlan1] [--seed 0] [--steps 40] [--out out/demo]
    python dialfred_launch.py nodes              # start the graph (simulator + oracle) until Ctrl-C
    python dialfred_launch.py dialogue [--split valid_unseen] [--tasks 3]   # ask the oracle on a few tasks
    python dialfred_launch.py eval --split valid_unseen --agent expert|random [--questioner random|all|confusion]
                                   (or --tasks PATH: a split file of your own, e.g. a sealed test split)
                                   [--limit N] [--workers 2] [--out out/eval/<split>_<agent>.jsonl]
                                   [--seed 0] [--resolution 128]

`eval` runs `--workers` simulator nodes, each in its own namespace (/eval_<pid>/w0/sim/step, ...),
drives them all from this process with asynchronous calls, appends each episode's result to the
JSON-lines file as it ends (a rerun skips the tasks already there), and prints SR / PWSR / GC / NQ
overall and per task type; the summary also goes to <out without .jsonl>.summary.json. With
`--questioner`, an oracle node per worker answers the agent's questions.

`demo`, `dialogue` and `eval` run in a ROS domain of their own unless ROS_DOMAIN_ID is set; `nodes`
runs in the caller's domain so that other terminals can reach it.
"""

from __future__ import annotations

import argparse
import collections
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

REPO = Path(__file__).resolve().parent
SERVICE_SETTLE_S = 0.2   # see Graph.client
RESEND_AFTER_S = 5.0     # a reset or question unanswered this long is sent again (see Graph.call)
# Every process of the graph (this one and its children) uses the project's Fast DDS profile: a
# shared-memory segment large enough for whole observations (see config/fastdds_profiles.xml).
os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(REPO / 'config' / 'fastdds_profiles.xml'))
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')


def use_private_ros_domain() -> int:
    """Put this process (and the nodes it starts) in a ROS domain of its own, unless the caller chose
    one: benchmarks must not be answered, or slowed, by another graph on this machine."""
    if 'ROS_DOMAIN_ID' not in os.environ:
        os.environ['ROS_DOMAIN_ID'] = str(1 + os.getpid() % 101)   # 1-101: safe on Linux
    return int(os.environ['ROS_DOMAIN_ID'])


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


def _libc_prctl():
    try:
        import ctypes
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
                                     start_new_session=True, preexec_fn=_die_with_parent)
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
        from dialfred_sim.ros_util import SERVICE_QOS
        cli = self.client_node.create_client(srv_type, name, qos_profile=SERVICE_QOS)
        deadline = time.monotonic() + timeout
        while not cli.wait_for_service(timeout_sec=0.1):
            self.check()
            if time.monotonic() > deadline:
                raise TimeoutError(f'service {name} not available after {timeout:.0f} s')
        # "Available" means the server's request reader matched; its reply writer may not have
        # matched our reply reader yet, and a reply sent before that is lost (a known DDS service
        # discovery race, ros2/rmw_fastrtps#390). A moment of discovery traffic closes the gap.
        settle = time.monotonic() + SERVICE_SETTLE_S
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
        reply = graph.call(reset_cli, SimReset.Request(scene=args.scene, seed=args.seed), retry_after=RESEND_AFTER_S)
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
    from dialfred_msgs.srv import OracleAnswer, SimReset
    with Graph([sim_node(args.resolution), oracle_node()]) as graph:
        graph.client(SimReset, '/sim/reset')
        graph.client(OracleAnswer, '/oracle/answer')
        print('graph up: /sim/reset, /sim/step, /sim/ground_truth, /sim/observation, /oracle/answer. Ctrl-C to stop.')
        while True:
            graph.check()
            time.sleep(0.5)


def run_dialogue(args) -> int:
    """Scripted integration run: on a few tasks, ask the oracle each question type and print the
    dialogue; with `--gif`, also save it as captioned frames (what the agent saw when it asked)."""
    from dialfred_msgs.msg import Action
    from dialfred_msgs.srv import OracleAnswer, SimReset, SimStep

    from dialfred_sim.agents import scale_pixel
    from dialfred_sim.tasks import load_split
    tasks = load_split(args.split)[args.first:args.first + args.tasks]
    film = []   # (frame, caption lines) for --gif
    with Graph([sim_node(args.resolution), oracle_node(human=args.human)]) as graph:
        reset_cli = graph.client(SimReset, '/sim/reset')
        step_cli = graph.client(SimStep, '/sim/step')
        ask_cli = graph.client(OracleAnswer, '/oracle/answer')

        def ask(qtype: str, noun: str, frame, title: str) -> None:
            request = OracleAnswer.Request(question_type=qtype, object_noun=noun)
            reply = graph.call(ask_cli, request, timeout=3600.0 if args.human else 30.0,   # a person takes time
                              retry_after=None if args.human else RESEND_AFTER_S)
            said = reply.answer if reply.valid else f'(invalid: {reply.reason})'
            print(f'  agent  [{qtype:<10}] {noun or "-":<14} -> oracle: {said}')
            film.append((frame, [title, f'Q [{qtype}{": " + noun if noun else ""}]', f'A: {said}']))

        for task in tasks:
            reply = graph.call(reset_cli, SimReset.Request(task_id=task.task_id, with_depth=False,
                                                           with_segmentation=False), retry_after=RESEND_AFTER_S)
            if not reply.ok:
                print(f'{task.task_id}: reset failed: {reply.error}', file=sys.stderr)
                return 1
            t = reply.task     # the public view; this job, like the checker, knows the type from its split
            frame = image_array(reply.observation.rgb)
            title = f'{t.task_id} ({task.task_type}): "{t.instruction}"'
            print(f'\n{t.task_id} ({task.task_type}) in {t.scene}: "{t.instruction}"')
            film.append((frame, [title, 'start']))
            # Ask about what the instruction names (the goto landmark comes first in object_nouns).
            named = [n for n in t.object_nouns if n in t.instruction.lower()]
            noun = (named or list(t.object_nouns) or [''])[0]
            for qtype in ('location', 'appearance', 'direction'):
                ask(qtype, noun, frame, title)
            ask('location', 'unicorn', frame, title)          # not in the scene: the oracle says why
            ask('colour', noun, frame, title)                 # not a question type
            # Walk the expert's path but the last action, and ask for directions again.
            def expert_step(k: int):
                """The expert's action k (its pixel scaled from the task's frames to this node's)."""
                a = task.expert_actions[k]
                x, y = scale_pixel(a.x, a.y, task.resolution, args.resolution)
                step = graph.call(step_cli, SimStep.Request(action=Action(action=a.action, x=x, y=y),
                                                            with_depth=False, with_segmentation=False))
                target = f' at ({x}, {y})' if x >= 0 else ''
                film.append((image_array(step.observation.rgb), [title, f'expert action {k + 1}: {a.action}{target}']))
                return step

            n = len(task.expert_actions)
            for k in range(n - 1):
                if expert_step(k).terminated:
                    break
            print(f'  ... after {n - 1} of the expert\'s {n} actions:')
            ask('direction', '', film[-1][0], title)
            outcome = 'goal reached' if expert_step(n - 1).success else 'goal NOT reached'
            print(f'  ... the expert\'s last action, {task.expert_actions[-1].action}: {outcome}')
            film[-1][1].append(outcome)
    if args.gif:
        save_captioned_gif(film, Path(args.gif))
        print(f'saved {len(film)} captioned frames to {args.gif}')
    return 0


def save_captioned_gif(film, path: Path, width: int = 320, seconds_per_frame: float = 1.0) -> None:
    """A GIF of (RGB frame, caption lines) pairs: each frame scaled to `width` with its lines under it."""
    import textwrap

    from PIL import Image, ImageDraw, ImageFont
    font = ImageFont.load_default(size=12)
    line_h, chars = 15, width // 6
    wrapped = [[w for line in lines for w in textwrap.wrap(line, chars)] for _, lines in film]
    panel = line_h * max(len(w) for w in wrapped) + 8
    images, durations = [], []
    for (frame, lines_in), lines in zip(film, wrapped):
        # Answers stay up long enough to read; actions go by quickly.
        durations.append(int(1000 * seconds_per_frame * (2.0 if len(lines_in) > 2 else 0.6)))
        h = round(frame.shape[0] * width / frame.shape[1])
        img = Image.new('RGB', (width, h + panel), (255, 255, 255))
        img.paste(Image.fromarray(frame).resize((width, h), Image.BILINEAR), (0, 0))
        draw = ImageDraw.Draw(img)
        for k, line in enumerate(lines):
            draw.text((4, h + 4 + k * line_h), line, fill=(20, 20, 20), font=font)
        images.append(img.convert('P', palette=Image.ADAPTIVE, colors=128))
    path.parent.mkdir(parents=True, exist_ok=True)
    images[0].save(path, save_all=True, append_images=images[1:], duration=durations, loop=0, optimize=True)


def _interrupt(signum, frame):
    raise KeyboardInterrupt


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
    dialogue = sub.add_parser('dialogue',
                              help='ask the oracle each question type on a few tasks and print the dialogue')
    dialogue.add_argument('--split', default='valid_unseen')
    dialogue.add_argument('--first', type=int, default=0, help='index of the first task')
    dialogue.add_argument('--tasks', type=int, default=3)
    dialogue.add_argument('--human', action='store_true', help='the oracle asks you in this terminal')
    dialogue.add_argument('--resolution', type=int, default=128)
    dialogue.add_argument('--gif', help='also save the dialogue as a GIF of captioned frames to this path')
    from dialfred_eval import ResultsFileError, add_eval_parser, run_eval_command
    add_eval_parser(sub)
    args = parser.parse_args(argv)
    # Ctrl-C and SIGTERM both unwind through the Graph context, which stops every child.
    signal.signal(signal.SIGTERM, _interrupt)
    if args.command != 'nodes':
        # These jobs talk only to the nodes they start: a ROS domain of their own (unless the caller
        # set ROS_DOMAIN_ID) keeps two runs on one machine from answering each other. `nodes` stays
        # in the caller's domain, for other terminals to reach.
        use_private_ros_domain()
    try:
        jobs = {'demo': run_demo, 'nodes': run_nodes, 'dialogue': run_dialogue, 'eval': run_eval_command}
        return jobs[args.command](args)
    except KeyboardInterrupt:
        print('interrupted; nodes stopped', file=sys.stderr)
        return 130
    except (NodeDied, TimeoutError, FileNotFoundError, ResultsFileError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
