"""Reproduce the paper's Tables II, III and IV end to end: `./dialfred reproduce`.

    ./dialfred reproduce                      # everything after set-up -> out/reproduce/ (resumable), docs/results.md
    ./dialfred reproduce --quick              # the same pipeline on tiny slices, in minutes -> out/reproduce_quick/
    ./dialfred reproduce --shipped            # no training: evaluate the shipped checkpoints -> out/reproduce_shipped
    ./dialfred reproduce --force rl           # rerun the rl stage and every stage after it
    ./dialfred reproduce --eval-path graph    # the tables' evaluations through the ROS graph (default: local)
    ./dialfred reproduce --status             # where the run stands: its stamps, and which stages a run would redo (runs nothing)
    ./dialfred reproduce --redoc              # the document again from the run's results (after a change to its code; runs nothing else)
    ./dialfred env python -m dialfred_bringup.reproduce.ship   # a finished run's models become the shipped ones

Stages, in order (each calls the project's own API or command; none repeats their logic):

| stage | what | output (under the run folder, `--out`) |
|---|---|---|
| demos | the performer's demonstrations of train (`dialfred_performer.prepare --annotate --labels`): the expert's frames with each pixel's class and depth (labels for perception only), and while each task is played the oracle's QAs at its start and middle and the synthetic annotators' row at its start (no second or third replay of train) | `~/.cache/dialfred/demonstrations/train_64` (quick: `cache/demonstrations`) |
| perception | the perception network trained on those frames and labels (`dialfred_performer.perception`: 400,000 frames, in bfloat16 where the CPU computes it natively) | `perception/perception.pt` |
| performer | performer training on the frozen perception network (`dialfred_performer.train --perception`: 12,000 updates of 16 episodes) | `performer/best.pt` |
| dialogues | synthetic train dialogues (`scripts/annotate_dialogues.py --splits train --from-demonstrations`: the rows the demos stage made, the same bytes as the script's own pass) | `~/.cache/dialfred/dialogues/train.jsonl.gz` (quick: `cache/dialogues`) |
| frames | train's first frames, copied out of the demonstrations (`dialfred_questioner.frames --demonstrations`) | `~/.cache/dialfred/questioner/train_first_64.npz` (quick: `cache/`) |
| pretrain | questioner pre-training (`dialfred_questioner.pretrain`) | `questioner/pretrain/best.pt` |
| rl | the RL fine-tunings (`dialfred_questioner.finetune` on valid_seen, 32 updates of 64 episodes): rl_begin, rl_anytime (gap 5), rl_anytime_1 (gap 1, Fixed-1 rewards), rl_anytime_10, rl_mc (model confusion), rl_anytime_withhold_{location,appearance,direction} (the oracle withholding 50% of that type's answers during training); beyond the paper rl_anytime_no_dialogue (the instruction only) map_rl_anytime (against the map-and-plan performer, `--model map`), and rl_anytime_chained and map_rl_anytime_chained (RL anytime against each performer under the chained protocol, `--protocol chained`: whole episodes on the performer's own state) | `questioner/<name>/final.pt` |
| eval | every setting of the tables, the map-and-plan performer's five and the swap control (All QAs with another task's answers, `--answers swapped`) among them (`dialfred_bringup.evaluation.run_eval`; `--eval-path local` (default): worker processes without ROS, `dialfred_bringup.local`; `graph`: performer nodes; `in-process`: the agent in this process, simulator and oracle nodes); resumable episode by episode | `eval/<split>_<setting>.jsonl` |
| chained | DialFRED's challenge test (`--protocol chained`, `dialfred_sim/chained.py`): on valid_unseen, both performers with the instruction only, All QAs, Random QA, RL anytime (fine-tuned under expert initialisation, and under chaining), and All QAs with swapped answers, each episode's tasks in order on the agent's own state; locally, or with `--eval-path graph`/`in-process` by the performer in this process through simulator and oracle nodes | `chained/<split>_<setting>.jsonl` |
| check | the first `--check-tasks` tasks of every setting played again through the ROS graph (performer, questioner, oracle and simulator nodes) and compared with the eval stage's episodes field by field (wall time aside); mismatches are listed in the document, not hidden | `check/<split>_<setting>.jsonl`, `check/report.json` |
| doc | Tables II, III, IV beside the paper's numbers with 95% bootstrap intervals, the worth of a question (by task family and type; the swap control), the chained table beside the expert-initialised one (with the worth of a question under chaining, the tasks lost to chaining per type and the 10 most common ways a chained episode goes wrong), what holds, the SR-NQ plot, the RL questioner's most frequent questions and dialogues that turned a failure into a success | `results.md`, `sr_nq.png` (and `--doc PATH`, its plot beside it: `sr_nq.png`, or `<stem>_sr_nq.png` for a doc of another name) |

Each stage writes `stamps/<stage>.json` with the hash of its inputs (its config, the hashes of the stages
it depends on, and the source files that make it). A stage whose stamp matches is skipped
(`[reproduce] <stage>: skipped (stamp matches)`); a changed input reruns it and therefore every stage
after it. A stage cut off midway resumes (training from its last.pt, evaluations from their results
files) when rerun with the same inputs; with other inputs its outputs are cleared first, except a
finished stage's (or RL run's, or setting's), which are moved to `<run>/replaced/<stage>/` and kept
there until it is redone again; `--status` marks such a stage stale before anything runs. A progress
line per stage (name, skipped/ran, seconds) goes to stderr and one JSON summary to stdout.

`--shipped` runs no training: the performer is the shipped `dialfred_performer/checkpoints/et.pt`
and the questioners the shipped `dialfred_questioner/checkpoints/<setting>.pt` (a setting whose file
is absent is left out of the tables, marked "no results"); its run folder is out/reproduce_shipped.
The document goes to the run folder, and is copied to docs/results.md (a full run in out/reproduce) or
`--doc PATH`; `--shipped` (the shipped checkpoints are a full run's, so its tables should be
docs/results.md's), a quick run or another `--out` copy it nowhere unless `--doc` says where, `--doc
none` never.
`--quick` runs the whole pipeline on slices (32 train tasks, a tiny performer and questioner, RL of
2 updates x 8 episodes of at most 30 steps, evaluations of 8 tasks by `--eval-path`); its numbers mean
nothing, it checks the pipeline. Caches of the quick run stay in its run folder (DIALFRED_DIALOGUE_DIR
and explicit paths), so it never replaces the full train data in ~/.cache.

Everything is seeded (`--seed`). Each stage's output is reproducible: the demonstrations, dialogues
and first frames are byte-identical across runs, and evaluating the same checkpoints gives the same
episodes. Performer training repeats bit for bit on one CPU, but not on every one: on one machine, one
process in two of the same command differed by a rounding in its first updates and trained a different
model, and the tables moved by up to 4.3 SR points (`./dialfred bench training_determinism` looks for
the cause; docs/figures.md). On an AMD EPYC no process of 28 left the common stream, but that stream
differs from the other CPU's from the first updates on, so a run on another CPU retrains other models.
The run times, listed apart from the tables, always differ.
"""

