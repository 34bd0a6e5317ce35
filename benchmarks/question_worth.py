#!/usr/bin/env python3
"""What a question is worth: SR points gained per question asked, from two results files of one agent
on the same tasks, one without questions and one with them; prints JSON.

Overall, per task family (the tasks with a go-to, whose goal includes standing near the expert's end
pose, against the rest) and per task type: SR without and with questions, NQ, and the worth
(SR with - SR without) / NQ. The paper's figure: (32.0 - 18.3) / 3.24 = 4.2 points per question for
All QAs on valid_unseen.

    ./dialfred bench question_worth --base out/eval/valid_unseen_et-XXXX.jsonl \\
        --asked out/eval/valid_unseen_et-XXXX+all.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys

from dialfred_sim.metrics import has_goto
from dialfred_sim.metrics import load_results, type_order

PAPER = {'instruction_only': 18.3, 'all_qas': 32.0, 'nq': 3.24}


def family(task_type: str) -> str:
    return 'with a go-to' if has_goto(task_type) else 'without a go-to'


def worth(base: list, asked: list) -> dict:
    n = len(base)
    sr0 = 100.0 * sum(r.success for r in base) / n
    sr1 = 100.0 * sum(r.success for r in asked) / n
    nq = sum(r.questions for r in asked) / n
    return {'n': n, 'SR_without': round(sr0, 2), 'SR_with': round(sr1, 2), 'NQ': round(nq, 3),
            'worth': round((sr1 - sr0) / nq, 3) if nq > 0 else None}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--base', required=True, help='results without questions')
    parser.add_argument('--asked', required=True, help='results of the same agent and tasks with questions')
    args = parser.parse_args()

    base = {r.task_id: r for r in load_results(args.base)}
    asked = {r.task_id: r for r in load_results(args.asked)}
    common = sorted(set(base) & set(asked))
    if not common:
        print('error: the two files share no task', file=sys.stderr)
        return 2
    if {(base[t].split, base[t].goal_rule) for t in common} != {(asked[t].split, asked[t].goal_rule) for t in common}:
        print('error: the two files differ in split or goal rule', file=sys.stderr)
        return 2
    groups: dict = {'overall': common}
    for t in common:
        groups.setdefault(f'family: {family(base[t].task_type)}', []).append(t)
    for t in sorted(common, key=lambda t: type_order(base[t].task_type)):
        groups.setdefault(f'type: {base[t].task_type}', []).append(t)
    print(json.dumps({
        'base': args.base, 'asked': args.asked, 'tasks': len(common),
        'goal_rule': base[common[0]].goal_rule, 'agents': [base[common[0]].agent, asked[common[0]].agent],
        'paper_worth': round((PAPER['all_qas'] - PAPER['instruction_only']) / PAPER['nq'], 3),
        'groups': {name: worth([base[t] for t in ids], [asked[t] for t in ids]) for name, ids in groups.items()},
    }, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
