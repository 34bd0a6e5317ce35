#!/usr/bin/env python3
"""Reproduce the paper's Tables II, III and IV end to end: `./dialfred reproduce`.

    ./dialfred reproduce                      # everything after set-up -> out/reproduce/ (resumable), docs/results.md
    ./dialfred reproduce --quick              # the same pipeline on tiny slices, in minutes -> out/reproduce_quick/
    ./dialfred reproduce --shipped            # no training: evaluate the shipped checkpoints -> docs/results_shipped.md
    ./dialfred reproduce --force rl           # rerun the rl stage and every stage after it
    ./dialfred reproduce --eval-path graph    # the tables' evaluations through the ROS graph (default: local)

Stages, in order (each calls the project's own API or command; none repeats their logic):

| stage | what | output (under the run folder, `--out`) |
|---|---|---|
| demos | the performer's demonstrations of train (`dialfred_performer.prepare --annotate`): the expert's frames, and while each task is played the oracle's QAs at its start and middle and the synthetic annotators' row at its start (no second or third replay of train) | `~/.cache/dialfred/demonstrations/train_64` (quick: `cache/demonstrations`) |
| performer | performer training (`dialfred_performer.train`: one epoch, 15,776 updates; the shipped checkpoint is the best of a 2-epoch run, which was also at the end of its epoch 1) | `performer/best.pt` |
| dialogues | synthetic train dialogues (`scripts/annotate_dialogues.py --splits train --from-demonstrations`: the rows the demos stage made, the same bytes as the script's own pass) | `~/.cache/dialfred/dialogues/train.jsonl.gz` (quick: `cache/dialogues`) |
| frames | train's first frames, copied out of the demonstrations (`dialfred_questioner.frames --demonstrations`) | `~/.cache/dialfred/questioner/train_first_64.npz` (quick: `cache/`) |
| pretrain | questioner pre-training (`dialfred_questioner.pretrain`) | `questioner/pretrain/best.pt` |
| rl | 9 RL fine-tunings (`dialfred_questioner.finetune` on valid_seen): rl_begin, rl_anytime (gap 5), rl_anytime_1 (gap 1, Fixed-1 rewards), rl_anytime_10, rl_mc (model confusion), rl_anytime_withhold_{location,appearance,direction} (the oracle withholding 50% of that type's answers during training) | `questioner/<name>/final.pt` |
| eval | every setting of the tables (`dialfred_bringup.evaluation.run_eval`; `--eval-path local` (default): worker processes without ROS, `dialfred_bringup.local`; `graph`: performer nodes; `in-process`: the agent in this process, simulator and oracle nodes); resumable episode by episode | `eval/<split>_<setting>.jsonl` |
| check | the first `--check-tasks` tasks of every setting played again through the ROS graph (performer, questioner, oracle and simulator nodes) and compared with the eval stage's episodes field by field (wall time aside); mismatches are listed in the document, not hidden | `check/<split>_<setting>.jsonl`, `check/report.json` |
| doc | Tables II, III, IV beside the paper's numbers with 95% bootstrap intervals, what holds, the SR-NQ plot, the RL questioner's most frequent questions and dialogues that turned a failure into a success | `results.md`, `sr_nq.png` (and `--doc PATH`, its plot beside it: `sr_nq.png`, or `<stem>_sr_nq.png` for a doc of another name) |

Each stage writes `stamps/<stage>.json` with the hash of its inputs (its config, the hashes of the stages
it depends on, and the source files that make it). A stage whose stamp matches is skipped
(`[reproduce] <stage>: skipped (stamp matches)`); a changed input reruns it and therefore every stage
after it. A stage cut off midway resumes (training from its last.pt, evaluations from their results
files) when rerun with the same inputs; with other inputs its outputs are cleared first. A progress
line per stage (name, skipped/ran, seconds) goes to stderr and one JSON summary to stdout.

`--shipped` runs no training: the performer is the shipped `dialfred_performer/checkpoints/et.pt`
and the questioners the shipped `dialfred_questioner/checkpoints/<setting>.pt` (a setting whose file
is absent is left out of the tables, marked "no results"); its run folder is out/reproduce_shipped.
The document goes to the run folder, and is copied to docs/results.md (a full run in out/reproduce),
docs/results_shipped.md (`--shipped` in out/reproduce_shipped) or `--doc PATH`; a quick run or another
`--out` copies it nowhere unless `--doc` says where, `--doc none` never.
`--quick` runs the whole pipeline on slices (32 train tasks, a tiny performer and questioner, RL of
2 updates x 8 episodes of at most 30 steps, evaluations of 8 tasks in this process); its numbers mean
nothing, it checks the pipeline. Caches of the quick run stay in its run folder (DIALFRED_DIALOGUE_DIR
and explicit paths), so it never replaces the full train data in ~/.cache.

Everything is seeded (`--seed`). Each stage's output is reproducible: the demonstrations, dialogues
and first frames are byte-identical across runs, and evaluating the same checkpoints gives the same
episodes. Performer training usually repeats bit for bit, but not always: in session 9, one process
in two of the same command differed by a rounding in its first updates and trained a different
model, and the tables moved by up to 4.3 SR points (docs/benchmarks.md; `./dialfred bench
training_determinism` looks for the cause). On the AMD EPYC of sessions 11-12 no process of 28 left the
common stream, but that stream differs from the old CPU's from the first updates on, so a run on
another CPU retrains other models. The run times, listed apart from the tables, always differ.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import pickle
import shlex
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional


from dialfred_performer.cli import arg, parse
from dialfred_sim.protocol import QUESTION_TYPES

from .baselines import BASELINES as TABLE2_BASELINES  # the one place of Table II's rows 1-4
from .paths import REPO

STAGES = ('demos', 'performer', 'dialogues', 'frames', 'pretrain', 'rl', 'eval', 'check', 'doc')
EVAL_PATHS = ('local', 'graph', 'in-process')
SPLITS = ('valid_seen', 'valid_unseen')
PERTURB_PROBABILITY = 0.5
SHIPPED_QUESTIONERS = REPO / 'src' / 'dialfred_questioner' / 'dialfred_questioner' / 'checkpoints'
RESOLUTION = 64

# The RL fine-tunings (FinetuneConfig fields beyond the shared ones).
RL_RUNS = {
    'rl_begin': dict(timing='begin'),
    'rl_anytime': dict(timing='anytime', gap=5),
    'rl_anytime_1': dict(timing='anytime', gap=1, rewards='fixed_1'),
    'rl_anytime_10': dict(timing='anytime', gap=10),
    'rl_mc': dict(timing='confusion'),
    **{f'rl_anytime_withhold_{t}': dict(timing='anytime', gap=5, perturb_type=t) for t in QUESTION_TYPES},
    # Beyond the paper: RL anytime reading the instruction only, as the original questioner did (ablation).
    'rl_anytime_no_dialogue': dict(timing='anytime', gap=5, dialogue=False),
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

# The paper's numbers. Table II rows 1-4 come from dialfred_bringup/baselines.py; rows 5-6 here.
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


def settings() -> list[Setting]:
    out = []
    for split in SPLITS:
        for key, b in TABLE2_BASELINES.items():
            out.append(Setting(key, split, b.questioner))
        out += [Setting('rl_begin', split, 'rl:rl_begin'), Setting('rl_anytime', split, 'rl:rl_anytime'),
                Setting('pretrained', split, 'rl:pretrained')]
    for t in QUESTION_TYPES:
        out.append(Setting(f'rl_anytime_withhold_{t}', 'valid_unseen', f'rl:rl_anytime_withhold_{t}', t))
        out.append(Setting(f'random_qa_withhold_{t}', 'valid_unseen', 'random', t))
    for run in ('rl_anytime_1', 'rl_anytime_10', 'rl_mc', 'rl_anytime_no_dialogue'):
        out.append(Setting(run, 'valid_unseen', f'rl:{run}'))
    return out


@dataclass(frozen=True)
class ReproduceConfig:
    """Run the whole DialFRED pipeline after set-up and write the results document (Tables II, III, IV)."""

    out: str = arg('', "the run folder (default out/reproduce; --quick: out/reproduce_quick; --shipped: "
                       "out/reproduce_shipped)")
    quick: bool = arg(False, 'tiny slices of every stage (minutes): checks the pipeline, the numbers mean nothing')
    shipped: bool = arg(False, 'no training stages: evaluate the shipped performer and questioner checkpoints')
    doc: str = arg('', "also write the document here; '' = docs/results.md for a full run in out/reproduce, "
                       "docs/results_shipped.md for --shipped in out/reproduce_shipped, nowhere else (--quick, "
                       "another --out); 'none' = only <out>/results.md")
    force: str = arg('', 'rerun this stage and every stage after it, stamps or not')
    until: str = arg('', "stop after this stage ('' = run to the end)")
    eval_path: str = arg('local', "how the tables' episodes are played: local (worker processes without ROS, "
                                  'the same episodes as the graph; fastest), graph (performer nodes), in-process '
                                  '(the agent in this process, simulator and oracle nodes)')
    check_tasks: int = arg(20, 'the check stage plays the first N tasks of every setting through the ROS graph and '
                               'compares them with the tables\' episodes (0: no check)')
    workers: int = arg(2, 'processes / simulator nodes of every stage')
    seed: int = arg(0, 'the seed of every stage')
    resamples: int = arg(2000, 'bootstrap resamples of the 95% intervals')
    progress: bool = arg(False, "the stages' own progress bars on stderr")

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

    @property
    def doc_target(self) -> Optional[Path]:
        """Where the document is copied besides the run folder (None: nowhere)."""
        if self.doc == 'none':
            return None
        if self.doc:
            return Path(self.doc) if Path(self.doc).is_absolute() else REPO / self.doc
        if self.quick or self.out:
            return None
        return REPO / 'docs' / ('results_shipped.md' if self.shipped else 'results.md')

    @property
    def run_dir(self) -> Path:
        name = self.out or ('out/reproduce_quick' if self.quick else
                            'out/reproduce_shipped' if self.shipped else 'out/reproduce')
        return Path(name) if Path(name).is_absolute() else REPO / name


# --------------------------------------------------------------------------------------------- sizes

class Plan:
    """What each stage runs (paths and configs), from the run's config: full size or quick slices."""

    def __init__(self, cfg: ReproduceConfig):
        from dialfred_questioner.frames import default_path
        from dialfred_sim.tasks.demonstrations import default_dir
        self.cfg, self.run = cfg, cfg.run_dir
        q = cfg.quick
        self.train_limit = 32 if q else 0
        cache = self.run / 'cache'
        self.demos = cache / 'demonstrations' / f'train_{RESOLUTION}' if q else default_dir('train', RESOLUTION)
        self.dialogue_dir = cache / 'dialogues' if q else None     # None: annotator's default (~/.cache)
        self.frames = cache / f'train_first_{RESOLUTION}.npz' if q else default_path('train', RESOLUTION)
        self.performer_dir = self.run / 'performer'
        self.pretrain_dir = self.run / 'questioner' / 'pretrain'
        self.eval_dir = self.run / 'eval'
        self.eval_limit = 8 if q else 0
        self.eval_path = cfg.eval_path
        self.check_dir = self.run / 'check'
        self.check_tasks = min(cfg.check_tasks, 2) if q else cfg.check_tasks

    # each stage's config, as plain JSON (part of its stamp)
    def demos_config(self) -> dict:
        return dict(split='train', resolution=RESOLUTION, workers=self.cfg.workers, limit=self.train_limit,
                    out=str(self.demos), progress=self.cfg.progress, annotate=True)

    def performer_config(self) -> dict:
        base = dict(demonstrations=str(self.demos), out=str(self.performer_dir), seed=self.cfg.seed,
                    progress=self.cfg.progress, epochs=1, max_updates=0, validation='', val_fraction=0.05)
        if self.cfg.quick:
            base.update(epochs=8, max_updates=200, batch_size=8, warmup_updates=10, log_every=10,
                        checkpoint_every=30, val_fraction=0.2,
                        model=dict(resolution=RESOLUTION, d_model=32, heads=2, layers=1, ff=64))
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
            from dialfred_performer.model import SHIPPED_CHECKPOINT
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
        base = dict(init=str(self.pretrain_dir / 'best.pt'), performer=str(self.performer_checkpoint),
                    split='valid_seen', out=str(self.run / 'questioner' / name), resolution=RESOLUTION,
                    workers=self.cfg.workers, seed=self.cfg.seed, progress=self.cfg.progress,
                    perturb_probability=PERTURB_PROBABILITY, **RL_RUNS[name])
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

    def eval_config(self, s: Setting, check: bool = False):
        """The evaluation of setting `s` for the tables, or with `check` its first check_tasks tasks
        through the graph (performer nodes)."""
        from dialfred_bringup.evaluation import EvalConfig
        questioner = s.questioner
        if questioner.startswith('rl:'):
            questioner = f'learned:{self.questioner_checkpoint(questioner[3:])}'
        path = 'graph' if check else self.eval_path
        limit = self.check_tasks if check else self.eval_limit or None
        if check and self.eval_limit:
            limit = min(limit, self.eval_limit)
        return EvalConfig(split=s.split, agent='et', performer='et' if path == 'graph' else '', local=path == 'local',
                          questioner=questioner, perturb_type=s.perturb_type,
                          perturb_probability=PERTURB_PROBABILITY, limit=limit,
                          workers=self.cfg.workers,
                          out=(self.check_dir if check else self.eval_dir) / f'{s.split}_{s.key}.jsonl',
                          seed=self.cfg.seed, resolution=RESOLUTION, checkpoint=self.performer_checkpoint)

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


