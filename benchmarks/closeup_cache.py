#!/usr/bin/env python3
"""The oracle's close-up renders remembered per world state (session 12) vs rendered every time. Prints JSON.

An appearance answer needs pixels of the object; when the agent's frame shows too few of them, the
oracle renders close-ups around it until one shows enough (`ground_truth.closeup_pixels`, about 5
renders of 7 ms each on average for train's task objects). Profiling found these renders at about
half of prepare's oracle-answers pass. The same object is often asked about again while nothing has
moved: at step 0 and at the middle step of an expert episode whose first half only walks, or by
several annotators at a task's start. `closeup_pixels` now remembers its result per object and world
state (every body's pose and joints; the cache is emptied whenever a body is made or removed).

This times both passes that go through every train task on the first `--limit` tasks of a
demonstrations folder, in one process, with the cache and with it switched off (every call renders),
interleaved, and checks that both give the same lines and rows:
- prepare's oracle-answers pass (`data.task_dialogue`, the demonstrations' resolution);
- the synthetic annotators' pass (`scripts/annotate_dialogues.py`'s `_annotate_chunk`, 300 px).

    ./dialfred bench closeup_cache [--limit 200] [--demonstrations DIR] [--rounds 2]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / 'benchmarks'))

from annotation_pass import load_script  # noqa: E402  (scripts/annotate_dialogues.py as a module)
from dialfred_sim.machine import cpu_model  # noqa: E402


def main() -> None:
    import dialfred_sim.ground_truth as gt
    from dialfred_performer.data import dialogue_line, load_demonstrations, task_dialogue
    from dialfred_sim.env import DialfredEnv
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
    script = load_script()
    script._init_worker(demo.meta['split'])          # the script's env (the simulator's default resolution)
    env = DialfredEnv(resolution=demo.meta['resolution'])
    cached = gt.closeup_pixels
    renders = {'n': 0}
    search = gt._search_closeup

    def counting_search(world, obj, min_pixels):
        renders['n'] += 1
        return search(world, obj, min_pixels)

    def uncached(world, obj, min_pixels=gt.MIN_APPEARANCE_PIXELS):
        return counting_search(world, obj, min_pixels)

    passes = {'oracle_pass': lambda: [dialogue_line(t, task_dialogue(env, t)) for t in tasks],
              'annotators_pass': lambda: script._annotate_chunk((0, len(tasks)))}
    seconds, results, searches = {}, {}, {}
    gt._search_closeup = counting_search
    try:
        for _ in range(args.rounds):
            for way, fn in (('no_cache', uncached), ('cache', cached)):
                gt.closeup_pixels = fn
                for name, run in passes.items():
                    renders['n'] = 0
                    t0 = time.perf_counter()
                    results[name, way] = run()
                    seconds.setdefault((name, way), []).append(time.perf_counter() - t0)
                    searches[name, way] = renders['n']
    finally:
        gt.closeup_pixels, gt._search_closeup = cached, search
        env.close()
    out = {'benchmark': 'closeup_cache', 'tasks': len(tasks), 'rounds': args.rounds, 'cpu': cpu_model()}
    for name in passes:
        ms = {way: round(1000 * min(seconds[name, way]) / len(tasks), 2) for way in ('no_cache', 'cache')}
        out[name] = {'ms_per_task': ms, 'speedup': round(ms['no_cache'] / ms['cache'], 3),
                     'closeup_searches': {way: searches[name, way] for way in ('no_cache', 'cache')},
                     'same_output': results[name, 'no_cache'] == results[name, 'cache']}
    print(json.dumps(out, indent=1))


if __name__ == '__main__':
    main()
