"""Where the performer points: on the held-out tasks of a labelled demonstrations build (the tasks the
performer's training holds out), teacher-forced along the expert's episodes with every QA of the task,
the share of interactions whose click lands on the target (the pixel the agent would send is one of
the target's pixels, from the build's targets.npy), and the share whose predicted action is the
expert's. Any performer checkpoint: the 8x8-cell pointer (it clicks its cell's centre) and the pixel
pointer alike, so the two are compared on one measure. Prints JSON.

    ./dialfred bench pointer_accuracy --checkpoint src/dialfred_performer/dialfred_performer/checkpoints/et.pt \
        --checkpoint out/performer_perception/best.pt [--demonstrations ~/.cache/dialfred/demonstrations/train_64]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from dialfred_performer.data import type_combinations, DemonstrationDataset, collate, held_out
from dialfred_performer.model import load_checkpoint
from dialfred_performer.nn.heads import cell_centre_pixel
from dialfred_sim.tasks.demonstrations import default_dir


def measure(checkpoint: Path, folder: Path, fraction: float, limit: int, batch: int) -> dict:
    model, vocab, info = load_checkpoint(checkpoint)
    cfg = model.config
    ds = DemonstrationDataset(folder, vocab, cfg.resolution, cfg.max_tokens, combinations=(type_combinations()[-1],),
                              grid_size=cfg.grid_size)
    if ds.demo.labels is None:
        raise SystemExit(f'{folder} has no labels: build it with prepare-performer --labels')
    items = [i for i, k in enumerate(ds.task_indices) if held_out(ds.demo.tasks[k]['task_id'], fraction)][:limit]
    size = ds.frame_size
    hits = clicks = actions = steps = 0
    t0 = time.monotonic()
    with torch.inference_mode():
        for b in range(0, len(items), batch):
            chunk = items[b:b + batch]
            data = collate([ds[i] for i in chunk])
            out = model(data)
            valid = data['step_valid']
            actions += int((out['action_logits'].argmax(-1)[valid] == data['actions'][valid]).sum())
            steps += int(valid.sum())
            best = out['pointer_logits'].argmax(-1).tolist()
            rows = [(bi, t) for bi, t in zip(*torch.nonzero(data['target_cells'] >= 0, as_tuple=True))]
            for (bi, t), cell in zip(rows, best):
                task = ds.demo.tasks[ds.task_indices[chunk[int(bi)]]]
                frame = task['first_frame'] + int(t)
                mask = np.unpackbits(ds.demo.labels['targets'][frame])[:size * size].reshape(size, size)
                if not mask.any():
                    continue                          # the target is not in view: no click can land
                x, y = cell_centre_pixel(cell, cfg.grid_size, size)
                hits += int(mask[y, x])
                clicks += 1
    return {'checkpoint': str(checkpoint), 'visual': cfg.visual, 'grid': cfg.grid_size, 'episodes': len(items),
            'interactions': clicks, 'click_on_target': round(hits / max(clicks, 1), 4),
            'action_accuracy': round(actions / max(steps, 1), 4), 'seconds': round(time.monotonic() - t0, 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--checkpoint', action='append', required=True, help='a performer checkpoint (repeatable)')
    ap.add_argument('--demonstrations', default=str(default_dir('train', 64)), help='a labelled build')
    ap.add_argument('--val-fraction', type=float, default=0.05, help="the performer's training held-out fraction")
    ap.add_argument('--limit', type=int, default=600, help='held-out episodes at most')
    ap.add_argument('--batch', type=int, default=16)
    args = ap.parse_args()
    torch.set_num_threads(2)
    rows = [measure(Path(c), Path(args.demonstrations).expanduser(), args.val_fraction, args.limit, args.batch)
            for c in args.checkpoint]
    print(json.dumps({'benchmark': 'pointer_accuracy', 'demonstrations': args.demonstrations, 'results': rows},
                     indent=1))


if __name__ == '__main__':
    main()