# --------------------------------------------------------------------------------------------- stages

def sha256_of(data) -> str:
    if isinstance(data, (bytes, bytearray)):
        return hashlib.sha256(data).hexdigest()
    return hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()


def weights_sha256(path: Path) -> str:
    """A checkpoint's weights digest: sha256 over its state_dict's tensors (name, dtype, shape and bytes, in
    name order). Two runs that train the same model get the same digest even though their files differ:
    a checkpoint also records the command and git commit that made it."""
    import torch
    try:
        state = torch.load(path, map_location='cpu', weights_only=False)['state_dict']
    except (OSError, RuntimeError, EOFError, KeyError, TypeError, pickle.UnpicklingError) as exc:
        raise ValueError(f'{path}: not a checkpoint with a state_dict ({exc})') from None
    h = hashlib.sha256()
    for name in sorted(state):
        t = state[name].detach().contiguous().reshape(-1)
        h.update(f'{name}\0{t.dtype}\0{tuple(state[name].shape)}\0'.encode())
        h.update(t.view(torch.uint8).numpy().tobytes())
    return h.hexdigest()


def newest_mtime(paths) -> float:
    """The newest modification time of the files under `paths` (0 if there are none)."""
    times = [0.0]
    for path in paths:
        path = Path(path)
        if path.is_file():
            times.append(path.stat().st_mtime)
        elif path.is_dir():
            times += [f.stat().st_mtime for f in path.rglob('*') if f.is_file()]
    return max(times)


def code_hash(paths: tuple[str, ...]) -> str:
    h = hashlib.sha256()
    for rel in paths:
        p = REPO / rel
        h.update(rel.encode() + b'\0' + (p.read_bytes() if p.exists() else b'(absent)') + b'\0')
    return h.hexdigest()


