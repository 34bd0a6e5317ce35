"""Actor-critic fine-tuning of the learned questioner against the frozen performer (DialFRED paper,
"Questioner fine-tuning using RL"; no ROS).

    python -m dialfred_questioner.finetune --out out/questioner/rl_anytime --timing anytime --gap 5
    python -m dialfred_questioner.finetune --out out/questioner/rl_begin --timing begin
    python -m dialfred_questioner.finetune --out out/questioner/rl_anytime_1 --gap 1 --rewards fixed_1
    python -m dialfred_questioner.finetune --out out/questioner/rl_mc --timing confusion
    python -m dialfred_questioner.finetune --out ... --perturb-type location       # Table III
    python -m dialfred_questioner.finetune --out out/questioner/map_rl_anytime --model map   # the map performer

Starts from a pre-trained questioner (`--init`, `pretrain.py`) and plays episodes of `--split`
(valid_seen, as the paper) in process: `rollout.play_rollout` with the shipped performer frozen (`--model`: the
Episodic Transformer, or the map-and-plan performer over its perception network), the oracle's
rules (`dialfred_oracle.in_process`, with the perturbation if any) and the env at the evaluation's
resolution, on `--workers` processes. Each update plays `--episodes-per-update` episodes with the
current policy (sampled with a generator seeded per episode, so the episodes do not depend on the
number of workers): `--samples-per-task` episodes of each task from the same start, the questioner
sampled anew in each. Then one actor-critic step on all their decisions (`rl.actor_critic_loss`:
discounted returns; advantages against a baseline, by default the leave-one-out mean return of the
task's other samples (`rl.group_baseline`; `--baseline critic`: the critic's V(s)); the critic
regressed on the returns; an entropy bonus; gradient clipping). Tasks are visited in a seeded
shuffled order, pass after pass.

Writes to `--out`, as it goes: `metrics.jsonl` (a line per update: return, SR, NQ, invalid share,
the mix of question types, the losses, seconds), `curves.png`, `last.pt` after every update (with the
optimiser state: `--resume` continues to the weights of an uninterrupted run) and `final.pt` at the
end. Checkpoints are `checkpoint.save`'s format plus the timing they were trained with, so
`LearnedQuestioner.from_checkpoint` asks as it learned to.
"""

from __future__ import annotations

import dataclasses
import json
import random
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np
import torch

from dialfred_oracle.answers import Perturbation
from dialfred_performer.model import SHIPPED_CHECKPOINT, load_checkpoint, read_state
from dialfred_performer.model_registry import PERFORMER_MODELS, camera_resolution, load_policy
from dialfred_sim.dataclass_cli import arg, check_bounds, parse
from dialfred_sim.metrics import git_commit
from dialfred_sim.processes import worker_pool
from dialfred_sim.chained import chain_episodes
from dialfred_sim.protocol import MAX_STEPS, PROTOCOLS
from dialfred_sim.protocol import question_types
from dialfred_sim.tasks import load_split

from .checkpoint import resume_training, save
from .model import Questioner
from .policy import LearnedQuestioner, score_records
from .rl import Rewards, actor_critic_loss, discounted_returns, group_baseline
from .rollout import TIMINGS, Timing, play_chained_rollout, play_rollout

MODULE = 'dialfred_questioner.finetune'
PACKAGE_DIR = Path(__file__).resolve().parent
PRETRAINED = PACKAGE_DIR / 'checkpoints' / 'pretrained.pt'
REWARDS = {'paper': Rewards(), 'fixed_1': Rewards.fixed_1()}
RESUMABLE_CHANGES = ('resume', 'progress', 'workers', 'updates')


