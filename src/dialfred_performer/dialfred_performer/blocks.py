"""The order of an epoch's training items, and the frozen perception network run once per block of tasks.

An epoch shows every training task once per question-type combination: eight items a task, all with the
task's frames. In random order (`epoch_batches`) the frozen perception network runs on every frame of
every item, six to eight times a frame in a run, and that is most of an update's time
(`./dialfred bench performer_update`). In block order (`block_batches`, `TrainConfig.block_tasks`) the
epoch's tasks are shuffled and cut into blocks; a block's items (every combination of its tasks) are
shuffled, bucketed by length and batched among themselves, so each batch still holds different tasks,
and the network runs once on each frame of the block when the block begins (`BlockFeatures`). It runs
on the block's frames in their order, in chunks of a fixed size, so a run resumed inside a block
computes the same numbers.

What changes with blocks is the order alone: each epoch still shows every item once. What the
performer reads is the same network's output, gathered per batch instead of computed per batch.
Showing all eight items of a task in one block saves the most (the network once per frame an epoch) but
sees two new tasks per update where random order sees about thirteen early on, and that cost
validation loss (measured: docs/performer.md); `per_visit` shows a task's items in several visits, one
per round of the epoch (two items a visit: the network four times per frame an epoch, eight new tasks
per update).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
import torch

from .preprocess import frame_tensor

CHUNK = 256          # frames per pass of the frozen network when a block begins


def bucketed(lengths: Sequence[int], batch_size: int, rng: np.random.Generator, bucket: int) -> list[list[int]]:
    """Positions 0..len(lengths)-1 in batches: shuffled by `rng`, cut into groups of bucket x batch_size
    sorted by length (less padding), batched, and the batches shuffled."""
    order = rng.permutation(len(lengths))
    lengths = np.asarray(lengths)
    batches = []
    for g in range(0, len(order), batch_size * bucket):
        group = order[g:g + batch_size * bucket]
        group = group[np.argsort(lengths[group], kind='stable')] if bucket > 1 else group
        batches += [group[j:j + batch_size].tolist() for j in range(0, len(group), batch_size)]
    return [batches[k] for k in rng.permutation(len(batches))] if bucket > 1 else batches


def epoch_batches(lengths: Sequence[int], batch_size: int, seed: int, epoch: int, bucket: int) -> list[list[int]]:
    """Positions 0..len(lengths)-1 in batches for one epoch, in random order (`bucketed`, seeded by
    (seed, epoch))."""
    return bucketed(lengths, batch_size, np.random.default_rng([seed, epoch]), bucket)


@dataclass(frozen=True)
class Block:
    first_batch: int               # the position of the block's first batch in the epoch's
    tasks: tuple[int, ...]         # the dataset's task positions (item // combinations), in the block's order


def block_batches(items: Sequence[int], lengths: Sequence[int], combinations: int, batch_size: int, seed: int,
                  epoch: int, bucket: int, block_tasks: int, per_visit: int = 0,
                  task_bucket: int = 1) -> tuple[list[list[int]], list[Block]]:
    """Positions into `items` (dataset indices, `lengths` their steps) in batches for one epoch in block
    order. Each task's items are shuffled and cut into visits of `per_visit` items (0: all of them, one
    visit); the epoch goes in rounds, round r showing every task's r-th visit: its tasks shuffled and cut
    into blocks of `block_tasks`, each block's items batched among themselves (`bucketed`). With
    `task_bucket` > 1 the round's shuffled tasks are sorted by length within groups of task_bucket x
    block_tasks before they are cut, and the round's blocks shuffled: a block as small as one batch
    then pads as little as random order's buckets do. Seeded by (seed, epoch). Returns (the batches, the
    blocks); every position is in exactly one batch."""
    if block_tasks < 1:
        raise ValueError(f'block_tasks must be at least 1, got {block_tasks}')
    if per_visit < 0:
        raise ValueError(f'per_visit must be at least 0, got {per_visit}')
    if task_bucket < 1:
        raise ValueError(f'task_bucket must be at least 1, got {task_bucket}')
    by_task: dict[int, list[int]] = {}
    for p, item in enumerate(items):
        by_task.setdefault(item // combinations, []).append(p)
    tasks = sorted(by_task)
    shuffle = np.random.default_rng([seed, epoch, 3])
    visits = {}
    for t in tasks:
        mine = [by_task[t][k] for k in shuffle.permutation(len(by_task[t]))]
        size = per_visit or len(mine)
        visits[t] = [mine[j:j + size] for j in range(0, len(mine), size)]
    rng = np.random.default_rng([seed, epoch, 1])
    batches: list[list[int]] = []
    blocks: list[Block] = []
    for r in range(max((len(v) for v in visits.values()), default=0)):
        here = [t for t in tasks if len(visits[t]) > r]
        order = [here[k] for k in rng.permutation(len(here))]
        if task_bucket > 1:
            group, steps = task_bucket * block_tasks, {t: lengths[visits[t][r][0]] for t in here}
            for g in range(0, len(order), group):
                order[g:g + group] = sorted(order[g:g + group], key=steps.__getitem__)     # stable
        cut = [tuple(order[s:s + block_tasks]) for s in range(0, len(order), block_tasks)]
        if task_bucket > 1:
            cut = [cut[k] for k in np.random.default_rng([seed, epoch, 4, r]).permutation(len(cut))]
        for block in cut:
            positions = [p for t in block for p in visits[t][r]]
            inner = bucketed([lengths[p] for p in positions], batch_size,
                             np.random.default_rng([seed, epoch, 2, len(blocks)]), bucket)
            blocks.append(Block(len(batches), block))
            batches += [[positions[q] for q in batch] for batch in inner]
    return batches, blocks


def block_of(blocks: Sequence[Block], batch: int) -> int:
    """The index of the block that holds batch position `batch`."""
    starts = [b.first_batch for b in blocks]
    return int(np.searchsorted(starts, batch, side='right')) - 1


class BlockFeatures:
    """The frozen network's output (`PerceivedFrames.outputs`) for every frame of one block's tasks,
    computed when the block is loaded, and gathered per batch (`attach`) by the items' `frame_ids`.

    Held per frame: the coarse map pooled to the embedding's cells, the decoder's map and the stem (about
    0.7 MB a frame in fp32 for the network of `./dialfred reproduce`)."""

    def __init__(self, visual, dataset, chunk: int = CHUNK):
        self.visual, self.dataset, self.chunk = visual, dataset, chunk
        self.tasks: Optional[tuple[int, ...]] = None
        self.ids = np.zeros(0, dtype=np.int64)       # the block's frame ids, sorted
        self.out = None                              # PerceptionOutput [F + 1, ...]: row F is a blank frame's
        self.frames_computed = 0
        self._blank = None                           # the blank (padding) frame's output: the network is frozen

    def frame_ids(self, tasks: Sequence[int]) -> np.ndarray:
        """The sorted frame ids (rows of the demonstrations' frames) that the items of `tasks` show."""
        ds = self.dataset
        ids = []
        for t in tasks:
            record = ds.demo.tasks[ds.task_indices[t]]
            first = record['first_frame']
            ids.append(np.arange(first, first + ds.steps_of(ds.task_indices[t])))
        return np.unique(np.concatenate(ids)) if ids else np.zeros(0, dtype=np.int64)

    def load(self, tasks: Sequence[int]) -> None:
        """Run the network on the frames of `tasks` (nothing if they are the loaded block's)."""
        tasks = tuple(tasks)
        if tasks == self.tasks:
            return
        self.out, self.tasks = None, None            # the last block's memory goes before the next one's
        ds, visual = self.dataset, self.visual
        ids = self.frame_ids(tasks)
        device = next(visual.parameters()).device
        size = ds.resolution
        parts = []
        for start in range(0, len(ids), self.chunk):
            frames = frame_tensor(np.asarray(ds.demo.frames[ids[start:start + self.chunk]]), size).to(device)
            parts.append(visual.outputs(frames, pooled=True))
        if self._blank is None:
            self._blank = visual.outputs(torch.zeros(1, 3, size, size, device=device), pooled=True)
        parts.append(self._blank)                                                                # padding
        self.out = type(parts[0])(*(torch.cat(maps) for maps in zip(*parts)))
        self.ids, self.tasks = ids, tasks
        self.frames_computed += len(ids)

    def attach(self, batch: dict) -> dict:
        """`batch` (a collated one, with `frame_ids` [B, T], -1 for padding) with `perceived`: the network's
        output for its B x T frames, flat, as `Performer.forward` reads it."""
        ids = batch['frame_ids'].reshape(-1).cpu().numpy()
        shown = ids >= 0
        rows = np.full(len(ids), len(self.ids), dtype=np.int64)     # padding: the blank frame's row
        at = np.searchsorted(self.ids, ids[shown])
        if (at >= len(self.ids)).any() or not np.array_equal(self.ids[at], ids[shown]):
            raise ValueError('the batch shows frames outside the loaded block')
        rows[shown] = at
        index = torch.from_numpy(rows).to(self.out.fine.device)
        return {**batch, 'perceived': type(self.out)(*(maps.index_select(0, index) for maps in self.out))}