PERF, QUES, SIM = 'src/dialfred_performer/dialfred_performer', 'src/dialfred_questioner/dialfred_questioner', \
    'src/dialfred_sim/dialfred_sim'
UP = 'src/dialfred_bringup/dialfred_bringup'
CODE = {
    'demos': (f'{PERF}/prepare.py', f'{PERF}/data.py', f'{SIM}/tasks/demonstrations.py',
              'src/dialfred_oracle/dialfred_oracle/annotator.py'),
    'performer': (f'{PERF}/train.py', f'{PERF}/model.py', f'{PERF}/data.py', f'{PERF}/preprocess.py'),
    'dialogues': ('scripts/annotate_dialogues.py', 'src/dialfred_oracle/dialfred_oracle/annotator.py'),
    'frames': (f'{QUES}/frames.py',),
    'pretrain': (f'{QUES}/pretrain.py', f'{QUES}/model.py', f'{QUES}/data.py'),
    'rl': (f'{QUES}/finetune.py', f'{QUES}/rollout.py', f'{SIM}/episode.py', f'{QUES}/policy.py', f'{QUES}/model.py'),
    'eval': (f'{UP}/evaluation.py', f'{UP}/local.py', f'{SIM}/episode.py', f'{QUES}/baselines.py', f'{QUES}/policy.py',
             f'{PERF}/agent.py', f'{SIM}/metrics.py'),
    'check': (f'{UP}/evaluation.py', f'{UP}/local.py', f'{UP}/reproduce.py'),
    'doc': (f'{UP}/reproduce.py', f'{UP}/results_doc.py', f'{UP}/baselines.py', f'{SIM}/metrics.py', f'{PERF}/curves.py'),
}
UPSTREAM = {
    'demos': (), 'performer': ('demos',), 'dialogues': ('demos',), 'frames': ('demos',), 'pretrain': ('performer', 'dialogues', 'frames'),
    'rl': ('performer', 'pretrain'), 'eval': ('performer', 'rl'), 'check': ('eval',), 'doc': ('eval', 'check'),
}
TRAINING = ('demos', 'performer', 'dialogues', 'frames', 'pretrain', 'rl')


