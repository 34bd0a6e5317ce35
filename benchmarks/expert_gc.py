#!/usr/bin/env python3
"""Goal-condition progress (GC) along the expert's path, for every task of a split (no ROS).

GC counts only the goal conditions that do not hold at a task's start (dialfred_sim.tasks.goals.
goal_progress). This replays each task's expert in a DialfredEnv and checks what that definition
promises: GC is 0 at the start of every task, and it never falls while the expert works. It also
shows, per task type, how many of the goal's conditions are left to do at the start, and what
ALFRED's count (every condition of the goal) would give for doing nothing.

Prints JSON. `falls` lists every task where the expert's GC fell, with the step.

    ./dialfred bench expert_gc [--split valid_unseen] [--limit N]
"""

from __future__ import annotations

import argparse
import json
import time

from dialfred_sim.env import DialfredEnv
from dialfred_sim.metrics import type_order
from dialfred_sim.tasks import load_split



def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--split', default='valid_unseen')
    parser.add_argument('--limit', type=int, default=None, help='only the first N tasks (default: all)')
    args = parser.parse_args()


    tasks = load_split(args.split)[:args.limit]
    env = DialfredEnv(resolution=tasks[0].resolution)
    t0 = time.monotonic()
    start_nonzero, falls, failed, per_type = [], [], [], {}
    try:
        for task in tasks:
            _, info = env.reset(options={'task': task})
            total = info['goal_conditions_total']
            row = per_type.setdefault(task.task_type, {'n': 0, 'conditions': 0, 'left_to_do': 0,
                                                       'held_at_start': 0})
            row['n'] += 1
            row['conditions'] += len(task.goal)
            row['left_to_do'] += total
            row['held_at_start'] += sum(env.goal_met_at_start) / len(task.goal)
            if info['goal_conditions_met'] != 0 or total == 0:
                start_nonzero.append(task.task_id)
            met = 0
            for k, a in enumerate(task.expert_actions):
                _, _, terminated, truncated, info = env.step({'action': a.action, 'pixel': (a.x, a.y)})
                if info['goal_conditions_met'] < met:
                    falls.append({'task_id': task.task_id, 'task_type': task.task_type, 'step': k,
                                  'action': a.action, 'from': met, 'to': info['goal_conditions_met'],
                                  'total': total})
                met = info['goal_conditions_met']
                if terminated or truncated:
                    break
            if not info['success']:
                failed.append({'task_id': task.task_id, 'error': info['last_action_error']})
    finally:
        env.close()
    types = sorted(per_type, key=type_order)
    print(json.dumps({
        'split': args.split,
        'tasks': len(tasks),
        'seconds': round(time.monotonic() - t0, 1),
        'gc_nonzero_or_nothing_to_do_at_start': start_nonzero,
        'expert_failures': failed,
        'falls': falls,
        # per type: mean conditions of the goal, mean left to do at the start (GC's denominator),
        # and the GC in percent that counting every condition (ALFRED's way) gives for doing nothing
        'per_type': {t: {'n': per_type[t]['n'],
                         'conditions': round(per_type[t]['conditions'] / per_type[t]['n'], 2),
                         'left_to_do': round(per_type[t]['left_to_do'] / per_type[t]['n'], 2),
                         'all_conditions_gc_for_nothing_pct': round(
                             100 * per_type[t]['held_at_start'] / per_type[t]['n'], 1)}
                     for t in types},
    }, indent=1))


if __name__ == '__main__':
    main()
