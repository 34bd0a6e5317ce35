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
index, as in a whole run) into <default name>_shardKofN.jsonl (or --out as given); `./dialfred merge` joins the shards' files
(dialfred_bringup/shards.py, docs/scaling.md).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import functools
import json
import os
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from dialfred_oracle.swap import SWAP_MODES
from dialfred_performer.models import PERFORMER_MODELS, camera_resolution, load_policy
from dialfred_sim.bag import IMAGE_FORMATS
from dialfred_sim.dataclass_cli import add_fields, arg, from_args
from dialfred_sim.env import DEFAULT_RESOLUTION    # camera pixels for every agent but the performer models (their own)
from dialfred_sim.metrics import ResultsFileError, played_at
from dialfred_sim.protocol import MAX_QUESTIONS, QUESTION_TYPES, DialogueAgent
from dialfred_sim.tasks.goals import DEFAULT_GOAL_RULE, GOAL_RULES, under_rule
from dialfred_sim.tasks.split_files import SPLIT_SIZES

from .graph import Graph
from .live import FOXGLOVE_PORT
from .paths import REPO
from .shards import check_shard, parse_shard, shard_suffix, shard_tasks, show_shard
from .workers import (LiveHook, PerformerWorker, SimWorker, Supervisor, play_episodes, start_live_view,
                      worker_nodes)




