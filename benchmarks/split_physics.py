#!/usr/bin/env python3
"""Does the current simulator still allow every recorded expert episode of a split? (no ROS)

A task's start state is rebuilt by replaying its episode's expert actions on the world without
rendering (`tasks.expert.replay`). When the world's rules change (say, open doors take floor,
a held object stays out of the walls), a split made before may hold actions the world now refuses.
This replays every episode of a split file and reports the refused ones, why, and how many tasks
reach the refused action (their start state cannot be rebuilt, or their own actions fail there).

    ./dialfred bench split_physics [--split valid_unseen] [--file PATH.jsonl.gz] [--limit N]

Prints JSON. Rendering effects (a recorded pixel that no longer shows its target) are not checked
here; `./dialfred bench expert_replay` plays the tasks through the graph for that.
"""

from __future__ import annotations

import argparse
import gzip
import json
import time
from collections import Counter
from pathlib import Path

from dialfred_sim.env import DialfredEnv
from dialfred_sim.tasks.expert import replay
from dialfred_sim.tasks.generator import apply_setup
from dialfred_sim.tasks.splits import split_path, tasks_from_json



def reason(error: str) -> str:
    """The refused rule, from a replay error."""
    if 'which is open' in error:
        return 'walks into an open door'
    if 'would hit you' in error:
        return 'opens a door into itself'
    if 'in hand would pass' in error or 'no room to hold' in error:
        return 'no room for the held object'
    return error


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--split', default='valid_unseen', help='a shipped split (ignored with --file)')
    parser.add_argument('--file', default=None, help='a split file (gzip JSON lines), e.g. an older version')
    parser.add_argument('--limit', type=int, default=None, help='only the first N episodes')
    args = parser.parse_args()


    path = Path(args.file) if args.file else split_path(args.split)
    with gzip.open(path, 'rt') as f:
        rows = [tasks_from_json(json.loads(line)) for line in f][:args.limit]
    env = DialfredEnv()
    t0 = time.monotonic()
    refused, reasons, tasks_hit = [], Counter(), 0
    try:
        for tasks in rows:
            episode = tasks[0].episode
            env.reset(seed=episode.seed, options={'scene': episode.scene})
            apply_setup(env.world, episode.setup)
            try:
                replay(env.world, episode.actions)
            except RuntimeError as exc:
                step = int(str(exc).split()[2])          # 'replay step K (...)'
                hit = [t.task_id for t in tasks if t.end > step]
                tasks_hit += len(hit)
                reasons[reason(str(exc))] += 1
                refused.append({'episode_id': episode.episode_id, 'scene': episode.scene, 'error': str(exc),
                                'tasks': hit})
    finally:
        env.close()
    print(json.dumps({
        'file': str(path),
        'episodes': len(rows),
        'tasks': sum(len(t) for t in rows),
        'seconds': round(time.monotonic() - t0, 1),
        'episodes_refused': len(refused),
        'tasks_affected': tasks_hit,
        'reasons': dict(reasons.most_common()),
        'refused': refused,
    }, indent=1))


if __name__ == '__main__':
    main()
