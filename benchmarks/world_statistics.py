#!/usr/bin/env python3
"""How the world and a split compare with AI2-THOR's and ALFRED's (no ROS); prints JSON.

Per room type: `navigable_points`, `receptacles`, `openable_fixtures`, `small_objects`; per split:
`goto_actions`, `goto_moves`, `goto_turns`, `goto_looks`, `actions_before_first_interaction`,
`first_target_multi_instance`, `first_target_in_closed`, `first_target_distance_m`,
`target_visible_at_task_start`. Beside each figure AI2-THOR has, `reference` is its value and
`ratio` ours over it. Definitions and sources: dialfred_sim/tasks/statistics.py, docs/dataset.md.

    ./dialfred bench world_statistics [--split valid_unseen | --file PATH] [--episodes N | --tasks N]

`--file` reads a split file of one's own instead of a shipped split (a sealed test split made by
`python -m dialfred_sim.tasks.splits test_unseen --seed S --out PATH`): how far a figure moves from one
sample of tasks to another, beside how far it lies from AI2-THOR's.
"""

from __future__ import annotations

import argparse
import json
import time

from dialfred_sim.tasks import load_split
from dialfred_sim.tasks.split_files import read_tasks_file
from dialfred_sim.tasks.statistics import world_statistics


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    source = parser.add_mutually_exclusive_group()
    source.add_argument('--split', default='valid_unseen', choices=('train', 'valid_seen', 'valid_unseen'),
                        help='a shipped split (default: valid_unseen)')
    source.add_argument('--file', default=None, metavar='PATH',
                        help='a split file of your own (.jsonl.gz, e.g. a sealed test split) instead')
    limits = parser.add_mutually_exclusive_group()
    limits.add_argument('--episodes', type=int, default=None, help='only the first N episodes of the split')
    limits.add_argument('--tasks', type=int, default=None, help='only the episodes of the first N tasks')
    args = parser.parse_args()
    for name in ('episodes', 'tasks'):
        value = getattr(args, name)
        if value is not None and value < 1:
            parser.error(f'--{name} must be at least 1, got {value}')


    t0 = time.monotonic()
    if args.file is not None:
        try:
            tasks_file = read_tasks_file(args.file)
        except (OSError, ValueError) as exc:
            parser.error(str(exc))          # exit 2, nothing measured
        tasks, source = tasks_file.tasks, {'split': tasks_file.split, 'file': tasks_file.describe()}
    else:
        tasks, source = load_split(args.split), {'split': args.split}
    if args.tasks is not None:
        tasks = tasks[:args.tasks]
    figures = world_statistics(tasks, args.episodes)
    print(json.dumps({**source, **figures, 'seconds': round(time.monotonic() - t0, 1)}, indent=1))


if __name__ == '__main__':
    main()
