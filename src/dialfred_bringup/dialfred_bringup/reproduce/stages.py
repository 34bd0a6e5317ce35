"""The stages of `./dialfred reproduce`, each stamped with the hash of its inputs and resumable."""

from __future__ import annotations

import ast
import contextlib
import dataclasses
import hashlib
import json
import os
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable, Optional

from dialfred_oracle.annotator import DIALOGUE_CACHE_ENV
from dialfred_performer.model import PerformerConfig
from dialfred_performer.model_registry import PERFORMER_MODELS
from dialfred_performer.perception import PerceptionConfig, train_perception
from dialfred_performer.prepare import PrepareConfig, prepare
from dialfred_questioner.finetune import FinetuneConfig, finetune
from dialfred_questioner.frames import build_first_frames
from dialfred_questioner.model import QuestionerConfig
from dialfred_questioner.pretrain import PretrainConfig, pretrain
from dialfred_sim.metrics import write_text_atomically, same_episode
from dialfred_sim.tasks import load_split

from ..baseline_runs import run_baseline
from ..eval_config import config_inputs
from ..evaluation import EvalRun, resumable_results
from ..machine import machine, speed_probe
from ..paths import REPO
from .document import (build_report, copy_doc, write_outputs)
from .plan import (TRAINING, sha256_of, Plan, RL_RUNS, ReproduceConfig, SHIPPED_RUN, STAGES, chained_settings, settings)


# --------------------------------------------------------------------------------------------- stages

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


def time_before(old: dict, outputs) -> tuple[float, int]:
    """(seconds, runs) of a cut-off stage or item's earlier runs, from its 'running' stamp: each run lasted
    from its start until its outputs were last written (the newest modification time under them)."""
    cut_off = max(0.0, newest_mtime(outputs) - old.get('started_at', time.time()))
    return old.get('seconds_before', 0.0) + cut_off, old.get('runs', 1) + 1


def clear(paths) -> None:
    """Remove these files and folders (those that exist)."""
    for path in paths:
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()


def set_aside(paths, folder: Path) -> list[Path]:
    """Move these files and folders (those that exist) into `folder`, emptied first: the outputs of a
    finished stage that is about to be redone with other inputs, kept until the next time that stage
    is redone (hours of training are not deleted by a changed line of code). Returns where they went."""
    paths = [p for p in paths if p.exists()]
    if not paths:
        return []
    clear([folder])
    folder.mkdir(parents=True)
    moved = []
    for i, path in enumerate(paths):
        target = folder / (path.name if sum(q.name == path.name for q in paths) == 1 else f'{i}_{path.name}')
        shutil.move(str(path), str(target))
        moved.append(target)
    return moved


