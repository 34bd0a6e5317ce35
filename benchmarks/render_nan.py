#!/usr/bin/env python3
"""Frames with NaN depth: pybullet's tiny renderer divides by each corner's view depth without clipping, so a
box corner exactly in the camera's plane turns its faces black with NaN depth (or drops them). The world draws
its eye 0.7 mm back along the view (`camera.EYE_SHIFT`) to keep corners off that plane. This renders every free
pose x 4 headings x the pitches of the episodes of the given scenes and counts frames with NaN depth, with the
shift and (`--no-shift`) without it; prints JSON.

    ./dialfred bench render_nan --split valid_seen --scenes FloorPlan23 FloorPlan5
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from dialfred_sim.env import DialfredEnv
from dialfred_sim.tasks import load_split
from dialfred_sim.world import camera


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--split', default='valid_seen')
    ap.add_argument('--scenes', nargs='+', default=['FloorPlan23', 'FloorPlan5'])
    ap.add_argument('--episodes', type=int, default=0, help='at most N episodes (0: every one of those scenes)')
    ap.add_argument('--resolution', type=int, default=64)
    ap.add_argument('--no-shift', action='store_true', help='draw from the true eye (the renderer before the shift)')
    args = ap.parse_args()

    if args.no_shift:
        camera.EYE_SHIFT = 0.0
    env = DialfredEnv(resolution=args.resolution)
    seen, frames, bad, t0 = set(), 0, [], time.monotonic()
    for task in load_split(args.split):
        if task.scene not in args.scenes or task.episode.episode_id in seen:
            continue
        if args.episodes and len(seen) >= args.episodes:
            break
        seen.add(task.episode.episode_id)
        env.reset(options={'task': task})
        for i, j in sorted(env.world.layout.navigable):
            for rotation in (0, 90, 180, 270):
                for horizon in (0, 15, 30, 45, 60):
                    try:
                        obs = env.teleport(i, j, rotation, horizon)
                    except ValueError:        # an open door there, or no room for what is held
                        continue
                    frames += 1
                    n = int(np.isnan(obs['depth']).sum())
                    if n:
                        bad.append({'episode': task.episode.episode_id, 'pose': [i, j, rotation, horizon], 'pixels': n})
    env.close()
    print(json.dumps({'split': args.split, 'scenes': args.scenes, 'episodes': len(seen), 'resolution': args.resolution,
                      'eye_shift_m': camera.EYE_SHIFT, 'frames': frames, 'nan_frames': len(bad),
                      'nan_pixels': [b['pixels'] for b in bad], 'examples': bad[:5],
                      'seconds': round(time.monotonic() - t0, 1)}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
