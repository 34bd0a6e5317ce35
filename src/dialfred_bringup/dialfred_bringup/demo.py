#!/usr/bin/env python3
"""`./dialfred demo`: the learned performer plays a few valid_unseen tasks through the whole node graph.

Four nodes run as separate processes (simulator, oracle, questioner, performer); this process is a
client of them only: it sends each task as a RunTask goal to `performer/run_task` (as the eval's
`--performer et` does), prints each question and answer as the performer's `dialogue/qa` topic
carries it, each action with its pixel as the goal's feedback reports it, and the outcome (success,
steps, goal conditions, end reason). The frames come from the simulator's `sim/observation` topic
(the observation after every reset and step). Each task is saved as a GIF of captioned frames (the
instruction, the latest QA, the action) under --out, beside one contact sheet of all of them.

    ./dialfred demo [--tasks N] [--questioner NAME] [--checkpoint PATH] ...   (--help: each option, its default)

Its options are the fields of `DemoConfig`.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from dialfred_performer.model_registry import PERFORMER_MODELS
from dialfred_performer.shipped import SHIPPED_CHECKPOINT
from dialfred_sim.agents import ExpertAgent
from dialfred_sim.dataclass_cli import arg
from dialfred_sim.env import DialfredEnv
from dialfred_sim.protocol import image_array
from dialfred_sim.tasks import load_split

from .baseline_runs import BASELINES
from .eval_config import EvalConfig, checkpoint_path, foxglove_field, record_field, record_format_field
from .eval_run import EvalRun
from .film import save_captioned_gif, save_contact_sheet
from .graph import Graph
from .paths import REPO
from .workers import LiveHook, PerformerWorker, play_episodes, start_live_view, worker_nodes

QA_SECONDS, ACTION_SECONDS = 2.0, 0.4     # how long a GIF frame stays up: an answer is read, an action seen


@dataclass
class EpisodeRecord:
    """What the client heard of one episode: frames by step, the QAs in order, each step's feedback."""

    task: object
    frames: dict = field(default_factory=dict)       # step count -> RGB array (0: after the reset)
    dialogue: list = field(default_factory=list)     # dialfred_msgs/QAPair, in the order published
    feedback: list = field(default_factory=list)     # RunTask.Feedback, one per action

    def complete(self, result) -> bool:
        return (len(self.feedback) >= result.steps and len(self.dialogue) >= result.questions
                and result.steps in self.frames)

    def frame(self, step: int):
        """The frame after `step` actions (the newest one before it, if that observation was missed)."""
        seen = [s for s in self.frames if s <= step] or list(self.frames)
        return self.frames[max(seen)]

    def film(self, outcome: str) -> tuple[list, list]:
        """(frame, caption lines) pairs and their durations in ms: the start; each answer over the
        frame it was asked at; each action over the frame after it, with the latest QA."""
        title = f'{self.task.task_id}: "{self.task.instruction}"'
        film, durations = [(self.frame(0), [title, 'start'])], [int(1000 * QA_SECONDS)]
        heard, latest = 0, 'no question asked yet'
        for fb in sorted(self.feedback, key=lambda f: f.step):
            while heard < min(fb.questions, len(self.dialogue)):
                qa = self.dialogue[heard]
                film.append((self.frame(fb.step - 1), [title, f'Q: {qa_question(qa)}', f'A: {qa_answer(qa)}']))
                durations.append(int(1000 * QA_SECONDS))
                latest, heard = f'last QA: {qa_question(qa)} {qa_answer(qa)}', heard + 1
            film.append((self.frame(fb.step), [title, latest, f'action {fb.step}: {action_text(fb)}']))
            durations.append(int(1000 * ACTION_SECONDS))
        film[-1][1].append(outcome)
        durations[-1] = int(1000 * QA_SECONDS)
        return film, durations


def qa_question(qa) -> str:
    return qa.question or f'[{qa.question_type}] {qa.object_noun}'


def qa_answer(qa) -> str:
    return qa.answer if qa.valid else '(no answer: the oracle could not answer that)'


def action_text(feedback) -> str:
    a = feedback.action
    pixel = f' at ({a.x}, {a.y})' if a.x >= 0 else ''
    return f'{a.action}{pixel}{"" if feedback.action_success else " (failed)"}'


