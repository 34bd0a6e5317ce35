"""Perception trained on our own world: a small convolutional network that learns what every pixel of a
frame is from the labels the simulator gives for free at training time (no ROS).

    ./dialfred prepare-performer --split train --labels          # frames with classes, depth, targets
    ./dialfred env python -m dialfred_performer.perception --out out/perception

E.T. (the paper's performer) did not learn to see from its action loss: it used visual features
trained elsewhere and a Mask R-CNN trained on AI2-THOR's frames. No pretrained weights can be had
here, so this is the honest equivalent: `Perception` reads an RGB frame only, and is trained on the
demonstrations' frames to predict, at 2 x 2-pixel cells, the class of what is there (`LABEL_CLASSES`:
nothing, floor, wall, ceiling and the 117 object types; object pixels weigh `object_weight` times a
structure pixel), its depth (metres), and its colour (so that the features keep what an appearance
answer talks about). The labels exist in training only; the performer that uses the features sees RGB.

Its outputs (`PerceptionOutput`): `coarse` [N, c3, R/8, R/8] (what the transformer's frame embedding
is made from), `fine` [N, c, R/2, R/2] (the decoder's map) and `stem` [N, c1, R, R] (full-resolution
edges and colours); the performer's pointer scores every pixel from `fine` and `stem`.

Written to --out: `perception.pt` (a `save_perception` file: config + weights; the best validation
loss), `last.pt` (with the optimiser and RNG state, for --resume), `metrics.jsonl`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple, Optional

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from dialfred_sim.dataclass_cli import arg, check_bounds, command_line, config_changes, parse
from dialfred_sim.tasks.demonstrations import DEPTH_STEP, default_dir, label_classes, load_demonstrations

from .data import held_out
from .malloc import ensure_malloc_settings

MODULE = 'dialfred_performer.perception'
PERCEPTION_FORMAT = 'dialfred-perception/1'
FIRST_OBJECT_CLASS = 4            # classes below are nothing, Floor, Wall, Ceiling


@dataclass(frozen=True)
class PerceptionNetConfig:
    """Sizes of the perception network."""

    resolution: int = 64
    c1: int = 24            # channels at R/2 (and of the full-resolution stem)
    c2: int = 48            # at R/4
    c3: int = 96            # at R/8
    decoder: int = 32       # channels of the decoder's R/2 map
    classes: int = 0        # set from label_classes() when 0


class PerceptionOutput(NamedTuple):
    coarse: torch.Tensor      # [N, c3, R/8, R/8]
    fine: torch.Tensor        # [N, decoder, R/2, R/2]
    stem: torch.Tensor        # [N, c1, R, R]


def _conv(cin: int, cout: int, stride: int = 1, dilation: int = 1) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, stride=stride, padding=dilation, dilation=dilation, bias=False),
                         nn.GroupNorm(8, cout), nn.ReLU(inplace=True))


class Perception(nn.Module):
    """RGB [N, 3, R, R] in [0, 1] -> PerceptionOutput; `heads(fine)` -> class logits, depth, colour at
    R/2 (training only)."""

    def __init__(self, config: PerceptionNetConfig):
        super().__init__()
        if config.resolution % 8:
            raise ValueError(f'the resolution must be a multiple of 8, got {config.resolution}')
        c = config
        self.config = config
        n_classes = c.classes or len(label_classes())
        self.stem = _conv(3, c.c1)                                               # R
        self.down1 = nn.Sequential(_conv(c.c1, c.c1, 2), _conv(c.c1, c.c1))      # R/2
        self.down2 = nn.Sequential(_conv(c.c1, c.c2, 2), _conv(c.c2, c.c2))      # R/4
        self.down3 = nn.Sequential(_conv(c.c2, c.c3, 2), _conv(c.c3, c.c3), _conv(c.c3, c.c3, dilation=2))  # R/8
        self.top = nn.Conv2d(c.c3, c.decoder, 1)
        self.lateral2 = nn.Conv2d(c.c2, c.decoder, 1)
        self.lateral1 = nn.Conv2d(c.c1, c.decoder, 1)
        self.smooth2 = _conv(c.decoder, c.decoder)
        self.smooth1 = _conv(c.decoder, c.decoder)
        self.class_head = nn.Conv2d(c.decoder, n_classes, 1)
        self.depth_head = nn.Conv2d(c.decoder, 1, 1)
        self.colour_head = nn.Conv2d(c.decoder, 3, 1)
        self.register_buffer('mean', torch.tensor([0.5, 0.5, 0.5]).view(1, 3, 1, 1), persistent=False)

    def encode(self, frames: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """The encoder's maps (stem, R/2, R/4, R/8): `decode` of them is `forward` of the frames."""
        stem = self.stem(frames - self.mean)
        f1 = self.down1(stem)
        f2 = self.down2(f1)
        return stem, f1, f2, self.down3(f2)

    def coarse(self, frames: torch.Tensor) -> torch.Tensor:
        """The R/8 map alone (PerceptionOutput.coarse), without the decoder."""
        return self.encode(frames)[3]

    def decode(self, encoded: tuple[torch.Tensor, ...]) -> PerceptionOutput:
        stem, f1, f2, f3 = encoded
        up = F.interpolate(self.top(f3), scale_factor=2, mode='nearest') + self.lateral2(f2)
        up = F.interpolate(self.smooth2(up), scale_factor=2, mode='nearest') + self.lateral1(f1)
        return PerceptionOutput(f3, self.smooth1(up), stem)

    def forward(self, frames: torch.Tensor) -> PerceptionOutput:
        return self.decode(self.encode(frames))

    def heads(self, fine: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """fine [N, c, R/2, R/2] -> (class logits [N, K, R/2, R/2], depth m [N, R/2, R/2], colour [N, 3, R/2, R/2])."""
        return self.class_head(fine), self.depth(fine), torch.sigmoid(self.colour_head(fine))

    def depth(self, fine: torch.Tensor) -> torch.Tensor:
        """The depth head alone: `heads(fine)[1]` without the class and colour heads (the class head is most
        of the three's cost; the numbers are the same)."""
        return F.softplus(self.depth_head(fine))[:, 0]


# ---------------------------------------------------------------------- labels -> targets

def cell_targets(classes: torch.Tensor, depth: torch.Tensor, rgb: torch.Tensor, n_classes: int):
    """Per-pixel labels [N, R, R] (uint8 classes, uint8 depth) and frames [N, 3, R, R] -> the targets at
    2 x 2 cells: class distribution [N, K, R/2, R/2] (the share of each class in the cell), depth in
    metres [N, R/2, R/2], mean colour [N, 3, R/2, R/2], object share [N, R/2, R/2]."""
    N, R = classes.shape[0], classes.shape[-1]
    cells = classes.long().view(N, R // 2, 2, R // 2, 2).permute(0, 1, 3, 2, 4).reshape(-1, 4)   # 4 pixels per cell
    share = torch.zeros(cells.shape[0], n_classes).scatter_add_(1, cells, torch.full(cells.shape, 0.25))
    share = share.view(N, R // 2, R // 2, n_classes).permute(0, 3, 1, 2)
    metres = F.avg_pool2d(depth.float()[:, None] * DEPTH_STEP, 2)[:, 0]
    colour = F.avg_pool2d(rgb, 2)
    objects = share[:, FIRST_OBJECT_CLASS:].sum(1)
    return share, metres, colour, objects


def small_object_boost(classes: torch.Tensor, n_classes: int, small_objects: float) -> torch.Tensor:
    """[N, K] how much more a cell of each class weighs in each frame: (A / area)^small_objects, at
    most 8, for a type covering less than A = 1/64 of the frame (1 for the rest), so that the few
    cells of a knife across the room count as much as they must for the network to learn to see it."""
    N = classes.shape[0]
    area = torch.zeros(N, n_classes).scatter_add_(1, classes.view(N, -1).long(),
                                                  torch.ones(N, classes[0].numel()))
    return (classes[0].numel() / 64.0 / area.clamp(min=1.0)).pow(small_objects).clamp(1.0, 8.0)


def perception_loss(net: Perception, out: PerceptionOutput, frames, classes, depth, object_weight: float,
                    small_objects: float = 0.0):
    """(loss, stats): class cross-entropy against each cell's class shares (object cells weigh
    `object_weight`, small ones more with `small_objects`: `small_object_boost`), L1 of depth in
    metres, L1 of colour."""
    logits, metres, colour = net.heads(out.fine)
    share, true_metres, true_colour, objects = cell_targets(classes, depth, frames, logits.shape[1])
    weight = 1.0 + (object_weight - 1.0) * objects
    if small_objects > 0:
        boost = small_object_boost(classes, logits.shape[1], small_objects) - 1.0
        weight = weight + object_weight * torch.einsum('nkhw,nk->nhw', share[:, FIRST_OBJECT_CLASS:],
                                                       boost[:, FIRST_OBJECT_CLASS:])
    ce = -(share * F.log_softmax(logits, 1)).sum(1)
    class_loss = (ce * weight).sum() / weight.sum()
    depth_loss = (metres - true_metres).abs().mean()
    colour_loss = (colour - true_colour).abs().mean()
    loss = class_loss + 0.5 * depth_loss + colour_loss
    with torch.no_grad():
        predicted = logits.argmax(1)
        majority = share.argmax(1)
        on_object = majority >= FIRST_OBJECT_CLASS
        stats = {'loss': float(loss), 'class': float(class_loss), 'depth_m': float(depth_loss),
                 'colour': float(colour_loss), 'cells': int(majority.numel()),
                 'cell_accuracy': float((predicted == majority).float().sum()),
                 'object_cells': int(on_object.sum()),
                 'object_accuracy': float((predicted == majority)[on_object].float().sum())}
    return loss, stats


# ---------------------------------------------------------------------- checkpoints

class PerceptionCheckpointError(ValueError):
    """A perception checkpoint that cannot be loaded, with why."""


def save_perception(path: Path, net: Perception, extra: Optional[dict] = None) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + '.tmp')
    torch.save({'format': PERCEPTION_FORMAT, 'config': dataclasses.asdict(net.config),
                'state_dict': net.state_dict(), 'extra': extra or {}}, tmp)
    tmp.replace(path)


def load_perception(path: Path, state: Optional[dict] = None) -> tuple[Perception, dict]:
    """(network in eval mode, extra) of a save_perception file (weights_only: no pickled code runs;
    `state`: the file's dict, when the caller has read it already)."""
    path = Path(path)
    if state is None and not path.is_file():
        raise FileNotFoundError(f'no perception checkpoint at {path} (made by python -m {MODULE})')
    try:
        if state is None:
            state = torch.load(path, map_location='cpu', weights_only=True)
        if state.get('format') != PERCEPTION_FORMAT:
            raise PerceptionCheckpointError(f'{path}: format {state.get("format")!r}, not {PERCEPTION_FORMAT!r}')
        net = Perception(PerceptionNetConfig(**state['config']))
        net.load_state_dict(state['state_dict'])
    except PerceptionCheckpointError:
        raise
    except Exception as exc:  # noqa: BLE001 - a damaged or foreign file raises many kinds
        raise PerceptionCheckpointError(f'{path} is not a perception checkpoint ({type(exc).__name__}: {exc})') from exc
    net.eval()
    return net, state.get('extra', {})


# ---------------------------------------------------------------------- training

@dataclass(frozen=True)
class PerceptionConfig:
    """Train the perception network on labelled demonstrations (prepare-performer --labels)."""

    demonstrations: str = arg(str(default_dir('train', 64)), 'a demonstrations folder built with --labels')
    val_fraction: float = arg(0.05, 'hold out the frames of the tasks whose id hashes below this (the performer\'s '
                                    'held-out tasks too)')
    out: str = arg('out/perception', 'where perception.pt, last.pt and metrics.jsonl go')
    c1: int = arg(PerceptionNetConfig.c1, 'channels at R/2 and of the stem')
    c2: int = arg(PerceptionNetConfig.c2, 'channels at R/4')
    c3: int = arg(PerceptionNetConfig.c3, 'channels at R/8')
    decoder: int = arg(PerceptionNetConfig.decoder, 'channels of the decoder map')
    frames: int = arg(250_000, 'training frames to show in all (a frame may be shown again)')
    batch_size: int = arg(64, 'frames per update')
    lr: float = arg(2e-3, 'peak learning rate (AdamW, warm-up then cosine)')
    weight_decay: float = arg(1e-4, 'AdamW weight decay')
    object_weight: float = arg(4.0, 'weight of a cell of an object against one of floor, wall or nothing')
    small_objects: float = arg(0.0, 'an object type covering less than 1/64 of a frame weighs (1/64 of the frame / '
                                    'its area)^this more (at most 8 times; 0: off)')
    val_frames: int = arg(4000, 'held-out frames evaluated at each validation')
    validate_every: int = arg(500, 'updates between validations (and last.pt)')
    seed: int = arg(0, 'the seed of the initial weights and of the frames drawn')
    threads: int = arg(2, 'torch threads')
    precision: str = arg('fp32', "the training steps' arithmetic: fp32, bf16 (autocast: the convolutions in "
                                 'bfloat16, the weights and the validation in fp32), or auto: bf16 where the CPU '
                                 'does bfloat16 natively (AMX or AVX512-BF16, `native_bf16`), else fp32')
    resume: bool = arg(False, 'go on from --out/last.pt')
    progress: bool = arg(True, 'a progress bar on stderr')

    def __post_init__(self):
        check_bounds(self, at_least_one=('frames', 'batch_size', 'val_frames', 'validate_every', 'threads'),
                     positive=('lr',))
        if not 0 < self.val_fraction < 1:
            raise ValueError(f'val_fraction must be in (0, 1), got {self.val_fraction}')
        if self.precision not in ('fp32', 'bf16', 'auto'):
            raise ValueError(f'--precision takes fp32, bf16 or auto, got {self.precision!r}')

    @property
    def arithmetic(self) -> str:
        """The precision the steps run in on this machine: fp32 or bf16 (`auto` resolved)."""
        return resolve_precision(self.precision)


def resolve_precision(precision: str) -> str:
    """fp32 or bf16 on this machine: `auto` is bf16 where the CPU does bfloat16 natively, else fp32."""
    if precision == 'auto':
        return 'bf16' if native_bf16() else 'fp32'
    return precision


def native_bf16() -> bool:
    """Whether this CPU computes bfloat16 natively (AMX or AVX512-BF16 in /proc/cpuinfo's flags). Where it
    does not, PyTorch emulates it, about ten times slower than fp32 (docs/figures.md)."""
    try:
        text = Path('/proc/cpuinfo').read_text()
    except OSError:
        return False
    flags = next((line.split(':', 1)[1].split() for line in text.splitlines() if line.startswith('flags')), [])
    return 'amx_bf16' in flags or 'avx512_bf16' in flags


def frame_split(demo, fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """(training frame rows, held-out frame rows) of a demonstrations build, by task."""
    train, val = [], []
    for t in demo.tasks:
        rows = range(t['first_frame'], t['first_frame'] + len(t['actions']) + 1)
        (val if held_out(t['task_id'], fraction) else train).extend(rows)
    return np.asarray(train, np.int64), np.asarray(val, np.int64)


def load_batch(demo, rows: np.ndarray) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    rows = np.sort(rows)                   # memmap reads in order
    frames = torch.from_numpy(np.ascontiguousarray(demo.frames[rows])).permute(0, 3, 1, 2).float() / 255.0
    classes = torch.from_numpy(np.ascontiguousarray(demo.labels['classes'][rows]))
    depth = torch.from_numpy(np.ascontiguousarray(demo.labels['depth'][rows]))
    return frames, classes, depth


def sum_stats(total: dict, stats: dict) -> None:
    for k, v in stats.items():
        total[k] = total.get(k, 0) + (v if k in ('cells', 'object_cells', 'cell_accuracy', 'object_accuracy')
                                      else v * stats['cells'])


def finish_stats(total: dict) -> dict:
    cells = max(total.get('cells', 0), 1)
    out = {k: round(total[k] / cells, 5) for k in ('loss', 'class', 'depth_m', 'colour') if k in total}
    out['cell_accuracy'] = round(total.get('cell_accuracy', 0) / cells, 5)
    out['object_accuracy'] = round(total.get('object_accuracy', 0) / max(total.get('object_cells', 0), 1), 5)
    return out


@torch.no_grad()
def validate(net: Perception, demo, rows: np.ndarray, cfg: PerceptionConfig) -> dict:
    net.eval()
    total: dict = {}
    for k in range(0, len(rows), cfg.batch_size):
        frames, classes, depth = load_batch(demo, rows[k:k + cfg.batch_size])
        _, stats = perception_loss(net, net(frames), frames, classes, depth, cfg.object_weight,
                                      cfg.small_objects)
        sum_stats(total, stats)
    net.train()
    return finish_stats(total)


def _frame_rows(cfg: PerceptionConfig, demo) -> tuple[np.ndarray, np.ndarray]:
    """The training frames and the held-out ones (at most cfg.val_frames, drawn with the seed) of `demo`."""
    if demo.labels is None:
        raise ValueError(f'{cfg.demonstrations} has no labels: build it with prepare-performer --labels')
    train_rows, val_rows = frame_split(demo, cfg.val_fraction)
    if not len(val_rows) or not len(train_rows):
        raise ValueError(f'{cfg.demonstrations}: {len(train_rows)} training and {len(val_rows)} held-out frames at '
                         f'--val-fraction {cfg.val_fraction}: both need some (more tasks, or another --val-fraction)')
    return train_rows, val_rows[np.random.default_rng([cfg.seed, 1]).permutation(len(val_rows))[:cfg.val_frames]]


def _resume(cfg: PerceptionConfig, out: Path, net: Perception, optimizer, scheduler) -> tuple[int, float, str]:
    """(update, best validation loss, arithmetic) to go on from: out/last.pt's, loaded into net, optimizer,
    scheduler and torch's generator, with --resume and a last.pt of the same config; else a fresh start."""
    if not (cfg.resume and (out / 'last.pt').exists()):
        return 0, float('inf'), cfg.arithmetic
    try:
        state = torch.load(out / 'last.pt', map_location='cpu', weights_only=True)
    except Exception as exc:  # noqa: BLE001 - a damaged or crafted file raises many kinds
        raise ValueError(f'{out / "last.pt"} cannot be resumed from ({type(exc).__name__}: {exc})') from None
    changes = config_changes(state['train_config'], cfg, ('resume', 'progress', 'threads'))
    if changes:
        raise ValueError(f'--resume with another config: {changes}')
    net.load_state_dict(state['state_dict'])
    optimizer.load_state_dict(state['optimizer'])
    scheduler.load_state_dict(state['scheduler'])
    torch.set_rng_state(state['torch_rng'])
    # auto precision resolved where the run began, kept
    return int(state['update']), float(state['best']), state.get('arithmetic', cfg.arithmetic)


def train_perception(cfg: PerceptionConfig) -> dict:
    """Train the perception network (`Perception`) on the labelled frames of cfg.demonstrations: AdamW with
    a warmed-up cosine, batches drawn by update number (a resumed run draws what the whole one would),
    mirrored half the time; validated every cfg.validate_every updates into out/metrics.jsonl, the best
    network by validation loss kept in out/perception.pt, the training state in out/last.pt. Returns the
    run's summary (the JSON line `main` prints)."""
    from dialfred_sim.progress import progress_bar  # lazy: tqdm, which the rest of this module does without
    torch.set_num_threads(cfg.threads)
    demo = load_demonstrations(Path(cfg.demonstrations).expanduser())
    train_rows, val_rows = _frame_rows(cfg, demo)
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(cfg.seed)
    net = Perception(PerceptionNetConfig(demo.meta['resolution'], cfg.c1, cfg.c2, cfg.c3, cfg.decoder,
                                         len(label_classes())))
    optimizer = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    updates = math.ceil(cfg.frames / cfg.batch_size)
    warmup = min(200, updates // 10 + 1)
    scheduler = torch.optim.lr_scheduler.LambdaLR(
        optimizer, lambda u: min(1.0, (u + 1) / warmup) * 0.5 * (1 + math.cos(math.pi * min(u, updates) / updates)))
    update, best, arithmetic = _resume(cfg, out, net, optimizer, scheduler)
    log = open(out / 'metrics.jsonl', 'a')
    total: dict = {}
    t0 = time.monotonic()
    net.train()
    with progress_bar(total=updates, initial=update, unit='update', disable=not cfg.progress,
              dynamic_ncols=True) as bar:
        while update < updates:
            rng = np.random.default_rng([cfg.seed, update])        # the frames of update u depend on u only
            frames, classes, depth = load_batch(demo, train_rows[rng.integers(len(train_rows), size=cfg.batch_size)])
            if rng.random() < 0.5:                                  # a mirrored room is a room too
                frames, classes, depth = frames.flip(-1), classes.flip(-1), depth.flip(-1)
            with torch.autocast('cpu', dtype=torch.bfloat16, enabled=arithmetic == 'bf16'):
                loss, stats = perception_loss(net, net(frames), frames, classes, depth, cfg.object_weight,
                                              cfg.small_objects)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
            optimizer.step()
            scheduler.step()
            update += 1
            sum_stats(total, stats)
            bar.update(1)
            if update % cfg.validate_every == 0 or update == updates:
                val = validate(net, demo, val_rows, cfg)
                row = {'update': update, 'frames': update * cfg.batch_size, 'train': finish_stats(total),
                       'val': val, 'lr': scheduler.get_last_lr()[0], 'seconds': round(time.monotonic() - t0, 1),
                       'precision': arithmetic}
                total = {}
                log.write(json.dumps(row) + '\n')
                log.flush()
                bar.set_postfix(val_loss=val['loss'], objects=val['object_accuracy'])
                if val['loss'] < best:
                    best = val['loss']
                    save_perception(out / 'perception.pt', net, {'update': update, 'val': val,
                                                                'command': command_line(MODULE, cfg)})
                tmp = out / 'last.pt.tmp'
                torch.save({'state_dict': net.state_dict(), 'optimizer': optimizer.state_dict(),
                            'scheduler': scheduler.state_dict(), 'update': update, 'best': best,
                            'torch_rng': torch.get_rng_state(), 'train_config': dataclasses.asdict(cfg),
                            'arithmetic': arithmetic}, tmp)
                tmp.replace(out / 'last.pt')
    log.close()
    _, extra = load_perception(out / 'perception.pt')
    return {'perception': str(out / 'perception.pt'), 'updates': update, 'best': extra.get('val'),
            'train_frames': len(train_rows), 'val_frames': len(val_rows), 'precision': arithmetic,
            'seconds': round(time.monotonic() - t0, 1)}


def main(argv: Optional[list[str]] = None) -> int:
    cfg = parse(PerceptionConfig, argv, prog=f'python -m {MODULE}')
    try:
        print(json.dumps(train_perception(cfg)))
    except (ValueError, FileNotFoundError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    ensure_malloc_settings(MODULE)
    sys.exit(main())
