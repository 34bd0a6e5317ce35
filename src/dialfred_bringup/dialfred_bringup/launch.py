#!/usr/bin/env python3
"""DialFRED launcher: starts the node graph as separate processes and runs scripted jobs on it.

There is no `ros2 launch` here, so this script does its job: it resolves each node executable the
way `ros2 run <pkg> node` does (ament index prefix + lib/<pkg>/node), starts it, waits until its
services answer, runs a job, and shuts everything down on exit or Ctrl-C. A node that dies is
reported with its exit code and the last lines it printed.

    ./dialfred launch demo [--tasks N] [--questioner NAME] [--checkpoint PATH]
                                   # the learned performer plays a few tasks through the sim, oracle,
                                   # questioner and performer nodes (dialfred_bringup/demo.py); captioned GIFs
    ./dialfred launch explore [--scene NAME] [--seed S] [--steps N] [--out DIR]
                                 # a scripted explorer through the simulator node alone; saves its frames
    ./dialfred launch nodes              # start the graph (simulator + oracle) until Ctrl-C
    ./dialfred launch dialogue [--split NAME] [--tasks N]   # ask the oracle on a few tasks
    ./dialfred launch eval [--split NAME | --tasks PATH] [--agent NAME] [--questioner NAME] [--limit N]
                                   [--workers N] [--out PATH] [--seed S] [--resolution PIXELS] ...

Each job's options are the fields of its config dataclass (`ExploreConfig`, `NodesConfig`,
`DialogueConfig` here, `DemoConfig`, `EvalConfig`); `./dialfred launch JOB --help` lists them with
their defaults.

`eval` runs `--workers` simulator nodes, each in its own namespace (/eval_<pid>/w0/sim/step, ...),
drives them all from this process with asynchronous calls, appends each episode's result to the
JSON-lines file as it ends (a rerun skips the tasks already there), and prints SR / PWSR / GC / NQ
overall and per task type; the summary also goes to <out without .jsonl>.summary.json. With
`--questioner`, an oracle node per worker answers the agent's questions.

`demo`, `explore`, `dialogue` and `eval` run in a ROS domain of their own unless ROS_DOMAIN_ID is set; `nodes`
runs in the caller's domain so that other terminals can reach it.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from dialfred_performer.model_registry import camera_resolution
from dialfred_performer.shipped import SHIPPED_CHECKPOINT
from dialfred_sim.bag import EpisodeRecorder
from dialfred_sim.dataclass_cli import Parser, add_fields, arg, from_args
from dialfred_sim.env import DEFAULT_RESOLUTION
from dialfred_sim.protocol import Question, image_array, question_types, scale_pixel
from dialfred_sim.ros_util import RESEND_AFTER_S
from dialfred_sim.scripted import ExplorerPolicy
from dialfred_sim.tasks import load_split
from dialfred_sim.tasks.split_files import SPLIT_SIZES

from .demo import DemoConfig, run_demo
from .eval_config import record_field, record_format_field
from .evaluation import ResultsFileError, add_eval_parser, run_eval_command
from .film import save_captioned_gif
from .graph import Graph, NodeDied, oracle_node, sim_node, use_private_ros_domain


@dataclass
class ExploreConfig:
    """A scripted exploring episode through the simulator node; saves its frames."""

    scene: str = arg('FloorPlan1', 'the room')
    seed: int = arg(0, 'the reset\'s seed and the explorer\'s')
    steps: int = arg(40, 'actions at most')
    resolution: int = arg(DEFAULT_RESOLUTION, 'camera pixels')
    out: Path = arg(Path('out/explore'), 'where the frames, the GIF and the contact sheet go', metavar='DIR')


@dataclass
class NodesConfig:
    """Start the node graph (simulator + oracle) and keep it running until Ctrl-C."""

    resolution: Optional[int] = arg(None, 'camera pixels (none: what the shipped et performer was trained at, '
                                    '64; a performer node started against the graph plays at that size)',
                                    metavar='PIXELS')
    human: bool = arg(False, 'the oracle asks you in this terminal (the simulator\'s answer suggested)')


@dataclass
class DialogueConfig:
    """Ask the oracle each question type on a few tasks and print the dialogue."""

    split: str = arg('valid_unseen', 'a shipped split', choices=SPLIT_SIZES)
    first: int = arg(0, 'index of the first task')
    tasks: int = arg(3, 'how many tasks')
    human: bool = arg(False, 'the oracle asks you in this terminal')
    resolution: int = arg(DEFAULT_RESOLUTION, 'camera pixels')
    gif: Optional[Path] = arg(None, 'also save the dialogue as a GIF of captioned frames to this path', metavar='PATH')
    record: Optional[Path] = record_field()
    record_format: str = record_format_field()


def run_explore(args: ExploreConfig) -> int:
    """Start the simulator node, play a scripted exploring episode through ROS, save its frames."""
    from dialfred_msgs.msg import Action  # lazy: the ROS messages, which the rest of this module does without
    # lazy: the ROS messages, which the rest of this module does without
    from dialfred_msgs.srv import SimReset, SimStep

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
    from PIL import Image  # lazy: PIL, which the rest of this module does without
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


def nodes_resolution(resolution: Optional[int]) -> int:
    """The camera of `launch nodes`: as given, else the one the shipped et performer was trained at."""
    if resolution is not None:
        return resolution
    return camera_resolution('et', SHIPPED_CHECKPOINT)


def run_nodes(args: NodesConfig) -> int:
    """Start the graph and keep it up until Ctrl-C, reporting any node that dies."""
    # lazy: the ROS messages, which the rest of this module does without
    from dialfred_msgs.srv import OracleAnswer, SimReset
    args.resolution = nodes_resolution(args.resolution)
    if not 16 <= args.resolution <= 1024:
        print(f'error: --resolution must be 16 to 1024 pixels, got {args.resolution}', file=sys.stderr)
        return 2
    with Graph([sim_node(args.resolution), oracle_node(human=args.human)]) as graph:
        graph.client(SimReset, '/sim/reset')
        graph.client(OracleAnswer, '/oracle/answer')
        print(f'graph up at {args.resolution}x{args.resolution} px: /sim/reset, /sim/step, /sim/ground_truth, '
              '/sim/observation, /oracle/answer. Ctrl-C to stop.')
        while True:
            graph.check()
            time.sleep(0.5)


class DialogueRun:
    """The scripted dialogue run's calls on a graph of a simulator and an oracle node: the questions of a
    task at its start and before the expert's last action, the expert's actions, the film and the bag."""

    def __init__(self, args: DialogueConfig, graph: Graph):
        # lazy: the ROS messages, which the rest of this module does without
        from dialfred_msgs.srv import OracleAnswer, SimReset, SimStep
        self.args, self.graph = args, graph
        self.reset_cli = graph.client(SimReset, '/sim/reset')
        self.step_cli = graph.client(SimStep, '/sim/step')
        self.ask_cli = graph.client(OracleAnswer, '/oracle/answer')
        self.film = []         # (frame, caption lines) for --gif
        self.episode = {}      # the task's recorder and counts, with --record

    def ask(self, qtype: str, noun: str, frame, title: str) -> None:
        from dialfred_msgs.srv import OracleAnswer  # lazy: the ROS messages, which the rest of this module does without
        args, episode = self.args, self.episode
        request = OracleAnswer.Request(question_type=qtype, object_noun=noun)
        reply = self.graph.call(self.ask_cli, request, timeout=3600.0 if args.human else 30.0,   # a person takes time
                                retry_after=None if args.human else RESEND_AFTER_S)
        said = reply.answer if reply.valid else f'(invalid: {reply.reason})'
        print(f'  agent  [{qtype:<10}] {noun or "-":<14} -> oracle: {said}')
        episode['questions'] += 1
        episode['invalid'] += not reply.valid
        if episode.get('recorder'):
            episode['recorder'].question(episode['steps'], qtype, noun, Question(qtype, noun).text,
                                         reply.answer, reply.valid)
        self.film.append((frame, [title, f'Q [{qtype}{": " + noun if noun else ""}]', f'A: {said}']))

    def expert_step(self, task, k: int, title: str):
        """The expert's action k (its pixel scaled from the task's frames to this node's)."""
        from dialfred_msgs.msg import Action  # lazy: the ROS messages, which the rest of this module does without
        from dialfred_msgs.srv import SimStep  # lazy: the ROS messages, which the rest of this module does without
        episode = self.episode
        a = task.expert_actions[k]
        x, y = scale_pixel(a.x, a.y, task.resolution, self.args.resolution)
        step = self.graph.call(self.step_cli, SimStep.Request(action=Action(action=a.action, x=x, y=y),
                                                              with_depth=False, with_segmentation=False))
        target = f' at ({x}, {y})' if x >= 0 else ''
        episode['steps'] = int(step.observation.step_count)
        if episode['recorder']:
            episode['recorder'].action(episode['steps'], a.action, x, y, step.observation.last_action_success,
                                       episode['questions'])
            episode['recorder'].observation_msg(step.observation)
        self.film.append((image_array(step.observation.rgb), [title, f'expert action {k + 1}: {a.action}{target}']))
        return step

    def play(self, task) -> bool:
        """One task: the questions at its start, the expert's path, directions before its last action.
        False if the simulator refused the reset."""
        from dialfred_msgs.srv import SimReset  # lazy: the ROS messages, which the rest of this module does without

        args, episode = self.args, self.episode
        reply = self.graph.call(self.reset_cli, SimReset.Request(task_id=task.task_id, with_depth=False,
                                                                 with_segmentation=False), retry_after=RESEND_AFTER_S)
        if not reply.ok:
            print(f'{task.task_id}: reset failed: {reply.error}', file=sys.stderr)
            return False
        t = reply.task     # the public view; this job, like the checker, knows the type from its split
        episode.update(steps=0, questions=0, invalid=0, recorder=None)
        if args.record:
            episode['recorder'] = EpisodeRecorder(t.task_id, t.scene, t.split, t.instruction, t.object_nouns,
                                                  image_format=args.record_format)
            episode['recorder'].observation_msg(reply.observation)
        frame = image_array(reply.observation.rgb)
        title = f'{t.task_id} ({task.task_type}): "{t.instruction}"'
        print(f'\n{t.task_id} ({task.task_type}) in {t.scene}: "{t.instruction}"')
        self.film.append((frame, [title, 'start']))
        # Ask about what the instruction names (the goto landmark comes first in object_nouns).
        named = [n for n in t.object_nouns if n in t.instruction.lower()]
        noun = (named or list(t.object_nouns) or [''])[0]
        for qtype in question_types():
            self.ask(qtype, noun, frame, title)
        self.ask('location', 'unicorn', frame, title)          # not in the scene: the oracle says why
        self.ask('colour', noun, frame, title)                 # not a question type
        # Walk the expert's path but the last action, and ask for directions again.
        n = len(task.expert_actions)
        for k in range(n - 1):
            if self.expert_step(task, k, title).terminated:
                break
        print(f'  ... after {n - 1} of the expert\'s {n} actions:')
        self.ask('direction', '', self.film[-1][0], title)
        last = self.expert_step(task, n - 1, title)
        outcome = 'goal reached' if last.success else 'goal NOT reached'
        print(f'  ... the expert\'s last action, {task.expert_actions[-1].action}: {outcome}')
        self.film[-1][1].append(outcome)
        if episode['recorder']:
            episode['recorder'].result(
                success=bool(last.success), steps=episode['steps'], goal_conditions_met=int(last.goal_conditions_met),
                goal_conditions_total=int(last.goal_conditions_total),
                failed_actions=int(last.observation.failed_actions), questions=episode['questions'],
                invalid_questions=episode['invalid'], end_reason='success' if last.success else 'stop',
                last_action=task.expert_actions[-1].action)
            print(f'  bag: {episode["recorder"].save(Path(args.record))}')
        return True


