#!/usr/bin/env python3
"""Render the four room types to PNG and a contact sheet for the README.

For each room type: an overview from a high corner of the room and two first-person frames of the
agent (what a model sees). Writes docs/images/rooms.png and one PNG per room under docs/images/rooms/.

    ./dialfred env python scripts/render_rooms.py [--scenes FloorPlan1,FloorPlan201,FloorPlan301,FloorPlan401]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from dialfred_sim.env import DialfredEnv

ROOT = Path(__file__).resolve().parents[1]
LABELS = {'kitchen': 'kitchen', 'living_room': 'living room', 'bedroom': 'bedroom', 'bathroom': 'bathroom'}


def overview(env: DialfredEnv, size: int) -> np.ndarray:
    """A view from just under the ceiling in a corner, looking at the room's centre."""
    c, lay = env.client, env.world.layout
    eye = (0.15, 0.15, 2.45)
    target = (lay.width * 0.6, lay.depth * 0.6, 0.3)
    view = c.computeViewMatrix(eye, target, (0, 0, 1))
    proj = c.computeProjectionMatrixFOV(80, 1.0, 0.05, 20)
    _, _, px, _, _ = env.world.draw(size, size, view, proj)
    return np.asarray(px, np.uint8).reshape(size, size, 4)[:, :, :3]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--scenes', default='FloorPlan1,FloorPlan201,FloorPlan301,FloorPlan401')
    ap.add_argument('--size', type=int, default=300)
    args = ap.parse_args()
    out = ROOT / 'docs' / 'images'
    (out / 'rooms').mkdir(parents=True, exist_ok=True)
    env = DialfredEnv(resolution=args.size)
    rows = []
    for scene in args.scenes.split(','):
        obs, info = env.reset(seed=0, options={'scene': scene})
        tiles = [overview(env, args.size), obs['rgb']]
        for _ in range(2):
            obs, *_ = env.step('RotateLeft')
        tiles.append(obs['rgb'])
        row = Image.fromarray(np.concatenate(tiles, axis=1))
        ImageDraw.Draw(row).text((6, 4), f'{scene}: {LABELS[info["room_type"]]}', fill=(255, 255, 255),
                                 stroke_width=2, stroke_fill=(0, 0, 0))
        row.save(out / 'rooms' / f'{scene}.png')
        rows.append(np.asarray(row))
    Image.fromarray(np.concatenate(rows, axis=0)).save(out / 'rooms.png')
    print(f'wrote {out / "rooms.png"}')


if __name__ == '__main__':
    main()