def record_field():
    """--record DIR, for every job that plays episodes (eval, demo, dialogue)."""
    return arg(None, 'write each episode as a ROS 2 bag (rosbag2, MCAP storage) into DIR/<split>_<number>/: task, '
               'camera, poses, QAs, actions and their results, the outcome; `./dialfred replay DIR/<bag>` prints '
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
    performer: str = arg('', f'a performer model ({" or ".join(PERFORMER_MODELS)}, dialfred_performer.models): a '
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
        'a learned questioner (greedy, asking at the chances of the timing it was trained with): '
        'pretrained, rl-begin, rl-anytime (every 5 steps), rl-anytime-1, rl-anytime-10, '
        'rl-mc (when the performer is unsure), rl-anytime-withhold-location|appearance|direction, '
        'rl-anytime-no-dialogue (the checkpoints shipped in dialfred_questioner/checkpoints), or learned:PATH (any '
        'questioner checkpoint; results are named learned-<file stem>-<sha256[:8]>); '
        'or package.module:ClassName (reset(task, seed), ask(observation, step), hear(qa))',
        aliases={'none': ''}, metavar='NAME')
    perturb_type: str = arg('', 'the paper\'s ablation: the oracle withholds answers of this type ("I don\'t know.")',
                            choices=QUESTION_TYPES, aliases={'none': ''})
    perturb_probability: float = arg(0.5, 'how often it withholds them (0.5 in the paper)')
    answers: str = arg('oracle', "oracle: the oracle's own answers; swapped: a control, each answer replaced by the "
                       "oracle's answer to the same question in another task of the split (a performer that "
                       "reads its answers does worse; dialfred_oracle/swap.py; results are named ..._swapped)",
                       choices=SWAP_MODES)
    human: bool = arg(False, 'the oracle asks you in this terminal (its answer suggested; an empty line takes it): '
                      'through the graph, one worker; each request may then wait an hour')
    max_questions: int = arg(MAX_QUESTIONS, 'questions in a row without acting before an episode ends with an '
                             'error (the performer node\'s max_questions)', metavar='N')
    goal_rule: str = arg(DEFAULT_GOAL_RULE, "how a task's go-to is judged: dialfred = within 4 actions of the "
                         "expert's end pose (DialFRED's rule); visible = the target in view and within reach "
                         '(results are named ..._goal-visible)', choices=GOAL_RULES)
    limit: Optional[int] = arg(None, 'only the first N tasks of the split (none: all)', metavar='N')
    shard: Optional[tuple] = arg(None, 'only shard K of N (0 <= K < N) of the selected tasks (after --limit): those '
                                 'whose index in the split is K modulo N, seeded as in a whole run; results go to '
                                 '<default name>_shardKofN.jsonl. Join the shards\' files with `./dialfred merge` '
                                 '(docs/scaling.md)', parse=parse_shard, show=show_shard, metavar='K/N')
    workers: int = arg(2, 'simulator nodes (or, with --local, processes) playing episodes in parallel')
    local: bool = arg(False, 'no ROS: each worker is a process with its own simulator, the oracle\'s rules and the '
                      'agent (the same episodes as through the graph, faster; not with --performer, --record, '
                      '--foxglove; dialfred_bringup/local.py)')
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
        agent = f'{self.agent}-{self.checkpoint_sha256[:8]}' if self.agent in PERFORMER_MODELS else self.agent
        return f'{agent}+{self.questioner_label}' if self.questioner else agent

    @property
    def oracle(self) -> str:
        """How the oracle answers, as results record it: '' exactly, 'location:0.5' perturbed."""
        if self.answers == 'swapped':
            return 'swapped'
        if self.human:
            return 'human'
        return f'{self.perturb_type}:{self.perturb_probability:g}' if self.perturb_type else ''

    @property
    def identity(self) -> dict:
        """What every results line of this run carries (metrics.episode_result's keywords)."""
        return {'agent': self.agent_name, 'oracle': self.oracle, 'seed': self.seed, 'goal_rule': self.goal_rule}

    def split_tasks(self) -> list:
        """Every task of the split played (or of the tasks file), in order, before --limit and --shard."""
        from dialfred_sim.tasks import load_split
        return self.tasks_source.tasks if self.tasks_file else load_split(self.split)

    @property
    def results_path(self) -> Path:
        if self.out:
            return Path(self.out)
        perturbed = f'_withhold-{self.perturb_type}-{self.perturb_probability:g}' if self.perturb_type else ''
        perturbed += '_swapped' if self.answers == 'swapped' else ''
        perturbed += f'_goal-{self.goal_rule}' if self.goal_rule != DEFAULT_GOAL_RULE else ''
        source = self.tasks_source
        tasks = f'{source.split}-{source.sha256[:8]}' if source else self.split   # a file: named by its content
        return REPO / 'out' / 'eval' / f'{tasks}_{self.agent_name}{perturbed}{shard_suffix(self.shard)}.jsonl'

    @property
    def tasks_record_path(self) -> Path:
        """Where a run on a tasks file records which file (path, sha256) its results came from."""
        return self.results_path.with_suffix('.tasks.json')

    def make_performer(self):
        """The acting agent alone: the `et` performer from its checkpoint, or a dialfred_sim.agents one."""
        if self.agent in PERFORMER_MODELS:
            try:
                return load_policy(self.agent, self.checkpoint_path)
            except FileNotFoundError as exc:
                raise ValueError(str(exc)) from None
        from dialfred_sim.agents import make_agent
        return make_agent(self.agent, self.resolution)

    @functools.cached_property
    def asks(self) -> bool:
        """Whether the run asks the oracle: with a questioner, or with an agent that asks by itself (a
        protocol.DialogueAgent, `ask(observation)` and `hear(qa)`: a class of yours)."""
        if self.questioner:
            return True
        if self.performer or self.agent in PERFORMER_MODELS:
            return False
        return isinstance(self.make_performer(), DialogueAgent)

    def make_agent(self):
        """A new agent as configured (ValueError for an unknown agent or questioner)."""
        from dialfred_questioner.baselines import with_questioner
        from dialfred_questioner.questioners import make_questioner
        return with_questioner(self.make_performer(), make_questioner(self.questioner) if self.questioner else None)

    def check(self) -> None:
        """ValueError for settings that cannot run together or out of range, a results file that cannot
        be written, or an agent or questioner that cannot be made: before anything starts."""
        check_shard(self.shard)
        if self.limit is not None and self.limit < 1:
            raise ValueError(f'--limit must be at least 1 (leave it out for every task), got {self.limit}')
        if self.workers < 1:
            raise ValueError(f'--workers must be at least 1, got {self.workers}')
        if not 1 <= self.max_questions <= 1000:
            raise ValueError(f'--max-questions must be 1 to 1000, got {self.max_questions}')
        if not 16 <= self.resolution <= 1024:
            raise ValueError(f'--resolution must be 16 to 1024 pixels, got {self.resolution}')
        if not self.request_timeout > 0 or not self.episode_timeout > 0:
            raise ValueError('--request-timeout and --episode-timeout must be more than 0 seconds')
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
            if self.performer not in PERFORMER_MODELS:
                raise ValueError(f'--performer must be one of {", ".join(PERFORMER_MODELS)} (the performer node\'s model), '
                                 f'got {self.performer!r}')
            self.agent = self.performer
        self.make_agent()     # the node path too: a bad checkpoint or questioner fails before any node starts
        if self.tasks_file:
            try:
                self.split = self.tasks_source.split      # the split played is the file's
            except FileNotFoundError as exc:
                raise ValueError(str(exc)) from None
        check_results_path(self.results_path)
        if self.answers not in SWAP_MODES:
            raise ValueError(f'--answers must be one of {", ".join(SWAP_MODES)}, got {self.answers!r}')
        if self.human:
            if self.local or self.workers != 1 or not self.asks or self.perturb_type or self.answers != 'oracle':
                raise ValueError('--human answers through the graph (not --local), with one worker (--workers 1), a '
                                 'questioner (or an agent that asks), and no --perturb-type or --answers swapped')
            self.request_timeout = max(self.request_timeout, 3600.0)      # a person takes time
        if self.answers == 'swapped' and (not self.asks or self.perturb_type):
            raise ValueError('--answers swapped needs a questioner (--questioner, or an agent that asks) and no '
                             '--perturb-type')
        if self.perturb_type:
            if not self.asks:
                raise ValueError('a perturbed oracle needs a questioner (--questioner, or an agent that asks)')
            if self.perturb_type not in QUESTION_TYPES:
                raise ValueError(f'--perturb-type must be one of {", ".join(QUESTION_TYPES)}, '
                                 f'got {self.perturb_type!r}')
            if not 0.0 <= self.perturb_probability <= 1.0:
                raise ValueError(f'--perturb-probability must be in [0, 1], got {self.perturb_probability}')

    @property
    def summary_path(self) -> Path:
        return self.results_path.with_suffix('.summary.json')


def check_results_path(path: Path) -> None:
    """ValueError unless `path` can be a results file: not a folder, in a folder that exists (or can be
    made: every missing folder's first existing one is a folder) and takes new files."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f'--out {path} is a folder: give a file in it, such as {path / "run.jsonl"}')
    existing = path.parent
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise ValueError(f'--out {path}: {existing} is a file, not a folder')
    try:      # a read-only or virtual file system (/proc) says no only when a file is made
        fd, probe = tempfile.mkstemp(dir=existing, prefix='.dialfred-write-check-')
    except OSError as exc:
        raise ValueError(f'--out {path}: no file can be made in {existing} ({exc.strerror})') from None
    os.close(fd)
    os.unlink(probe)


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
    code: str = ''          # the commit the run started at ('+dirty': an edited checkout)

    def to_json(self) -> dict:
        from dialfred_sim.metrics import failures
        c = self.config
        loop_s = self.wall_s - self.startup_s
        return {
            'split': c.split, 'tasks_file': c.tasks_source.describe() if c.tasks_source else None,
            'agent': c.agent_name, 'privileged': any(r.privileged for r in self.results),
            'oracle': c.oracle, 'seed': c.seed, 'resolution': c.resolution, 'goal_rule': c.goal_rule,
            'workers': c.workers,
            'through': 'performer node' if c.performer else ('local processes (no ROS)' if c.local else 'in-process agent'),
            'checkpoint': ({'path': str(c.checkpoint_path), 'sha256': c.checkpoint_sha256} if c.agent in PERFORMER_MODELS
                           else None),
            'limit': c.limit, 'shard': {'index': c.shard[0], 'count': c.shard[1]} if c.shard else None,
            'results_file': str(c.results_path), 'tasks': len(self.results),
            'played_at': played_at(self.results),
            'this_run': {'episodes': self.ran, 'startup_s': round(self.startup_s, 3), 'wall_s': round(self.wall_s, 3),
                         'episodes_per_s': round(self.ran / loop_s, 3) if self.ran and loop_s > 0 else None,
                         'restarts': self.restarts,
                         'code': self.code},
            'summary': self.summary,
            'failures': [{'task_id': r.task_id, 'task_type': r.task_type, 'end_reason': r.end_reason,
                          'error': r.error} for r in failures(self.results)],
        }


def run_namespace() -> str:
    """The namespace of this run's nodes (/eval_<pid>): no other run, even in the same ROS domain,
    can reach them or be reached by this one. Where discovery reaches other hosts (a shard per host,
    docs/scaling.md), the host's name goes in too (/eval_<host>_<pid>): a pid is unique on one host only."""
    from dialfred_bringup.graph import discovery_spans_hosts, host_token
    return f'/eval_{host_token()}_{os.getpid()}' if discovery_spans_hosts() else f'/eval_{os.getpid()}'


def short_commit(code: str) -> str:
    """A commit as people read it: 12 hex digits, and '+dirty' if it has it."""
    return code if code in ('unrecorded', 'unknown') else code[:12] + ('+dirty' if code.endswith('+dirty') else '')


def warn_of_other_code(path, results, code: str) -> None:
    """Say on stderr when a resumed results file holds episodes played at another commit than `code`."""
    others = played_at([r for r in results if r.code != code])
    if others:
        print(f'warning: {path} holds {sum(others.values())} episodes played at other commits '
              f'({", ".join(f"{short_commit(c)}: {n}" for c, n in others.items())}); this run is at {short_commit(code)}; '
              'they are kept (choose another --out to play every episode at this commit)', file=sys.stderr)


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
        if r.goal_rule != config.goal_rule:
            held = repr(r.goal_rule) if r.goal_rule else "'visible' (written before results recorded the rule)"
            raise ResultsFileError(f'{path} holds results judged by the goal rule {held}, not {config.goal_rule!r}: '
                                   'choose another --out')
    check_tasks_record(config, bool(existing))
    check_run_record(config, bool(existing))
    return results_by_task(existing, task_ids)


def run_record(config: EvalConfig) -> dict:
    """What a results file's episodes were played with beyond what each result line records."""
    return {'resolution': int(config.resolution), 'max_questions': int(config.max_questions)}


def check_run_record(config: EvalConfig, has_results: bool) -> None:
    """Results are kept with a record of the camera and the question limit they were played with
    (<results>.run.json): ResultsFileError, naming the difference, if a run would add episodes played
    otherwise. Writes the record for a new results file (and for one made before records were kept)."""
    from dialfred_sim.metrics import write_text_atomically
    path, want = config.results_path.with_suffix('.run.json'), run_record(config)
    held = None
    if has_results and path.exists():
        try:
            held = json.loads(path.read_text())
        except ValueError:
            held = None
        if not isinstance(held, dict):
            raise ResultsFileError(f'{path} is not a record of a run: choose another --out')
        differ = [f'{k} {held.get(k)!r}, not {v!r}' for k, v in want.items() if held.get(k) != v]
        if differ:
            raise ResultsFileError(f'{config.results_path} holds episodes played with {"; ".join(differ)}: '
                                   'choose another --out (or the same settings)')
    if held != want:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomically(path, json.dumps(want, indent=1) + '\n')


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
    from dialfred_sim.progress import progress_bar as _bar
    return _bar(total=total, initial=done, unit='ep', disable=not enabled,
                smoothing=0.05)


def run_eval(config: EvalConfig, progress: bool = True, traces: Optional[dict] = None) -> EvalReport:
    """Evaluate `config.agent` on the split's tasks through `config.workers` simulator nodes.

    Results go to the JSON-lines file as each episode ends; tasks already there are skipped (resume).
    Writes the summary JSON next to it and returns the report of every selected task. `traces`: a
    dict to fill with each played task's actions, {task_id: [(name, x, y), ...]} (the performer path
    takes them from the goals' feedback). The results file is this run's alone while it runs
    (`metrics.results_lock`: a second run into it is refused, naming this one).
    """
    from dialfred_sim.metrics import results_lock
    config.check()    # an unknown agent or questioner, or a bad setting, fails here before any node starts
    with results_lock(config.results_path):
        return _run_eval(config, progress, traces)


def _run_eval(config: EvalConfig, progress: bool, traces: Optional[dict]) -> EvalReport:
    from dialfred_performer.model import git_commit
    from dialfred_sim.metrics import append_result, summarize, write_text_atomically

    t0 = time.monotonic()
    tasks = config.split_tasks()[:config.limit]
    tasks = [under_rule(t, config.goal_rule) for t in tasks]      # goals and expert lengths as the run judges them
    selected = shard_tasks(tasks, config.shard)       # (index in the split, task): the index seeds the episode
    tasks = [t for _, t in selected]
    done = resumable_results(config, [t.task_id for t in tasks])
    jobs = [(k, t) for k, t in selected if t.task_id not in done]
    if done:
        print(f'resuming: {len(done)} of {len(tasks)} tasks are already in {config.results_path}; '
              f'{len(jobs)} to play', file=sys.stderr)
    ran, startup_s, restarts = 0, 0.0, 0
    code = git_commit()
    warn_of_other_code(config.results_path, done.values(), code)

    def recorder(bar):
        """on_result of either path: the result line (stamped with the code's commit) written at once
        (resumable), counted, shown."""
        def record(result) -> None:
            nonlocal ran
            result = dataclasses.replace(result, code=code)
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
                    worker = SimWorker(graph, ns, config.make_agent(), config, oracle=config.asks)
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
    report = EvalReport(config, results, ran, startup_s, time.monotonic() - t0, summarize(results), restarts, code)
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


def default_resolution(config: EvalConfig) -> int:
    """The camera of the performer model played (dialfred_performer.models.camera_resolution: the et
    performer's training resolution, 128 for the map performer); 128 for other agents. An unreadable
    checkpoint: 128, and check() says why."""
    model = config.agent if config.agent in PERFORMER_MODELS else config.performer
    if model not in PERFORMER_MODELS:
        return DEFAULT_RESOLUTION
    try:
        return camera_resolution(model, config.checkpoint_path)
    except (FileNotFoundError, ValueError):
        return DEFAULT_RESOLUTION


def run_eval_command(args) -> int:
    config = eval_config(args)
    try:
        config.check()
    except ValueError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    try:
        report = run_eval(config, progress=args.progress)
    except KeyboardInterrupt:
        if config.results_path.exists() and config.results_path.stat().st_size:
            print(f'interrupted: finished episodes are in {config.results_path}; the same command resumes',
                  file=sys.stderr)
        else:
            print('interrupted before the first episode ended: nothing was written', file=sys.stderr)
        raise
    print_report(report)
    return 0


def add_eval_parser(sub) -> argparse.ArgumentParser:
    """The `eval` subcommand: EvalConfig's fields and --no-progress."""
    ev = sub.add_parser('eval', help='evaluate an agent on a split; resumable JSON-lines results and a metrics table',
                        description=EvalConfig.__doc__.split('\n\n')[0])
    add_fields(EvalConfig, ev)
    ev.add_argument('--progress', action=argparse.BooleanOptionalAction, default=True,
                    help='a progress bar on stderr (default: --progress)')
    ev.set_defaults(config_parser=ev)
    return ev


def eval_config(args) -> EvalConfig:
    """The EvalConfig of `eval`'s parsed arguments."""
    return from_args(EvalConfig, args, args.config_parser)


