"""`EvalRun`: an evaluation as it is played, made from its options (`eval_config.EvalConfig`).

`EvalRun(config)` checks the options (ValueError saying what is wrong, before anything starts) and
resolves them into `options`, a copy (the caller's config is not changed): `--performer` names the
agent played, a tasks file names the split, a person answering gets an hour per request. The run then
gives what follows from its options, and nothing else does:

- the agent factory: `make_performer()` (a registered performer model from its checkpoint, or a
  dialfred_sim.agents agent) and `make_agent()` (with its questioner); `asks`, whether the run asks the
  oracle;
- the checkpoints' digests and the names results carry: `agent_name`, `oracle`, `identity` (what
  every results line records), `questioner_label`;
- where results go: `results_path`, `summary_path`, `tasks_record_path`; and the tasks: `split_tasks()`.

Worker processes (`local.py`) and the graph's workers (`workers.py`) are given the run.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
import tempfile
from pathlib import Path
from typing import Optional

from dialfred_oracle.answerers import ANSWERER_PREFIX, AnswersError, answerer_label, is_answerer_spec, load_answerer
from dialfred_performer.model_registry import PERFORMER_MODELS, load_policy
from dialfred_questioner.baselines import with_questioner
from dialfred_questioner.questioners import make_questioner
from dialfred_sim.agents import make_agent as make_reference_agent
from dialfred_sim.bag import IMAGE_FORMATS
from dialfred_sim.protocol import DEFAULT_PROTOCOL, PROTOCOLS, DialogueAgent, question_types
from dialfred_sim.tasks.goals import DEFAULT_GOAL_RULE
from dialfred_sim import tasks as task_sets
from dialfred_sim.tasks.splits import read_tasks_file

from .eval_config import EvalConfig, checkpoint_path
from .paths import REPO
from .shards import check_shard, shard_suffix


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


def check_ranges(o: EvalConfig) -> None:
    """ValueError for an option out of its range, or options that cannot go together (no file is read)."""
    check_shard(o.shard)
    if o.limit is not None and o.limit < 1:
        raise ValueError(f'--limit must be at least 1 (leave it out for every task), got {o.limit}')
    if o.workers < 1:
        raise ValueError(f'--workers must be at least 1, got {o.workers}')
    if not 1 <= o.max_questions <= 1000:
        raise ValueError(f'--max-questions must be 1 to 1000, got {o.max_questions}')
    if not 16 <= o.resolution <= 1024:
        raise ValueError(f'--resolution must be 16 to 1024 pixels, got {o.resolution}')
    if not o.request_timeout > 0 or not o.episode_timeout > 0:
        raise ValueError('--request-timeout and --episode-timeout must be more than 0 seconds')
    if o.max_restarts < 0:
        raise ValueError(f'--max-restarts must be 0 or more, got {o.max_restarts}')
    if o.record_format not in IMAGE_FORMATS:
        raise ValueError(f'--record-format must be one of {", ".join(IMAGE_FORMATS)}, got {o.record_format!r}')
    if o.record is not None and Path(o.record).exists() and not Path(o.record).is_dir():
        raise ValueError(f'--record {o.record} exists and is not a folder')
    if o.local and (o.record is not None or o.foxglove is not None):
        raise ValueError('--local plays without ROS: it cannot go with --record or --foxglove')
    if o.performer and o.performer not in PERFORMER_MODELS:
        raise ValueError(f'--performer must be one of {", ".join(PERFORMER_MODELS)} (the performer node\'s model), '
                         f'got {o.performer!r}')
    if o.protocol not in PROTOCOLS:
        raise ValueError(f'--protocol must be one of {", ".join(PROTOCOLS)}, got {o.protocol!r}')
    if is_answerer_spec(o.answers):
        try:
            load_answerer(o.answers)
        except AnswersError as exc:
            raise ValueError(str(exc)) from None
    if o.perturb_type and o.perturb_type not in question_types():
        raise ValueError(f'--perturb-type must be one of {", ".join(question_types())}, got {o.perturb_type!r}')
    if o.perturb_type and not 0.0 <= o.perturb_probability <= 1.0:
        raise ValueError(f'--perturb-probability must be in [0, 1], got {o.perturb_probability}')


class EvalRun:
    """An evaluation run of checked, resolved options (see the module's doc). ValueError from the
    constructor for options that cannot run, a results file that cannot be written, or an agent or
    questioner that cannot be made."""

    def __init__(self, config: EvalConfig, check: bool = True):
        """`check` False: resolve the options without checking them (no agent is made, no file probed):
        to name a run's files or read its results."""
        if check:
            check_ranges(config)
        o = self.options = dataclasses.replace(config)
        if o.performer:
            o.agent = o.performer
            if o.local:          # the same performer, without ROS: --local --performer et is --local --agent et
                o.performer = ''
        if o.tasks_file:
            try:
                o.split = self.tasks_source.split      # the split played is the file's
            except FileNotFoundError as exc:
                raise ValueError(str(exc)) from None
        if o.answers == 'human':         # --answers human is --human
            o.human, o.answers = True, 'oracle'
        if o.human:
            o.request_timeout = max(o.request_timeout, 3600.0)      # a person takes time
            o.episode_timeout = float('inf')       # the robot waits for its person: a goal is never cut off
        if check:
            self.check()

    def check(self) -> None:
        """ValueError for an agent or questioner that cannot be made, a results file that cannot be written,
        or options that need an oracle the run does not ask."""
        o = self.options
        self.make_agent()     # the node path too: a bad checkpoint or questioner fails before any node starts
        check_results_path(self.results_path)
        if o.human and (o.local or o.workers != 1 or not self.asks or o.perturb_type or o.answers != 'oracle'):
            raise ValueError('--human answers through the graph (not --local), with one worker (--workers 1: one '
                             'person answers one question at a time), a questioner (or an agent that asks), and no '
                             '--perturb-type or other --answers')
        if o.human_timeout is not None and (not o.human or o.human_timeout <= 0):
            raise ValueError('--human-timeout is a number of seconds above 0, with --human')
        if o.answers == 'swapped' and (not self.asks or o.perturb_type):
            raise ValueError('--answers swapped needs a questioner (--questioner, or an agent that asks) and no '
                             '--perturb-type')
        if self.answerer and (not self.asks or o.perturb_type):
            raise ValueError(f'--answers {o.answers} needs a questioner (--questioner, or an agent that asks) and no '
                             '--perturb-type')
        if o.perturb_type and not self.asks:
            raise ValueError('a perturbed oracle needs a questioner (--questioner, or an agent that asks)')

    # ------------------------------------------------------------------ the agent
    def make_performer(self):
        """The acting agent alone: a registered performer model from its checkpoint, or a
        dialfred_sim.agents agent (a class of yours among them)."""
        o = self.options
        if o.agent in PERFORMER_MODELS:
            try:
                return load_policy(o.agent, self.checkpoint_path)
            except FileNotFoundError as exc:
                raise ValueError(str(exc)) from None
        return make_reference_agent(o.agent, o.resolution)

    def make_agent(self):
        """A new agent as configured (ValueError for an unknown agent or questioner)."""
        o = self.options
        return with_questioner(self.make_performer(), make_questioner(o.questioner) if o.questioner else None)

    @functools.cached_property
    def asks(self) -> bool:
        """Whether the run asks the oracle: with a questioner, or with an agent that asks by itself (a
        protocol.DialogueAgent, `ask(observation)` and `hear(qa)`: a class of yours)."""
        o = self.options
        if o.questioner:
            return True
        if o.performer or o.agent in PERFORMER_MODELS:
            return False
        return isinstance(self.make_performer(), DialogueAgent)

    # ------------------------------------------------------------------ checkpoints and names
    @property
    def checkpoint_path(self) -> Path:
        return checkpoint_path(self.options)

    @functools.cached_property
    def checkpoint_sha256(self) -> str:
        try:
            return hashlib.sha256(self.checkpoint_path.read_bytes()).hexdigest()
        except OSError:
            raise ValueError(f'no performer checkpoint at {self.checkpoint_path} (--checkpoint PATH)') from None

    @property
    def learned_questioner_path(self) -> Optional[Path]:
        """The checkpoint file of a questioner given as learned:PATH, else None."""
        q = self.options.questioner
        if ':' not in q:
            return None
        from dialfred_questioner.policy import LEARNED_PREFIX     # here: policy imports torch
        return Path(q[len(LEARNED_PREFIX):]).expanduser() if q.startswith(LEARNED_PREFIX) else None

    @functools.cached_property
    def questioner_label(self) -> str:
        """The questioner's name as results carry it: learned:PATH as learned-<file stem>-<its sha256[:8]>
        (no slashes in a file name), a shipped learned one as <name>-<its sha256[:8]> (results of two
        checkpoints never mix, as the performer's), any other as given."""
        # Imported here: policy imports torch, which a run without a learned questioner does without.
        from dialfred_questioner.policy import SHIPPED_LEARNED, learned_checkpoint
        q, path = self.options.questioner, self.learned_questioner_path
        if path is None and q not in SHIPPED_LEARNED:
            return q
        path = path if path is not None else learned_checkpoint(q)
        try:
            digest = hashlib.sha256(path.read_bytes()).hexdigest()[:8]
        except OSError:
            raise ValueError(f'no questioner checkpoint at {path}') from None
        return f'learned-{path.stem}-{digest}' if self.learned_questioner_path is not None else f'{q}-{digest}'

    @property
    def agent_name(self) -> str:
        """The name results carry: the agent's (a performer model's with its checkpoint's sha256, so that
        results of two checkpoints never mix), with its questioner's (`questioner_label`) after a '+'."""
        o = self.options
        agent = f'{o.agent}-{self.checkpoint_sha256[:8]}' if o.agent in PERFORMER_MODELS else o.agent
        return f'{agent}+{self.questioner_label}' if o.questioner else agent

    @property
    def answerer(self) -> str:
        """The --answers of an answerer of dialfred_oracle.answerers (a FILE or a class), '' for a built-in."""
        return self.options.answers if is_answerer_spec(self.options.answers) else ''

    @functools.cached_property
    def answerer_label(self) -> str:
        """The answerer as results record it (answerers.answerer_label: a file by its name and digest)."""
        try:
            return answerer_label(self.answerer) if self.answerer else ''
        except AnswersError as exc:
            raise ValueError(str(exc)) from None

    @property
    def oracle(self) -> str:
        """How the oracle answers, as results record it: '' exactly, 'location:0.5' perturbed, 'swapped',
        'human', 'answers:<label>' worded by an answerer."""
        o = self.options
        if o.answers == 'swapped':
            return 'swapped'
        if self.answerer:
            return ANSWERER_PREFIX + self.answerer_label
        if o.human:
            return 'human'
        return f'{o.perturb_type}:{o.perturb_probability:g}' if o.perturb_type else ''

    @property
    def played(self) -> str:
        """How this run plays its episodes, as its results lines record it (EpisodeResult.played)."""
        o = self.options
        return 'performer node' if o.performer else ('local processes (no ROS)' if o.local else 'in-process agent')

    @property
    def identity(self) -> dict:
        """What every results line of this run carries (metrics.episode_result's keywords)."""
        return {'agent': self.agent_name, 'oracle': self.oracle, 'seed': self.options.seed,
                'goal_rule': self.options.goal_rule, 'protocol': self.options.protocol}

    # ------------------------------------------------------------------ tasks and files
    @functools.cached_property
    def tasks_source(self):
        """The tasks file read once (dialfred_sim.tasks.splits.TasksFile), or None for a shipped split."""
        return read_tasks_file(self.options.tasks_file) if self.options.tasks_file else None

    def split_tasks(self) -> list:
        """Every task of the split played (or of the tasks file), in order, before --limit and --shard."""
        return self.tasks_source.tasks if self.options.tasks_file else task_sets.load_split(self.options.split)

    @property
    def results_path(self) -> Path:
        o = self.options
        if o.out:
            return Path(o.out)
        perturbed = f'_withhold-{o.perturb_type}-{o.perturb_probability:g}' if o.perturb_type else ''
        perturbed += '_swapped' if o.answers == 'swapped' else ''
        perturbed += f'_answers-{self.answerer_label}' if self.answerer else ''
        perturbed += f'_goal-{o.goal_rule}' if o.goal_rule != DEFAULT_GOAL_RULE else ''
        perturbed += f'_{o.protocol}' if o.protocol != DEFAULT_PROTOCOL else ''
        source = self.tasks_source
        tasks = f'{source.split}-{source.sha256[:8]}' if source else o.split   # a file: named by its content
        name = self.agent_name.replace(':', '.')      # package.module:Class: no colon in a file name
        return REPO / 'out' / 'eval' / f'{tasks}_{name}{perturbed}{shard_suffix(o.shard)}.jsonl'

    @property
    def tasks_record_path(self) -> Path:
        """Where a run on a tasks file records which file (path, sha256) its results came from."""
        return self.results_path.with_suffix('.tasks.json')

    @property
    def summary_path(self) -> Path:
        return self.results_path.with_suffix('.summary.json')
