"""Train the performer on expert demonstrations and their dialogues (imitation with teacher forcing).

    ./dialfred prepare-performer --split train --resolution 64 --workers 2      # once: data + vocabulary
    ./dialfred train-performer --out out/performer                              # CPU, all cores
    ./dialfred train-performer --out out/performer --resume                     # continue after a stop

`TrainConfig` is the command line (`--help` lists every field with its default). The data are a
demonstrations folder made by `dialfred_performer.prepare` (frames, tasks, dialogues.jsonl,
vocabulary.json); validation is a second folder (`--validation`, e.g. valid_seen) or the training
tasks whose id hashes below `--val-fraction`. Batches are padded episodes, grouped by length within
buckets of a seeded shuffle. AdamW, linear warmup then cosine decay, gradient clipping.

Written to `--out`: `last.pt` (every `--checkpoint-every` updates, at each epoch's end and when a
session stops; with the optimiser, schedule and RNG state, so `--resume` continues to the very
weights of an uninterrupted run), `epoch-NNN.pt` and `best.pt` (lowest validation loss),
`metrics.jsonl` (a line per `--log-every` updates and per validation), `curves.png`. Every checkpoint
is a `model.save_checkpoint` file, loadable by `PerformerAgent.from_checkpoint`. A first Ctrl-C
stops after the current update and writes last.pt; --resume goes on from there.

An epoch shows every training task once per question-type combination (8x its frames; the paper's
augmentation); --no-every-combination shows each once, with a combination drawn per epoch.

On several processes (one host or many), with DistributedDataParallel (gloo on CPU, nccl on CUDA):

    torchrun --nproc_per_node 2 -m dialfred_performer.train --threads 1 --out out/performer ...

The global batch stays --batch-size (each process takes an equal share of every batch, in the
single process's order), only rank 0 writes files, and --resume works as with one process
(`distributed.py` says what is and is not the same computation as one process).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import random
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

import numpy as np
import torch

from dialfred_sim.dataclass_cli import arg, check_bounds, command_line, config_changes, parse
from dialfred_sim.metrics import git_commit
from dialfred_sim.progress import progress_bar
from dialfred_sim.protocol import ACTIONS
from dialfred_sim.tasks.demonstrations import default_dir

from .blocks import BlockFeatures, block_batches, block_of, epoch_batches
from .curves import draw_curves
from .data import (DIALOGUES_FILE, DemonstrationDataset, base_task_id, collate, held_out, paraphrase_texts,
                   vocabulary_texts)
from .distributed import (Ranks, any_rank, check_batch, finish, gather_rng, global_counts, init, rank_device,
                          rank_seed, rank_share, reduce_stats, sharded_loss, zero_stats)
from .malloc import MALLOC_SETTINGS, ensure_malloc_settings
from .metrics import STAT_KEYS, MetricsLog, batch_stats, evaluate, summarize, to_device
from .model import Performer, PerformerConfig, load_checkpoint, performer_loss, save_checkpoint
from .nn import PerceivedFrames
from .perception import load_perception, resolve_precision
from .prepare import VOCABULARY_FILE, oracle_texts
from .preprocess import Vocabulary

MODULE = 'dialfred_performer.train'
# Fields that may change between a run and its --resume (all must match otherwise). Only the same
# device and thread count give bit-identical weights; another may change the last bits.
RESUMABLE_CHANGES = ('resume', 'progress', 'device', 'threads', 'loader_workers', 'stop_after', 'checkpoint_every')


@dataclass(frozen=True)
class TrainConfig:
    """Train the DialFRED performer (Episodic Transformer) on expert demonstrations with dialogues."""

    demonstrations: str = arg(str(default_dir('train', 64)),
                              'training demonstrations folder (made by python -m dialfred_performer.prepare)')
    validation: str = arg('', "validation demonstrations folder (e.g. valid_seen's); '' = hold out training tasks")
    val_fraction: float = arg(0.05, 'without --validation: hold out the training tasks whose id hashes below this')
    dialogues: bool = arg(True, "train with the folder's dialogues.jsonl (--no-dialogues: instructions only)")
    every_combination: bool = arg(True, 'an epoch shows each task once per question-type combination (8x); '
                                        '--no-every-combination: once, with a combination drawn per epoch')
    streams: int = arg(0, 'answer-stream items per task beside the combinations\' (data.stream_dialogue: answers of '
                          'some types at some or every step; needs --stream-answers and a folder whose dialogues '
                          'log every step)')
    detours: str = arg('', "a demonstrations folder of the same tasks made with --detours (prepare-performer): its "
                           "episodes (wrong moves in a go-to, the expert's way back) join the training's, each task's "
                           "items as many")
    guided: str = arg('', "a demonstrations folder of the same tasks made with --guided (prepare-performer): its "
                          "episodes (the last go-to walked as the direction answers say) join the training's, "
                          "each with the direction answer at every step (data.guided_dialogue), as many items")
    stream_directions: bool = arg(True, "the stream items of the plain and detour episodes ask for directions too "
                                        "(--no-stream-directions: only a guided walk's items hear the direction at "
                                        "many steps, where every move is what it says; the paper's items keep theirs)")
    reworded: float = arg(0.0, "the share of training answers said in the synthetic annotator's words instead of the "
                               "oracle's templates (data.reword; the vocabulary then also has the annotator's words)")
    vocabulary: str = arg('', "vocabulary.json; '' = the training folder's, else built from its texts")
    out: str = arg('out/performer', 'folder for checkpoints, metrics.jsonl and curves.png')
    model: PerformerConfig = field(default_factory=PerformerConfig)
    perception: str = arg('', 'a perception checkpoint (python -m dialfred_performer.perception): the performer sees '
                              'through it, frozen, and points at pixels; \'\' = the small CNN learnt with the actions')
    epochs: int = arg(10, 'passes over the training episodes (each task once per question-type combination)')
    max_updates: int = arg(0, 'stop after this many optimiser updates in all (0: epochs x updates per epoch)')
    batch_size: int = arg(16, 'episodes per update')
    bucket: int = arg(32, 'episodes are sorted by length within shuffled groups of bucket x batch_size '
                          '(less padding; 1: no grouping)')
    block_tasks: int = arg(0, 'with --perception: an epoch goes in blocks of this many tasks (every combination of '
                              'a block\'s tasks batched among themselves) and the frozen network runs once per frame '
                              'of a block instead of once per item (blocks.py); 0: items in random order')
    block_items: int = arg(0, 'with --block-tasks: how many of a task\'s items (question-type combinations) a block '
                              'shows together; the epoch visits each task in rounds, this many items a visit (0: all '
                              'of them in one visit)')
    block_bucket: int = arg(1, 'with --block-tasks: a round\'s shuffled tasks are sorted by length within groups of '
                               'this many blocks before they are cut, and the blocks shuffled (a block of one batch '
                               'then pads as little as random order\'s buckets); 1: no grouping')
    validate_every: int = arg(0, 'also validate every this many updates (0: at the end of each epoch and of the run only)')
    lr: float = arg(1e-3, 'peak learning rate (AdamW)')
    final_lr_fraction: float = arg(0.01, 'the cosine decays to lr x this')
    warmup_updates: int = arg(500, 'linear warmup from 0 to lr')
    weight_decay: float = arg(0.01, 'AdamW weight decay (matrices only; not biases, norms)')
    grad_clip: float = arg(1.0, 'clip the gradient norm to this (0: no clipping)')
    pointer_weight: float = arg(1.0, 'weight of the pointer loss')
    perception_precision: str = arg('fp32', "the frozen perception network's arithmetic (with --perception): fp32, "
                                            "bf16 (its convolutions in bfloat16, about half its time), or auto: bf16 "
                                            "where the CPU does bfloat16 natively (AMX or AVX512-BF16), else fp32. "
                                            "Recorded in the model's config: the agent perceives so too where the "
                                            "CPU does bfloat16 natively")
    perception_channels_last: bool = arg(True, 'with --perception: the frozen network runs on channels-last tensors '
                                               '(oneDNN\'s faster layout on a CPU, as the agent runs it; the same '
                                               'numbers up to rounding)')
    recovery: float = arg(0.0, 'the share of training items with a failed click inserted before an interaction '
                               '(data.insert_failed_interaction; needs --failure-input)')
    blocked: float = arg(0.0, "the share of guided walks' items (--guided) with a failed MoveAhead before each "
                              "sidestep, where the way the direction answer said was blocked (data.blocked_steps; "
                              'needs --failed-moves)')
    seed: int = arg(0, 'seeds python, numpy and torch, the shuffles and the dialogue draws')
    deterministic: bool = arg(True, 'torch.use_deterministic_algorithms (warn only on CUDA)')
    device: str = arg('auto', "'auto' (cuda if present, else cpu), 'cpu', 'cuda' or 'cuda:N'")
    threads: int = arg(0, 'torch CPU threads (0: the cores this process may use, shared among the training processes of its host)')
    loader_workers: int = arg(0, 'DataLoader worker processes (0: load in the training process)')
    log_every: int = arg(50, 'updates per line of metrics.jsonl')
    checkpoint_every: int = arg(500, 'updates between writes of last.pt')
    stop_after: int = arg(0, 'end this session after this many updates (0: run to the end); --resume continues')
    resume: bool = arg(False, 'continue from out/last.pt (same config required)')
    init: str = arg('', "start from this performer checkpoint's weights (its vocabulary and sizes; a failed "
                        "action's row starts as the action's) and train as configured; '' = from scratch")
    progress: bool = arg(True, 'progress bar on stderr')

    def __post_init__(self):
        check_bounds(self, at_least_one=('epochs', 'batch_size', 'bucket', 'log_every', 'checkpoint_every',
                                         'block_bucket'),
                     non_negative=('max_updates', 'warmup_updates', 'weight_decay', 'grad_clip', 'pointer_weight',
                                   'threads', 'loader_workers', 'stop_after', 'seed', 'block_tasks', 'block_items',
                                   'validate_every'),
                     positive=('lr',), fractions=('final_lr_fraction',))
        if self.block_items and not self.block_tasks:
            raise ValueError('--block-items needs --block-tasks (it says how a block shows a task\'s items)')
        if not 0 <= self.val_fraction < 1:
            raise ValueError(f'val_fraction must be in [0, 1), got {self.val_fraction}')
        if not (self.device in ('auto', 'cpu', 'cuda') or self.device.startswith('cuda:')):
            raise ValueError(f"device must be 'auto', 'cpu', 'cuda' or 'cuda:N', got {self.device!r}")
        m = self.model
        if m.visual != 'cnn' or m.perception_net:
            raise ValueError('--visual and --perception-net come from the perception checkpoint: give --perception PATH')
        if m.frozen_arithmetic != 'fp32':
            raise ValueError('--frozen-arithmetic is recorded from --perception-precision: give that instead')
        if m.resolution < 8 or m.resolution % 8:
            raise ValueError(f'resolution must be a positive multiple of 8, got {m.resolution}')
        if m.d_model < 8 or m.d_model % 8 or m.heads < 1 or m.d_model % m.heads:
            raise ValueError(f'd_model ({m.d_model}) must be a multiple of 8 and of heads ({m.heads})')
        for name in ('layers', 'ff', 'max_tokens', 'max_steps'):
            if getattr(m, name) < 1:
                raise ValueError(f'{name} must be at least 1, got {getattr(m, name)}')
        if not 0 <= m.dropout < 1:
            raise ValueError(f'dropout must be in [0, 1), got {m.dropout}')
        if self.perception_precision not in ('fp32', 'bf16', 'auto'):
            raise ValueError(f'--perception-precision takes fp32, bf16 or auto, got {self.perception_precision!r}')
        if not 0 <= self.recovery <= 1:
            raise ValueError(f'recovery must be in [0, 1], got {self.recovery}')
        if self.block_tasks and not self.perception:
            raise ValueError('--block-tasks keeps the frozen perception network\'s output per block: it needs '
                             '--perception PATH')
        if self.streams and not m.stream_answers:
            raise ValueError('--streams trains on answers at any step: it needs --stream-answers (the model reads its '
                             'language as an answer stream)')
        if not 0 <= self.reworded <= 1:
            raise ValueError(f'reworded must be in [0, 1], got {self.reworded}')
        if not 0 <= self.blocked <= 1:
            raise ValueError(f'blocked must be in [0, 1], got {self.blocked}')
        if self.blocked > 0 and not (m.failed_moves and self.guided):
            raise ValueError('--blocked teaches what to do after a blocked move in guided walks: it needs '
                             '--failure-input --failed-moves and --guided')
        if self.recovery > 0 and not m.failure_input:
            raise ValueError('--recovery teaches what to do after a failed click: it needs --failure-input')


# ---------------------------------------------------------------------- set-up

def seed_everything(seed: int, deterministic: bool, device: torch.device) -> None:
    """The one seeding block: python, numpy, torch (CPU and CUDA), deterministic kernels."""
    if device.type == 'cuda':
        os.environ.setdefault('CUBLAS_WORKSPACE_CONFIG', ':4096:8')    # before cuBLAS starts
        torch.backends.cudnn.benchmark = False
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)            # also seeds every CUDA device
    torch.use_deterministic_algorithms(deterministic, warn_only=device.type == 'cuda')


def pick_device(name: str) -> torch.device:
    if name == 'auto':
        return torch.device('cuda' if torch.cuda.is_available() else 'cpu')
    if name.startswith('cuda') and not torch.cuda.is_available():
        raise ValueError(f'--device {name}: torch sees no CUDA device here')
    return torch.device(name)


def check_folder(path: Path, what: str, need_dialogues: bool) -> None:
    if not (path / 'meta.json').is_file():
        raise FileNotFoundError(f'no finished {what} demonstrations in {path} (no meta.json); make them with '
                                '`./dialfred prepare-performer --split SPLIT --resolution R`')
    if need_dialogues and not (path / DIALOGUES_FILE).is_file():
        raise FileNotFoundError(f'no {DIALOGUES_FILE} in {path}; make it with `./dialfred prepare-performer` '
                                '(or train on instructions only with --no-dialogues)')


@dataclass
class Data:
    train: DemonstrationDataset
    train_items: list[int]            # indices into `train`
    val: Optional[DemonstrationDataset]
    val_items: list[int]

    @staticmethod
    def item_lengths(ds: DemonstrationDataset, items: Sequence[int]) -> list[int]:
        combos = ds.per_task
        tasks = ds.demo.tasks
        return [len(tasks[ds.task_indices[i // combos]]['actions']) + 1 for i in items]


def frozen_arithmetic(cfg: TrainConfig) -> str:
    """The frozen perception network's arithmetic on this machine, fp32 or bf16 (--perception-precision with
    auto resolved); a resumed run keeps the one it began with (`Trainer`)."""
    return resolve_precision(cfg.perception_precision)


def model_config(cfg: TrainConfig) -> tuple[PerformerConfig, Optional[dict]]:
    """(the performer's config, the perception weights or None): with --perception, the model sees
    through that network (its sizes go into the config, its weights into the performer)."""
    if not cfg.perception:
        if cfg.model.reach_input:
            raise ValueError('--reach-input needs --perception PATH: the distances are the network\'s predictions')
        return cfg.model, None
    net, _ = load_perception(Path(cfg.perception))
    if net.config.resolution != cfg.model.resolution:
        raise ValueError(f'the perception network reads {net.config.resolution} px frames, the performer '
                         f'{cfg.model.resolution} px (--resolution)')
    sizes = json.dumps(dataclasses.asdict(net.config), sort_keys=True)
    return dataclasses.replace(cfg.model, visual='perception', perception_net=sizes), net.state_dict()


def load_data(cfg: TrainConfig, vocab: Vocabulary) -> Data:
    m, _ = model_config(cfg)
    train = DemonstrationDataset(Path(cfg.demonstrations), vocab, m.resolution, m.max_tokens, seed=cfg.seed,
                                 grid_size=m.grid_size, recovery=cfg.recovery, streams=cfg.streams,
                                 stream=m.stream_answers, reworded=cfg.reworded,
                                 detours=Path(cfg.detours) if cfg.detours else None,
                                 guided=Path(cfg.guided) if cfg.guided else None, blocked=cfg.blocked,
                                 stream_directions=cfg.stream_directions, fresh=m.fresh_types)
    if not cfg.dialogues:
        train.combinations, train.streams = ((),), 0
    combos = train.per_task
    every = list(range(len(train)))
    if cfg.validation:
        val = DemonstrationDataset(Path(cfg.validation), vocab, m.resolution, m.max_tokens, seed=cfg.seed,
                                   grid_size=m.grid_size, streams=cfg.streams, stream=m.stream_answers,
                                   fresh=m.fresh_types)
        if not cfg.dialogues:
            val.combinations, val.streams = ((),), 0
        return Data(train, every, val, list(range(len(val))))
    ids = [base_task_id(train.demo.tasks[k]['task_id']) for k in train.task_indices]
    out = {i for i, t in enumerate(ids) if held_out(t, cfg.val_fraction)}
    if cfg.val_fraction > 0 and not out and len(ids) > 1:      # a tiny folder still gets one
        first = min(ids, key=lambda t: hashlib.sha256(t.encode()).hexdigest())
        out = {i for i, t in enumerate(ids) if t == first}        # with its detour, if any
    train_items = [i for i in every if i // combos not in out]
    train.no_recovery = out              # the held-out tasks are validated as the expert played them
    if not train_items:
        raise ValueError(f'no training tasks left in {cfg.demonstrations} after holding out {len(out)}')
    return Data(train, train_items, train if out else None, [i for i in every if i // combos in out])


def load_vocabulary(cfg: TrainConfig) -> Vocabulary:
    """--vocabulary, or the training folder's (built from its texts if it has none); with --reworded, extended
    by the annotator's words for the folder's answers (`data.paraphrase_texts`)."""
    path = Path(cfg.vocabulary) if cfg.vocabulary else Path(cfg.demonstrations) / VOCABULARY_FILE
    if path.is_file():
        vocab = Vocabulary.load(path)
    elif cfg.vocabulary:
        raise FileNotFoundError(f'no vocabulary at {path}')
    else:
        vocab = Vocabulary.build(vocabulary_texts(Path(cfg.demonstrations)) + oracle_texts())
    if cfg.reworded and not cfg.vocabulary:
        vocab = vocab.extended(paraphrase_texts(Path(cfg.demonstrations)))
    return vocab


def epoch_items(data: Data, cfg: TrainConfig, epoch: int) -> list[int]:
    """The training items of `epoch`: all of them, or (--no-every-combination) one per task, its
    question-type combination drawn from (seed, epoch, task)."""
    if cfg.every_combination:
        return data.train_items
    combos = data.train.per_task
    tasks = sorted({i // combos for i in data.train_items})
    draws = np.random.default_rng([cfg.seed, epoch, 1]).integers(combos, size=len(tasks))
    return [k * combos + int(c) for k, c in zip(tasks, draws)]


def lr_factor(update: int, warmup: int, total: int, final: float) -> float:
    """Linear warmup to 1 over `warmup` updates, then cosine to `final` at `total`."""
    if update < warmup:
        return (update + 1) / warmup
    progress = min(1.0, (update - warmup) / max(1, total - warmup))
    return final + (1 - final) * 0.5 * (1 + math.cos(math.pi * progress))


def make_optimizer(model: torch.nn.Module, cfg: TrainConfig) -> torch.optim.Optimizer:
    learnt = [(n, p) for n, p in model.named_parameters() if p.requires_grad]      # not a frozen perception
    decay = [p for n, p in learnt if p.ndim >= 2 and 'norm' not in n]
    rest = [p for n, p in learnt if not (p.ndim >= 2 and 'norm' not in n)]
    return torch.optim.AdamW([{'params': decay, 'weight_decay': cfg.weight_decay},
                              {'params': rest, 'weight_decay': 0.0}], lr=cfg.lr)


# ---------------------------------------------------------------------- checkpoints

@dataclass
class Progress:
    epoch: int = 0
    batch_in_epoch: int = 0           # batches of `epoch` already trained on
    update: int = 0
    best_val_loss: float = math.inf
    window: dict = field(default_factory=lambda: dict.fromkeys(STAT_KEYS, 0))


def save_training(path: Path, model, vocab, cfg, optimizer, scheduler, progress: Progress, full: bool = True,
                  commit: Optional[str] = None, rank_rng: Optional[list] = None) -> None:
    """`rank_rng`: every training process's torch RNG state (several processes), so each resumes its stream."""
    extra = {'train_config': json.dumps(dataclasses.asdict(cfg)), 'progress': dataclasses.asdict(progress)}
    if full:
        extra.update(optimizer=optimizer.state_dict(), scheduler=scheduler.state_dict(),
                     torch_rng=torch.get_rng_state(),
                     cuda_rng=torch.cuda.get_rng_state_all() if torch.cuda.is_available() else [])
        if rank_rng is not None:
            extra['rank_torch_rng'] = rank_rng
    save_checkpoint(path, model, vocab, command=command_line(MODULE, cfg), extra=extra, commit=commit)


def restore_training(path: Path, cfg: TrainConfig, model, optimizer, scheduler,
                     ranks: Ranks = Ranks()) -> tuple[Vocabulary, Progress]:
    """Load `path` (a full last.pt) into model, optimiser and schedule; restore the RNG (this rank's,
    if the run had as many processes; else a stream of (seed, rank, update)); the progress.
    ValueError if its config differs from `cfg` in anything but RESUMABLE_CHANGES."""
    loaded, vocab, info = load_checkpoint(path)
    extra = info['extra']
    if 'optimizer' not in extra:
        raise ValueError(f'{path} has no optimiser state: it cannot be resumed from')
    saved = json.loads(extra['train_config'])
    diff = config_changes(saved, cfg, RESUMABLE_CHANGES)
    if diff:
        raise ValueError(f'--resume: the config differs from the one {path} was trained with '
                         f'(field: (then, now)): {diff}')
    model.load_state_dict(loaded.state_dict())
    optimizer.load_state_dict(extra['optimizer'])
    scheduler.load_state_dict(extra['scheduler'])
    torch.set_rng_state(extra['torch_rng'])
    if extra['cuda_rng'] and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(extra['cuda_rng'])
    progress = Progress(**extra['progress'])
    per_rank = extra.get('rank_torch_rng') or []
    if len(per_rank) == ranks.world and ranks.distributed:
        torch.set_rng_state(per_rank[ranks.rank])
    elif ranks.rank:         # the run had another number of processes: rank 0 goes on with its stream
        torch.manual_seed(rank_seed(cfg.seed, ranks.rank, progress.update))
    return vocab, progress


def warm_start(model: Performer, vocab: Vocabulary, path: Path) -> None:
    """Load the weights of the performer checkpoint `path` into `model` (--init): the same vocabulary,
    sizes and perception network; a model with the failure input that the checkpoint lacks gets each
    failed action's embedding row from the action's own (it starts as if the action had worked)."""
    source, source_vocab, _ = load_checkpoint(path)
    if source_vocab != vocab:
        raise ValueError(f'--init {path}: its vocabulary is not the training folder\'s')
    mine, theirs = model.state_dict(), source.state_dict()
    key = 'actions.embedding.weight'
    differ = sorted(k for k in set(mine) | set(theirs) if k != key and
                    (k not in mine or k not in theirs or mine[k].shape != theirs[k].shape))
    if differ:
        raise ValueError(f'--init {path}: another model ({", ".join(differ[:4])} differ); only the failure input '
                         f'may be added')
    other_net = [k for k in mine if k.startswith('visual.net.') and not torch.equal(mine[k], theirs[k])]
    if other_net:
        raise ValueError(f'--init {path}: it sees through another perception network than --perception')
    rows, n = theirs[key], len(ACTIONS)
    if mine[key].shape[0] < rows.shape[0]:
        raise ValueError(f'--init {path}: it has the failure input (--failure-input) and this run does not')
    if mine[key].shape[0] > rows.shape[0]:            # failed_id(a) = n + 1 + a: each starts as its action's row
        rows = torch.cat([rows, rows[:n]])
    model.load_state_dict({**theirs, key: rows})


# ---------------------------------------------------------------------- training

class StopRequest:
    """While it is held, a first Ctrl-C (SIGINT) asks the loop to stop after the current update and
    write last.pt (a consistent state to --resume from); a second one stops at once."""

    def __init__(self):
        self.asked = False
        self.previous = signal.signal(signal.SIGINT, self._handle)

    def _handle(self, signum, frame) -> None:
        if self.asked:
            raise KeyboardInterrupt
        self.asked = True
        print('\nCtrl-C: stopping after this update and writing last.pt (again: stop now)', file=sys.stderr)

    def release(self) -> None:
        signal.signal(signal.SIGINT, self.previous)


def ignore_interrupts(_worker_id: int) -> None:
    """DataLoader workers leave Ctrl-C to the training process (which stops cleanly)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class Training:
    """One session of a training run: `__init__` sets it up (devices, seeds, data, the model, the optimiser,
    a resumed state), `run()` trains until the run or the session ends and returns the summary. Every
    random draw happens in the order of one uninterrupted run, so a resumed run is the same run."""

    def __init__(self, cfg: TrainConfig, ranks: Ranks):
        self.cfg, self.ranks = cfg, ranks
        check_batch(cfg.batch_size, ranks)
        self.out = out = Path(cfg.out)
        self.commit = git_commit()        # the code this run starts with, recorded in every checkpoint it writes
        check_folder(Path(cfg.demonstrations), 'training', cfg.dialogues)
        if cfg.detours:
            check_folder(Path(cfg.detours), 'detour', cfg.dialogues)
        if cfg.guided:
            check_folder(Path(cfg.guided), 'guided', cfg.dialogues)
        if cfg.validation:
            check_folder(Path(cfg.validation), 'validation', cfg.dialogues)
        if cfg.resume and not (out / 'last.pt').is_file():
            raise FileNotFoundError(f'--resume: no {out / "last.pt"} to continue from')
        self.device = device = rank_device(pick_device(cfg.device), ranks)
        torch.set_num_threads(cfg.threads or max(1, len(os.sched_getaffinity(0)) // ranks.local_world))
        seed_everything(cfg.seed, cfg.deterministic, device)
        init(ranks, device)
        out.mkdir(parents=True, exist_ok=True)

        self.arithmetic = frozen_arithmetic(cfg)
        if cfg.resume:
            _, self.vocab, info = load_checkpoint(out / 'last.pt')
            self.arithmetic = info['config'].frozen_arithmetic      # auto as resolved where the run began
        else:
            self.vocab = load_vocabulary(cfg)
        self.data = load_data(cfg, self.vocab)
        self.model = model = self._model()
        self.features = self.val_features = None           # blocks.BlockFeatures with --block-tasks
        if cfg.block_tasks:
            self.features = BlockFeatures(model.visual, self.data.train)
            self.data.train.with_frames = False
            if self.data.val is self.data.train:
                self.val_features = self.features
            elif self.data.val is not None:
                self.val_features = BlockFeatures(model.visual, self.data.val)
                self.data.val.with_frames = False
        self.per_epoch = per_epoch = len(self.epoch_plan(0)[1])
        self.total = total = min(cfg.epochs * per_epoch, cfg.max_updates or math.inf)
        self.optimizer = make_optimizer(model, cfg)
        self.scheduler = torch.optim.lr_scheduler.LambdaLR(
            self.optimizer, lambda u: lr_factor(u, cfg.warmup_updates, total, cfg.final_lr_fraction))
        self.progress = Progress()
        if cfg.resume:
            _, self.progress = restore_training(out / 'last.pt', cfg, model, self.optimizer, self.scheduler, ranks)
        elif ranks.rank:
            torch.manual_seed(rank_seed(cfg.seed, ranks.rank))     # this rank's dropout stream (after the same init)
        self.net = model
        if ranks.distributed:
            self.net = torch.nn.parallel.DistributedDataParallel(
                model, device_ids=[device.index] if device.type == 'cuda' else None)
        self.log = None
        if ranks.main:       # the only process that writes files
            self.log = MetricsLog(out / 'metrics.jsonl', self.progress.update if cfg.resume else None)
            (out / 'config.json').write_text(json.dumps(dataclasses.asdict(cfg), indent=1) + '\n')
        self.bar = progress_bar(total=total, initial=self.progress.update, unit='update',
                                disable=not (cfg.progress and ranks.main),
                                desc=f'epoch {self.progress.epoch + 1}/{cfg.epochs}')
        self.session_updates, self.frames_seen, self.t_start = 0, 0, time.monotonic()
        self.t_window, self.last = time.monotonic(), {}

    def _model(self) -> Performer:
        """The model of the run's config on its device: the perception network's weights, --init's."""
        cfg = self.cfg
        model_cfg, perception_weights = model_config(cfg)
        if model_cfg.visual == 'perception':                # the agent perceives as the performer trained
            model_cfg = dataclasses.replace(model_cfg, frozen_arithmetic=self.arithmetic)
        model = Performer(model_cfg, len(self.vocab))
        if perception_weights is not None:
            model.visual.net.load_state_dict(perception_weights)
        if cfg.init and not cfg.resume:
            warm_start(model, self.vocab, Path(cfg.init))
        if isinstance(model.visual, PerceivedFrames):
            model.visual.precision = self.arithmetic
            if cfg.perception_channels_last:
                model.visual.to_channels_last()
        return model.to(self.device)

    def checkpoint(self, name: str = 'last.pt', full: bool = True) -> None:
        """Rank 0 writes; with several processes every rank must call it (a full one gathers their RNGs)."""
        ranks = self.ranks
        rank_rng = gather_rng(ranks) if full and ranks.distributed else None
        if ranks.main:
            save_training(self.out / name, self.model, self.vocab, self.cfg, self.optimizer, self.scheduler,
                          self.progress, full, self.commit, rank_rng)

    def validate_and_draw(self) -> None:
        data, ranks, cfg = self.data, self.ranks, self.cfg
        if data.val is not None and data.val_items:
            mine = data.val_items[ranks.rank::ranks.world]          # each process a share; the sums all-reduced
            val = evaluate(self.model, data.val, mine, Data.item_lengths(data.val, mine), cfg.batch_size,
                           cfg.pointer_weight, self.device,
                           reduce=(lambda totals: reduce_stats(totals, self.device)) if ranks.distributed else None,
                           features=self.val_features, block_tasks=cfg.block_tasks)
            if self.log is not None:
                self.log.write({'kind': 'val', 'update': self.progress.update, 'epoch': self.progress.epoch, **val})
            self.last['val'] = val
            if val['loss'] < self.progress.best_val_loss:
                self.progress.best_val_loss = val['loss']
                self.checkpoint('best.pt', full=False)
        if ranks.main:
            draw_curves(self.out / 'metrics.jsonl', self.out / 'curves.png')

    def epoch_plan(self, epoch: int) -> tuple[list[int], list[list[int]], Optional[list]]:
        """(the epoch's items, its batches as positions into them, its blocks or None): in random order, or
        with --block-tasks in blocks (blocks.block_batches)."""
        cfg, data = self.cfg, self.data
        items = epoch_items(data, cfg, epoch)
        lengths = Data.item_lengths(data.train, items)
        if not cfg.block_tasks:
            return items, epoch_batches(lengths, cfg.batch_size, cfg.seed, epoch, cfg.bucket), None
        batches, blocks = block_batches(items, lengths, data.train.per_task, cfg.batch_size, cfg.seed, epoch,
                                        cfg.bucket, cfg.block_tasks, cfg.block_items, cfg.block_bucket)
        return items, batches, blocks

    def update(self, batch, stand_in: bool) -> None:
        """One optimiser step on this process's share of a global batch, counted, logged and checkpointed."""
        cfg, ranks, progress, device = self.cfg, self.ranks, self.progress, self.device
        batch = to_device(batch, device)
        if ranks.distributed:
            steps, targets = global_counts(batch, stand_in, device)
            outputs = self.net(batch)
            loss = sharded_loss(outputs, batch, cfg.pointer_weight, steps, targets, ranks.world,
                                weight=0.0 if stand_in else 1.0)
        else:
            outputs = self.model(batch)
            loss, _ = performer_loss(outputs, batch, cfg.pointer_weight)
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        if cfg.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(self.model.parameters(), cfg.grad_clip)
        self.optimizer.step()
        self.scheduler.step()
        progress.update += 1
        progress.batch_in_epoch += 1
        self.session_updates += 1
        stats = zero_stats() if stand_in else batch_stats(outputs, batch)
        stats = reduce_stats(stats, device) if ranks.distributed else stats     # the global batch's
        for k, v in stats.items():
            progress.window[k] += v
        self.frames_seen += stats['steps']
        self.bar.update(1)
        if progress.update % cfg.log_every == 0 and self.log is not None:
            now = time.monotonic()
            row = summarize(progress.window, cfg.pointer_weight)
            row.update(frames_per_s=round(row['steps'] / max(now - self.t_window, 1e-9), 2),
                       lr=self.scheduler.get_last_lr()[0])
            self.log.write({'kind': 'train', 'update': progress.update, 'epoch': progress.epoch, **row})
            self.bar.set_postfix(loss=f'{row["loss"]:.3f}', act=f'{row["action_accuracy"]:.3f}',
                                 fps=f'{row["frames_per_s"]:.0f}')
            self.last['train'] = row
        if progress.update % cfg.log_every == 0:
            progress.window, self.t_window = dict.fromkeys(STAT_KEYS, 0), time.monotonic()
        if (cfg.validate_every and progress.update % cfg.validate_every == 0 and progress.update < self.total
                and progress.batch_in_epoch < self.per_epoch):       # the epoch's and the run's end validate anyway
            self.validate_and_draw()
            self.t_window = time.monotonic()                      # frames/s of training only
        if progress.update % cfg.checkpoint_every == 0:
            self.checkpoint()

    def epoch(self, stop_request: StopRequest) -> bool:
        """The rest of the current epoch (ended at --stop-after, Ctrl-C or the last update); whether the
        session must halt."""
        cfg, ranks, progress, data = self.cfg, self.ranks, self.progress, self.data
        items, batches, blocks = self.epoch_plan(progress.epoch)
        todo = [[items[p] for p in b] for b in batches[progress.batch_in_epoch:]]
        # this process's share of each global batch (all of it for one process); a stand-in weighs 0
        shares = [rank_share(b, ranks) for b in todo] if ranks.distributed else [(b, False) for b in todo]
        # Its own generator: a DataLoader iterator draws a seed, which must not come from torch's global
        # RNG (dropout's), or a resumed run (one more iterator) would draw different dropout masks.
        loader = torch.utils.data.DataLoader(data.train, batch_sampler=[b for b, _ in shares], collate_fn=collate,
                                             num_workers=cfg.loader_workers,
                                             generator=torch.Generator().manual_seed(cfg.seed),
                                             worker_init_fn=ignore_interrupts if cfg.loader_workers else None)
        halt = False
        for position, (batch, (_, stand_in)) in enumerate(zip(loader, shares), start=progress.batch_in_epoch):
            if blocks is not None:
                self.features.load(blocks[block_of(blocks, position)].tasks)
                batch = self.features.attach(to_device(batch, self.device))
            self.update(batch, stand_in)
            halt = (bool(cfg.stop_after) and self.session_updates >= cfg.stop_after) or stop_request.asked
            if ranks.distributed:
                halt = any_rank(halt, self.device)        # a Ctrl-C seen by one process stops all at this update
            if halt or progress.update >= self.total:
                break
        if progress.batch_in_epoch == len(batches):          # the epoch is complete
            self.validate_and_draw()
            progress.epoch += 1
            progress.batch_in_epoch = 0
            self.checkpoint(f'epoch-{progress.epoch:03d}.pt', full=False)
            self.checkpoint()
            self.bar.set_description(f'epoch {min(progress.epoch + 1, cfg.epochs)}/{cfg.epochs}')
            self.t_window = time.monotonic()                      # frames/s of training only
        return halt

    def run(self) -> dict:
        """Train until the run ends, --stop-after or Ctrl-C; write last.pt; the session's summary."""
        cfg, progress = self.cfg, self.progress
        stop_request = StopRequest()
        try:
            self.model.train()
            halt = False                      # --stop-after reached or Ctrl-C: this session ends
            while progress.epoch < cfg.epochs and progress.update < self.total and not halt:
                halt = self.epoch(stop_request)
            finished = progress.update >= self.total or progress.epoch >= cfg.epochs
            if finished and progress.batch_in_epoch and self.session_updates:   # max_updates ended it in an epoch
                self.validate_and_draw()
            self.checkpoint()
            if not finished and self.ranks.main:
                draw_curves(self.out / 'metrics.jsonl', self.out / 'curves.png')
            self.bar.close()
        finally:
            stop_request.release()
        return self.summary(finished)

    def summary(self, finished: bool) -> dict:
        seconds = time.monotonic() - self.t_start
        progress, data = self.progress, self.data
        return {'finished': finished, 'updates': progress.update, 'epoch': progress.epoch, 'total_updates': self.total,
                'session_updates': self.session_updates, 'session_seconds': round(seconds, 2),
                'frames_per_s': round(self.frames_seen / max(seconds, 1e-9), 2), 'device': str(self.device),
                'threads': torch.get_num_threads(), 'processes': self.ranks.world,
                'malloc_settings': all(k in os.environ for k in MALLOC_SETTINGS),
                'train_episodes': len(data.train_items),
                'val_episodes': len(data.val_items), 'val': self.last.get('val'), 'out': str(self.out)}


def train(cfg: TrainConfig, ranks: Optional[Ranks] = None) -> dict:
    """Train (or continue) the run of `cfg` as process `ranks` of a distributed run (default: torchrun's
    environment; one process without it); the final summary (also the last line printed by main)."""
    return Training(cfg, ranks or Ranks.from_env()).run()


def main(argv: Optional[list[str]] = None) -> int:
    cfg = parse(TrainConfig, argv, prog=f'python -m {MODULE}')
    ranks = Ranks.from_env()
    try:
        summary = train(cfg, ranks)
    except (FileNotFoundError, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    finally:
        finish(ranks)
    if ranks.main:
        print(json.dumps(summary))
    return 0


if __name__ == '__main__':
    ensure_malloc_settings(MODULE)
    sys.exit(main())
