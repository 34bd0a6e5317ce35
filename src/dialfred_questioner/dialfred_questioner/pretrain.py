"""Supervised pre-training of the learned questioner on a split's (SYNTHETIC) annotated dialogues.

    ./dialfred env python3 scripts/annotate_dialogues.py --splits train --workers 2     # once: the dialogues
    ./dialfred env python3 -m dialfred_questioner.frames train --workers 2            # once: first frames
    python -m dialfred_questioner.pretrain --out out/questioner [--resume]

Each annotation (two per task; `dialfred_questioner.data`) is an example: the instruction, the task's
first frame (encoded by the frozen visual encoder of the performer checkpoint `--performer`, whose
vocabulary the questioner also reads with), step 0, no dialogue -> the annotator's question type and
object, or none. Teacher forcing (the log-likelihood of the two tokens), AdamW, gradient clipping;
the tasks whose id hashes below `--val-fraction` are held out and scored after every epoch. Writes
to `--out`: `last.pt` after every epoch (with the optimiser and RNG state, so `--resume` continues to
the weights of an uninterrupted run), `best.pt` (lowest validation loss), `metrics.jsonl`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import random
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np
import torch

from dialfred_oracle.annotator import load_dialogues
from dialfred_performer.data import held_out
from dialfred_performer.model import SHIPPED_CHECKPOINT, load_checkpoint
from dialfred_sim.dataclass_cli import arg, check_bounds, parse
from dialfred_sim.metrics import git_commit

from .checkpoint import resume_training, save
from .data import Example, catalog_nouns, collate, frame_features, pretraining_examples
from .frames import FirstFrames, default_path
from .model import Questioner, QuestionerConfig

MODULE = 'dialfred_questioner.pretrain'
RESUMABLE_CHANGES = ('resume', 'progress', 'threads', 'epochs')


@dataclass(frozen=True)
class PretrainConfig:
    """Pre-train the DialFRED questioner on synthetic annotated dialogues (teacher forcing)."""

    split: str = arg('train', 'the annotated dialogues of this split (dialfred_oracle.annotator.load_dialogues)')
    frames: str = arg('', "the split's first frames (dialfred_questioner.frames; '': its default file, at "
                          "the performer's resolution)")
    performer: str = arg(str(SHIPPED_CHECKPOINT), 'performer checkpoint: its visual encoder (frozen) and vocabulary')
    out: str = arg('out/questioner', 'folder for last.pt, best.pt and metrics.jsonl')
    model: QuestionerConfig = field(default_factory=QuestionerConfig)
    epochs: int = arg(5, 'passes over the annotations')
    batch_size: int = arg(64, 'examples per update')
    lr: float = arg(1e-3, 'learning rate (AdamW)')
    weight_decay: float = arg(0.01, 'AdamW weight decay')
    grad_clip: float = arg(1.0, 'clip the gradient norm to this (0: no clipping)')
    val_fraction: float = arg(0.05, 'hold out the tasks whose id hashes below this')
    limit: int = arg(0, 'only the first N annotated tasks (0: all)')
    seed: int = arg(0, 'seeds python, numpy, torch and the shuffles')
    threads: int = arg(0, 'torch CPU threads (0: every core this process may use)')
    resume: bool = arg(False, 'continue from out/last.pt (same config required)')
    progress: bool = arg(True, 'progress bar on stderr')

    def __post_init__(self):
        check_bounds(self, at_least_one=('epochs', 'batch_size'),
                     non_negative=('limit', 'threads', 'seed', 'weight_decay', 'grad_clip'), positive=('lr',))
        if not 0 <= self.val_fraction < 1:
            raise ValueError(f'val_fraction must be in [0, 1), got {self.val_fraction}')


def batches(n: int, size: int, rng: random.Random) -> list[list[int]]:
    order = list(range(n))
    rng.shuffle(order)
    return [order[k:k + size] for k in range(0, n, size)]


@torch.no_grad()
def score(model: Questioner, examples: list[Example], vocab, features, batch_size: int) -> dict:
    """Mean loss, type accuracy and question accuracy (type and, where needed, object) on `examples`."""
    was = model.training
    model.eval()
    loss = types_right = right = 0.0
    for k in range(0, len(examples), batch_size):
        b = collate(examples[k:k + batch_size], vocab, features)
        enc = model.encode(b['lang_ids'], b['lang_types'], b['lang_valid'], b['image'], b['steps'])
        loss += float(-model.log_prob(enc, b['types'], b['nouns']).sum())
        got_types, got_nouns, _ = model.sample(enc, greedy=True)
        types_right += float((got_types == b['types']).sum())
        right += float(((got_types == b['types']) & (got_nouns == b['nouns'])).sum())
    model.train(was)
    n = max(len(examples), 1)
    return {'loss': loss / n, 'type_accuracy': types_right / n, 'question_accuracy': right / n, 'n': len(examples)}


def pretrain(cfg: PretrainConfig) -> dict:
    from dialfred_sim.progress import progress_bar  # lazy: tqdm, which the rest of this module does without

    out = Path(cfg.out)
    commit = git_commit()
    torch.set_num_threads(cfg.threads or len(os.sched_getaffinity(0)))
    random.seed(cfg.seed)
    np.random.seed(cfg.seed)
    torch.manual_seed(cfg.seed)
    performer, vocab, info = load_checkpoint(Path(cfg.performer))
    info = dict(info, path=str(cfg.performer))
    visual = performer.visual
    if cfg.model.image != performer.config.d_model:
        raise ValueError(f'--image must be the performer\'s d_model ({performer.config.d_model}), got {cfg.model.image}')
    rows = load_dialogues(cfg.split)[:cfg.limit or None]
    frames_path = Path(cfg.frames) if cfg.frames else default_path(cfg.split, performer.config.resolution)
    first = FirstFrames(frames_path)
    nouns = catalog_nouns()
    examples, skipped = pretraining_examples(rows, first.index, nouns)
    if not examples:
        raise ValueError(f'no examples: {skipped} annotations skipped (are {frames_path} and the '
                         f'{cfg.split} dialogues of the same split?)')
    used = sorted({e.frame for e in examples})
    slot = {f: k for k, f in enumerate(used)}
    features = frame_features(visual, first.frames[used], performer.config.resolution)
    examples = [dataclasses.replace(e, frame=slot[e.frame]) for e in examples]
    val = [e for e in examples if held_out(e.task_id, cfg.val_fraction)]
    train = [e for e in examples if not held_out(e.task_id, cfg.val_fraction)]
    model = Questioner(cfg.model, len(vocab), nouns)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    epoch, best = 0, math.inf
    log_path = out / 'metrics.jsonl'
    if cfg.resume:
        extra, _ = resume_training(out, cfg, RESUMABLE_CHANGES, model, opt, 'epoch')
        torch.set_rng_state(extra['torch_rng'])
        epoch, best = extra['epoch'], extra['best']
    else:
        out.mkdir(parents=True, exist_ok=True)
        log_path.write_text('')
    visual_state = {k: v.clone() for k, v in visual.state_dict().items()}
    t0 = time.monotonic()
    report = {}
    while epoch < cfg.epochs:
        rng = random.Random(f'{cfg.seed}/{epoch}')
        model.train()
        total = 0.0
        plan = batches(len(train), cfg.batch_size, rng)
        for idx in progress_bar(plan, desc=f'epoch {epoch + 1}/{cfg.epochs}', unit='batch',
                        disable=not cfg.progress):
            b = collate([train[i] for i in idx], vocab, features)
            enc = model.encode(b['lang_ids'], b['lang_types'], b['lang_valid'], b['image'], b['steps'])
            loss = -model.log_prob(enc, b['types'], b['nouns']).mean()
            opt.zero_grad()
            loss.backward()
            if cfg.grad_clip:
                torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.grad_clip)
            opt.step()
            total += float(loss.detach()) * len(idx)
        epoch += 1
        report = {'epoch': epoch, 'train_loss': total / max(len(train), 1),
                  'val': score(model, val, vocab, features, 256) if val else None,
                  'seconds': round(time.monotonic() - t0, 1)}
        with open(log_path, 'a') as f:
            f.write(json.dumps(report) + '\n')
        val_loss = report['val']['loss'] if val else report['train_loss']
        if val_loss < best:
            best = val_loss
            save(out / 'best.pt', model, vocab, visual_state, info, cfg, commit)
        save(out / 'last.pt', model, vocab, visual_state, info, cfg, commit,
             extra={'config': json.dumps(dataclasses.asdict(cfg)), 'optimizer': opt.state_dict(),
                    'torch_rng': torch.get_rng_state(), 'epoch': epoch, 'best': best})
    return {'examples': {'train': len(train), 'val': len(val), 'skipped': skipped}, **report, 'out': str(out)}


def main(argv: Optional[list[str]] = None) -> int:
    cfg = parse(PretrainConfig, argv, prog=f'python -m {MODULE}')
    print(json.dumps(pretrain(cfg)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
