"""Training metrics of the performer: per-batch sums (cross-entropies, correct actions and pointer
cells), their summary (loss, action and pointer accuracy), validation, and metrics.jsonl."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional, Sequence

import torch
import torch.nn.functional as F

from .data import collate
from .model import pointer_ce

STAT_KEYS = ('steps', 'targets', 'action_ce', 'pointer_ce', 'action_correct', 'pointer_correct', 'episodes')


def batch_stats(outputs: dict, batch: dict) -> dict:
    """Sums over a batch: cross-entropies and correct predictions (action over the steps whose action is
    a target; pointer over steps with a target, right when its best cell is one of the target's)."""
    valid = batch['action_valid']
    a_logits, p_logits = outputs['action_logits'].detach()[valid], outputs['pointer_logits'].detach()
    a_target, masks = batch['actions'][valid], batch['target_masks']
    best = p_logits.argmax(-1) if len(masks) else None
    return {'steps': int(valid.sum()), 'targets': len(masks),
            'action_ce': float(F.cross_entropy(a_logits, a_target, reduction='sum')),
            'pointer_ce': float(pointer_ce(p_logits, masks, reduction='sum')) if len(masks) else 0.0,
            'action_correct': int((a_logits.argmax(-1) == a_target).sum()),
            'pointer_correct': int(masks[torch.arange(len(masks)), best].sum()) if len(masks) else 0,
            'episodes': int(valid.shape[0])}


def summarize(stats: dict, pointer_weight: float) -> dict:
    steps, targets = max(stats['steps'], 1), max(stats['targets'], 1)
    action, pointer = stats['action_ce'] / steps, stats['pointer_ce'] / targets
    return {'loss': action + pointer_weight * pointer, 'action_loss': action, 'pointer_loss': pointer,
            'action_accuracy': stats['action_correct'] / steps,
            'pointer_accuracy': stats['pointer_correct'] / targets if stats['targets'] else None,
            'steps': stats['steps'], 'episodes': stats['episodes']}


def to_device(batch: dict, device: torch.device) -> dict:
    return {k: v.to(device, non_blocking=True) if torch.is_tensor(v) else v for k, v in batch.items()}


@torch.no_grad()
def evaluate(model, ds, items: Sequence[int], lengths: Sequence[int], batch_size: int, pointer_weight: float,
             device: torch.device, reduce=None, features=None, block_tasks: int = 0) -> dict:
    """Validation: loss, action and pointer accuracy over `items` of the dataset `ds` (episodes of
    `lengths` steps, batched shortest first), in eval mode; uses no random numbers. `reduce`: applied
    to the summed statistics before the summary (the sum over training processes, each with its share).
    With `features` (a blocks.BlockFeatures over `ds`), the items go in blocks of `block_tasks` tasks
    (in task order), the frozen network run once per block."""
    was_training = model.training
    model.eval()
    total = dict.fromkeys(STAT_KEYS, 0)
    length_of = dict(zip(items, lengths))
    combos = ds.per_task
    tasks = sorted({i // combos for i in items}) if features is not None else [None]
    step = block_tasks if features is not None else 1
    for start in range(0, len(tasks), step):
        block = tasks[start:start + step]
        chosen = set(block)
        group = items if features is None else [i for i in items if i // combos in chosen]
        if features is not None:
            features.load(block)
        order = sorted(group, key=lambda i: length_of[i])          # stable: shortest first
        for b in range(0, len(order), batch_size):
            batch = to_device(collate([ds[i] for i in order[b:b + batch_size]]), device)
            if features is not None:
                batch = features.attach(batch)
            for k, v in batch_stats(model(batch), batch).items():
                total[k] += v
    model.train(was_training)
    return summarize(reduce(total) if reduce else total, pointer_weight)


class MetricsLog:
    """metrics.jsonl: appended a line at a time; on resume, lines after the checkpoint are dropped."""

    def __init__(self, path: Path, keep_until: Optional[int]):
        self.path = path
        if keep_until is None:
            path.write_text('')
        elif path.exists():
            kept = [line for line in path.read_text().splitlines() if line and json.loads(line)['update'] <= keep_until]
            path.write_text(''.join(line + '\n' for line in kept))

    def write(self, row: dict) -> None:
        with open(self.path, 'a') as f:
            f.write(json.dumps(row) + '\n')
