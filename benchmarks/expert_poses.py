#!/usr/bin/env python3
"""Where the expert ends a go-to, against ALFRED's plain designated pose (no ROS); prints JSON.

The expert ends each go-to at the first pose, in the order of ALFRED's designated-pose rule, from which
all that follows can be done without walking: the target in view and within reach, and also, for a
fetch from a closed container, the object inside it once it is open (`inside`), and for a go-to that
ends in a put, the held object landing in view and within reach (`put`). See
dialfred_sim/tasks/expert.py and docs/tasks.md. The plain pose is the first that passes the view check
alone. An agent that aims at the plain pose (the map performer's last stand, docs/map_performer.md)
ends where DialFRED's goal rule wants it except where the two differ by more than 4 actions.

The bench plays the first episodes of a split again, asking the expert at each go-to with an `inside`
or `put` check for the plain pose as well, and reports how many such go-tos end elsewhere and how far
apart the two poses lie: `gap_actions` counts grid steps, quarter turns and 15-degree looks between
them, a lower bound of the shortest path's actions (walls can lengthen it). Each episode played must
equal the shipped split's, byte for byte as JSON (`same_as_shipped`), or the figures would describe
another split.

    ./dialfred bench expert_poses [--split valid_unseen] [--episodes N]
"""

from __future__ import annotations

import argparse
import gzip
import json
import time
from collections import Counter

from dialfred_sim.tasks import expert as expert_module
from dialfred_sim.tasks.split_files import packaged_path
from dialfred_sim.tasks.splits import generate_split


def gap_actions(a, b) -> int:
    """Grid steps, quarter turns and looks between poses (i, j, heading, horizon): a lower bound of the
    actions of a path from one to the other."""
    turns = abs((a[2] - b[2] + 180) % 360 - 180) // 90
    return int(abs(a[0] - b[0]) + abs(a[1] - b[1]) + turns + round(abs(a[3] - b[3]) / 15))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--split', default='valid_unseen', choices=('train', 'valid_seen', 'valid_unseen'))
    parser.add_argument('--episodes', type=int, default=None, help='only the first N episodes (default: all)')
    args = parser.parse_args()
    if args.episodes is not None and args.episodes < 1:
        parser.error(f'--episodes must be at least 1, got {args.episodes}')


    find_pose = expert_module.Expert.find_pose
    checked = []

    def find_pose_and_plain(self, focus, inside=(), put=None):
        pose, actions = find_pose(self, focus, inside, put)
        if inside or put is not None:
            try:
                plain = find_pose(self, focus)[0]
            except expert_module.ExpertFailed:
                plain = None
            checked.append({'focus': self.world.objects[focus[0]].otype.name, 'inside': bool(inside),
                            'put': put is not None, 'pose': pose, 'plain': plain})
        return pose, actions

    with gzip.open(packaged_path(args.split), 'rt') as f:
        shipped = [json.loads(line) for line in f if line.strip()]
    limit = len(shipped) if args.episodes is None else min(args.episodes, len(shipped))
    t0 = time.monotonic()
    expert_module.Expert.find_pose = find_pose_and_plain
    same = 0
    try:
        rows = generate_split(args.split, progress=False)
        for k, row in enumerate(rows):
            same += json.loads(json.dumps(row)) == shipped[k]
            if k + 1 >= limit:
                rows.close()
                break
    finally:
        expert_module.Expert.find_pose = find_pose
    moved = [c for c in checked if c['plain'] is None or tuple(c['plain']) != tuple(c['pose'])]
    gaps = Counter(None if c['plain'] is None else gap_actions(c['pose'], c['plain']) for c in moved)
    beyond = sum(1 for c in moved if c['plain'] is not None and gap_actions(c['pose'], c['plain']) > 4)
    print(json.dumps({
        'split': args.split, 'episodes': limit, 'same_as_shipped': same,
        'gotos_checked': len(checked), 'gotos_checked_put': sum(c['put'] for c in checked),
        'gotos_checked_inside': sum(c['inside'] for c in checked),
        'elsewhere': len(moved), 'elsewhere_put': sum(c['put'] for c in moved),
        'elsewhere_inside': sum(c['inside'] for c in moved),
        'elsewhere_beyond_4_actions_at_least': beyond,
        'no_plain_pose': gaps.pop(None, 0),
        'gap_actions': {str(k): v for k, v in sorted(gaps.items())},
        'elsewhere_by_type': dict(Counter(c['focus'] for c in moved).most_common()),
        'seconds': round(time.monotonic() - t0, 1)}, indent=1))


if __name__ == '__main__':
    main()
