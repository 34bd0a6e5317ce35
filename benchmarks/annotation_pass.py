"""Could the synthetic annotators' train rows be made inside prepare's oracle pass? Prints JSON.

`./dialfred reproduce` resets every train task twice after rendering: once in prepare's oracle-answers
pass (`data.task_dialogue`, at the demonstrations' resolution, 64) and once more in
`scripts/annotate_dialogues.py` (the simulator's default resolution, 300). Annotating each task right
after the pass's reset (`task_dialogue(..., at_start=...)`) would save the second reset. This times
both ways on the first `--limit` tasks of a demonstrations folder, in one process, and compares what
they give with the script's own function (`_annotate_chunk`) as the reference.

Measured in session 11 (first 200 train tasks): 1.45x faster, the same dialogue lines, but 1 of the 200
annotator rows differed (its situation the same: an appearance answer, whose colour is sampled from the
agent's frame at the env's resolution). So the rows depend on the resolution, the merge would change
the train dialogue data, and it is not used: reproduce still runs the script's own pass.

    ./dialfred bench annotation_pass [--limit 200] [--demonstrations DIR] [--rounds 2]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dialfred_sim.machine import cpu_model  # noqa: E402


def load_script():
    spec = importlib.util.spec_from_file_location('annotate_dialogues', REPO / 'scripts' / 'annotate_dialogues.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> None:
    from dialfred_oracle.annotator import annotate_task
    from dialfred_performer.data import dialogue_line, load_demonstrations, task_dialogue
    from dialfred_sim.env import DialfredEnv
    from dialfred_sim.tasks import load_split
    from dialfred_sim.tasks.demonstrations import default_dir
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--demonstrations', default=str(default_dir('train', 64)))
    ap.add_argument('--limit', type=int, default=200)
    ap.add_argument('--rounds', type=int, default=2, help='each way timed this many times, interleaved')
    args = ap.parse_args()
    if args.limit < 1 or args.rounds < 1:
        ap.error('--limit and --rounds must be at least 1')
    demo = load_demonstrations(Path(args.demonstrations))
    tasks = demo.tasks[:args.limit]
    by_id = {t.task_id: t for t in load_split(demo.meta['split'])[:len(tasks)]}
    script = load_script()
    script._init_worker(demo.meta['split'])          # the script's env (the simulator's default resolution)
    env = DialfredEnv(resolution=demo.meta['resolution'])

    def separate():
        lines = [dialogue_line(t, task_dialogue(env, t)) for t in tasks]
        return lines, script._annotate_chunk((0, len(tasks)))

    def merged():
        lines, rows = [], []
        for t in tasks:
            def at_start(e, task=by_id[t['task_id']]):
                rows.append(annotate_task(e, task).to_json())
            lines.append(dialogue_line(t, task_dialogue(env, t, at_start)))
        return lines, rows

    ways = {'separate_passes': separate, 'one_pass': merged}
    seconds = {k: [] for k in ways}
    results = {}
    for _ in range(args.rounds):
        for name, fn in ways.items():
            t0 = time.perf_counter()
            results[name] = fn()
            seconds[name].append(time.perf_counter() - t0)
    env.close()
    best = {k: min(v) for k, v in seconds.items()}
    print(json.dumps({
        'benchmark': 'annotation_pass', 'tasks': len(tasks), 'rounds': args.rounds, 'cpu': cpu_model(),
        'seconds_best': {k: round(v, 2) for k, v in best.items()},
        'ms_per_task': {k: round(1000 * v / len(tasks), 2) for k, v in best.items()},
        'speedup': round(best['separate_passes'] / best['one_pass'], 3),
        'same_dialogue_lines': results['separate_passes'][0] == results['one_pass'][0],
        'same_annotator_rows': results['separate_passes'][1] == results['one_pass'][1],
        'annotator_rows_differing': sum(a != b for a, b in zip(*(results[k][1] for k in ways))),
        'situations_differing': sum(a['situation'] != b['situation'] for a, b in zip(*(results[k][1] for k in ways))),
    }, indent=1))


if __name__ == '__main__':
    main()
