"""Data-parallel training of the performer over processes (torchrun + DistributedDataParallel).

    torchrun --nproc_per_node 2 -m dialfred_performer.train --threads 1 ...     # or python -m torch.distributed.run

Every process (rank) builds the same global batches as a single process would (the same seeded
shuffle) and takes its share of each: the items at positions rank, rank + N, ... (`rank_share`). The
global batch stays `--batch-size` (which must divide by N). The loss of a rank is its sums of
cross-entropies over the *global* counts of valid steps and pointer targets (all-reduced before the
forward pass), times N: DDP averages the ranks' gradients, so the update is the gradient of the
single process's loss (`sharded_loss`). A rank left without an item (a last batch smaller than N)
plays a copy of the batch's first item with weight 0: it still joins the gradient all-reduce. The
statistics of metrics.jsonl are all-reduced sums, so rank 0 logs those of the whole batch.

What still differs from one process: the order of float sums (gradient all-reduce, padding to each
rank's own longest episode), and dropout: each rank draws its masks from its own stream
(`rank_seed`; rank 0 keeps the single process's), so with dropout > 0 the runs agree in
distribution, not draw for draw.
"""

from __future__ import annotations

import datetime
import os
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch
import torch.nn.functional as F

from .metrics import STAT_KEYS
from .model import pointer_ce


@dataclass(frozen=True)
class Ranks:
    """This process's place among the training processes (torchrun's RANK, WORLD_SIZE, LOCAL_RANK)."""

    rank: int = 0
    world: int = 1
    local: int = 0          # on this host
    local_world: int = 1    # processes on this host (they share its cores)

    @staticmethod
    def from_env() -> 'Ranks':
        world = int(os.environ.get('WORLD_SIZE', 1))
        return Ranks(int(os.environ.get('RANK', 0)), world, int(os.environ.get('LOCAL_RANK', 0)),
                     int(os.environ.get('LOCAL_WORLD_SIZE', world)))

    @property
    def distributed(self) -> bool:
        return self.world > 1

    @property
    def main(self) -> bool:
        """Rank 0: the one that writes checkpoints, metrics and curves."""
        return self.rank == 0


def backend_for(device: torch.device) -> str:
    return 'nccl' if device.type == 'cuda' else 'gloo'


def init(ranks: Ranks, device: torch.device, timeout_s: float = 7200.0) -> None:
    """Join the process group of torchrun's environment (gloo on CPU, nccl on CUDA); nothing for one process."""
    if ranks.distributed and not torch.distributed.is_initialized():
        torch.distributed.init_process_group(backend_for(device), timeout=datetime.timedelta(seconds=timeout_s))


def finish(ranks: Ranks) -> None:
    if ranks.distributed and torch.distributed.is_initialized():
        torch.distributed.destroy_process_group()


def rank_device(device: torch.device, ranks: Ranks) -> torch.device:
    """On CUDA, each process of a host takes its own GPU (cuda:LOCAL_RANK)."""
    if ranks.distributed and device.type == 'cuda':
        torch.cuda.set_device(ranks.local)
        return torch.device('cuda', ranks.local)
    return device


def rank_seed(seed: int, rank: int, update: int = 0) -> int:
    """Rank 0's torch seed is the run's (a 1-process run's stream); the others' are drawn from (seed,
    rank) (and the update, for a run resumed on another number of processes)."""
    if rank == 0 and not update:
        return seed
    return int(np.random.SeedSequence([seed, rank] + ([update] if update else [])).generate_state(1)[0])


def check_batch(batch_size: int, ranks: Ranks) -> None:
    if batch_size % ranks.world:
        raise ValueError(f'batch_size {batch_size} does not divide by the {ranks.world} processes: each takes an '
                         'equal share of the global batch')


def rank_share(batch: Sequence[int], ranks: Ranks) -> tuple[list[int], bool]:
    """(this rank's items of a global batch, whether they are a weightless stand-in): the items at
    positions rank, rank + N, ... (within a batch sorted by length, every rank gets alike lengths);
    a rank left without one gets the batch's first item, to be weighted 0."""
    share = list(batch[ranks.rank::ranks.world])
    return (share, False) if share else ([batch[0]], True)


def all_reduce_sum(values: Sequence[float], device: torch.device) -> list[float]:
    """The sums over the ranks of `values` (float64)."""
    t = torch.tensor(values, dtype=torch.float64, device=device)
    torch.distributed.all_reduce(t)
    return t.tolist()


def global_counts(batch: dict, stand_in: bool, device: torch.device) -> tuple[float, float]:
    """(steps with an action target, pointer targets) of the global batch: the sums of the ranks' counts."""
    local = [0.0, 0.0] if stand_in else [float(batch['action_valid'].sum()), float((batch['target_cells'] >= 0).sum())]
    steps, targets = all_reduce_sum(local, device)
    return steps, targets


def sharded_loss(outputs: dict, batch: dict, pointer_weight: float, steps: float, targets: float, world: int,
                 weight: float = 1.0) -> torch.Tensor:
    """This rank's part of `model.performer_loss` of the global batch, scaled for DDP's averaging:
    world x (action cross-entropy sum / global valid steps + pointer_weight x pointer cross-entropy sum /
    global targets). Summed over the ranks and divided by `world`, it is the single process's loss (and
    its gradient the update's). Every output takes part in the graph (DDP expects a gradient for each
    parameter), whatever this rank's share holds."""
    valid, masks = batch['action_valid'], batch['target_masks']
    action = F.cross_entropy(outputs['action_logits'][valid], batch['actions'][valid], reduction='sum') / max(steps, 1.0)
    pointer = outputs['pointer_logits'].sum() * 0.0
    if targets > 0 and len(masks):
        pointer = pointer + pointer_ce(outputs['pointer_logits'], masks, reduction='sum') / targets
    return (action + pointer_weight * pointer) * (world * weight)


def reduce_stats(stats: dict, device: torch.device) -> dict:
    """batch_stats summed over the ranks (counts stay ints)."""
    summed = all_reduce_sum([float(stats[k]) for k in STAT_KEYS], device)
    return {k: (v if isinstance(stats[k], float) else int(round(v))) for k, v in zip(STAT_KEYS, summed)}


def zero_stats() -> dict:
    """The statistics of a stand-in share: nothing counted."""
    return {k: 0.0 if k.endswith('_ce') else 0 for k in STAT_KEYS}


def any_rank(flag: bool, device: torch.device) -> bool:
    """Whether `flag` holds on some rank (a Ctrl-C seen by one process stops them all at the same update)."""
    return all_reduce_sum([float(flag)], device)[0] > 0


def gather_rng(ranks: Ranks) -> list:
    """Every rank's torch RNG state (on each rank), for a checkpoint to resume each rank's dropout stream."""
    states = [None] * ranks.world
    torch.distributed.all_gather_object(states, torch.get_rng_state())
    return states