def file_sha256(path: Path) -> str:
    """The sha256 of a file's bytes ('absent' if there is none)."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except FileNotFoundError:
        return 'absent'


def python_meaning(source: bytes) -> bytes:
    """What a Python file does, without its comments, docstrings and layout: its syntax tree with the
    docstrings taken out, dumped (the bytes themselves if it does not parse)."""
    try:
        tree = ast.parse(source)
    except (SyntaxError, ValueError):
        return source
    for node in ast.walk(tree):
        body = getattr(node, 'body', None)
        if (isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and body
                and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)):
            node.body = body[1:] or [ast.Pass()]
    return ast.dump(tree).encode()


def code_hash(paths: tuple[str, ...], raw: bool = False) -> str:
    """The sha256 of these files (relative to the repository): of what their Python does (python_meaning),
    so that an edit of comments, docstrings or layout reruns nothing; with `raw`, of their bytes (the
    hash that stamps made before held, still accepted: Runner.known)."""
    h = hashlib.sha256()
    for rel in paths:
        p = REPO / rel
        data = p.read_bytes() if p.exists() else b'(absent)'
        if p.exists() and p.suffix == '.py' and not raw:
            data = python_meaning(data)
        h.update(rel.encode() + b'\0' + data + b'\0')
    return h.hexdigest()


PERF, QUES, SIM = 'src/dialfred_performer/dialfred_performer', 'src/dialfred_questioner/dialfred_questioner', \
    'src/dialfred_sim/dialfred_sim'
UP = 'src/dialfred_bringup/dialfred_bringup'
# What plays each performer model in an episode (the registry's sources): the rl and eval stages' items of
# that model hash it.
MODEL_CODE = {name: model.sources for name, model in PERFORMER_MODELS.items()}
# The learned questioner as it plays (its network, its inputs, its timing and rewards), and as it is trained.
QUESTIONER_CODE = (f'{QUES}/policy.py', f'{QUES}/shipped.py', f'{QUES}/model.py', f'{QUES}/data.py', f'{QUES}/rollout.py', f'{QUES}/rl.py')
RL_CODE = (f'{QUES}/finetune.py', f'{QUES}/checkpoint.py', f'{SIM}/episode.py', *QUESTIONER_CODE)
EVAL_CODE = (f'{UP}/evaluation.py', f'{UP}/workers.py', f'{UP}/local.py', f'{UP}/silent.py', f'{SIM}/episode.py',
             f'{QUES}/baselines.py', f'{QUES}/questioners.py', *QUESTIONER_CODE, f'{SIM}/metrics.py')
# The question types' modules: the annotator's rules of each type are there.
ANNOTATOR_RULES = tuple(f'src/dialfred_oracle/dialfred_oracle/questions/{name}.py'
                        for name in ('base', 'location', 'appearance', 'direction'))
CHAINED_CODE = (*EVAL_CODE, f'{SIM}/chained.py', f'{SIM}/traces.py')
CODE = {
    'demos': (f'{PERF}/prepare.py', f'{PERF}/data.py', f'{SIM}/tasks/demonstrations.py',
              'src/dialfred_oracle/dialfred_oracle/annotator.py', *ANNOTATOR_RULES),
    'perception': (f'{PERF}/perception.py', f'{SIM}/tasks/demonstrations.py'),
    'performer': (f'{PERF}/train.py', f'{PERF}/model.py', f'{PERF}/data.py', f'{PERF}/preprocess.py',
                  f'{PERF}/nn/enc_perceived.py'),
    'dialogues': ('scripts/annotate_dialogues.py', 'src/dialfred_oracle/dialfred_oracle/annotator.py', *ANNOTATOR_RULES),
    'frames': (f'{QUES}/frames.py',),
    'pretrain': (f'{QUES}/pretrain.py', f'{QUES}/checkpoint.py', f'{QUES}/model.py', f'{QUES}/data.py'),
    'rl': (*RL_CODE, *MODEL_CODE['map']),
    'eval': (*EVAL_CODE, *MODEL_CODE['map']),
    'chained': (*CHAINED_CODE, *MODEL_CODE['map']),
    'check': (f'{UP}/evaluation.py', f'{UP}/workers.py', f'{UP}/local.py', f'{UP}/reproduce/stages.py'),
    'doc': (f'{UP}/reproduce/document.py', f'{UP}/reproduce/plan.py', f'{UP}/baseline_runs.py', f'{SIM}/metrics.py',
            f'{PERF}/curves.py'),
}
# The simulator's rules. They are not in the stages' hashes (a change would rerun every stage from the
# demonstrations on); each stamp records their digest instead, and a stage skipped although they changed
# since it ran says so.
WORLD_CODE = ('src/dialfred_sim/dialfred_sim/world', 'src/dialfred_sim/dialfred_sim/actions.py',
              'src/dialfred_sim/dialfred_sim/env.py', 'src/dialfred_sim/dialfred_sim/tasks/expert.py',
              'src/dialfred_sim/dialfred_sim/tasks/goals.py', 'src/dialfred_sim/dialfred_sim/tasks/types.py')


def world_code_hash(raw: bool = False) -> str:
    files = []
    for rel in WORLD_CODE:
        p = REPO / rel
        files += sorted(str(f.relative_to(REPO)) for f in p.rglob('*.py')) if p.is_dir() else [rel]
    return code_hash(tuple(files), raw)


# Stages of many items (RL runs, evaluation settings) stamped one by one (Runner.run_item): a change to the
# stage's inputs reruns the items whose own inputs changed, and reuses the others.
ITEMIZED = ('rl', 'eval', 'chained')
# Stages that fill caches outside the run's folder, shared with other commands: their files are rewritten in
# place (the same inputs give the same bytes), never cleared.
CACHES = ('demos', 'dialogues', 'frames')
UPSTREAM = {
    'demos': (), 'perception': ('demos',), 'performer': ('demos', 'perception'), 'dialogues': ('demos',), 'frames': ('demos',), 'pretrain': ('performer', 'dialogues', 'frames'),
    'rl': ('performer', 'pretrain'), 'eval': ('performer', 'rl'), 'chained': ('performer', 'rl'), 'check': ('eval',),
    'doc': ('eval', 'chained', 'check'),
}


@contextlib.contextmanager
def dialogues_from(folder: Optional[Path]):
    """With `folder` (a quick run's own dialogues) as the annotator's dialogue cache while the block runs;
    None leaves the default cache."""
    if folder is None:
        yield
        return
    old = os.environ.get(DIALOGUE_CACHE_ENV)
    os.environ[DIALOGUE_CACHE_ENV] = str(folder)
    try:
        yield
    finally:
        if old is None:
            os.environ.pop(DIALOGUE_CACHE_ENV, None)
        else:
            os.environ[DIALOGUE_CACHE_ENV] = old


def graph_check(p: Plan, progress: bool, log: Callable[[str], None]) -> dict:
    """The check stage: the first p.check_tasks tasks of every setting played through the graph (performer,
    questioner, oracle and simulator nodes), each episode compared with the eval stage's; check/report.json."""
    p.check_dir.mkdir(parents=True, exist_ok=True)
    report = {'tasks': p.check_tasks, 'eval_path': p.eval_path, 'settings': {}}
    for s in p.check_settings():
        config = p.eval_config(s, check=True)
        t0 = time.monotonic()
        run_baseline(config, progress)
        ids = [t.task_id for t in load_split(s.split)[:config.limit]]
        graph = resumable_results(EvalRun(config, check=False), ids)
        tables = resumable_results(EvalRun(p.eval_config(s), check=False), ids)
        differing = [i for i in ids if i not in tables or not same_episode(graph[i], tables[i])]
        report['settings'][f'{s.split}/{s.key}'] = {'episodes': len(ids), 'differing': differing,
                                                    'seconds': round(time.monotonic() - t0, 1)}
        log(f'check: {s.split} {s.key}: {len(ids) - len(differing)} of {len(ids)} episodes the same '
             'through the graph')
    write_text_atomically(p.check_dir / 'report.json', json.dumps(report, indent=1) + '\n')
    return {'episodes': sum(r['episodes'] for r in report['settings'].values()),
            'differing': sum(len(r['differing']) for r in report['settings'].values())}


class Runner:
    def __init__(self, cfg: ReproduceConfig):
        self.cfg, self.plan = cfg, Plan(cfg)
        self.stamps_dir = cfg.run_dir / 'stamps'
        self.hashes: dict[str, str] = {}
        self.summary: dict[str, dict] = {}
        self.forced = False

    def log(self, text: str) -> None:
        print(f'[reproduce] {text}', file=sys.stderr, flush=True)

    def stage_inputs(self, stage: str, raw: bool = False) -> dict:
        p = self.plan
        config = {
            'demos': p.demos_config, 'perception': p.perception_config, 'performer': p.performer_config, 'dialogues': p.dialogues_config,
            'frames': p.frames_config, 'pretrain': p.pretrain_config,
            'rl': lambda: {name: p.rl_config(name) for name in RL_RUNS},
            'eval': lambda: {'settings': [dataclasses.asdict(s) for s in settings() if p.available(s)],
                             'eval_path': p.eval_path, 'limit': p.eval_limit, 'seed': self.cfg.seed,
                             'performer': str(p.performer_checkpoint),
                             'questioners': {r: str(p.questioner_checkpoint(r)) for r in (*RL_RUNS, 'pretrained')},
                             'shipped': self.shipped_hashes() if self.cfg.shipped else None},
            'chained': lambda: {'settings': [dataclasses.asdict(s) for s in chained_settings() if p.available(s)],
                                'eval_path': p.eval_path, 'limit': p.eval_limit, 'seed': self.cfg.seed,
                                'performer': str(p.performer_checkpoint),
                                'questioners': {r: str(p.questioner_checkpoint(r)) for r in (*RL_RUNS, 'pretrained')},
                                'shipped': self.shipped_hashes() if self.cfg.shipped else None},
            'check': lambda: {'settings': [dataclasses.asdict(s) for s in p.check_settings()],
                              'tasks': p.check_tasks, 'seed': self.cfg.seed},
            'doc': lambda: {'resamples': self.cfg.resamples, 'limit': p.eval_limit,
                            'shipped_run': file_sha256(SHIPPED_RUN) if self.cfg.shipped else None},
        }[stage]()
        return {'stage': stage, 'config': config, 'code': code_hash(CODE[stage], raw),
                'upstream': {u: self.hashes.get(u, 'shipped') for u in UPSTREAM[stage]}}

    def shipped_hashes(self) -> dict:
        files = [self.plan.performer_checkpoint] + [self.plan.questioner_checkpoint(r) for r in (*RL_RUNS, 'pretrained')]
        return {str(f): sha256_of(f.read_bytes()) if f.exists() else None for f in files}

    def discard(self, name: str, outputs: list[Path], old: Optional[dict]) -> None:
        """Clear a stage's (or item's) outputs before it runs afresh; those of a finished one are set aside
        in <run>/replaced/<name>/ instead (the previous set-aside of that name is deleted then)."""
        if old and old.get('status') == 'done':
            moved = set_aside(outputs, self.cfg.run_dir / 'replaced' / name)
            if moved:
                self.log(f'{name}: its inputs changed; the outputs of its finished run are kept in '
                         f'{moved[0].parent} until it is redone again')
            return
        clear(outputs)

    def digest(self, stage: str, inputs: dict, old: Optional[dict]) -> str:
        """The hash `stage` is known by now (its stamp must hold it to be skipped); upstream stages'
        hashes must be in self.hashes first."""
        return self.known(old, sha256_of(inputs), lambda: sha256_of(self.stage_inputs(stage, raw=True)))

    def planned_hashes(self) -> dict[str, str]:
        """{stage: the hash a run would compare with its stamp now}, computed in stage order as `run`
        does, without running or writing anything (`--status` marks a done stage whose stamp differs as
        stale: a run would clear and redo it, and the stages after it)."""
        for stage in STAGES:
            if not (self.cfg.shipped and stage in TRAINING):
                self.hashes[stage] = self.digest(stage, self.stage_inputs(stage), self.read_stamp(stage))
        return dict(self.hashes)

    @staticmethod
    def known(old: Optional[dict], digest: str, raw_digest: Callable[[], str]) -> str:
        """The hash to know a stage or item by: `digest`, or the stamp's own when the stamp was made
        with the byte hash of the same code (raw_digest), so that stamps made before still match."""
        if old and old.get('hash') not in (None, digest) and old.get('hash') == raw_digest():
            return old['hash']
        return digest

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
        record = {**record, 'machine': machine()}      # the seconds, and bit patterns, depend on it
        tmp.write_text(json.dumps(record, indent=1, sort_keys=True) + '\n')
        tmp.replace(self.stamp_path(stage))

    def run_stage(self, stage: str, action: Callable[[bool], dict], outputs: list[Path]) -> None:
        """Skip `stage` if its stamp holds the hash of its inputs, else run `action(resume)`: resume is
        True when the stage was cut off with these same inputs (else its outputs are cleared first)."""
        if self.cfg.force == stage:
            self.forced = True
        inputs = self.stage_inputs(stage)
        old = self.read_stamp(stage)
        digest = self.digest(stage, inputs, old)
        self.hashes[stage] = digest
        world = world_code_hash()
        if old and old.get('hash') == digest and old.get('status') == 'done' and not self.forced:
            self.log(f'{stage}: skipped (stamp matches, {digest[:12]})')
            ran_with = old.get('world_code', world)
            if ran_with != world and ran_with != world_code_hash(raw=True):   # the byte hash: only when needed
                self.log(f'{stage}: warning: the simulator\'s rules (dialfred_sim world/, actions, env, expert, '
                         f'goals) changed since this stage ran; --force {stage} reruns it with them')
            self.summary[stage] = {'status': 'skipped', 'hash': digest, 'seconds': 0.0}
            return
        resume = bool(old and old.get('hash') == digest and old.get('status') == 'running')
        if not resume and stage not in ITEMIZED and stage not in CACHES:
            self.discard(stage, outputs, old)
        why = 'resuming' if resume else ('forced' if self.forced else ('inputs changed' if old else 'no stamp'))
        before, runs = time_before(old, outputs) if resume else (0.0, 1)
        # the machine's speed beside the stage's time: a fixed convolution's seconds at each run's start and end
        probes = [*((old or {}).get('speed_probe_s', []) if resume else []), speed_probe()]
        self.log(f'{stage}: running ({why}, {digest[:12]}; speed probe {probes[-1] * 1000:.1f} ms)')
        self.write_stamp(stage, {'stage': stage, 'hash': digest, 'status': 'running', 'inputs': inputs,
                                 'started_at': time.time(), 'seconds_before': round(before, 1), 'runs': runs,
                                 'speed_probe_s': probes})
        t0 = time.monotonic()
        report = action(resume) or {}
        this_run = time.monotonic() - t0
        seconds = round(before + this_run, 1)
        probes.append(speed_probe())
        self.write_stamp(stage, {'stage': stage, 'hash': digest, 'status': 'done', 'inputs': inputs,
                                 'world_code': world,
                                 'seconds': seconds, 'seconds_this_run': round(this_run, 1), 'runs': runs,
                                 'speed_probe_s': probes, 'report': report})
        self.log(f'{stage}: ran in {this_run:.1f} s' + (f' ({seconds:.1f} s over {runs} runs)' if runs > 1 else '')
                 + f'; speed probe {probes[-1] * 1000:.1f} ms')
        self.summary[stage] = {'status': 'ran', 'hash': digest, 'seconds': seconds, 'runs': runs, 'report': report}

    # ---- the stages

    def demos(self, resume: bool) -> dict:
        return prepare(PrepareConfig(**self.plan.demos_config()))

    def perception(self, resume: bool) -> dict:
        c = self.plan.perception_config()
        resume = resume and (self.plan.perception_dir / 'last.pt').exists()
        report = train_perception(PerceptionConfig(**c, resume=resume))
        return {k: v for k, v in report.items() if isinstance(v, (int, float, str, dict))}

    def performer(self, resume: bool) -> dict:
        # lazy: PIL, tqdm, which the rest of this module does without
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
        c = self.plan.frames_config()
        path = build_first_frames(c['split'], c['resolution'], Path(c['out']), limit=c['limit'],
                                  progress=self.cfg.progress, demonstrations=Path(c['demonstrations']))
        return {'path': str(path)}

    def pretrain(self, resume: bool) -> dict:
        c = dict(self.plan.pretrain_config())
        if 'model' in c:
            c['model'] = QuestionerConfig(**c['model'])
        resume = resume and (self.plan.pretrain_dir / 'last.pt').exists()
        with dialogues_from(self.plan.dialogue_dir):
            report = pretrain(PretrainConfig(**c, resume=resume))
        return {k: v for k, v in report.items() if isinstance(v, (int, float, str))}

    def run_item(self, stage: str, item: str, inputs: dict, code: tuple[str, ...], outputs: list[Path],
                 action: Callable[[bool], dict]) -> dict:
        """One RL run or evaluation setting of an itemized stage, stamped on its own (stamps/<stage>/<item>.json)
        so that a change to one item reruns it alone: reuse it if it was done with these inputs and this code, resume it
        if it was cut off with them, else clear its outputs and run it. {'seconds', 'reused', **action's report}."""
        stamp = self.stamps_dir / stage / f'{item.replace("/", "_")}.json'
        try:
            old = json.loads(stamp.read_text())
        except (OSError, ValueError):
            old = None
        digest = self.known(old, sha256_of({'inputs': inputs, 'code': code_hash(code)}),
                            lambda: sha256_of({'inputs': inputs, 'code': code_hash(code, raw=True)}))
        if old and old.get('hash') == digest and old.get('status') == 'done':
            self.log(f'{stage}: {item} reused (done before with the same inputs, {old.get("seconds", 0):.0f} s)')
            return {**old.get('report', {}), 'seconds': old.get('seconds', 0.0), 'reused': True}
        resume = bool(old and old.get('hash') == digest and old.get('status') == 'running')
        if not resume:
            self.discard(f'{stage}/{item.replace("/", "_")}', outputs, old)
        before, runs = time_before(old, outputs) if resume else (0.0, 1)
        stamp.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomically(stamp, json.dumps({'hash': digest, 'status': 'running', 'inputs': inputs,
                                                 'started_at': time.time(), 'seconds_before': round(before, 1),
                                                 'runs': runs}, indent=1, sort_keys=True, default=str) + '\n')
        t0 = time.monotonic()
        report = action(resume) or {}
        this_run = time.monotonic() - t0
        seconds = round(before + this_run, 1)
        write_text_atomically(stamp, json.dumps({'hash': digest, 'status': 'done', 'inputs': inputs, 'report': report,
                                                 'seconds': seconds, 'seconds_this_run': round(this_run, 1),
                                                 'runs': runs}, indent=1, sort_keys=True, default=str) + '\n')
        self.log(f'{stage}: {item} in {this_run:.1f} s' + (f' ({seconds:.1f} s over {runs} runs)' if runs > 1 else ''))
        return {**report, 'seconds': seconds, 'reused': False}

    def rl(self, resume: bool) -> dict:
        p, items = self.plan, {}
        performer = file_sha256(p.performer_checkpoint)
        for name in RL_RUNS:
            c = p.rl_config(name)
            folder = Path(c['out'])

            def run(resume: bool, c=c, folder=folder) -> dict:
                report = finetune(FinetuneConfig(**c, resume=resume and (folder / 'last.pt').exists()))
                return {'sr': report.get('sr'), 'nq': report.get('nq')}
            inputs = {'config': c, 'performer': performer, 'init': file_sha256(Path(c['init']))}
            items[name] = self.run_item('rl', name, inputs, (*RL_CODE, *MODEL_CODE[c.get('model', 'et')]), [folder],
                                        run)
        return {'items': items}

    def eval(self, resume: bool) -> dict:
        return self.evaluations('eval', settings(), self.plan.eval_dir, self.plan.eval_config, EVAL_CODE)

    def chained(self, resume: bool) -> dict:
        """The settings of plan.CHAINED_KEYS under the chained protocol (DialFRED's challenge test), one item each."""
        p = self.plan
        return self.evaluations('chained', chained_settings(), p.chained_dir,
                                lambda s: p.eval_config(s, chained=True), CHAINED_CODE)

    def evaluations(self, stage: str, chosen: list, folder: Path, config_of: Callable, code: tuple) -> dict:
        """The eval or chained stage: each available setting of `chosen` played (`config_of(setting)`) as an item
        of its own, its results in `folder`."""
        p, items = self.plan, {}
        folder.mkdir(parents=True, exist_ok=True)
        performer = file_sha256(p.performer_checkpoint)
        for s in chosen:
            if not p.available(s):
                self.log(f'{stage}: {s.split} {s.key}: no questioner checkpoint, left out')
                continue
            config = config_of(s)
            questioner = s.questioner
            if questioner.startswith('rl:'):
                questioner = file_sha256(p.questioner_checkpoint(questioner[3:]))
            inputs = {'setting': dataclasses.asdict(s), 'config': config_inputs(config), 'performer': performer,
                      'questioner': questioner}
            # the results file and its companions (summary, runs, lock, tasks record, trace): <split>_<key>.*
            outputs = sorted(folder.glob(f'{s.split}_{s.key}.*'))

            # Played locally, the no-question setting of each performer and split (first in `chosen`) keeps its
            # episodes in folder/silent/ (a chained episode whole); the other settings take an episode from there
            # when their questioner would ask nothing in it (dialfred_bringup.silent).
            silent = (('replay' if s.questioner else 'record', folder / 'silent' / f'{s.split}_{s.performer}')
                      if p.eval_path == 'local' else None)

            def run(resume: bool, config=config, silent=silent) -> dict:
                run_baseline(config, self.cfg.progress, silent)    # resumes a cut-off results file; its wall time
                return {}                                          # in <results>.runs.jsonl
            items[f'{s.split}/{s.key}'] = self.run_item(stage, f'{s.split}/{s.key}', inputs,
                                                        (*code, *MODEL_CODE[s.performer]), outputs, run)
        return {'items': items}

    def check(self, resume: bool) -> dict:
        """Play the first tasks of every setting through the graph; compare with the eval stage's episodes."""
        return graph_check(self.plan, self.cfg.progress, self.log)

    def doc(self, resume: bool) -> dict:
        report = build_report(self.plan, self.cfg.resamples)
        paths = write_outputs(self.plan, report)
        return {'doc': str(paths[0]), 'plot': str(paths[1]), 'sha256': sha256_of(paths[0].read_bytes())}

    def run(self) -> dict:
        self.cfg.run_dir.mkdir(parents=True, exist_ok=True)
        t0 = time.monotonic()
        for stage in STAGES:
            if self.cfg.shipped and stage in TRAINING:
                self.log(f'{stage}: skipped (--shipped)')
                self.summary[stage] = {'status': 'shipped', 'seconds': 0.0}
            else:
                self.run_stage(stage, getattr(self, stage), self.plan.stage_outputs(stage))
            if stage == self.cfg.until:
                break
        target = self.cfg.doc_target if 'doc' in self.summary else None
        if target is not None:
            target.parent.mkdir(parents=True, exist_ok=True)
            copy_doc(self.plan.run, target)
        return {'run': str(self.cfg.run_dir), 'quick': self.cfg.quick, 'shipped': self.cfg.shipped,
                'stages': self.summary, 'seconds': round(time.monotonic() - t0, 1),
                'doc': str(self.plan.run / 'results.md'), 'copied_to': str(target) if target else None}