class Runner:
    def __init__(self, cfg: ReproduceConfig):
        self.cfg, self.plan = cfg, Plan(cfg)
        self.stamps_dir = cfg.run_dir / 'stamps'
        self.hashes: dict[str, str] = {}
        self.summary: dict[str, dict] = {}
        self.forced = False

    def log(self, text: str) -> None:
        print(f'[reproduce] {text}', file=sys.stderr, flush=True)

    def stage_inputs(self, stage: str) -> dict:
        p = self.plan
        config = {
            'demos': p.demos_config, 'performer': p.performer_config, 'dialogues': p.dialogues_config,
            'frames': p.frames_config, 'pretrain': p.pretrain_config,
            'rl': lambda: {name: p.rl_config(name) for name in RL_RUNS},
            'eval': lambda: {'settings': [dataclasses.asdict(s) for s in settings() if p.available(s)],
                             'eval_path': p.eval_path, 'limit': p.eval_limit, 'seed': self.cfg.seed,
                             'performer': str(p.performer_checkpoint),
                             'questioners': {r: str(p.questioner_checkpoint(r)) for r in (*RL_RUNS, 'pretrained')},
                             'shipped': self.shipped_hashes() if self.cfg.shipped else None},
            'check': lambda: {'settings': [dataclasses.asdict(s) for s in p.check_settings()],
                              'tasks': p.check_tasks, 'seed': self.cfg.seed},
            'doc': lambda: {'resamples': self.cfg.resamples, 'limit': p.eval_limit},
        }[stage]()
        return {'stage': stage, 'config': config, 'code': code_hash(CODE[stage]),
                'upstream': {u: self.hashes.get(u, 'shipped') for u in UPSTREAM[stage]}}

    def shipped_hashes(self) -> dict:
        files = [self.plan.performer_checkpoint] + [self.plan.questioner_checkpoint(r) for r in (*RL_RUNS, 'pretrained')]
        return {str(f): sha256_of(f.read_bytes()) if f.exists() else None for f in files}

    def stamp_path(self, stage: str) -> Path:
        return self.stamps_dir / f'{stage}.json'

    def read_stamp(self, stage: str) -> Optional[dict]:
        try:
            return json.loads(self.stamp_path(stage).read_text())
        except (OSError, ValueError):
            return None

    def write_stamp(self, stage: str, record: dict) -> None:
        self.stamps_dir.mkdir(parents=True, exist_ok=True)
        tmp = self.stamp_path(stage).with_suffix('.tmp')
        from dialfred_bringup.machine import machine
        record = {**record, 'machine': machine()}      # the seconds, and bit patterns, depend on it
        tmp.write_text(json.dumps(record, indent=1, sort_keys=True) + '\n')
        tmp.replace(self.stamp_path(stage))

    def run_stage(self, stage: str, action: Callable[[bool], dict], outputs: list[Path]) -> None:
        """Skip `stage` if its stamp holds the hash of its inputs, else run `action(resume)`: resume is
        True when the stage was cut off with these same inputs (else its outputs are cleared first)."""
        if self.cfg.force == stage:
            self.forced = True
        inputs = self.stage_inputs(stage)
        digest = sha256_of(inputs)
        self.hashes[stage] = digest
        old = self.read_stamp(stage)
        if old and old.get('hash') == digest and old.get('status') == 'done' and not self.forced:
            self.log(f'{stage}: skipped (stamp matches, {digest[:12]})')
            self.summary[stage] = {'status': 'skipped', 'hash': digest, 'seconds': 0.0}
            return
        resume = bool(old and old.get('hash') == digest and old.get('status') == 'running')
        if not resume:
            for path in outputs:
                if path.is_dir():
                    shutil.rmtree(path)
                elif path.exists():
                    path.unlink()
        why = 'resuming' if resume else ('forced' if self.forced else ('inputs changed' if old else 'no stamp'))
        # A resumed stage's time includes its cut-off runs: each lasted from its start until its
        # outputs were last written (the newest modification time under them).
        before, runs = (old.get('seconds_before', 0.0) + max(0.0, newest_mtime(outputs) - old.get('started_at', time.time())),
                        old.get('runs', 1) + 1) if resume else (0.0, 1)
        self.log(f'{stage}: running ({why}, {digest[:12]})')
        self.write_stamp(stage, {'stage': stage, 'hash': digest, 'status': 'running', 'inputs': inputs,
                                 'started_at': time.time(), 'seconds_before': round(before, 1), 'runs': runs})
        t0 = time.monotonic()
        report = action(resume) or {}
        this_run = time.monotonic() - t0
        seconds = round(before + this_run, 1)
        self.write_stamp(stage, {'stage': stage, 'hash': digest, 'status': 'done', 'inputs': inputs,
                                 'seconds': seconds, 'seconds_this_run': round(this_run, 1), 'runs': runs,
                                 'report': report})
        self.log(f'{stage}: ran in {this_run:.1f} s' + (f' ({seconds:.1f} s over {runs} runs)' if runs > 1 else ''))
        self.summary[stage] = {'status': 'ran', 'hash': digest, 'seconds': seconds, 'runs': runs, 'report': report}

    # ---- the stages

    def demos(self, resume: bool) -> dict:
        from dialfred_performer.prepare import PrepareConfig, prepare
        return prepare(PrepareConfig(**self.plan.demos_config()))

    def performer(self, resume: bool) -> dict:
        from dialfred_performer.model import PerformerConfig
        from dialfred_performer.train import TrainConfig, train
        c = dict(self.plan.performer_config())
        if 'model' in c:
            c['model'] = PerformerConfig(**c['model'])
        resume = resume and (self.plan.performer_dir / 'last.pt').exists()
        if self.cfg.quick:
            c['threads'] = 1
        report = train(TrainConfig(**c, resume=resume))
        return {k: report.get(k) for k in ('finished', 'updates', 'session_seconds', 'val')}

    def dialogues(self, resume: bool) -> dict:
        c = self.plan.dialogues_config()
        env = dict(os.environ)
        if c['dialogue_dir']:
            env['DIALFRED_DIALOGUE_DIR'] = c['dialogue_dir']
        cmd = [sys.executable, str(REPO / 'scripts' / 'annotate_dialogues.py'), '--splits', *c['splits'],
               '--workers', str(c['workers']), '--limit', str(c['limit']),
               '--from-demonstrations', c['demonstrations'], '--doc', str(self.cfg.run_dir / 'dialogue_data.md')]
        done = subprocess.run(cmd, env=env, cwd=REPO, stdout=subprocess.PIPE, text=True)
        if done.returncode:
            raise RuntimeError(f'{shlex.join(cmd)} exited with {done.returncode}')
        first = json.loads(done.stdout.splitlines()[0])
        return {k: first.get(k) for k in ('split', 'path', 'seconds', 'tasks') if k in first}

    def frames(self, resume: bool) -> dict:
        from dialfred_questioner.frames import build_first_frames
        c = self.plan.frames_config()
        path = build_first_frames(c['split'], c['resolution'], Path(c['out']), limit=c['limit'],
                                  progress=self.cfg.progress, demonstrations=Path(c['demonstrations']))
        return {'path': str(path)}

    def with_dialogues_env(self, fn):
        d = self.plan.dialogue_dir
        if d is None:
            return fn()
        from dialfred_oracle.annotator import DIALOGUE_CACHE_ENV
        old = os.environ.get(DIALOGUE_CACHE_ENV)
        os.environ[DIALOGUE_CACHE_ENV] = str(d)
        try:
            return fn()
        finally:
            if old is None:
                os.environ.pop(DIALOGUE_CACHE_ENV, None)
            else:
                os.environ[DIALOGUE_CACHE_ENV] = old

    def pretrain(self, resume: bool) -> dict:
        from dialfred_questioner.model import QuestionerConfig
        from dialfred_questioner.pretrain import PretrainConfig, pretrain
        c = dict(self.plan.pretrain_config())
        if 'model' in c:
            c['model'] = QuestionerConfig(**c['model'])
        resume = resume and (self.plan.pretrain_dir / 'last.pt').exists()
        report = self.with_dialogues_env(lambda: pretrain(PretrainConfig(**c, resume=resume)))
        return {k: v for k, v in report.items() if isinstance(v, (int, float, str))}

    def rl(self, resume: bool) -> dict:
        from dialfred_questioner.finetune import FinetuneConfig, finetune
        out = {}
        for name in RL_RUNS:
            c = self.plan.rl_config(name)
            folder = Path(c['out'])
            if (folder / 'final.pt').exists() and resume:
                self.log(f'rl: {name} done before the cut-off')
                continue
            t0 = time.monotonic()
            report = finetune(FinetuneConfig(**c, resume=resume and (folder / 'last.pt').exists()))
            out[name] = {'sr': report.get('sr'), 'nq': report.get('nq'), 'seconds': round(time.monotonic() - t0, 1)}
            self.log(f'rl: {name} in {out[name]["seconds"]:.1f} s (last update: SR {report.get("sr")}, '
                     f'NQ {report.get("nq")})')
        return out

    def eval(self, resume: bool) -> dict:
        from dialfred_bringup.baselines import run_baseline
        self.plan.eval_dir.mkdir(parents=True, exist_ok=True)
        out = {}
        for s in settings():
            if not self.plan.available(s):
                self.log(f'eval: {s.split} {s.key}: no questioner checkpoint, left out')
                continue
            config = self.plan.eval_config(s)
            t0 = time.monotonic()
            run_baseline(config, self.cfg.progress)     # run_eval, and its wall time in <results>.runs.jsonl
            out[f'{s.split}/{s.key}'] = round(time.monotonic() - t0, 1)
            self.log(f'eval: {s.split} {s.key} in {out[f"{s.split}/{s.key}"]:.1f} s')
        return {'seconds': out}

    def check(self, resume: bool) -> dict:
        """Play the first tasks of every setting through the graph; compare with the eval stage's episodes."""
        from dialfred_bringup.baselines import run_baseline

        from dialfred_bringup.evaluation import resumable_results
        from dialfred_sim.metrics import write_text_atomically
        from dialfred_sim.tasks import load_split
        p = self.plan
        p.check_dir.mkdir(parents=True, exist_ok=True)
        report = {'tasks': p.check_tasks, 'eval_path': p.eval_path, 'settings': {}}
        for s in p.check_settings():
            config = p.eval_config(s, check=True)
            t0 = time.monotonic()
            run_baseline(config, self.cfg.progress)
            ids = [t.task_id for t in load_split(s.split)[:config.limit]]
            graph = resumable_results(config, ids)
            tables = resumable_results(p.eval_config(s), ids)
            differing = [i for i in ids if i not in tables or
                         dataclasses.replace(graph[i], wall_s=0.0) != dataclasses.replace(tables[i], wall_s=0.0)]
            report['settings'][f'{s.split}/{s.key}'] = {'episodes': len(ids), 'differing': differing,
                                                        'seconds': round(time.monotonic() - t0, 1)}
            self.log(f'check: {s.split} {s.key}: {len(ids) - len(differing)} of {len(ids)} episodes the same '
                     'through the graph')
        write_text_atomically(p.check_dir / 'report.json', json.dumps(report, indent=1) + '\n')
        return {'episodes': sum(r['episodes'] for r in report['settings'].values()),
                'differing': sum(len(r['differing']) for r in report['settings'].values())}

    def doc(self, resume: bool) -> dict:
        report = build_report(self.plan, self.cfg.resamples)
        paths = write_outputs(self.plan, report)
        return {'doc': str(paths[0]), 'plot': str(paths[1]), 'sha256': sha256_of(paths[0].read_bytes())}

    def outputs(self, stage: str) -> list[Path]:
        p = self.plan
        return {
            'demos': [], 'dialogues': [], 'frames': [],          # caches: rewritten in place (same bytes)
            'performer': [p.performer_dir], 'pretrain': [p.pretrain_dir],
            'rl': [p.run / 'questioner' / name for name in RL_RUNS], 'eval': [p.eval_dir], 'check': [p.check_dir],
            'doc': [p.run / 'results.md', p.run / 'sr_nq.png'],
        }[stage]

    def run(self) -> dict:
        self.cfg.run_dir.mkdir(parents=True, exist_ok=True)
        t0 = time.monotonic()
        for stage in STAGES:
            if self.cfg.shipped and stage in TRAINING:
                self.log(f'{stage}: skipped (--shipped)')
                self.summary[stage] = {'status': 'shipped', 'seconds': 0.0}
            else:
                self.run_stage(stage, getattr(self, stage), self.outputs(stage))
            if stage == self.cfg.until:
                break
        target = self.cfg.doc_target if 'doc' in self.summary else None
        if target is not None:
            target.parent.mkdir(parents=True, exist_ok=True)
            copy_doc(self.plan.run, target)
        return {'run': str(self.cfg.run_dir), 'quick': self.cfg.quick, 'shipped': self.cfg.shipped,
                'stages': self.summary, 'seconds': round(time.monotonic() - t0, 1),
                'doc': str(self.plan.run / 'results.md'), 'copied_to': str(target) if target else None}


# --------------------------------------------------------------------------------------------- the report