from __future__ import annotations

import json
import sys
from typing import Optional

from dialfred_sim.dataclass_cli import parse

from .document import build_report, copy_doc, draw_frontier, render, why_lines, write_outputs
from .plan import (EXTRA, MAP_ROWS, PAPER_T2, PAPER_T3, PAPER_T4, PERTURB_PROBABILITY, RESOLUTION, RL_RUNS, SHIPPED_QUESTIONERS,
                   SPLITS, STAGES, Plan, ReproduceConfig, Setting, chained_settings, settings, weights_sha256)
from .stages import Runner
from .status import run_status, status_lines

__all__ = ['EXTRA', 'MAP_ROWS', 'PAPER_T2', 'PAPER_T3', 'PAPER_T4', 'PERTURB_PROBABILITY', 'RESOLUTION', 'RL_RUNS',
           'SHIPPED_QUESTIONERS', 'SPLITS', 'STAGES', 'Plan', 'ReproduceConfig', 'Runner', 'Setting', 'chained_settings',
           'copy_doc',
           'draw_frontier', 'main', 'render', 'settings', 'weights_sha256', 'why_lines', 'write_outputs']


def main(argv: Optional[list[str]] = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    cfg = parse(ReproduceConfig, argv, prog='./dialfred reproduce')
    if cfg.status:
        planned = Runner(cfg).planned_hashes() if (cfg.run_dir / 'stamps').is_dir() else None
        print('\n'.join(status_lines(run_status(cfg.run_dir, cfg.shipped, planned=planned))))
        return 0
    if cfg.redoc:
        return redoc(cfg)
    try:
        summary = Runner(cfg).run()
    except (FileNotFoundError, ValueError, RuntimeError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    print(json.dumps(summary))
    return 0


def redoc(cfg: ReproduceConfig) -> int:
    """`--redoc`: the doc stage's document and plot, written again from the run's results files as they
    are (no stamp is read or written, no stage runs), then copied where --doc says."""
    plan = Plan(cfg)
    if not any(plan.eval_dir.glob('*.jsonl')):
        print(f'error: no results files in {plan.eval_dir}: --redoc writes the document of a run that has evaluated',
              file=sys.stderr)
        return 2
    doc, plot = write_outputs(plan, build_report(plan, cfg.resamples))
    target = cfg.doc_target
    if target is not None:
        target.parent.mkdir(parents=True, exist_ok=True)
        copy_doc(plan.run, target)
    print(json.dumps({'doc': str(doc), 'plot': str(plot), 'copied_to': str(target) if target else None}))
    return 0
