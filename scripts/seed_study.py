#!/usr/bin/env python3
"""How much the tables move with the questioner's RL seed: fine-tune the same RL settings with other seeds
and evaluate every checkpoint on the same episodes. Prints JSON; writes `<out>/seeds.md`.

    ./dialfred env python scripts/seed_study.py [--runs rl_anytime rl_anytime_no_dialogue] [--seeds 1 2]
        [--random-seeds 0 1 2] [--split valid_unseen] [--limit N] [--workers 2] [--out out/seed_study]
        [--doc docs/seeds.md]

One training run is one draw (docs/figures.md: a retrained performer moved SR by up to 4.6 points).
This study holds the performer (the shipped `et.pt`) and the pre-trained questioner (the shipped
`pretrained.pt`) fixed and varies only what RL fine-tuning draws from its seed (task order, episodes,
the questioner's samples):

- for each `--runs` setting (reproduce's RL_RUNS, the same config as `./dialfred reproduce`) and each
  `--seeds` seed: `dialfred_questioner.finetune` with that seed -> `<out>/<run>_s<seed>/final.pt`
  (resumes from last.pt; a finished run is skipped);
- each checkpoint is evaluated on `--split` with evaluation seed 0 (the tables' seed), locally (no ROS;
  the same episodes as through the graph: tests/bringup/test_eval_local.py) -> `<out>/eval/...jsonl` (resumable
  episode by episode);
- the shipped checkpoint of the setting is evaluated the same way, as one more draw ("shipped", trained
  with seed 0 on another machine);
- Random QA is evaluated with each `--random-seeds` evaluation seed (its only randomness), to compare
  RL's spread with the baseline's own.

Every number comes from the results files, so a rerun reprints them without playing anything.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

from dialfred_bringup.evaluation import EvalConfig, run_eval
from dialfred_bringup.reproduce import PERTURB_PROBABILITY, RESOLUTION, RL_RUNS, SHIPPED_QUESTIONERS, weights_sha256
from dialfred_performer.model import SHIPPED_CHECKPOINT
from dialfred_questioner.finetune import FinetuneConfig, finetune
from dialfred_sim.metrics import summarize

ROOT = Path(__file__).resolve().parents[1]


def log(msg: str) -> None:
    print(f'[seed_study] {msg}', file=sys.stderr, flush=True)


def finetune_run(run: str, seed: int, out: Path, workers: int, progress: bool, **overrides) -> Path:
    """The RL setting `run` fine-tuned with `seed` from the shipped pre-trained questioner."""
    folder = out / f'{run}_s{seed}'
    if (folder / 'final.pt').exists():
        return folder / 'final.pt'
    t0 = time.monotonic()
    finetune(FinetuneConfig(init=str(SHIPPED_QUESTIONERS / 'pretrained.pt'), performer=str(SHIPPED_CHECKPOINT),
                            split='valid_seen', out=str(folder), resolution=RESOLUTION, workers=workers,
                            seed=seed, progress=progress, perturb_probability=PERTURB_PROBABILITY,
                            resume=(folder / 'last.pt').exists(), **RL_RUNS[run], **overrides))
    log(f'{run} seed {seed}: fine-tuned in {time.monotonic() - t0:.1f} s')
    return folder / 'final.pt'


def evaluate(name: str, questioner: str, split: str, seed: int, limit, workers: int, out: Path,
             progress: bool) -> dict:
    """One evaluation (resumable); its overall row."""
    config = EvalConfig(split=split, agent='et', local=True, questioner=questioner, limit=limit,
                        workers=workers, out=out / 'eval' / f'{split}_{name}.jsonl', seed=seed,
                        resolution=RESOLUTION, perturb_probability=PERTURB_PROBABILITY)
    t0 = time.monotonic()
    report = run_eval(config, progress=progress)
    if report.ran:
        log(f'{name}: {report.ran} episodes in {time.monotonic() - t0:.1f} s')
    row = summarize(report.results)['overall']
    return {k: row[k] for k in ('n', 'SR', 'PWSR', 'NQ')}


def spread(values: list) -> dict:
    return {'mean': round(statistics.fmean(values), 2),
            'sd': round(statistics.stdev(values), 2) if len(values) > 1 else None,
            'min': min(values), 'max': max(values), 'draws': len(values)}


def markdown(result: dict) -> str:
    lines = [f'Split {result["split"]}, {result["episodes"]} episodes per evaluation; performer and pre-trained '
             f'questioner fixed (shipped; the performer\'s weights sha256 {result.get("performer_sha256", "?")}); RL draws: the shipped checkpoint and the fine-tunings of `--seeds`. '
             'Command: `./dialfred env python scripts/seed_study.py '
             + ' '.join(result['argv']) + '`.', '',
             '| setting | draw | SR | PWSR | NQ |', '|---|---|---|---|---|']
    for name, draws in result['draws'].items():
        for draw, row in draws.items():
            lines.append(f'| {name} | {draw} | {row["SR"]:.1f} | {row["PWSR"]:.1f} | {row["NQ"]:.2f} |')
    lines += ['', '| setting | SR mean | SR sd | SR min-max | NQ mean | draws |', '|---|---|---|---|---|---|']
    for name, s in result['spread'].items():
        sd = '' if s['SR']['sd'] is None else f'{s["SR"]["sd"]:.2f}'
        lines.append(f'| {name} | {s["SR"]["mean"]:.2f} | {sd} | {s["SR"]["min"]:.1f}-{s["SR"]["max"]:.1f} '
                     f'| {s["NQ"]["mean"]:.2f} | {s["SR"]["draws"]} |')
    return '\n'.join(lines) + '\n'


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--runs', nargs='+', default=['rl_anytime', 'rl_anytime_no_dialogue'], choices=sorted(RL_RUNS))
    ap.add_argument('--seeds', nargs='*', type=int, default=[1, 2], help='RL seeds to fine-tune (beside the shipped)')
    ap.add_argument('--random-seeds', nargs='*', type=int, default=[0, 1, 2],
                    help='evaluation seeds of Random QA')
    ap.add_argument('--split', default='valid_unseen', choices=['valid_seen', 'valid_unseen'])
    ap.add_argument('--limit', type=int, default=0, help='only the first N tasks of the split (0: all)')
    ap.add_argument('--workers', type=int, default=2)
    ap.add_argument('--out', default=str(ROOT / 'out' / 'seed_study'))
    ap.add_argument('--no-progress', action='store_true')
    ap.add_argument('--doc', default='', help='also write the tables here (e.g. docs/seeds.md), under a heading')
    ap.add_argument('--updates', type=int, default=0, help='RL updates (0: the reproduce config, 64); for tests')
    ap.add_argument('--episodes-per-update', type=int, default=0, help='(0: the reproduce config, 64); for tests')
    ap.add_argument('--max-steps', type=int, default=0, help='RL episodes cut off after this many steps (0: 1000)')
    args = ap.parse_args(argv)
    if any(s < 0 for s in args.seeds + args.random_seeds) or args.limit < 0 or args.workers < 1:
        ap.error('seeds and --limit must be >= 0, --workers >= 1')
    for run in args.runs:
        if RL_RUNS[run].get('perturb_type'):
            ap.error(f'{run} trains with a perturbed oracle; this study evaluates with the plain one')
    overrides = {k: getattr(args, k) for k in ('updates', 'episodes_per_update', 'max_steps') if getattr(args, k)}
    out = Path(args.out)
    progress = not args.no_progress
    limit = args.limit or None
    draws: dict = {}
    for run in args.runs:
        draws[run] = {'shipped': evaluate(f'{run}_shipped', f'learned:{SHIPPED_QUESTIONERS / (run + ".pt")}',
                                          args.split, 0, limit, args.workers, out, progress)}
        for seed in args.seeds:
            ckpt = finetune_run(run, seed, out, args.workers, progress, **overrides)
            draws[run][f'seed {seed}'] = evaluate(f'{run}_s{seed}', f'learned:{ckpt}', args.split, 0, limit,
                                                  args.workers, out, progress)
    if args.random_seeds:
        draws['random_qa'] = {f'eval seed {s}': evaluate(f'random_qa_e{s}', 'random', args.split, s, limit,
                                                         args.workers, out, progress) for s in args.random_seeds}
    result = {'split': args.split, 'performer_sha256': weights_sha256(SHIPPED_CHECKPOINT)[:12], 'episodes': next(iter(next(iter(draws.values())).values()))['n'],
              'argv': list(argv if argv is not None else sys.argv[1:]), 'draws': draws,
              'spread': {name: {m: spread([r[m] for r in d.values()]) for m in ('SR', 'NQ')}
                         for name, d in draws.items()}}
    out.mkdir(parents=True, exist_ok=True)
    (out / 'seeds.md').write_text(markdown(result))
    if args.doc:
        Path(args.doc).parent.mkdir(parents=True, exist_ok=True)
        Path(args.doc).write_text('# How much the tables move with the RL seed\n\n'
                                  '<!-- Generated by scripts/seed_study.py; rerun it rather than editing. -->\n\n'
                                  + markdown(result))
    (out / 'summary.json').write_text(json.dumps(result, indent=1) + '\n')
    print(json.dumps(result))
    return 0


if __name__ == '__main__':
    sys.exit(main())