def setting_row(plan: Plan, s: Setting, resamples: int) -> dict:
    """The numbers of one setting from its results file (n = 0 when it has none)."""
    from dialfred_bringup.evaluation import resumable_results
    from dialfred_sim.metrics import intervals, summarize
    from dialfred_sim.tasks import load_split
    if not plan.available(s) or not (plan.eval_dir / f'{s.split}_{s.key}.jsonl').exists():
        return {'n': 0}
    config = plan.eval_config(s)
    tasks = load_split(s.split)[:config.limit]
    done = resumable_results(config, [t.task_id for t in tasks])
    results = [done[t.task_id] for t in tasks if t.task_id in done]
    if not results:
        return {'n': 0}
    overall = summarize(results)['overall']
    ci = intervals(results, resamples=resamples, seed=config.seed)
    counts = {t: sum(r.question_types.get(t, 0) for r in results) for t in QUESTION_TYPES}
    recorded = sum(len(r.dialogue) for r in results)
    total = sum(r.questions for r in results)
    shares = ({t: counts[t] / recorded for t in QUESTION_TYPES} if recorded else
              ({t: 0.0 for t in QUESTION_TYPES} if total == 0 else None))
    asked = [[(qa['type'], qa['noun']) for qa in r.dialogue] for r in results]
    repeats = sum(len(a) - len(set(a)) for a in asked)
    from dialfred_questioner.rl import Rewards
    returns = {name: sum(rewards.of_episode(r.success, r.steps, r.questions, r.invalid_questions) for r in results)
               / len(results) for name, rewards in (('return', Rewards()), ('return_fixed_1', Rewards.fixed_1()))}
    return {'n': len(results), 'tasks': len(tasks), 'repeats': round(repeats / recorded, 3) if recorded else 0.0,
            'steps': round(sum(r.steps for r in results) / len(results), 2),
            **{k: round(v, 4) for k, v in returns.items()},
            **{k: round(overall[k], 2 if k != 'NQ' else 3) for k in ('SR', 'PWSR', 'GC', 'NQ')},
            'CI95': {k: [round(lo, 2 if k != 'NQ' else 3), round(hi, 2 if k != 'NQ' else 3)]
                     for k, (lo, hi) in ci.items()},
            'shares': {t: round(v, 3) for t, v in shares.items()} if shares is not None else None,
            'results': results}


def build_report(plan: Plan, resamples: int) -> dict:
    rows = {(s.split, s.key): setting_row(plan, s, resamples) for s in settings()}
    return {'rows': rows, 'plan': plan}


def _v(row: dict, key: str) -> str:
    if not row.get('n'):
        return 'no results'
    d = 2 if key == 'NQ' else 1
    lo, hi = row['CI95'][key]
    return f'{row[key]:.{d}f} [{lo:.{d}f}, {hi:.{d}f}]'


def _n(row: dict) -> str:
    if not row.get('n'):
        return '0'
    return f'{row["n"]}' if row['n'] == row['tasks'] else f'{row["n"]} of {row["tasks"]}'


def _share(row: dict, t: str) -> str:
    if not row.get('n'):
        return 'no results'
    return 'not recorded' if row['shares'] is None else f'{row["shares"][t]:.2f}'


def most_asked(rows: dict, top: int = 10) -> list[tuple[str, int]]:
    from collections import Counter
    c = Counter()
    for split in SPLITS:
        for r in rows[(split, 'rl_anytime')].get('results', []):
            for qa in r.dialogue:
                c[f'{qa["type"]} {qa["noun"]}'.strip()] += 1
    return sorted(c.items(), key=lambda kv: (-kv[1], kv[0]))[:top]


def turned_around(rows: dict, count: int = 5) -> list[tuple]:
    """Tasks failed by the performer alone (instruction only) and succeeded with RL anytime's questions."""
    from dialfred_sim.tasks import load_split
    out = []
    for split in SPLITS:
        base = {r.task_id: r for r in rows[(split, 'instruction_only')].get('results', [])}
        tasks = {t.task_id: t for t in load_split(split)}
        for r in rows[(split, 'rl_anytime')].get('results', []):
            b = base.get(r.task_id)
            if b is not None and not b.success and r.success and r.dialogue:
                out.append((tasks[r.task_id], b, r))
    return out[:count]


def what_holds(rows: dict) -> list[str]:
    u = lambda key: rows[('valid_unseen', key)]
    lines = []

    def have(*keys):
        return all(u(k).get('n') for k in keys)

    def verdict(ok: bool) -> str:
        return '**holds**' if ok else '**does not hold**'

    if have('rl_anytime', 'all_qas'):
        rl, allq = u('rl_anytime'), u('all_qas')
        ok = rl['SR'] >= allq['SR'] and rl['NQ'] <= allq['NQ'] / 4
        lines.append(f'RL anytime matches All QAs with a quarter of the questions (valid_unseen SR {rl["SR"]:.1f} >= '
                     f'{allq["SR"]:.1f}, NQ {rl["NQ"]:.2f} <= {allq["NQ"]:.2f} / 4 = {allq["NQ"] / 4:.2f}; paper 33.6 vs '
                     f'32.0 SR, NQ 0.71 vs 3.24): {verdict(ok)}.')
    for split in SPLITS:
        rl, rnd = rows[(split, 'rl_anytime')], rows[(split, 'random_qa')]
        if rl.get('n') and rnd.get('n'):
            p = PAPER_T2
            lines.append(f'RL anytime beats Random QA on {split} (SR {rl["SR"]:.1f} vs {rnd["SR"]:.1f}, 95% '
                         f'[{rl["CI95"]["SR"][0]:.1f}, {rl["CI95"]["SR"][1]:.1f}] vs [{rnd["CI95"]["SR"][0]:.1f}, '
                         f'{rnd["CI95"]["SR"][1]:.1f}]; paper {p["rl_anytime"]["SR"][split]} vs '
                         f'{p["random_qa"]["SR"][split]}): {verdict(rl["SR"] > rnd["SR"])}.')
    drops = {}
    for kind, base in (('rl_anytime', 'rl_anytime'), ('random_qa', 'random_qa')):
        if have(base, *(f'{kind}_withhold_{t}' for t in QUESTION_TYPES)):
            drops[kind] = {t: u(base)['SR'] - u(f'{kind}_withhold_{t}')['SR'] for t in QUESTION_TYPES}
    for kind, name in (('rl_anytime', 'RL anytime'), ('random_qa', 'Random')):
        if kind in drops:
            d = drops[kind]
            ok = d['location'] > d['appearance'] and d['location'] > d['direction']
            lines.append(f'Withholding location answers hurts {name} more than appearance or direction (SR drop '
                         f'{d["location"]:+.1f} vs {d["appearance"]:+.1f} and {d["direction"]:+.1f} points; paper '
                         f'{"1.4 vs 1.2 and 0.6" if kind == "rl_anytime" else "2.4 vs 2.3 and 2.2"}): {verdict(ok)}.')
    base = u('rl_anytime')
    if base.get('n') and base['shares'] is not None:
        for t in QUESTION_TYPES:
            w = u(f'rl_anytime_withhold_{t}')
            if w.get('n') and w['shares'] is not None:
                ok = w['shares'][t] < base['shares'][t]
                paper = PAPER_T3[f'rl_anytime_withhold_{t}'][4][QUESTION_TYPES.index(t)]
                lines.append(f'RL trained with {t} answers withheld asks fewer {t} questions (share {w["shares"][t]:.2f} '
                             f'vs {base["shares"][t]:.2f} unperturbed; paper {paper:.2f} vs '
                             f'{PAPER_T3["rl_anytime"][4][QUESTION_TYPES.index(t)]:.2f}): {verdict(ok)}.')
    if 'rl_anytime' in drops and 'random_qa' in drops:
        rl = sum(drops['rl_anytime'].values()) / 3
        rnd = sum(drops['random_qa'].values()) / 3
        lines.append(f'Under a perturbed oracle RL loses less SR than Random (mean drop over the three types '
                     f'{rl:+.1f} vs {rnd:+.1f} points; paper +0.9 vs +2.3): {verdict(rl < rnd)}.')
    for split in SPLITS:      # beyond the paper: the objective RL maximises, against its start (both ask at the start)
        rl, start = rows[(split, 'rl_begin')], rows[(split, 'pretrained')]
        if rl.get('n') and start.get('n') and rl['n'] == start['n']:
            lo, hi = paired_interval(rl['results'], start['results'])
            lines.append(f'(Beyond the paper) RL begin raises the return it maximises over its pre-trained start, both '
                         f'asking at the start, on {split} (return {rl["return"]:+.4f} vs {start["return"]:+.4f}, '
                         f'difference 95% [{lo:+.4f}, {hi:+.4f}] over the same tasks; SR {rl["SR"]:.1f} vs '
                         f'{start["SR"]:.1f}, NQ {rl["NQ"]:.2f} vs {start["NQ"]:.2f}): '
                         + ('**holds**' if lo > 0 else '**not shown** (the interval includes 0)' if hi > 0
                            else '**does not hold**') + '.')
    return lines


