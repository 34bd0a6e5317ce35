"""What `./dialfred reproduce` runs: the settings of the paper's tables, the run's config and sizes."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from dialfred_oracle.annotator import dialogue_path
from dialfred_performer.model import read_state, state_digest
from dialfred_performer.model_registry import performer_model
from dialfred_performer.shipped import SHIPPED_CHECKPOINT
from dialfred_questioner.frames import default_path
from dialfred_sim.dataclass_cli import arg
from dialfred_sim.protocol import PAPER_QUESTION_TYPES
from dialfred_sim.tasks.demonstrations import default_dir

from ..baseline_runs import BASELINES as TABLE2_BASELINES  # the one place of Table II's rows 1-4
from ..evaluation import EvalConfig
from ..paths import REPO


STAGES = ('demos', 'perception', 'performer', 'dialogues', 'frames', 'pretrain', 'rl', 'eval', 'chained', 'check',
          'doc')
EVAL_PATHS = ('local', 'graph', 'in-process')
SPLITS = ('valid_seen', 'valid_unseen')
PERTURB_PROBABILITY = 0.5
SHIPPED_QUESTIONERS = REPO / 'src' / 'dialfred_questioner' / 'dialfred_questioner' / 'checkpoints'
# The training stages' times (and machine) of the run whose models are shipped: written by `ship`, read by
# the document of `reproduce --shipped`.
SHIPPED_RUN = REPO / 'src' / 'dialfred_bringup' / 'dialfred_bringup' / 'reproduce' / 'shipped_run.json'
RESOLUTION = 64
# The perception network (PerceptionConfig fields): wider than PerceptionNetConfig's defaults, trained on more
# frames, with small objects' cells weighted up. Against the defaults at 250,000 frames it labels 38.9% of
# pickupable objects' cells with their type (26.0%), 91.1% of held-out object cells (86.2%).
# It trains in bfloat16 where the CPU computes it natively (`precision='auto'`: AMX or AVX512-BF16), else in fp32:
# bf16 took 25% less time at the same validation loss on such a CPU, but on one with AVX2 alone each update
# took 10 times as long (docs/figures.md), so a CPU without it keeps fp32 and its time.
PERCEPTION = dict(c1=32, c2=64, c3=128, decoder=48, frames=400_000, small_objects=0.5, precision='auto')
# The performer's updates (batches of 16 episodes): 12,000 is three quarters of an epoch, in random order. The
# frozen perception network runs on every frame of every item. Batches of 8 tasks x 2 items (the network once for
# both: --block-tasks 8 --block-items 2 --block-bucket 32) cost 5.7% more validation loss after 1,000 updates
# (1.633 against 1.545) and, in the whole run, were not faster: 0.486 s an update against random order's 0.359 in
# the run before (docs/performer.md), so the pipeline keeps random order. The network runs channels-last, in
# bfloat16 where the CPU does it natively (auto: half the network's time, which is most of an update's), else in
# fp32; the precision goes into the performer's config, and the agent and the questioners perceive so too.
PERFORMER_UPDATES = 12_000
PERFORMER_PERCEPTION_PRECISION = 'auto'
# Actor-critic updates of every RL fine-tuning: the second 32 of 64 moved RL anytime's SR by -0.1 point.
RL_UPDATES = 32

# The RL fine-tunings (FinetuneConfig fields beyond the shared ones).
RL_RUNS = {
    'rl_begin': dict(timing='begin'),
    'rl_anytime': dict(timing='anytime', gap=5),
    'rl_anytime_1': dict(timing='anytime', gap=1, rewards='fixed_1'),
    'rl_anytime_10': dict(timing='anytime', gap=10),
    'rl_mc': dict(timing='confusion'),
    **{f'rl_anytime_withhold_{t}': dict(timing='anytime', gap=5, perturb_type=t) for t in PAPER_QUESTION_TYPES},
    # Beyond the paper: RL anytime reading the instruction only, as the original questioner did (ablation).
    'rl_anytime_no_dialogue': dict(timing='anytime', gap=5, dialogue=False),
    # Beyond the paper: RL anytime fine-tuned against the map-and-plan performer (over the same perception).
    'map_rl_anytime': dict(timing='anytime', gap=5, model='map'),
    # DialFRED's challenge test: RL anytime fine-tuned under the chained protocol, against each performer.
    'rl_anytime_chained': dict(timing='anytime', gap=5, protocol='chained'),
    'map_rl_anytime_chained': dict(timing='anytime', gap=5, model='map', protocol='chained'),
}
# The rows of the returns table (both splits where the setting was evaluated there).
RETURN_ROWS = ('instruction_only', 'all_qas', 'random_qa', 'random_mc', 'pretrained', 'rl_begin', 'rl_anytime',
               'rl_anytime_1', 'rl_anytime_10', 'rl_mc', 'rl_anytime_no_dialogue')
# Rows beyond the paper's tables: (name, what it shows).
EXTRA = {
    'pretrained': 'Pre-trained only (no RL; asks at the start)',
    'rl_anytime': 'RL anytime (reads the dialogue so far)',
    'rl_anytime_no_dialogue': 'RL anytime, instruction only (the original\'s input)',
}

# Beyond the paper: the map-and-plan performer's settings (valid_unseen), each beside the Episodic
# Transformer's setting of the same questioner: {key: (name, the E.T. setting's key, questioner, answers)}.
MAP_ROWS = {
    'map_instruction_only': ('Instruction only', 'instruction_only', '', 'oracle'),
    'map_all_qas': ('All QAs', 'all_qas', 'all', 'oracle'),
    'map_random_qa': ('Random QA', 'random_qa', 'random', 'oracle'),
    'map_all_qas_swapped': ('All QAs, answers swapped', 'all_qas_swapped', 'all', 'swapped'),
    'map_rl_anytime': ('RL anytime', 'rl_anytime', 'rl:map_rl_anytime', 'oracle'),
}
# Beyond the paper: the control of whether a performer reads its answers (valid_unseen): All QAs with each
# answer replaced by the answer to the same question in another task (dialfred_oracle/swap.py).
SWAPPED = 'all_qas_swapped'
# The worth of a question, per performer: (name, instruction only, All QAs, Random QA, All QAs swapped).
WORTH_ROWS = {
    'et': ('Episodic Transformer', 'instruction_only', 'all_qas', 'random_qa', SWAPPED),
    'map': ('map-and-plan', 'map_instruction_only', 'map_all_qas', 'map_random_qa', 'map_all_qas_swapped'),
}

# The paper's numbers. Table II rows 1-4 come from dialfred_bringup/baseline_runs.py; rows 5-6 here.
PAPER_T2 = {
    **{k: {'number': b.number, 'name': b.name, 'SR': b.paper_sr, 'PWSR': b.paper_pwsr, 'NQ': b.paper_nq}
       for k, b in TABLE2_BASELINES.items()},
    'rl_begin': {'number': 5, 'name': 'RL begin', 'SR': {'valid_seen': 47.3, 'valid_unseen': 32.7},
                 'PWSR': {'valid_seen': 33.5, 'valid_unseen': 20.1}, 'NQ': 0.37},
    'rl_anytime': {'number': 6, 'name': 'RL anytime', 'SR': {'valid_seen': 47.8, 'valid_unseen': 33.6},
                   'PWSR': {'valid_seen': 34.2, 'valid_unseen': 20.4}, 'NQ': 0.71},
}
# Table III (valid_unseen): SR, PWSR, NQ, location / appearance / direction shares.
PAPER_T3 = {
    'rl_anytime': ('RL anytime', 33.6, 20.4, 0.71, (0.65, 0.14, 0.21)),
    'rl_anytime_withhold_location': ('RL Loc perturb', 32.2, 19.8, 0.66, (0.47, 0.15, 0.38)),
    'rl_anytime_withhold_appearance': ('RL App perturb', 32.4, 19.9, 0.40, (0.92, 0.04, 0.04)),
    'rl_anytime_withhold_direction': ('RL Dir perturb', 33.0, 20.4, 0.61, (0.51, 0.45, 0.04)),
    'random_qa': ('Random', 28.4, 17.3, 0.81, (0.36, 0.31, 0.33)),
    'random_qa_withhold_location': ('Random Loc perturb', 26.0, 16.0, 0.81, (0.36, 0.31, 0.33)),
    'random_qa_withhold_appearance': ('Random App perturb', 26.1, 16.1, 0.81, (0.36, 0.31, 0.33)),
    'random_qa_withhold_direction': ('Random Dir perturb', 26.2, 15.8, 0.81, (0.36, 0.31, 0.33)),
}
# Table IV: unseen SR, unseen PWSR, NQ.
PAPER_T4 = {
    'rl_anytime_1': ('RL anytime (Fixed 1)', 34.7, 21.2, 21.39),
    'rl_anytime': ('RL anytime (Fixed 5)', 33.6, 20.4, 0.71),
    'rl_anytime_10': ('RL anytime (Fixed 10)', 32.4, 19.9, 0.36),
    'rl_mc': ('RL anytime (MC)', 33.0, 20.4, 0.31),
}


@dataclass(frozen=True)
class Setting:
    """One evaluation: a questioner (a baseline's name, or an RL run's checkpoint) on a split, maybe perturbed."""

    key: str          # results file: eval/<split>_<key>.jsonl
    split: str
    questioner: str   # '' = none; a dialfred_questioner baseline; or 'rl:<run>' (an RL run's checkpoint)
    perturb_type: str = ''
    performer: str = 'et'   # the performer's model (dialfred_performer.model_registry): et or map
    answers: str = 'oracle'   # or 'swapped': the swap control (EvalConfig.answers)


def settings() -> list[Setting]:
    out = []
    for split in SPLITS:
        for key, b in TABLE2_BASELINES.items():
            out.append(Setting(key, split, b.questioner))
        out += [Setting('rl_begin', split, 'rl:rl_begin'), Setting('rl_anytime', split, 'rl:rl_anytime'),
                Setting('pretrained', split, 'rl:pretrained')]
    for t in PAPER_QUESTION_TYPES:
        out.append(Setting(f'rl_anytime_withhold_{t}', 'valid_unseen', f'rl:rl_anytime_withhold_{t}', t))
        out.append(Setting(f'random_qa_withhold_{t}', 'valid_unseen', 'random', t))
    for run in ('rl_anytime_1', 'rl_anytime_10', 'rl_mc', 'rl_anytime_no_dialogue'):
        out.append(Setting(run, 'valid_unseen', f'rl:{run}'))
    out.append(Setting(SWAPPED, 'valid_unseen', 'all', answers='swapped'))
    for key, (_, _, questioner, answers) in MAP_ROWS.items():
        out.append(Setting(key, 'valid_unseen', questioner, performer='map', answers=answers))
    return out


# The chained stage (DialFRED's challenge test, dialfred_sim/chained.py): these settings of the eval stage played
# again under the chained protocol, each task of an episode from the state the agent's own actions left.
# Beside them, RL anytime fine-tuned under chaining (RL_RUNS' *_chained), for each performer.
CHAINED_KEYS = ('instruction_only', 'all_qas', 'random_qa', 'rl_anytime', 'rl_anytime_chained', SWAPPED,
                'map_instruction_only', 'map_all_qas', 'map_random_qa', 'map_rl_anytime', 'map_rl_anytime_chained',
                'map_all_qas_swapped')
CHAINED_RL = {'rl_anytime_chained': Setting('rl_anytime_chained', 'valid_unseen', 'rl:rl_anytime_chained'),
              'map_rl_anytime_chained': Setting('map_rl_anytime_chained', 'valid_unseen', 'rl:map_rl_anytime_chained',
                                                performer='map')}


def chained_settings() -> list[Setting]:
    """The settings of the chained stage (valid_unseen, both performers): the eval stage's of CHAINED_KEYS, and
    RL anytime fine-tuned under chaining."""
    by_key = {**{s.key: s for s in settings() if s.split == 'valid_unseen'}, **CHAINED_RL}
    return [by_key[k] for k in CHAINED_KEYS]


@dataclass(frozen=True)
class ReproduceConfig:
    """Run the whole DialFRED pipeline after set-up and write the results document (Tables II, III, IV)."""

    out: str = arg('', "the run folder (default out/reproduce; --quick: out/reproduce_quick; --shipped: "
                       "out/reproduce_shipped)")
    quick: bool = arg(False, 'tiny slices of every stage (minutes): checks the pipeline, the numbers mean nothing')
    shipped: bool = arg(False, 'no training stages: evaluate the shipped performer and questioner checkpoints')
    doc: str = arg('', "also write the document here; '' = docs/results.md for a full run in out/reproduce, "
                       "nowhere else (--shipped, --quick, "
                       "another --out); 'none' = only <out>/results.md")
    force: str = arg('', 'rerun this stage and every stage after it, stamps or not')
    until: str = arg('', "stop after this stage ('' = run to the end)")
    eval_path: str = arg('local', "how the tables' episodes are played: local (worker processes without ROS, "
                                  'the same episodes as the graph; fastest), graph (performer nodes), in-process '
                                  '(the agent in this process, simulator and oracle nodes)')
    check_tasks: int = arg(10, 'the check stage plays the first N tasks of every setting through the ROS graph and '
                               'compares them with the tables\' episodes (0: no check)')
    workers: int = arg(2, 'processes / simulator nodes of every stage')
    seed: int = arg(0, 'the seed of every stage')
    resamples: int = arg(2000, 'bootstrap resamples of the 95% intervals')
    progress: bool = arg(False, "the stages' own progress bars on stderr")
    status: bool = arg(False, 'say where the run folder stands (each stage and item: done, stale, running or cut off, '
                              'not started; their times) and run nothing')
    redoc: bool = arg(False, "write the document again from the run's results files as they are, whatever the stamps "
                             "say (after a change to the document's own code), and copy it as --doc says; runs no stage")

    def __post_init__(self):
        for name in ('force', 'until'):
            if getattr(self, name) and getattr(self, name) not in STAGES:
                raise ValueError(f'--{name} takes one of {", ".join(STAGES)}, got {getattr(self, name)!r}')
        if self.quick and self.shipped:
            raise ValueError('--quick and --shipped do not go together')
        if self.workers < 1:
            raise ValueError('--workers must be at least 1')
        if self.eval_path not in EVAL_PATHS:
            raise ValueError(f'--eval-path takes one of {", ".join(EVAL_PATHS)}, got {self.eval_path!r}')
        if self.check_tasks < 0:
            raise ValueError('--check-tasks must be 0 or more')
        if self.redoc and (self.status or self.force or self.until):
            raise ValueError('--redoc runs no stage: it does not go with --status, --force or --until')

    @property
    def doc_target(self) -> Optional[Path]:
        """Where the document is copied besides the run folder (None: nowhere)."""
        if self.doc == 'none':
            return None
        if self.doc:
            return Path(self.doc) if Path(self.doc).is_absolute() else REPO / self.doc
        if self.quick or self.out or self.shipped:
            return None
        return REPO / 'docs' / 'results.md'

    @property
    def run_dir(self) -> Path:
        name = self.out or ('out/reproduce_quick' if self.quick else
                            'out/reproduce_shipped' if self.shipped else 'out/reproduce')
        return Path(name) if Path(name).is_absolute() else REPO / name


# --------------------------------------------------------------------------------------------- sizes

class Plan:
    """What each stage runs (paths and configs), from the run's config: full size or quick slices."""

    def __init__(self, cfg: ReproduceConfig):
        self.cfg, self.run = cfg, cfg.run_dir
        q = cfg.quick
        self.train_limit = 32 if q else 0
        cache = self.run / 'cache'
        self.demos = cache / 'demonstrations' / f'train_{RESOLUTION}' if q else default_dir('train', RESOLUTION)
        self.dialogue_dir = cache / 'dialogues' if q else None     # None: annotator's default (~/.cache)
        self.frames = cache / f'train_first_{RESOLUTION}.npz' if q else default_path('train', RESOLUTION)
        self.perception_dir = self.run / 'perception'
        self.performer_dir = self.run / 'performer'
        self.pretrain_dir = self.run / 'questioner' / 'pretrain'
        self.eval_dir = self.run / 'eval'
        self.chained_dir = self.run / 'chained'
        self.eval_limit = 8 if q else 0
        self.eval_path = cfg.eval_path
        self.check_dir = self.run / 'check'
        self.check_tasks = min(cfg.check_tasks, 2) if q else cfg.check_tasks

    # each stage's config, as plain JSON (part of its stamp)
    def demos_config(self) -> dict:
        return dict(split='train', resolution=RESOLUTION, workers=self.cfg.workers, limit=self.train_limit,
                    out=str(self.demos), progress=self.cfg.progress, annotate=True, labels=True)

    def perception_config(self) -> dict:
        base = dict(demonstrations=str(self.demos), out=str(self.perception_dir), seed=self.cfg.seed,
                    progress=self.cfg.progress, **PERCEPTION)
        if self.cfg.quick:
            base.update(frames=512, batch_size=16, val_frames=64, validate_every=16, threads=1,
                        c1=8, c2=16, c3=16, decoder=8)
        return base

    @property
    def perception_checkpoint(self) -> Path:
        return self.perception_dir / 'perception.pt'

    def performer_config(self) -> dict:
        base = dict(demonstrations=str(self.demos), out=str(self.performer_dir), seed=self.cfg.seed,
                    progress=self.cfg.progress, epochs=1, max_updates=PERFORMER_UPDATES, validation='',
                    val_fraction=0.05, perception=str(self.perception_checkpoint), model=dict(reach_input=True),
                    perception_precision=PERFORMER_PERCEPTION_PRECISION)
        if self.cfg.quick:
            base.update(epochs=8, max_updates=200, batch_size=8, warmup_updates=10, log_every=10,
                        checkpoint_every=30, val_fraction=0.2,
                        model=dict(resolution=RESOLUTION, d_model=32, heads=2, layers=1, ff=64, reach_input=True))
        return base

    def dialogues_config(self) -> dict:
        return dict(splits=['train'], workers=self.cfg.workers, limit=self.train_limit,
                    dialogue_dir=str(self.dialogue_dir) if self.dialogue_dir else '', demonstrations=str(self.demos))

    def frames_config(self) -> dict:
        return dict(split='train', resolution=RESOLUTION, out=str(self.frames), demonstrations=str(self.demos),
                    limit=self.train_limit)

    @property
    def performer_checkpoint(self) -> Path:
        if self.cfg.shipped:
            return Path(SHIPPED_CHECKPOINT)
        best = self.performer_dir / 'best.pt'
        return best if best.exists() or not (self.performer_dir / 'last.pt').exists() else self.performer_dir / 'last.pt'

    def pretrain_config(self) -> dict:
        base = dict(split='train', frames=str(self.frames), performer=str(self.performer_checkpoint),
                    out=str(self.pretrain_dir), seed=self.cfg.seed, limit=self.train_limit,
                    progress=self.cfg.progress)
        if self.cfg.quick:
            base.update(epochs=1, batch_size=8, threads=1, val_fraction=0.2,
                        model=dict(embedding=16, hidden=32, image=32))
        return base

    def rl_config(self, name: str) -> dict:
        run = RL_RUNS[name]
        base = dict(init=str(self.pretrain_dir / 'best.pt'), performer=str(self.performer_checkpoint),
                    split='valid_seen', out=str(self.run / 'questioner' / name),
                    resolution=camera(run.get('model', 'et')), workers=self.cfg.workers, seed=self.cfg.seed,
                    progress=self.cfg.progress, perturb_probability=PERTURB_PROBABILITY, updates=RL_UPDATES, **run)
        if self.cfg.quick:
            base.update(updates=2, episodes_per_update=8, max_steps=30, limit=16)
        return base

    def questioner_checkpoint(self, run: str) -> Path:
        """The checkpoint of an RL run, or of the pre-trained questioner for 'pretrained'."""
        if self.cfg.shipped:
            return SHIPPED_QUESTIONERS / f'{run}.pt'
        if run == 'pretrained':
            return self.pretrain_dir / 'best.pt'
        return self.run / 'questioner' / run / 'final.pt'

    def stage_outputs(self, stage: str) -> list[Path]:
        """What `stage` writes: cleared before it runs with new inputs (CACHES' are rewritten in place
        instead), and timed by their modification times when it was cut off."""
        dialogues = self.dialogue_dir / 'train.jsonl.gz' if self.dialogue_dir else dialogue_path('train')
        return {
            'demos': [self.demos], 'dialogues': [dialogues], 'frames': [self.frames],
            'perception': [self.perception_dir], 'performer': [self.performer_dir], 'pretrain': [self.pretrain_dir],
            'rl': [self.run / 'questioner' / name for name in RL_RUNS], 'eval': [self.eval_dir],
            'chained': [self.chained_dir],
            'check': [self.check_dir], 'doc': [self.run / 'results.md', self.run / 'sr_nq.png'],
        }[stage]

    def eval_config(self, s: Setting, check: bool = False, chained: bool = False):
        """The evaluation of setting `s` for the tables, or with `check` its first check_tasks tasks
        through the graph (performer nodes), or with `chained` under the chained protocol (the performer in
        the launcher's process where the tables' path is the graph's: the performer node plays one task a
        goal)."""
        questioner = s.questioner
        if questioner.startswith('rl:'):
            questioner = f'learned:{self.questioner_checkpoint(questioner[3:])}'
        path = 'graph' if check else self.eval_path
        if chained:
            return EvalConfig(split=s.split, agent=s.performer, local=path == 'local', protocol='chained',
                              questioner=questioner, perturb_type=s.perturb_type, answers=s.answers,
                              perturb_probability=PERTURB_PROBABILITY, limit=self.eval_limit or None,
                              workers=self.cfg.workers, out=self.chained_dir / f'{s.split}_{s.key}.jsonl',
                              seed=self.cfg.seed, resolution=camera(s.performer), checkpoint=self.performer_checkpoint)
        limit = self.check_tasks if check else self.eval_limit or None
        if check and self.eval_limit:
            limit = min(limit, self.eval_limit)
        return EvalConfig(split=s.split, agent=s.performer, performer=s.performer if path == 'graph' else '',
                          local=path == 'local',
                          questioner=questioner, perturb_type=s.perturb_type, answers=s.answers,
                          perturb_probability=PERTURB_PROBABILITY, limit=limit,
                          workers=self.cfg.workers,
                          out=(self.check_dir if check else self.eval_dir) / f'{s.split}_{s.key}.jsonl',
                          seed=self.cfg.seed, resolution=camera(s.performer), checkpoint=self.performer_checkpoint)

    def check_settings(self) -> list:
        """The settings the check stage plays through the graph: all of them (quick: the first with a learned
        questioner and the first with a perturbed oracle)."""
        chosen = [s for s in settings() if self.available(s)]
        if self.cfg.quick:
            chosen = [s for s in chosen if s.questioner.startswith('rl:')][:1] + [s for s in chosen if s.perturb_type][:1]
        return chosen if self.check_tasks else []

    def available(self, s: Setting) -> bool:
        """Whether the setting's questioner checkpoint exists (only shipped ones can be missing)."""
        return not s.questioner.startswith('rl:') or self.questioner_checkpoint(s.questioner[3:]).exists()


def camera(model: str) -> int:
    """The camera pixels a performer model plays at: its registered fixed camera (the map performer's), else
    the resolution the pipeline trains the checkpoint at (the E.T.'s: model_registry.camera_resolution)."""
    fixed = performer_model(model).fixed_camera
    return RESOLUTION if fixed is None else fixed


TRAINING = ('demos', 'perception', 'performer', 'dialogues', 'frames', 'pretrain', 'rl')


def sha256_of(data) -> str:
    if isinstance(data, (bytes, bytearray)):
        return hashlib.sha256(data).hexdigest()
    return hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()


def weights_sha256(path: Path) -> str:
    """A checkpoint's weights digest (dialfred_performer.model.state_digest of its state_dict). Two runs
    that train the same model get the same digest even though their files differ: a checkpoint also
    records the command and git commit that made it."""
    try:
        state = read_state(path)['state_dict']
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f'{path}: not a checkpoint with a state_dict ({exc})') from None
    return state_digest(state)
