"""Where one performer update's time goes: the training loop of `dialfred_performer.train` on the frozen
perception network, timed piece by piece over real batches of the demonstrations. Pieces: loading and
collating the batch; the frozen network (`PerceivedFrames.perceive`: encoder and decoder on every frame,
the embedding and the keys of the interaction frames); the reach input's gradient-free pointer over every
step (`pointer_logits`, `distances`); the rest of the forward pass (language, transformer, heads);
the loss and backward pass; the optimiser step. Prints JSON.

    ./dialfred bench performer_update --perception out/reproduce/perception/perception.pt \
        [--demonstrations ~/.cache/dialfred/demonstrations/train_64] [--updates 40] [--skip 5] [--threads 2] \
        [--precision bf16] [--no-channels-last] [--block-tasks 8 --block-items 2 --block-bucket 32]

The model is the one `./dialfred reproduce` trains (its performer stage's config: batch 16, the reach
input); its weights are fresh (the time of an update does not depend on them). The batches timed are
spread evenly over the first epoch's (in block order: the epoch's first batches, each block's network pass
timed when the block is loaded and spread over its batches); the first `--skip` warm the allocator and are
not counted.

An update's time grows with its frames (the frozen network runs on every one), and a few dozen batches
can average many more or fewer frames than the epoch's. So the figure to multiply by a stage's updates is
`seconds_per_update_at_epoch_mean`: the sample's seconds per frame times the epoch's mean frames per
update (`epoch_frames_per_update`, from every batch's lengths).
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from collections import defaultdict

import torch

from dialfred_performer.blocks import block_of
from dialfred_performer.data import collate
from dialfred_performer.distributed import Ranks
from dialfred_performer.model import PerformerConfig, performer_loss
from dialfred_performer.nn.enc_perceived import PerceivedFrames
from dialfred_performer.train import TrainConfig, Training
from dialfred_sim.tasks.demonstrations import default_dir


class Clock:
    """Seconds per named piece, per update."""

    def __init__(self):
        self.now = defaultdict(float)

    def wrap(self, obj, name: str, key: str) -> None:
        inner = getattr(obj, name)

        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            out = inner(*args, **kwargs)
            self.now[key] += time.perf_counter() - t0
            return out
        setattr(obj, name, timed)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--perception', required=True, help='the perception checkpoint the performer sees through')
    ap.add_argument('--demonstrations', default=str(default_dir('train', 64)))
    ap.add_argument('--updates', type=int, default=40, help='updates timed')
    ap.add_argument('--skip', type=int, default=5, help='updates first run and not counted')
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--batch-size', type=int, default=16)
    ap.add_argument('--block-tasks', type=int, default=0,
                    help='time the block order (the network run once per frame of each block) instead')
    ap.add_argument('--block-items', type=int, default=0, help="TrainConfig.block_items (a task's items a visit)")
    ap.add_argument('--block-bucket', type=int, default=1, help='TrainConfig.block_bucket (blocks sorted by length)')
    ap.add_argument('--no-channels-last', action='store_true',
                    help='the frozen network on contiguous tensors (TrainConfig.perception_channels_last off)')
    ap.add_argument('--precision', choices=('fp32', 'bf16'), default='fp32',
                    help="the frozen network's arithmetic (TrainConfig.perception_precision; bf16 is native only on "
                         'CPUs with AVX512-BF16 or AMX, emulated and slow elsewhere)')
    args = ap.parse_args()

    out = tempfile.mkdtemp(prefix='performer_update_')
    cfg = TrainConfig(demonstrations=args.demonstrations, perception=args.perception, out=out, epochs=1,
                      max_updates=args.updates + args.skip, batch_size=args.batch_size, threads=args.threads,
                      progress=False, model=PerformerConfig(reach_input=True),
                      block_tasks=args.block_tasks, block_items=args.block_items, block_bucket=args.block_bucket,
                      perception_precision=args.precision, perception_channels_last=not args.no_channels_last)
    t0 = time.perf_counter()
    training = Training(cfg, Ranks())
    setup_s = time.perf_counter() - t0
    model, data = training.model, training.data
    visual = model.visual
    if not isinstance(visual, PerceivedFrames):
        raise SystemExit('the model does not see through a perception network')
    clock = Clock()
    clock.wrap(visual, 'outputs', 'frozen_network')
    clock.wrap(visual, 'pointer_logits', 'reach_pointer')
    clock.wrap(visual, 'distances', 'reach_distances')

    items, batches, blocks = training.epoch_plan(0)
    lengths = data.item_lengths(data.train, items)
    epoch_frames = statistics.fmean(sum(lengths[p] for p in b) for b in batches)
    n = args.updates + args.skip
    if blocks is None:
        positions = list(range(0, len(batches), max(1, len(batches) // n)))[:n]   # spread: lengths as the run meets them
    else:
        positions = list(range(min(n, len(batches))))     # in plan order, each block loaded when its first batch comes
    model.train()
    rows, frames, block_load_s, block_batches_n, loaded = [], [], 0.0, 0, None
    for k, position in enumerate(positions):
        b = batches[position]
        block = block_of(blocks, position) if blocks is not None else None
        if block is not None and block != loaded:
            loaded = block
            t0 = time.perf_counter()
            training.features.load(blocks[loaded].tasks)
            end = blocks[loaded + 1].first_batch if loaded + 1 < len(blocks) else len(batches)
            if end > args.skip:          # a block with timed batches: its load is spread over all of its batches
                block_load_s += time.perf_counter() - t0
                block_batches_n += end - blocks[loaded].first_batch
        clock.now.clear()
        t0 = time.perf_counter()
        batch = collate([data.train[items[p]] for p in b])
        if blocks is not None:
            batch = training.features.attach(batch)
        t1 = time.perf_counter()
        outputs = model(batch)
        t2 = time.perf_counter()
        loss, _ = performer_loss(outputs, batch, cfg.pointer_weight)
        training.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        t3 = time.perf_counter()
        torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.grad_clip)
        training.optimizer.step()
        t4 = time.perf_counter()
        if k < args.skip:
            continue
        inner = clock.now['frozen_network'] + clock.now['reach_pointer'] + clock.now['reach_distances']
        rows.append({'load_and_collate': t1 - t0, 'frozen_network': clock.now['frozen_network'],
                     'reach_pointer': clock.now['reach_pointer'], 'reach_distances': clock.now['reach_distances'],
                     'rest_of_forward': (t2 - t1) - inner, 'loss_and_backward': t3 - t2,
                     'clip_and_step': t4 - t3, 'update': t4 - t0})
        frames.append(int(batch['step_valid'].sum()))
    pieces = list(rows[0])
    mean = {p: statistics.fmean(r[p] for r in rows) for p in pieces}
    print(json.dumps({
        'perception': args.perception, 'demonstrations': args.demonstrations, 'threads': args.threads,
        'batch_size': cfg.batch_size, 'updates_timed': len(rows), 'setup_s': round(setup_s, 1),
        'frames_per_update': round(statistics.fmean(frames), 1),
        'seconds_per_update': {p: round(v, 4) for p, v in mean.items()},
        'share_of_update': {p: round(mean[p] / mean['update'], 3) for p in pieces if p != 'update'},
        'block_tasks': args.block_tasks, 'block_items': args.block_items, 'block_bucket': args.block_bucket,
        'channels_last': not args.no_channels_last, 'precision': args.precision, 'block_load_s': round(block_load_s, 2),
        'block_batches': block_batches_n,
        'seconds_per_update_with_block_load': round(mean['update'] + block_load_s / max(block_batches_n, 1), 4),
        'frames_per_s': round(sum(frames) / sum(r['update'] for r in rows), 1),
        'epoch_frames_per_update': round(epoch_frames, 1),
        'seconds_per_update_at_epoch_mean': round(sum(r['update'] for r in rows) / sum(frames) * epoch_frames, 4),
        'median_update_s': round(statistics.median(r['update'] for r in rows), 4),
    }, indent=1))


if __name__ == '__main__':
    main()