def sampled_mix(run_dir: Path, last: int = 8) -> Optional[dict]:
    """The question-type mix an RL run sampled over its last `last` updates (its metrics.jsonl), weighting
    each update by its questions; None when the run's training log is not there (shipped checkpoints)."""
    path = run_dir / 'metrics.jsonl'
    try:
        records = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    except (OSError, ValueError):
        return None
    records = [r for r in records if r.get('mix')][-last:]
    weights = [r.get('nq', 0.0) * r.get('episodes', 0) for r in records]
    if not records or not sum(weights):
        return None
    return {t: sum(w * r['mix'].get(t, 0.0) for w, r in zip(weights, records)) / sum(weights) for t in QUESTION_TYPES}


def why_lines(plan: Plan, rows: dict) -> list[str]:
    """What the numbers say about why the paper's findings hold or not here: the worth of a question
    against the rewards' price, greedy against sampled question mixes, what RL does when answers are
    withheld. Every figure is computed from the rows or the RL runs' training logs."""
    from dialfred_questioner.rl import Rewards
    rewards, lines = Rewards(), []
    price = -rewards.question / rewards.success * 100           # SR points a question must buy to pay for itself

    def row(split, key):
        return rows.get((split, key), {})

    for split in SPLITS:
        alone, allq, pre = row(split, 'instruction_only'), row(split, 'all_qas'), row(split, 'pretrained')
        if not (alone.get('n') and allq.get('n') and allq['NQ']):
            continue
        worth = (allq['SR'] - alone['SR']) / allq['NQ']
        p_alone, p_all = PAPER_T2['instruction_only'], PAPER_T2['all_qas']
        paper_worth = (p_all['SR'][split] - p_alone['SR'][split]) / p_all['NQ']
        text = (f'The worth of a question on {split}: All QAs\' answers raise SR by {worth:.1f} points per question over '
                f'instruction only ({allq["SR"]:.1f} vs {alone["SR"]:.1f} with {allq["NQ"]:.2f} questions; the paper\'s '
                f'performer: {paper_worth:.1f}). Under the paper\'s rewards a question pays for itself only if it buys '
                f'more than {price:.1f} SR points (its {rewards.question:+.2f} against success {rewards.success:+.0f}; '
                f'steps aside), so asking everything {"loses" if worth < price else "earns"} return here '
                f'(All QAs {allq["return"]:+.4f} vs instruction only {alone["return"]:+.4f})')
        if pre.get('n') and pre['NQ']:
            text += (f'; the pre-trained questioner\'s questions at the start buy {(pre["SR"] - alone["SR"]) / pre["NQ"]:.1f} '
                     f'points each ({pre["NQ"]:.2f} per episode)')
        lines.append(text + ('. RL maximises that return, so with answers worth less than their price it learns to ask '
                             'few questions, and its SR stays near those few questions\' SR rather than All QAs\'.'
                             if worth < price else '. Here answers are worth their price, so RL has reason to ask.'))
    mixes = {}
    for key in ('rl_anytime', *(f'rl_anytime_withhold_{t}' for t in QUESTION_TYPES)):
        if not plan.cfg.shipped:
            mix = sampled_mix(plan.run / 'questioner' / key)
            if mix is not None:
                mixes[key] = mix
    greedy = row('valid_unseen', 'rl_anytime').get('shares')
    if greedy:
        fmt = lambda m: ' / '.join(f'{m[t]:.2f}' for t in QUESTION_TYPES)
        text = (f'Question mix: the evaluation plays each questioner greedily, asking the type its policy ranks first; '
                f'RL anytime\'s greedy shares on valid_unseen are {fmt(greedy)} (location / appearance / direction)')
        if 'rl_anytime' in mixes:
            text += f', while sampling in training (its last 8 updates) it asked {fmt(mixes["rl_anytime"])}'
            moved = [f'{t} withheld: {fmt(mixes[f"rl_anytime_withhold_{t}"])} (its {t} share '
                     f'{mixes[f"rl_anytime_withhold_{t}"][t] - mixes["rl_anytime"][t]:+.2f})'
                     for t in QUESTION_TYPES if f'rl_anytime_withhold_{t}' in mixes]
            if moved:
                text += '; sampled mixes of the runs trained with one type withheld: ' + '; '.join(moved)
        else:
            text += ' (the RL runs\' training logs are not in this run folder: no sampled mixes)'
        lines.append(text + '. A shift of the sampled mix that leaves the first-ranked type in place does not show '
                     'in the greedy shares of Table III.')
    base, loc = row('valid_unseen', 'rl_anytime'), row('valid_unseen', 'rl_anytime_withhold_location')
    if base.get('n') and loc.get('n'):
        lines.append(f'With location answers withheld half the time, RL trained that way asks {loc["NQ"]:.2f} questions '
                     f'per episode against {base["NQ"]:.2f} unperturbed, and {loc["repeats"]:.3f} of its questions '
                     f'repeat one already asked (unperturbed {base["repeats"]:.3f}): '
                     + ('it asks the withheld type again until it is answered rather than switching type.'
                        if loc['NQ'] > base['NQ'] and loc['repeats'] > base['repeats'] else
                        'it does not ask the withheld type again more often.'))
    return lines


def paired_interval(a: list, b: list, resamples: int = 2000, seed: int = 0) -> tuple[float, float]:
    """95% bootstrap interval of the mean paired difference of the paper's return, a - b (results of the
    same tasks, in the same order)."""
    import numpy as np

    from dialfred_questioner.rl import Rewards
    ret = lambda r: Rewards().of_episode(r.success, r.steps, r.questions, r.invalid_questions)
    d = np.array([ret(x) - ret(y) for x, y in zip(a, b)])
    rng = np.random.default_rng(seed)
    means = d[rng.integers(0, len(d), size=(resamples, len(d)))].mean(axis=1)
    return float(np.quantile(means, 0.025)), float(np.quantile(means, 0.975))