@dataclass(frozen=True)
class FinetuneConfig:
    """Fine-tune the DialFRED questioner with actor-critic RL against the frozen performer."""

    init: str = arg(str(PRETRAINED), 'the pre-trained questioner checkpoint to start from')
    performer: str = arg(str(SHIPPED_CHECKPOINT), 'the performer checkpoint (frozen)')
    model: str = arg('et', 'the performer\'s model, as the performer node\'s `model` parameter: et (the Episodic '
                           'Transformer of --performer) or map (the map-and-plan performer over its perception network)')
    split: str = arg('valid_seen', 'the split whose tasks are played')
    out: str = arg('out/questioner/rl_anytime', 'folder for metrics.jsonl, curves.png, last.pt, final.pt')
    timing: str = arg('anytime', f'when the questioner may ask: {", ".join(TIMINGS)}')
    gap: int = arg(5, 'anytime: performer steps between chances to ask')
    epsilon: float = arg(0.5, 'confusion: ask when the top-2 action probabilities differ by less')
    rewards: str = arg('paper', f'reward set: {", ".join(REWARDS)} (the paper\'s Fixed-1 penalties)')
    dialogue: bool = arg(True, 'the questioner reads the dialogue so far (--no-dialogue: the instruction only, '
                               'as the original; an ablation)')
    perturb_type: str = arg('', 'the oracle withholds answers of this question type ...')
    perturb_probability: float = arg(0.5, '... with this probability')
    updates: int = arg(64, 'actor-critic updates')
    episodes_per_update: int = arg(64, 'episodes played per update')
    samples_per_task: int = arg(4, 'episodes of each task (one start, the questioner sampled anew) per update')
    baseline: str = arg('group', "the policy's baseline: group (the leave-one-out mean return of the task's other "
                                 "samples) or critic (V(s)); the critic is trained either way")
    lr: float = arg(1e-3, 'learning rate (Adam)')
    gamma: float = arg(0.99, 'discount between the questioner\'s decisions')
    entropy: float = arg(0.01, 'entropy bonus weight')
    value_weight: float = arg(0.5, 'critic loss weight')
    grad_clip: float = arg(1.0, 'clip the gradient norm to this (0: no clipping)')
    resolution: int = arg(0, "the env's frames (0: the performer model's camera, as the evaluation plays it: the et "
                             "performer's training resolution, 128 px for the map performer)")
    max_steps: int = arg(MAX_STEPS, 'performer steps before an episode is cut off (the evaluation\'s limit)')
    limit: int = arg(0, 'only the first N tasks of the split (0: all)')
    protocol: str = arg('expert', "how the tasks are played (dialfred_sim.chained): expert = each from the expert's "
                        "state; chained = an episode's tasks in order on the state the performer's own actions left "
                        '(an update then plays whole episodes until they hold episodes_per_update / samples_per_task '
                        'tasks, each episode samples_per_task times)', choices=PROTOCOLS)
    workers: int = arg(2, 'rollout processes')
    seed: int = arg(0, 'seeds the task order, the episodes and the sampling')
    resume: bool = arg(False, 'continue from out/last.pt (same config required)')
    progress: bool = arg(True, 'a progress line per update on stderr')

    def __post_init__(self):
        Timing(self.timing, self.gap, self.epsilon)               # ValueError for a bad timing
        if self.model not in PERFORMER_MODELS:
            raise ValueError(f'model must be one of {", ".join(PERFORMER_MODELS)}, got {self.model!r}')
        if self.rewards not in REWARDS:
            raise ValueError(f'rewards must be one of {", ".join(REWARDS)}, got {self.rewards!r}')
        if self.perturb_type and self.perturb_type not in question_types():
            raise ValueError(f'perturb_type must be one of {", ".join(question_types())}, got {self.perturb_type!r}')
        if self.baseline not in ('group', 'critic'):
            raise ValueError(f'baseline must be group or critic, got {self.baseline!r}')
        if self.baseline == 'group' and self.samples_per_task < 2:
            raise ValueError('the group baseline needs samples_per_task >= 2')
        if self.samples_per_task < 1 or self.episodes_per_update % self.samples_per_task:
            raise ValueError(f'episodes_per_update ({self.episodes_per_update}) must be a multiple of '
                             f'samples_per_task ({self.samples_per_task})')
        check_bounds(self, at_least_one=('updates', 'episodes_per_update', 'workers', 'max_steps'),
                     non_negative=('limit', 'seed', 'entropy', 'value_weight', 'grad_clip', 'resolution'),
                     positive=('lr',), fractions=('perturb_probability',))
        if not 0.0 < self.gamma <= 1.0:
            raise ValueError(f'gamma must be in (0, 1], got {self.gamma}')
        if self.protocol not in PROTOCOLS:
            raise ValueError(f'protocol must be one of {", ".join(PROTOCOLS)}, got {self.protocol!r}')

    @property
    def timing_of(self) -> Timing:
        return Timing(self.timing, self.gap, self.epsilon)


