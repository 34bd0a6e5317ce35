"""What the perception network finds: on the first frame of every k-th task of a split, rendered at 128
pixels, each object the simulator shows with at least --min-pixels pixels counts as found when the
network labels at least one cell under the object's mask with the object's type. Reported for all
objects, for pickupable ones (the small things a task picks up) and for the rest (furniture,
appliances), at each input resolution asked for (the network is fully convolutional; it was trained
at its checkpoint's). Prints JSON.

    ./dialfred bench perception_recall [--checkpoint PATH] [--split valid_unseen] [--every 30] \
        [--resolution 64 --resolution 128]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from dialfred_performer.mapper.agent import MapAgent
from dialfred_performer.model import SHIPPED_CHECKPOINT
from dialfred_performer.preprocess import frame_tensor
from dialfred_sim.env import DialfredEnv
from dialfred_sim.tasks.split_files import load_split


def measure(checkpoint: Path, split: str, every: int, resolutions: list[int], min_pixels: int) -> dict:
    agent = MapAgent.from_checkpoint(checkpoint)
    env = DialfredEnv(resolution=128)
    counts = {r: {'pickupable': [0, 0], 'other': [0, 0]} for r in resolutions}
    tasks = load_split(split)[::every]
    t0 = time.monotonic()
    for task in tasks:
        obs, _ = env.reset(options={'task': task})
        seg = obs['segmentation']
        labels = {}
        with torch.inference_mode():
            for r in resolutions:
                out = agent.net(frame_tensor(obs['rgb'], r)[None])
                labels[r] = agent.net.heads(out.fine)[0][0].argmax(0).numpy()
        for body, name in zip(*env.world.instance_table()):
            type_name = name.rsplit('_', 1)[0]
            t = agent.catalog.get(type_name)
            mask = seg == body
            if t is None or type_name not in agent.class_id or int(mask.sum()) < min_pixels:
                continue
            kind = 'pickupable' if t.pickupable else 'other'
            for r in resolutions:
                s = labels[r].shape[0]
                under = mask.reshape(s, 128 // s, s, 128 // s).any(axis=(1, 3))
                counts[r][kind][0] += 1
                counts[r][kind][1] += bool((labels[r][under] == agent.class_id[type_name]).any())
    result = {'checkpoint': str(checkpoint), 'split': split, 'frames': len(tasks), 'min_pixels_at_128': min_pixels,
              'seconds': round(time.monotonic() - t0, 1), 'recall': {}}
    for r in resolutions:
        row = {}
        for kind, (n, found) in counts[r].items():
            row[kind] = {'objects': n, 'found': found, 'recall': round(found / n, 4) if n else None}
        n = sum(v[0] for v in counts[r].values())
        found = sum(v[1] for v in counts[r].values())
        row['all'] = {'objects': n, 'found': found, 'recall': round(found / n, 4) if n else None}
        result['recall'][str(r)] = row
    return result


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--checkpoint', type=Path, default=SHIPPED_CHECKPOINT,
                   help='a perception performer checkpoint or a perception.pt (default: the shipped performer)')
    p.add_argument('--split', default='valid_unseen')
    p.add_argument('--every', type=int, default=30, help='the first frame of every k-th task')
    p.add_argument('--resolution', type=int, action='append', help='input resolutions (default: 64 and 128)')
    p.add_argument('--min-pixels', type=int, default=4, help='an object counts if it shows this many pixels at 128')
    a = p.parse_args(argv)
    if a.every < 1 or a.min_pixels < 1:
        p.error('--every and --min-pixels must be at least 1')
    print(json.dumps(measure(a.checkpoint, a.split, a.every, a.resolution or [64, 128], a.min_pixels), indent=1))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
