#!/usr/bin/env python3
"""What the performers make of other words for the same answers: All QAs with the oracle's template
answers against All QAs with an answerer's (default: the held-out wording,
`dialfred_oracle.wording:HeldOutWording`), on the same tasks, for each agent, played locally in one run.
Prints JSON: SR, PWSR, NQ of each, the SR lost to the wording with its paired 95% bootstrap interval, the
same for the instruction only when given (`--base`, what is left of a question's worth), and the answers'
words (mean length, distinct words, the share of words the templates never use).

The results are kept in --out (resumed when run again), named as `launch eval` names them.

    ./dialfred bench answer_wording [--split valid_unseen] [--limit N] [--agents et map] [--workers 2]
                                    [--answers dialfred_oracle.wording:HeldOutWording] [--base]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from dialfred_bringup.eval_run import EvalRun
from dialfred_bringup.evaluation import EvalConfig, run_eval
from dialfred_bringup.machine import cpu_model
from dialfred_sim.metrics import summarize
from dialfred_sim.tasks.instructions import tokenize

HELD_OUT = 'dialfred_oracle.wording:HeldOutWording'


def paired(a: list, b: list, resamples: int = 2000, seed: int = 0) -> list:
    """95% bootstrap interval of the mean of a - b (success in points), the same tasks in the same order."""
    d = 100.0 * (np.array([x.success for x in a], float) - np.array([y.success for y in b], float))
    rng = np.random.default_rng(seed)
    means = d[rng.integers(0, len(d), size=(resamples, len(d)))].mean(axis=1)
    return [round(float(np.quantile(means, 0.025)), 2), round(float(np.quantile(means, 0.975)), 2)]


def words_of(results: list) -> list[list[str]]:
    return [tokenize(qa['answer']) for r in results for qa in r.dialogue if qa.get('valid') and qa.get('answer')]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--split', default='valid_unseen')
    ap.add_argument('--limit', type=int, default=None, help='the first N tasks (default: every task)')
    ap.add_argument('--agents', nargs='+', default=['et', 'map'])
    ap.add_argument('--workers', type=int, default=2)
    ap.add_argument('--answers', default=HELD_OUT, help='the answerer (FILE or package.module:Class)')
    ap.add_argument('--base', action='store_true', help='also the instruction only, for the worth of a question')
    ap.add_argument('--out', type=Path, default=Path('out/bench/answer_wording'))
    args = ap.parse_args()
    if (args.limit is not None and args.limit < 1) or args.workers < 1:
        ap.error('--limit and --workers must be at least 1')
    args.out.mkdir(parents=True, exist_ok=True)
    report: dict = {'split': args.split, 'answers': args.answers, 'cpu': cpu_model(), 'agents': {}}
    for agent in args.agents:
        played, seconds = {}, {}
        settings = {'oracle': dict(questioner='all'), 'answerer': dict(questioner='all', answers=args.answers)}
        if args.base:
            settings['instruction only'] = {}
        for name, extra in settings.items():
            config = EvalConfig(split=args.split, agent=agent, local=True, workers=args.workers, limit=args.limit,
                                **extra)
            path = args.out / EvalRun(config, check=False).results_path.name
            t0 = time.monotonic()
            played[name] = sorted(run_eval(EvalConfig(**{**vars(config), 'out': path}), progress=True).results,
                                  key=lambda r: r.task_id)
            seconds[name] = round(time.monotonic() - t0, 1)
        row: dict = {'tasks': len(played['oracle']), 'wall_s': seconds}
        for name, results in played.items():
            s = summarize(results)['overall']
            row[name] = {'SR': round(s['SR'], 2), 'PWSR': round(s['PWSR'], 2), 'NQ': round(s['NQ'], 3)}
        row['SR_lost_to_wording'] = round(row['oracle']['SR'] - row['answerer']['SR'], 2)
        row['SR_lost_to_wording_95'] = paired(played['oracle'], played['answerer'])
        if args.base:
            nq = row['oracle']['NQ']
            row['worth_oracle'] = round((row['oracle']['SR'] - row['instruction only']['SR']) / nq, 3)
            row['worth_answerer'] = round((row['answerer']['SR'] - row['instruction only']['SR']) / nq, 3)
        template_vocabulary = {w for ws in words_of(played['oracle']) for w in ws}
        said = words_of(played['answerer'])
        tokens = [w for ws in said for w in ws]
        row['answer_words'] = {
            'mean_oracle': round(float(np.mean([len(ws) for ws in words_of(played['oracle'])])), 2),
            'mean_answerer': round(float(np.mean([len(ws) for ws in said])), 2),
            'distinct_answerer': len(set(tokens)),
            'share_not_in_templates': round(sum(w not in template_vocabulary for w in tokens) / len(tokens), 3)}
        report['agents'][agent] = row
    print(json.dumps(report, indent=1))


if __name__ == '__main__':
    main()