def episode_plan(n_tasks: int, update: int, per_update: int, seed: int, samples: int = 1) -> list[tuple[int, int, int]]:
    """(task index, episode seed, sampling seed) of each episode of update `update` (0-based): the
    tasks in a shuffled order per pass (seeded by `seed` and the pass), consecutive tasks of that order,
    each played `samples` times from the same start (episode seed) with different sampling seeds."""
    out = []
    per = per_update // samples
    for k in range(update * per, (update + 1) * per):
        epoch, pos = divmod(k, n_tasks)
        order = list(range(n_tasks))
        random.Random(f'{seed}/pass{epoch}').shuffle(order)
        start = int(np.random.SeedSequence([seed, k]).generate_state(1)[0])
        for j in range(samples):
            out.append((order[pos], start, int(np.random.SeedSequence([seed, k, j]).generate_state(1)[0])))
    return out


def chained_plan(sizes: list[int], update: int, per_update: int, seed: int, samples: int = 1) -> list[tuple]:
    """(chained episode index, its tasks' episode seeds, sampling seed) of each rollout of update `update` under
    the chained protocol: the episodes (of `sizes` tasks each) in a shuffled order per pass (seeded by `seed` and
    the pass), each update taking them in turn from where the last one stopped until they hold at least
    per_update // samples tasks, each played `samples` times from the same start with different sampling seeds."""
    per = max(1, per_update // samples)
    orders: dict = {}

    def at(k: int) -> int:
        epoch, pos = divmod(k, len(sizes))
        if epoch not in orders:
            orders[epoch] = list(range(len(sizes)))
            random.Random(f'{seed}/chained-pass{epoch}').shuffle(orders[epoch])
        return orders[epoch][pos]

    k = 0
    for _ in range(update + 1):
        taken, tasks = [], 0
        while tasks < per:
            taken.append((k, at(k)))
            tasks += sizes[at(k)]
            k += 1
    out = []
    for k, e in taken:
        starts = [int(np.random.SeedSequence([seed, k, j]).generate_state(1)[0]) for j in range(sizes[e])]
        out += [(e, starts, int(np.random.SeedSequence([seed, k, 1000 + j]).generate_state(1)[0])) for j in range(samples)]
    return out


# ---------------------------------------------------------------------- rollout workers

_W: dict = {}


def _init_worker(cfg_json: str) -> None:
    from dialfred_sim.env import DialfredEnv  # lazy: gymnasium, which the rest of this module does without
    torch.set_num_threads(1)
    cfg = FinetuneConfig(**json.loads(cfg_json))
    _W['cfg'] = cfg
    _W['env'] = DialfredEnv(resolution=cfg.resolution, max_steps=cfg.max_steps)
    _W['performer'] = load_policy(cfg.model, Path(cfg.performer))
    _W['policy'] = LearnedQuestioner.from_checkpoint(Path(cfg.init), greedy=False, timing=cfg.timing_of)
    _W['policy'].reads_dialogue = cfg.dialogue
    _W['tasks'] = [t.task_id for t in load_split(cfg.split)][:cfg.limit or None]
    _W['chained'] = chained_episodes(cfg)
    _W['perturbation'] = (Perturbation(cfg.perturb_type, cfg.perturb_probability, cfg.seed)
                          if cfg.perturb_type else None)


def _play_chunk(args: tuple[dict, list[tuple]]) -> list[tuple[int, dict]]:
    """Play (episode number, task index, episode seed, sampling seed) with the policy's weights `state`; under
    the chained protocol (first numbers, chained episode index, its tasks' seeds, sampling seed), one number a task."""
    state, jobs = args
    cfg, policy = _W['cfg'], _W['policy']
    policy.model.load_state_dict(state)
    policy.model.eval()
    out = []
    for number, where, seed, sample_seed in jobs:
        policy.generator.manual_seed(sample_seed)
        if cfg.protocol == 'chained':
            tasks = [t for _, t in _W['chained'][where].tasks]
            played = play_chained_rollout(_W['env'], _W['performer'], policy, tasks, seed, cfg.timing_of,
                                          REWARDS[cfg.rewards], _W['perturbation'])
        else:
            played = [play_rollout(_W['env'], _W['performer'], policy, _W['tasks'][where], seed, cfg.timing_of,
                                   REWARDS[cfg.rewards], _W['perturbation'])]
        for j, ep in enumerate(played):
            out.append((number + j, {
                'task_id': ep.task_id, 'success': ep.success, 'steps': ep.steps, 'questions': ep.questions,
                'invalid': ep.invalid_questions, 'rewards': ep.rewards, 'records': [d.record for d in ep.decisions],
                'asked': [d.question.question_type if d.question else None for d in ep.decisions],
                'dialogue': [(qa.question.question_type, qa.question.object_noun, qa.valid, qa.answer)
                             for qa in ep.dialogue]}))
    return out


def chained_episodes(cfg: FinetuneConfig) -> list:
    """The chained episodes of the split's (first `limit`) tasks (dialfred_sim.chained)."""
    return chain_episodes(enumerate(load_split(cfg.split)[:cfg.limit or None]))


def update_jobs(cfg: FinetuneConfig, update: int, n_tasks: int, sizes: list[int]) -> tuple[list, list]:
    """The rollouts of update `update` as jobs for _play_chunk, and each played task's group (the rollouts of
    the same task from the same start, for the group baseline)."""
    if cfg.protocol != 'chained':
        plan = episode_plan(n_tasks, update, cfg.episodes_per_update, cfg.seed, cfg.samples_per_task)
        jobs = [(update * cfg.episodes_per_update + k, t, s, z) for k, (t, s, z) in enumerate(plan)]
        return jobs, [k // cfg.samples_per_task for k in range(len(plan))]
    jobs, groups, number = [], [], 0
    for slot, (e, seeds, z) in enumerate(chained_plan(sizes, update, cfg.episodes_per_update, cfg.seed,
                                                      cfg.samples_per_task)):
        jobs.append((number, e, seeds, z))
        groups += [(slot // cfg.samples_per_task, j) for j in range(sizes[e])]
        number += sizes[e]
    return jobs, groups


def rollout_chunks(jobs: list, workers: int, per_worker: int = 8) -> list[list]:
    """`jobs` cut into about `per_worker` chunks per worker, handed out as workers free up: episodes'
    lengths vary, and one fixed share per worker left the others idle while the longest share was
    still playing. An episode's outcome depends only on its job and the weights, so
    the chunks change no result (tests/questioner/test_questioner_finetune.py: one worker or two, the same weights)."""
    if workers <= 1:
        return [jobs] if jobs else []
    size = max(1, -(-len(jobs) // (workers * per_worker)))
    return [jobs[i:i + size] for i in range(0, len(jobs), size)]


# ---------------------------------------------------------------------- the update

def update_step(model: Questioner, opt, episodes: list[dict], cfg: FinetuneConfig) -> dict:
    """One actor-critic step on every decision of `episodes` (complete episodes, in order)."""
    records, rewards, ends, starts = [], [], [], []
    for ep in episodes:
        if ep['records']:
            starts.append(len(records))
        records.extend(ep['records'])
        rewards.extend(ep['rewards'])
        ends.extend([False] * (len(ep['records']) - 1) + [True] if ep['records'] else [])
    if not records:
        return {'policy': 0.0, 'critic': 0.0, 'entropy': 0.0, 'advantage_mean': 0.0, 'decisions': 0}
    returns = discounted_returns(rewards, ends, cfg.gamma)
    baseline = None
    if cfg.baseline == 'group':
        played = [ep for ep in episodes if ep['records']]
        baseline = group_baseline([float(returns[k]) for k in starts], [ep['group'] for ep in played],
                                  [len(ep['records']) for ep in played])
    model.eval()           # no dropout: the log-probabilities of the policy that played
    log_probs, entropies, values = score_records(model, records)
    loss, parts = actor_critic_loss(log_probs, values, entropies, returns, cfg.value_weight, cfg.entropy,
                                    baseline=baseline)
    opt.zero_grad()
    loss.backward()
    if cfg.grad_clip:
        parts['grad_norm'] = float(torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.grad_clip))
    opt.step()
    return {**parts, 'decisions': len(records)}


def summary(episodes: list[dict]) -> dict:
    n = max(len(episodes), 1)
    asked = [t for ep in episodes for t in ep['asked'] if t]
    questions = sum(ep['questions'] for ep in episodes)
    return {'episodes': len(episodes), 'return': sum(sum(ep['rewards']) for ep in episodes) / n,
            'sr': sum(ep['success'] for ep in episodes) / n, 'nq': questions / n,
            'invalid_share': sum(ep['invalid'] for ep in episodes) / max(questions, 1),
            'steps': sum(ep['steps'] for ep in episodes) / n,
            'mix': {t: asked.count(t) / max(len(asked), 1) for t in question_types()}}


TYPE_COLOURS = ((31, 119, 180), (255, 127, 14), (148, 103, 189), (140, 86, 75), (227, 119, 194), (188, 189, 34))


def rl_panels() -> tuple:
    """The panels of the fine-tuning curves: one line of the question-type mix per registered type."""
    mix = tuple((f'mix.{t}', t, TYPE_COLOURS[k % len(TYPE_COLOURS)]) for k, t in enumerate(question_types()))
    return (
        ('return per episode', (('return', 'return', (31, 119, 180)),), None),
        ('SR and NQ', (('sr', 'SR', (44, 160, 44)), ('nq', 'questions / episode', (214, 39, 40))), None),
        ('question types (share)', mix, (0.0, 1.0)),
        ('critic loss', (('critic', 'critic', (127, 127, 127)),), None),
    )


def draw_rl_curves(metrics_path: Path, out_path: Path) -> Path:
    """The fine-tuning curves (return, SR, NQ, question-type mix, critic loss per update) as a PNG."""
    # lazy: PIL, which the rest of this module does without
    from dialfred_performer.curves import draw_series, read_metrics
    rows = [{**r, **{f'mix.{k}': v for k, v in r.get('mix', {}).items()}} for r in read_metrics(metrics_path)]
    return draw_series(rows, rl_panels(), out_path, x_key='update', x_label='x: actor-critic updates')


def finetune(cfg: FinetuneConfig) -> dict:
    if not cfg.resolution:
        cfg = dataclasses.replace(cfg, resolution=camera_resolution(cfg.model, Path(cfg.performer)))
    out = Path(cfg.out)
    commit = git_commit()
    torch.set_num_threads(1)
    torch.manual_seed(cfg.seed)
    init = LearnedQuestioner.from_checkpoint(Path(cfg.init))
    model = init.model
    model.eval()
    base = read_state(Path(cfg.init))
    _, _, performer_info = load_checkpoint(Path(cfg.performer))
    performer_info = dict(performer_info, path=str(cfg.performer), model=cfg.model)
    if base.get('performer') and Path(base['performer']).name != Path(cfg.performer).name:
        print(f'note: {cfg.init} was pre-trained with the visual encoder of {base["performer"]}, '
              f'fine-tuned here against {cfg.performer}', file=sys.stderr)
    n_tasks = len(load_split(cfg.split)[:cfg.limit or None])
    if n_tasks == 0:
        raise ValueError(f'the split {cfg.split!r} has no tasks')
    sizes = [len(e.tasks) for e in chained_episodes(cfg)] if cfg.protocol == 'chained' else []
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    update, seconds_before = 0, 0.0
    log_path = out / 'metrics.jsonl'
    if cfg.resume:
        extra, lines = resume_training(out, cfg, RESUMABLE_CHANGES, model, opt, 'update')
        update = extra['update']
        seconds_before = json.loads(lines[-1]).get('seconds', 0.0) if lines else 0.0   # the cut-off run's time
    else:
        out.mkdir(parents=True, exist_ok=True)
        log_path.write_text('')
    timing = dataclasses.asdict(cfg.timing_of)
    visual_state = {k: v.clone() for k, v in init.visual.state_dict().items()}

    def write(path: Path, extra: Optional[dict] = None) -> None:
        save(path, model, init.vocab, visual_state, performer_info, cfg, commit, extra=extra, timing=timing,
             module=MODULE, reads_dialogue=cfg.dialogue)

    t0 = time.monotonic() - seconds_before             # 'seconds' counts the whole run, cut-off runs included
    report: dict = {}
    cfg_json = json.dumps(dataclasses.asdict(cfg))
    with worker_pool(cfg.workers, initializer=_init_worker, initargs=(cfg_json,)) as pool:
        while update < cfg.updates:
            jobs, groups = update_jobs(cfg, update, n_tasks, sizes)
            state = {k: v.detach().clone() for k, v in model.state_dict().items()}
            played = sorted((x for part in pool.imap_unordered(_play_chunk, [(state, c) for c in
                                                                             rollout_chunks(jobs, cfg.workers)])
                             for x in part), key=lambda x: x[0])
            episodes = [dict(ep, group=group) for (_, ep), group in zip(played, groups)]
            t_play = time.monotonic()
            parts = update_step(model, opt, episodes, cfg)
            update += 1
            report = {'update': update, **summary(episodes), **parts,
                      'seconds': round(time.monotonic() - t0, 1),
                      'update_seconds': round(time.monotonic() - t_play, 3)}
            with open(log_path, 'a') as f:
                f.write(json.dumps(report) + '\n')
            write(out / 'last.pt', extra={'config': json.dumps(dataclasses.asdict(cfg)), 'optimizer': opt.state_dict(),
                                          'update': update, 'examples': [ep['dialogue'] for ep in episodes[:4]]})
            draw_rl_curves(log_path, out / 'curves.png')
            if cfg.progress:
                mix = ' '.join(f'{t[:3]} {v:.2f}' for t, v in report['mix'].items())
                print(f'update {update}/{cfg.updates}: return {report["return"]:+.3f}  SR {report["sr"]:.3f}  '
                      f'NQ {report["nq"]:.2f}  invalid {report["invalid_share"]:.2f}  [{mix}]  '
                      f'critic {report["critic"]:.4f}  {report["seconds"]:.0f} s', file=sys.stderr, flush=True)
    write(out / 'final.pt', extra={'updates': update, 'seconds': report.get('seconds')})
    return {**report, 'out': str(out), 'final': str(out / 'final.pt')}


def main(argv: Optional[list[str]] = None) -> int:
    cfg = parse(FinetuneConfig, argv, prog=f'python -m {MODULE}')
    print(json.dumps(finetune(cfg)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