def draw_frontier(points: list[tuple[str, float, float]], out_path: Path) -> Path:
    """SR against NQ, one labelled dot per setting (Pillow; the style of dialfred_performer.curves)."""
    from PIL import Image, ImageDraw, ImageFont

    from dialfred_performer.curves import _ticks
    font = ImageFont.load_default()
    legend = [f'{label} ({sr:.1f}, {nq:.2f})' for label, sr, nq in points]
    probe = ImageDraw.Draw(Image.new('RGB', (1, 1)))
    R = 48 + int(max([probe.textlength(t, font=font) for t in legend] + [100]))     # the legend fits, always
    W, H, (L, T, B) = 520 + R, max(480, 40 + 14 * len(points)), (56, 30, 40)
    image = Image.new('RGB', (W, H), 'white')
    draw = ImageDraw.Draw(image)
    title = 'SR (valid_unseen) against questions per episode (NQ)'
    draw.text((W // 2 - len(title) * 3, 8), title, fill='black', font=font)
    left, top, right, bottom = L, T, W - R, H - B
    draw.rectangle((left, top, right, bottom), outline=(160, 160, 160))
    x_hi = max([p[2] for p in points] + [1.0]) * 1.08
    y_hi = max([p[1] for p in points] + [10.0]) * 1.1

    def at(x, y):
        return left + x / x_hi * (right - left), bottom - y / y_hi * (bottom - top)

    for y in _ticks(0.0, y_hi):
        _, py = at(0, y)
        draw.line((left, py, right, py), fill=(230, 230, 230))
        draw.text((4, py - 6), f'{y:.3g}', fill='black', font=font)
    for x in _ticks(0.0, x_hi):
        px, _ = at(x, 0)
        draw.text((px - 8, bottom + 4), f'{x:g}', fill='black', font=font)
    draw.text((right - 60, bottom + 18), 'NQ', fill='black', font=font)
    draw.text((4, top - 18), 'SR %', fill='black', font=font)
    palette = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
               (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207)]
    frontier, best = [], -1.0
    for _label, sr, nq in sorted(points, key=lambda p: (p[2], -p[1])):
        if sr > best:
            frontier.append(at(nq, sr))
            best = sr
    if len(frontier) > 1:
        draw.line(frontier, fill=(200, 200, 200), width=2)
    def mark(shape: int, x: float, y: float, colour) -> None:
        """Colours repeat after 10 settings; each round of them gets another shape, so no two settings look alike."""
        box = (x - 4, y - 4, x + 4, y + 4)
        if shape == 0:
            draw.ellipse(box, fill=colour)
        elif shape == 1:
            draw.rectangle(box, fill=colour)
        elif shape == 2:
            draw.polygon([(x, y - 5), (x - 5, y + 4), (x + 5, y + 4)], fill=colour)
        else:
            draw.polygon([(x, y - 5), (x + 5, y), (x, y + 5), (x - 5, y)], fill=colour)

    for k, (_label, sr, nq) in enumerate(points):
        colour, shape = palette[k % len(palette)], (k // len(palette)) % 4
        mark(shape, *at(nq, sr), colour)
        y = top + 14 * k
        mark(shape, right + 16, y + 6, colour)
        draw.text((right + 26, y), legend[k], fill='black', font=font)
    out_path = Path(out_path)
    image.save(out_path)
    return out_path


def _relative(path: Path) -> str:
    try:
        return str(Path(path).resolve().relative_to(REPO))
    except ValueError:
        return str(path)


def check_line(plan: Plan) -> str:
    """What the check stage found: the settings' first tasks through the graph against the tables' episodes."""
    path = plan.check_dir / 'report.json'
    if not plan.check_tasks or not path.exists():
        return '- check through the ROS graph: not run (`--check-tasks 0`)'
    report = json.loads(path.read_text())
    rows = report['settings']
    episodes = sum(r['episodes'] for r in rows.values())
    bad = {k: r['differing'] for k, r in rows.items() if r['differing']}
    head = (f'- check through the ROS graph (performer, questioner, oracle and simulator nodes): the first '
            f'{report["tasks"]} tasks of {len(rows)} settings, {episodes} episodes: ')
    if not bad:
        return head + 'every one the same as the tables\' episodes (steps, success, questions, dialogue, end)'
    return head + f'**{sum(map(len, bad.values()))} differ** ' + '; '.join(
        f'{k}: {", ".join(v[:5])}' for k, v in sorted(bad.items()))


def render(plan: Plan, report: dict, plot_name: str) -> str:
    from dialfred_sim.protocol import question_text
    rows, cfg = report['rows'], plan.cfg
    mode = '--quick' if cfg.quick else '--shipped' if cfg.shipped else ''
    command = './dialfred reproduce' + (f' {mode}' if mode else '')
    through = {'local': 'in local worker processes without ROS (`dialfred_bringup.local`, the graph\'s episodes)',
               'graph': 'through the ROS graph (performer nodes)',
               'in-process': 'by the agent in the launcher\'s process with simulator and oracle nodes'}[plan.eval_path]
    out = [
        '# Results: the paper\'s Tables II, III and IV reproduced',
        '',
        f'<!-- Generated file: written by `{command}` (dialfred_bringup/reproduce.py). Do not edit by hand; rerun it. -->',
        f'Generated by `{command}` (`dialfred_bringup/reproduce.py`) from the results files in `{_relative(plan.eval_dir)}/`; '
        'every number here is computed from them.',
        '',
    ]
    if cfg.quick:
        out += ['**Quick run**: tiny slices of every stage (32 train tasks, a tiny performer and questioner, 2 RL '
                'updates of 8 episodes); these numbers check the pipeline and mean nothing.', '']
    perf = plan.performer_checkpoint
    out += ['## Settings', '',
            f'- performer: `{_relative(perf)}` (weights sha256 `{weights_sha256(perf)[:16]}`...: a digest of its '
            'tensors, the same wherever the same model is trained; the file itself also records its command and commit)'
            if perf.exists()
            else f'- performer: `{_relative(perf)}` (absent)',
            '- questioners: ' + ('the shipped checkpoints in `' + _relative(SHIPPED_QUESTIONERS) + '/`' if cfg.shipped
                                 else f'fine-tuned by the rl stage in `{_relative(plan.run / "questioner")}/`') +
            ', played greedily',
            f'- evaluation: `et` performer at {RESOLUTION} px, played {through}, seed {cfg.seed}, '
            + (f'the first {plan.eval_limit} tasks of each split' if plan.eval_limit else 'every task of each split')
            + f'; perturbed oracle: one type\'s answers withheld with probability {PERTURB_PROBABILITY}',
            check_line(plan),
            f'- intervals: 95% percentile bootstrap over episodes, {cfg.resamples} resamples '
            '(`dialfred_sim.metrics.intervals`); SR and PWSR in percent, NQ questions per episode', '']
    # Table II
    out += ['## Table II: baselines', '',
            '| # | setting | split | n | SR [95%] | paper SR | PWSR [95%] | paper PWSR | NQ [95%] | paper NQ |',
            '|---|---|---|---|---|---|---|---|---|---|']
    for key, p in PAPER_T2.items():
        for split in SPLITS:
            r = rows[(split, key)]
            out.append(f'| {p["number"]} | {p["name"]} | {split} | {_n(r)} | {_v(r, "SR")} | {p["SR"][split]} | '
                       f'{_v(r, "PWSR")} | {p["PWSR"][split]} | {_v(r, "NQ")} | {p["NQ"]} |')
    # Table III
    out += ['', '## Table III: the oracle withholding 50% of one type\'s answers (valid_unseen)', '',
            'RL rows: questioners fine-tuned with the same perturbed oracle they are evaluated with; Random: the '
            '`random` baseline. Shares: of the questions asked, those of each type (from the results\' dialogues).',
            '',
            '| setting | n | SR [95%] | paper SR | PWSR [95%] | paper PWSR | NQ [95%] | paper NQ '
            '| location | appearance | direction | paper shares (loc / app / dir) |',
            '|---|---|---|---|---|---|---|---|---|---|---|---|']
    for key, (name, sr, pwsr, nq, shares) in PAPER_T3.items():
        r = rows[('valid_unseen', key)]
        out.append(f'| {name} | {_n(r)} | {_v(r, "SR")} | {sr} | {_v(r, "PWSR")} | {pwsr} | {_v(r, "NQ")} | {nq} | '
                   + ' | '.join(_share(r, t) for t in QUESTION_TYPES) + ' | ' + ' / '.join(f'{v:.2f}' for v in shares)
                   + ' |')
    # Table IV
    out += ['', '## Table IV: question timing (valid_unseen)', '',
            'Fixed N: the questioner may ask every N performer steps (Fixed 1 with the paper\'s question-promoting '
            'rewards, `--rewards fixed_1`); MC: when the performer is confused (top-2 action probabilities within '
            'epsilon).', '',
            '| setting | n | SR [95%] | paper SR | PWSR [95%] | paper PWSR | NQ [95%] | paper NQ |',
            '|---|---|---|---|---|---|---|---|']
    for key, (name, sr, pwsr, nq) in PAPER_T4.items():
        r = rows[('valid_unseen', key)]
        out.append(f'| {name} | {_n(r)} | {_v(r, "SR")} | {sr} | {_v(r, "PWSR")} | {pwsr} | {_v(r, "NQ")} | {nq} |')
    # beyond the paper
    out += ['', '## Beyond the paper: the pre-trained questioner, and reading the dialogue (valid_unseen)', '',
            'The pre-trained questioner before any RL (greedy, at the start, as its annotators asked), and RL anytime '
            'fine-tuned the same way with the original questioner\'s input (the instruction only, never the dialogue '
            'so far). Repeats: the share of questions that repeat one already asked in the episode.', '',
            '| setting | n | SR [95%] | PWSR [95%] | NQ [95%] | repeats | location | appearance | direction |',
            '|---|---|---|---|---|---|---|---|---|']
    for key, name in EXTRA.items():
        r = rows[('valid_unseen', key)]
        out.append(f'| {name} | {_n(r)} | {_v(r, "SR")} | {_v(r, "PWSR")} | {_v(r, "NQ")} | '
                   f'{r["repeats"]:.3f} | ' if r.get('n') else f'| {name} | 0 | no results | | | | ')
        if r.get('n'):
            out[-1] += ' | '.join(_share(r, t) for t in QUESTION_TYPES) + ' |'
        else:
            out[-1] += ' | | |'
    # what RL optimizes
    out += ['', '## What RL optimizes: the return under the paper\'s rewards', '',
            'The mean undiscounted episode return, success +1, each performer step -0.01, each question -0.05, each '
            'unanswerable question -0.1 more (the Fixed-1 column: -0.002 and -0.01), computed from the same results. '
            'RL maximises this on valid_seen; SR is only part of it.', '',
            '| setting | split | n | SR | NQ | steps | return | return (Fixed-1 rewards) |',
            '|---|---|---|---|---|---|---|---|']
    for split in SPLITS:
        for key in RETURN_ROWS:
            r = rows.get((split, key), {})
            if r.get('n'):
                out.append(f'| {setting_name(key)} | {split} | {r["n"]} | {r["SR"]:.1f} | {r["NQ"]:.2f} | '
                           f'{r["steps"]:.1f} | {r["return"]:+.4f} | {r["return_fixed_1"]:+.4f} |')
    # plot
    out += ['', '## Cost and benefit: SR against NQ', '',
            f'![SR against NQ, every setting on valid_unseen]({plot_name})', '',
            'Every setting on valid_unseen; the grey line joins the settings no other beats with fewer questions.', '']
    # what holds
    out += ['## What holds', '', 'Computed from the tables above; the paper\'s numbers in brackets.', '']
    out += [f'- {line}' for line in what_holds(rows)] or ['- not enough results yet']
    why = why_lines(plan, rows)
    if why:
        out += ['', '## Why, as far as the numbers say', '',
                'Computed from the tables above and, for the sampled mixes, the RL runs\' training logs '
                '(`questioner/<run>/metrics.jsonl`).', '']
        out += [f'- {line}' for line in why]
    # questions
    out += ['', '## The questions RL anytime asks most (both splits)', '']
    asked = most_asked(rows)
    if asked:
        out += ['| question | times |', '|---|---|']
        for q, k in asked:
            kind, _, noun = q.partition(' ')
            out.append(f'| {question_text(kind, noun)} | {k} |')
    else:
        out.append('No questions recorded.')
    out += ['', '## Dialogues that turned a failure into a success', '',
            'Tasks the performer failed alone (instruction only) and finished with RL anytime\'s questions '
            '(same task, same seed).', '']
    examples = turned_around(rows)
    if not examples:
        out.append('None among the results.')
    for task, base, r in examples:
        out += [f'- `{task.task_id}` ({task.task_type}): "{task.instruction}"; alone: {base.end_reason} after '
                f'{base.steps} steps; with questions: success in {r.steps} steps']
        for qa in r.dialogue:
            answer = qa['answer'] if qa['valid'] else '(no answer)'
            out.append(f'  - Q: {question_text(qa["type"], qa["noun"])} A: {answer}')
    out += ['', '## Run times', '']
    stamps = plan.run / 'stamps'
    total = 0.0
    for stage in STAGES[:-1]:
        try:
            s = json.loads((stamps / f'{stage}.json').read_text())
            total += s.get('seconds', 0)
            runs = s.get('runs', 1)
            out.append(f'- {stage}: {s.get("seconds", 0):.0f} s' + (f' (over {runs} runs: it was resumed)' if runs > 1 else ''))
        except (OSError, ValueError):
            out.append(f'- {stage}: not run here' + (' (shipped)' if cfg.shipped and stage in TRAINING else ''))
    out.append(f'- total of the stages: {total / 60:.1f} min')
    return '\n'.join(out) + '\n'


def setting_name(key: str) -> str:
    """A setting's name in the plot and the returns table (the paper's where it has one)."""
    names = {**{k: p['name'] for k, p in PAPER_T2.items()}, **{k: v[0] for k, v in PAPER_T3.items()},
             **{k: v[0] for k, v in PAPER_T4.items()}, 'pretrained': 'Pre-trained only',
             'rl_anytime_no_dialogue': 'RL anytime, instruction only'}
    return names[key]


def write_outputs(plan: Plan, report: dict) -> tuple[Path, Path]:
    rows = report['rows']
    points = []
    seen = set()
    for s in settings():
        r = rows[(s.split, s.key)]
        if s.split == 'valid_unseen' and r.get('n') and s.key not in seen:
            seen.add(s.key)
            points.append((setting_name(s.key), r['SR'], r['NQ']))
    plot = draw_frontier(points, plan.run / 'sr_nq.png')
    doc = plan.run / 'results.md'
    doc.write_text(render(plan, report, plot.name))
    return doc, plot


def copy_doc(run: Path, target: Path) -> None:
    """Copy the run's results.md to `target` with its plot beside it: sr_nq.png next to a results.md,
    <stem>_sr_nq.png (the link rewritten) next to a doc of another name, so that two documents (a full
    run's and the shipped checkpoints') can share a folder."""
    text = (run / 'results.md').read_text()
    plot = 'sr_nq.png' if target.name == 'results.md' else f'{target.stem}_sr_nq.png'
    text = text.replace('](sr_nq.png)', f']({plot})')
    shutil.copyfile(run / 'sr_nq.png', target.with_name(plot))
    target.write_text(text)


def main(argv: Optional[list[str]] = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    cfg = parse(ReproduceConfig, argv, prog='./dialfred reproduce')
    try:
        summary = Runner(cfg).run()
    except (FileNotFoundError, ValueError, RuntimeError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    print(json.dumps(summary))
    return 0


if __name__ == '__main__':
    sys.exit(main())