def outcome_text(result) -> str:
    gc = f'{result.goal_conditions_met}/{result.goal_conditions_total}'
    why = f' ({result.error})' if result.error else ''
    return (f'{"SUCCESS" if result.success else "failure"}: {result.steps} steps, goal conditions {gc}, '
            f'{result.questions} questions, end reason {result.end_reason}{why}')


# The demo's tasks by default: one of each of three task families (going to an object and picking it up,
# putting one down, opening something), in that order, the first of each type in valid_unseen, then the
# second, ... A fixed rule that never looks at how the performer does.
DEMO_TYPES = ('Move & Pick', 'Move & Put', 'Move & Open')
RESULTS_DOC = REPO / 'docs' / 'results.md'


def demo_tasks(tasks: list, count: int, first: Optional[int] = None) -> list[tuple[int, object]]:
    """(index in the split, task) of the demo's `count` tasks: from index `first` on, or by DEMO_TYPES."""
    indexed = list(enumerate(tasks))
    if first is not None:
        return indexed[first:first + count]
    by_type = [[(k, t) for k, t in indexed if t.task_type == name] for name in DEMO_TYPES]
    chosen = [group[k] for k in range(max(map(len, by_type), default=0)) for group in by_type if k < len(group)]
    return chosen[:count]


def reference_line(config: EvalConfig, doc: Path = RESULTS_DOC) -> str:
    """Where the demo's few episodes stand: this performer's and questioner's valid_unseen SR in the results
    document of the shipped checkpoints (Table II), or where to measure it."""
    names = {b.questioner: b.name for b in BASELINES.values()}
    name, agent = names.get(config.questioner), config.performer or config.agent
    if agent == 'et' and checkpoint_path(config).resolve() == Path(SHIPPED_CHECKPOINT).resolve() \
            and name is not None and doc.exists():
        for line in doc.read_text().splitlines():
            cells = [c.strip() for c in line.strip('|').split('|')]
            if len(cells) > 4 and cells[1] == name and cells[2] == 'valid_unseen':
                return (f'on all {cells[3]} valid_unseen tasks this performer with {name} succeeds on {cells[4].split()[0]}% '
                        f'(docs/results.md)')
    return ('this performer\'s success rate on all of valid_unseen: ./dialfred launch eval --local --split valid_unseen '
            f'--agent {agent} --questioner {config.questioner or "none"}')


@dataclass
class DemoConfig:
    """The learned performer plays a few valid_unseen tasks through the sim, oracle, questioner and
    performer nodes; captioned GIFs."""

    tasks: int = arg(3, 'how many tasks')
    first: Optional[int] = arg(None, 'play valid_unseen\'s tasks from this index on (none: the first task of each of '
                               + ', '.join(repr(t) for t in DEMO_TYPES) + ', then the second of each, ...: chosen by '
                               'type, never by outcome)', metavar='INDEX')
    questioner: str = arg('all', 'all, random, confusion, none, a learned questioner (rl-anytime, rl-mc, ... or '
                          'learned:PATH: see eval --help), or package.module:ClassName', aliases={'none': ''},
                          metavar='NAME')
    performer: str = arg('et', "the performer node's model: et (the Episodic Transformer) or map (the map-and-plan "
                         "performer over the checkpoint's perception network; its belief map is published too)",
                         choices=list(PERFORMER_MODELS), metavar='MODEL')
    checkpoint: Optional[Path] = arg(None, 'the performer checkpoint (none: the one shipped in the package, as the '
                                     'eval\'s)', metavar='PATH')
    resolution: Optional[int] = arg(None, 'camera pixels (none: the resolution the checkpoint was trained at)',
                                    metavar='PIXELS')
    human: bool = arg(False, 'the oracle asks you in this terminal (the simulator\'s answer suggested); each '
                      'question is put to you once, and the robot waits as long as you need (see --human-timeout)')
    human_timeout: Optional[float] = arg(None, "with --human: seconds you may take to answer before the robot hears "
                                         "\"I don't know.\" and goes on (none: as long as you need)", metavar='S')
    max_steps: int = arg(100, 'the simulator ends an episode after this many actions (the benchmark\'s limit is 1000)')
    seed: int = arg(0, 'the run\'s seed')
    out: Path = arg(Path('out/demo'), 'where the GIFs and the contact sheet go', metavar='DIR')
    episode_timeout: float = arg(600.0, 'seconds one task may take before its goal is cancelled (not with --human: '
                                 'the robot waits for its person)')
    foxglove: Optional[int] = foxglove_field()
    record: Optional[Path] = record_field()
    record_format: str = record_format_field()

    def eval_config(self) -> EvalConfig:
        """The evaluation the demo's worker plays: one performer node, this questioner."""
        return EvalConfig(split='valid_unseen', performer=self.performer, questioner=self.questioner, checkpoint=self.checkpoint,
                          resolution=self.resolution, seed=self.seed, workers=1, human=self.human,
                          human_timeout=self.human_timeout, episode_timeout=self.episode_timeout,
                          foxglove=self.foxglove, record=self.record, record_format=self.record_format)


