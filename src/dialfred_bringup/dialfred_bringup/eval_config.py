"""`EvalConfig`: the options of an evaluation (`./dialfred launch eval`), and nothing else.

Its fields are the command line's options (dialfred_sim.dataclass_cli makes the parser and the docs'
table from them). What follows from them (the agent, the names of the results, the checks) is
`eval_run.EvalRun`, made from a config; `evaluation.run_eval` plays one.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from dialfred_performer.model_registry import PERFORMER_MODELS, SHIPPED_CHECKPOINT, camera_resolution
from dialfred_questioner.shipped import shipped_list
from dialfred_sim.bag import IMAGE_FORMATS
from dialfred_sim.dataclass_cli import arg
from dialfred_sim.env import DEFAULT_RESOLUTION    # camera pixels for every agent but the performer models (their own)
from dialfred_sim.protocol import DEFAULT_PROTOCOL, MAX_QUESTIONS, PROTOCOLS, question_types
from dialfred_sim.tasks.goals import DEFAULT_GOAL_RULE, GOAL_RULES
from dialfred_sim.tasks.split_files import SPLIT_SIZES

from .live import FOXGLOVE_PORT
from .shards import parse_shard, show_shard


def record_field():
    """--record DIR, for every job that plays episodes (eval, demo, dialogue)."""
    return arg(None, 'write each episode as a ROS 2 bag (rosbag2, MCAP storage) into DIR/<split>_<number>/: task, '
               'camera, poses, QAs, actions and their results, the outcome (a chained episode: one bag, '
               'DIR/<split>_<first number>_chained/, its tasks in order); `./dialfred replay DIR/<bag>` prints '
               'and renders one', metavar='DIR')


def record_format_field():
    return arg('raw', 'camera frames in the bags: raw sensor_msgs/Image or CompressedImage (png, jpeg)',
               choices=IMAGE_FORMATS)


def foxglove_field():
    return arg(None, 'watch the workers live in the Foxglove app: a Foxglove WebSocket server on PORT (the flag '
               f'alone: {FOXGLOVE_PORT}) streams each camera, a top-down map with the agent, the dialogue and the '
               'progress', const=FOXGLOVE_PORT, metavar='PORT')


@dataclass
class EvalConfig:
    """One evaluation run: an agent over (the first `limit` tasks of) a split.

    Its fields are the options of `./dialfred launch eval` (dialfred_sim.dataclass_cli)."""

    split: str = arg('valid_unseen', 'a shipped split', choices=SPLIT_SIZES, group='tasks')
    tasks_file: Optional[Path] = arg(
        None, 'a split file of your own instead of --split, e.g. a sealed test split made with '
        '`python -m dialfred_sim.tasks.splits test_unseen --seed S --size N --out PATH`; results record its '
        'path and sha256 and are never mixed with another file\'s', flag='--tasks', metavar='PATH', group='tasks')
    agent: str = arg('expert', 'expert, random, et (the performer of --checkpoint, in this process), map (the '
                     'map-and-plan performer over the perception network of --checkpoint, in this process), or your own '
                     'class as package.module:ClassName (on the Python path; made as ClassName(resolution=R), with '
                     'reset(task, seed) and act(observation))')
    performer: str = arg('', f'a performer model ({" or ".join(PERFORMER_MODELS)}, dialfred_performer.model_registry): a '
                         'performer node per worker (its `model` parameter) plays each task as a RunTask goal (with '
                         'sim, oracle and questioner nodes in its namespace); this process only sends goals and '
                         'records results. none: the agent is a Python object of this process (--agent with the '
                         'model\'s name plays the same performer there)', choices=list(PERFORMER_MODELS),
                         aliases={'none': ''})
    checkpoint: Optional[Path] = arg(None, 'the et performer\'s checkpoint (none: the one shipped in the package, '
                                     'dialfred_performer/checkpoints/et.pt)', metavar='PATH')
    questioner: str = arg(
        '', 'ask the oracle (one oracle node per worker): none = no questions; '
        'random = the paper\'s Random QA: at the start, a type drawn with 25% each for '
        'location, appearance, direction and no question, then every question of that type '
        '(one per instruction object, or one direction question); '
        'all = location + appearance of every instruction object, then direction; '
        'confusion = a random question whenever the agent is unsure (needs action_probabilities); '
        'every:TYPES or every-N:TYPES = every question of those types (joined by +, or all) before every '
        '(N-th) action, e.g. every:direction; '
        'a learned questioner (greedy, asking at the chances of the timing it was trained with): '
        f'{shipped_list()} (the checkpoints shipped in '
        'dialfred_questioner/checkpoints), or learned:PATH (any '
        'questioner checkpoint; results are named learned-<file stem>-<sha256[:8]>); '
        'or package.module:ClassName (reset(task, seed), ask(observation, step), hear(qa))',
        aliases={'none': ''}, metavar='NAME')
    perturb_type: str = arg('', 'the paper\'s ablation: the oracle withholds answers of this type ("I don\'t know.")',
                            choices=question_types, aliases={'none': ''})
    perturb_probability: float = arg(0.5, 'how often it withholds them (0.5 in the paper)')
    answers: str = arg('oracle', "who words the answers: oracle (its own templates); swapped (a control: each answer "
                       "replaced by the oracle's answer to the same question in another task of the split, "
                       "dialfred_oracle/swap.py; results ..._swapped); human (a person in this terminal, as --human); "
                       "FILE (JSON lines {task, type, noun, answer}: a person's words, for runs that repeat); or "
                       "package.module:ClassName (say(asked, content) -> words; e.g. "
                       "dialfred_oracle.wording:HeldOutWording, words no performer was trained on); results record "
                       "the answerer and are named ..._answers-<label> (dialfred_oracle/answerers.py)",
                       metavar='WHO')
    human: bool = arg(False, 'the oracle asks you in this terminal (its answer suggested; an empty line takes it): '
                      'through the graph, one worker; each question is put to you once, and the robot waits as long '
                      'as you need (see --human-timeout)')
    human_timeout: Optional[float] = arg(None, "with --human: seconds you may take to answer before the robot hears "
                                         "\"I don't know.\" and goes on (none: as long as you need)", metavar='S')
    max_questions: int = arg(MAX_QUESTIONS, 'questions in a row without acting before an episode ends with an '
                             'error (the performer node\'s max_questions)', metavar='N')
    goal_rule: str = arg(DEFAULT_GOAL_RULE, "how a task's go-to is judged: dialfred = within 4 actions of the "
                         "expert's end pose (DialFRED's rule); visible = the target in view and within reach "
                         '(results are named ..._goal-visible)', choices=GOAL_RULES)
    protocol: str = arg(DEFAULT_PROTOCOL, "how the tasks are played: expert = each from the expert's state at its first "
                        'action (the paper\'s tables); chained = each episode\'s tasks in order, every task from the '
                        'state the agent\'s own actions left, ended only by the agent\'s Stop or its limits and judged '
                        "then (DialFRED's challenge test; a task whose goal held at its start scores as not done; "
                        'results are named ..._chained; dialfred_sim/chained.py)', choices=PROTOCOLS)
    limit: Optional[int] = arg(None, 'only the first N tasks of the split (none: all)', metavar='N')
    shard: Optional[tuple] = arg(None, 'only shard K of N (0 <= K < N) of the selected tasks (after --limit): those '
                                 'whose index in the split is K modulo N, seeded as in a whole run; results go to '
                                 '<default name>_shardKofN.jsonl. Join the shards\' files with `./dialfred merge` '
                                 '(docs/scaling.md)', parse=parse_shard, show=show_shard, metavar='K/N')
    workers: int = arg(2, 'simulator nodes (or, with --local, processes) playing episodes in parallel')
    local: bool = arg(False, 'no ROS: each worker is a process with its own simulator, the oracle\'s rules and the '
                      'agent (the same episodes as through the graph, faster; --performer M plays the agent M so; '
                      'not with --record, --foxglove; dialfred_bringup/local.py)')
    out: Optional[Path] = arg(None, 'the results file (none: out/eval/<split>_<agent>[+<questioner>].jsonl)',
                              metavar='PATH')
    seed: int = arg(0, 'the run\'s seed: episode k of the split is seeded with (seed, k)')
    resolution: Optional[int] = arg(None, 'camera pixels (none: for the et performer, the resolution its checkpoint '
                                    'was trained at, 64 for the shipped one; for the map performer and other '
                                    'agents 128)', metavar='PIXELS')
    request_timeout: float = arg(120.0, 'seconds one reset or step may take before the run gives up')
    episode_timeout: float = arg(1800.0, 'seconds one RunTask goal (--performer et) may take before it is cancelled')
    max_restarts: int = arg(3, 'a worker whose node dies or stops answering has its nodes restarted and its '
                            'episode replayed from the start, at most this many times in a row (0: a dead node '
                            'ends the run)')
    record: Optional[Path] = record_field()
    record_format: str = record_format_field()
    foxglove: Optional[int] = foxglove_field()

    def __post_init__(self):
        if self.resolution is None:
            self.resolution = default_resolution(self)


def checkpoint_path(config: EvalConfig) -> Path:
    """The performer checkpoint of `config`: --checkpoint, or the one shipped in the package."""
    return Path(config.checkpoint) if config.checkpoint else SHIPPED_CHECKPOINT


def default_resolution(config: EvalConfig) -> int:
    """The camera of the performer model played (dialfred_performer.model_registry.camera_resolution: the et
    performer's training resolution, 128 for the map performer); 128 for other agents. An unreadable
    checkpoint: 128, and EvalRun says why."""
    model = config.agent if config.agent in PERFORMER_MODELS else config.performer
    if model not in PERFORMER_MODELS:
        return DEFAULT_RESOLUTION
    try:
        return camera_resolution(model, checkpoint_path(config))
    except (FileNotFoundError, ValueError):
        return DEFAULT_RESOLUTION


# Options added after runs were stamped with their configs, at the value that plays as before: left out of
# `config_inputs`, so that a run stamped before them is not stale.
LATER_DEFAULTS = {'protocol': DEFAULT_PROTOCOL, 'human_timeout': None}


def config_inputs(config: EvalConfig) -> dict:
    """The options of `config` as a stage's inputs (reproduce/stages.py): every field, but those of
    LATER_DEFAULTS at their default."""
    return {k: v for k, v in dataclasses.asdict(config).items() if not (k in LATER_DEFAULTS and v == LATER_DEFAULTS[k])}