def run_dialogue(args: DialogueConfig) -> int:
    """Scripted integration run: on a few tasks, ask the oracle each question type and print the
    dialogue; with `--gif`, also save it as captioned frames (what the agent saw when it asked)."""
    tasks = load_split(args.split)[args.first:args.first + args.tasks]
    with Graph([sim_node(args.resolution), oracle_node(human=args.human)]) as graph:
        run = DialogueRun(args, graph)
        for task in tasks:
            if not run.play(task):
                return 1
    if args.gif:
        save_captioned_gif(run.film, Path(args.gif))
        print(f'saved {len(run.film)} captioned frames to {args.gif}')
    return 0


def _interrupt(signum, frame):
    raise KeyboardInterrupt


JOBS = {'demo': (DemoConfig, run_demo), 'explore': (ExploreConfig, run_explore), 'nodes': (NodesConfig, run_nodes),
        'dialogue': (DialogueConfig, run_dialogue)}


def make_parser() -> argparse.ArgumentParser:
    """The launcher's command line: a subcommand per job, its options the fields of the job's config."""
    # `./dialfred demo` is `./dialfred launch demo`: the wrapper names itself, so the usage says what was typed.
    parser = Parser(prog=os.environ.get('DIALFRED_LAUNCH_PROG', './dialfred launch'), description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='command', required=True)
    for name, (config_class, _) in JOBS.items():
        summary = config_class.__doc__.split('\n\n')[0]
        job = sub.add_parser(name, help=' '.join(summary.split()), description=summary)
        add_fields(config_class, job)
        job.set_defaults(config_parser=job)
    add_eval_parser(sub)
    return parser


def main(argv=None) -> int:
    args = make_parser().parse_args(argv)
    # Ctrl-C and SIGTERM both unwind through the Graph context, which stops every child.
    signal.signal(signal.SIGTERM, _interrupt)
    if args.command != 'nodes':
        # These jobs talk only to the nodes they start: a ROS domain of their own (unless the caller
        # set ROS_DOMAIN_ID) keeps two runs on one machine from answering each other. `nodes` stays
        # in the caller's domain, for other terminals to reach.
        use_private_ros_domain()
    try:
        if args.command == 'eval':
            return run_eval_command(args)
        config_class, run = JOBS[args.command]
        return run(from_args(config_class, args, args.config_parser))
    except KeyboardInterrupt:
        print('interrupted; nodes stopped', file=sys.stderr)
        return 130
    except (FileNotFoundError, ResultsFileError) as exc:     # input that cannot be used: a usage error
        print(f'error: {exc}', file=sys.stderr)
        return 2
    except (NodeDied, TimeoutError) as exc:                   # a run that failed on its way
        print(f'error: {exc}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