def checked_demo(demo: DemoConfig):
    """(the run, the chosen (index, task) pairs) of `demo`, or the exit status 2 after saying on stderr
    what is wrong (a missing or corrupt checkpoint, an unknown questioner, bad --tasks / --first)."""
    if not checkpoint_path(demo.eval_config()).is_file():
        print(f'error: no performer checkpoint at {checkpoint_path(demo.eval_config())}; train one with '
              './dialfred prepare-performer && ./dialfred train-performer --out out/performer (see the README), '
              'or pass --checkpoint PATH', file=sys.stderr)
        return 2
    try:
        run = EvalRun(demo.eval_config())    # a corrupt checkpoint or an unknown questioner fails before any node starts
    except ValueError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    if demo.tasks < 1 or (demo.first is not None and demo.first < 0):
        print('error: --tasks must be at least 1 and --first at least 0', file=sys.stderr)
        return 2
    chosen = demo_tasks(load_split(run.options.split), demo.tasks, demo.first)
    if not chosen:
        print(f'error: no tasks from index {demo.first} of {run.options.split}', file=sys.stderr)
        return 2
    return run, chosen


class DemoWatcher:
    """What the demo shows of the episode being played: the QAs (dialogue/qa) and the actions (the goal's
    feedback) as they come, and the frames (sim/observation) for its GIF."""

    def __init__(self, graph: Graph):
        # lazy: the ROS messages, which the rest of this module does without
        from dialfred_msgs.msg import Observation, QAPair
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        self.graph, self.record = graph, None
        node = graph.client_node
        self.qa_sub = node.create_subscription(QAPair, 'dialogue/qa', self.heard, 100)
        frames_qos = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=100)
        self.obs_sub = node.create_subscription(Observation, 'sim/observation', self.seen, frames_qos)

    def heard(self, qa) -> None:
        if self.record is not None:
            self.record.dialogue.append(qa)
            heard = f'\n     heard: {qa.heard}' if qa.heard else ''
            print(f'  Q: {qa_question(qa)}\n  A: {qa_answer(qa)}{heard}', flush=True)

    def seen(self, obs) -> None:
        if self.record is not None:
            self.record.frames[int(obs.step_count)] = image_array(obs.rgb)

    def stepped(self, task, feedback) -> None:
        if self.record is not None and task is self.record.task:
            self.record.feedback.append(feedback)
            print(f'  step {feedback.step:>3}  {action_text(feedback)}', flush=True)

    def wait_for_topics(self, timeout: float = 30.0) -> None:
        deadline = time.monotonic() + timeout
        while self.qa_sub.get_publisher_count() == 0 or self.obs_sub.get_publisher_count() == 0:
            self.graph.spin_until_any([], 0.1)
            if time.monotonic() > deadline:
                raise TimeoutError('the performer\'s dialogue/qa or the simulator\'s sim/observation topic did '
                                   f'not appear in {timeout:g} s')
        self.graph.spin_until_any([], 0.3)     # the publishers see this subscriber a moment later


def play_demo_task(graph: Graph, worker, watcher: DemoWatcher, index: int, task, out: Path, sheet: list) -> bool:
    """Play one task as a RunTask goal, printing its dialogue, actions and outcome; save its GIF (and add its
    frames to `sheet`). Whether it succeeded."""
    print(f'\n{task.task_id} ({task.task_type}) in {task.scene}: "{task.instruction}"', flush=True)
    record = watcher.record = EpisodeRecord(task)
    results = []
    play_episodes(graph, [worker], [(index, task)], results.append)
    result = results[0]
    deadline = time.monotonic() + 2.0    # the last frame and feedback may come after the result
    while not record.complete(result) and time.monotonic() < deadline:
        graph.spin_until_any([], 0.1)
    outcome = outcome_text(result)
    print(f'  -> {outcome}')
    if record.frames:
        film, durations = record.film(outcome)
        gif = out / f'{task.task_id.replace("/", "_")}.gif'
        save_captioned_gif(film, gif, durations_ms=durations)
        print(f'  saved {gif} ({len(film)} frames)')
        sheet.append((f'{task.task_id} {outcome}', [record.frames[s] for s in sorted(record.frames)]))
    else:
        print('  (no frames were received from sim/observation)', file=sys.stderr)
    watcher.record = None
    return bool(result.success)


