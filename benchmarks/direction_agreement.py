#!/usr/bin/env python3
"""How often a demonstration does what the oracle's direction answer of its step says: for each direction
answer, the actions taken at the steps where it was the answer in force (the oracle asked at every step,
`dialogues.jsonl`'s log), and the share that obey it as `data.DirectionGuide` reads it (`obeys`). An expert's shortest way need not turn where an answer says to turn (the answer points to the
expert's end as the crow flies); a guided build's walks (`prepare-performer --guided`) do, and the report
counts their steps apart (`walk`).

    ./dialfred bench direction_agreement [--demonstrations DIR]     # default: ~/.cache/dialfred/demonstrations/train_64
"""

from __future__ import annotations

import argparse
import collections
import json
from pathlib import Path

from dialfred_performer.data import DIALOGUES_FILE, answers_at, load_dialogues, obeys
from dialfred_sim.tasks.demonstrations import default_dir, load_demonstrations


def agreement(folder: Path) -> dict:
    demo = load_demonstrations(folder)
    dialogues = load_dialogues(folder / DIALOGUES_FILE)
    if not dialogues or not all(d.every_step for d in dialogues.values()):
        raise SystemExit(f'{folder}: its {DIALOGUES_FILE} does not log the answers of every step '
                         '(make it again with prepare-performer)')
    counts = {part: collections.defaultdict(collections.Counter) for part in ('expert', 'walk')}
    for task in demo.tasks:
        d = dialogues.get(task['task_id'])
        if d is None:
            continue
        walk = task.get('guided') or (0, 0, 0)
        moves = [a.qa.answer for a in d.qas if a.qa.question.question_type == 'direction']
        if not moves:
            continue
        for step, (action, *_rest) in enumerate(task['actions']):
            said = answers_at(d.qas, step, ('direction',))
            if not said:
                continue
            part = 'walk' if walk[0] <= step < walk[0] + walk[1] else 'expert'
            counts[part][said[0].qa.answer][action] += 1
    report = {'demonstrations': str(folder), 'tasks': len(demo.tasks)}
    for part, by_answer in counts.items():
        rows, steps, obeyed = {}, 0, 0
        for answer, actions in sorted(by_answer.items()):
            n = sum(actions.values())
            ok = sum(v for a, v in actions.items() if obeys(answer, a))
            rows[answer] = {'steps': n, 'obeyed': round(ok / n, 3),
                            'actions': {a: round(v / n, 3) for a, v in actions.most_common()}}
            steps, obeyed = steps + n, obeyed + ok
        report[part] = {'steps': steps, 'obeyed': round(obeyed / steps, 3) if steps else None, 'answers': rows}
    return report


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--demonstrations', default='', help='a prepared folder (default: train at 64 px)')
    args = ap.parse_args()
    folder = Path(args.demonstrations) if args.demonstrations else default_dir('train', 64)
    print(json.dumps(agreement(folder), indent=1))


if __name__ == '__main__':
    main()
