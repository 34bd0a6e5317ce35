"""prepare's oracle-answers pass: playing each expert episode only to its middle step vs to its end. Prints JSON.

The performer's training dialogues (`dialogues.jsonl` of a demonstrations folder) hold the oracle's answers
at step 0 and at step n // 2 of each expert episode. Until session 10 the pass replayed the whole episode;
nothing is asked after the middle, so `data.task_dialogue` now stops there. This times both on the first
`--limit` tasks of the folder, in one process with one env, and checks that the two give the same lines as
each other and as the folder's `dialogues.jsonl` (written by whichever version built the folder).

    ./dialfred bench dialogue_pass [--limit 300] [--demonstrations DIR] [--rounds 2]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def whole_episode_dialogue(env, task: dict) -> list:
    """The pass before session 10: every recorded action is played, asking at step 0 and n // 2."""
    from dialfred_performer.data import oracle_qas
    env.reset(options={'task_id': task['task_id']})
    n = len(task['actions'])
    ask_at = sorted({0, n // 2})
    qas = []
    for step in range(n + 1):
        if step in ask_at:
            qas += oracle_qas(env, task['object_nouns'], step)
        if step < n:
            name, x, y, _ = task['actions'][step]
            env.step({'action': name, 'pixel': (x, y)})
    return qas


def main() -> None:
    from dialfred_performer.data import DIALOGUES_FILE, dialogue_line, load_demonstrations, task_dialogue
    from dialfred_sim.env import DialfredEnv
    from dialfred_sim.tasks.demonstrations import default_dir
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--demonstrations', default=str(default_dir('train', 64)))
    ap.add_argument('--limit', type=int, default=300)
    ap.add_argument('--rounds', type=int, default=2, help='each way timed this many times, interleaved')
    args = ap.parse_args()
    if args.limit < 1 or args.rounds < 1:
        ap.error('--limit and --rounds must be at least 1')
    folder = Path(args.demonstrations)
    demo = load_demonstrations(folder)
    tasks = demo.tasks[:args.limit]
    env = DialfredEnv(resolution=demo.meta['resolution'])
    ways = {'to_the_end': whole_episode_dialogue, 'to_the_middle': task_dialogue}
    seconds = {k: [] for k in ways}
    lines = {}
    for _ in range(args.rounds):
        for name, fn in ways.items():
            t0 = time.perf_counter()
            lines[name] = [dialogue_line(t, fn(env, t)) for t in tasks]
            seconds[name].append(time.perf_counter() - t0)
    env.close()
    shipped = folder / DIALOGUES_FILE
    saved = shipped.read_text().splitlines(keepends=True)[:len(tasks)] if shipped.exists() else None
    best = {k: min(v) for k, v in seconds.items()}
    print(json.dumps({
        'benchmark': 'dialogue_pass', 'tasks': len(tasks), 'rounds': args.rounds,
        'steps_per_task': sum(len(t['actions']) for t in tasks) / len(tasks),
        'seconds_best': {k: round(v, 2) for k, v in best.items()},
        'ms_per_task': {k: round(1000 * v / len(tasks), 2) for k, v in best.items()},
        'speedup': round(best['to_the_end'] / best['to_the_middle'], 3),
        'same_lines': lines['to_the_end'] == lines['to_the_middle'],
        'same_as_folder_file': None if saved is None else saved == lines['to_the_middle'],
    }, indent=1))


if __name__ == '__main__':
    main()