def play_expert_reference(task, resolution: int, max_steps: int, out: Path, sheet: list) -> bool:
    """The expert's path on `task`, played in this process (no ROS) as a reference of what success looks like:
    its GIF (`<task>_expert_reference.gif`) and a row of the contact sheet, labelled as the expert's. The demo
    shows it whatever the performer did (the task is the demo's first, by the same fixed rule). Whether the
    expert reached the goal."""
    agent = ExpertAgent(resolution)
    env = DialfredEnv(resolution=resolution, max_steps=max(max_steps, len(task.expert_actions) + 1))
    try:
        obs, _ = env.reset(options={'task': task})
        agent.reset(task)
        title = f'{task.task_id}: "{task.instruction}"'
        label = "the expert's path (a reference, not the performer)"
        film, durations, frames = [(obs['rgb'], [title, label, 'start'])], [int(1000 * QA_SECONDS)], [obs['rgb']]
        success = False
        for k in range(len(task.expert_actions) + 1):
            name, x, y = agent.act(obs)
            obs, reward, terminated, truncated, _ = env.step({'action': name, 'pixel': (x, y)})
            success = reward > 0
            target = f' at ({x}, {y})' if x >= 0 else ''
            film.append((obs['rgb'], [title, label, f'expert action {k + 1}: {name}{target}']))
            durations.append(int(1000 * ACTION_SECONDS))
            frames.append(obs['rgb'])
            if terminated or truncated:
                break
    finally:
        env.close()
    outcome = 'goal reached' if success else 'goal NOT reached'
    film[-1][1].append(outcome)
    durations[-1] = int(1000 * QA_SECONDS)
    gif = out / f'{task.task_id.replace("/", "_")}_expert_reference.gif'
    save_captioned_gif(film, gif, durations_ms=durations)
    sheet.append((f"{task.task_id} the expert's path (reference): {outcome}", frames))
    print(f"\nFor reference, the expert's path on {task.task_id} (privileged: it replays the task's recorded plan; "
          f'not the performer): {len(frames) - 1} actions, {outcome}\n  saved {gif} ({len(film)} frames)')
    return success


def run_demo(demo: DemoConfig) -> int:
    """Start sim, oracle, questioner and performer nodes; play --tasks tasks as RunTask goals; print
    the dialogue, the actions and the outcomes; save a captioned GIF per task and a contact sheet."""
    checked = checked_demo(demo)
    if checked == 2:
        return 2
    run, chosen = checked
    config = run.options
    out = Path(demo.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f'checkpoint {run.checkpoint_path}, questioner {config.questioner or "none"}, {config.resolution} px, '
          f'seed {config.seed}')
    t0 = time.monotonic()
    nodes = worker_nodes(run, '', publish_observations=True, max_steps=demo.max_steps)
    with Graph(nodes) as graph:
        watcher = DemoWatcher(graph)
        worker = PerformerWorker(graph, '', run, on_feedback=watcher.stepped)
        if config.foxglove is not None:
            view = start_live_view(run, graph, [''], len(chosen))
            worker.live = LiveHook(view, 'w0')
        watcher.wait_for_topics()
        print(f'graph ready in {time.monotonic() - t0:.1f} s (sim, oracle, questioner, performer nodes)')
        sheet, successes = [], 0
        for index, task in chosen:
            successes += play_demo_task(graph, worker, watcher, index, task, out, sheet)
        if config.foxglove is not None:
            view.close()
    expert = play_expert_reference(chosen[0][1], config.resolution, demo.max_steps, out, sheet)
    if sheet:
        save_contact_sheet(sheet, out / 'contact_sheet.png')
        print(f'\ncontact sheet: {out / "contact_sheet.png"}')
    print(f'\n{successes} of {len(chosen)} succeeded; {reference_line(config)}. The expert\'s reference path on '
          f'{chosen[0][1].task_id}: {"goal reached" if expert else "goal NOT reached"}.')
    return 0
