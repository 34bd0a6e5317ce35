"""Make a finished `./dialfred reproduce` run's models the shipped ones: one pipeline, one set of numbers.

    ./dialfred env python -m dialfred_bringup.reproduce.ship [--run out/reproduce] [--dry-run]

The run's performer (`performer/best.pt`) becomes `dialfred_performer/checkpoints/et.pt`, and its
pre-trained and RL questioners become `dialfred_questioner/checkpoints/<name>.pt`. The questioners
were trained with a frozen copy of the performer's frame encoder; the shipped files name et.pt instead of
carrying that copy in every file (`dialfred_questioner.policy.share_visual`, checked by weights digest on
every load), which keeps the shipped checkpoints small. The times and machine of the run's finished
stages go to `reproduce/shipped_run.json`: the document of `reproduce --shipped` says from them what the
models cost (the training stages'), and `reproduce --status` estimates from them what a run has left
(every stage's, the evaluations and the graph check included). Nothing is written unless every model of
the run is there, and each of its stamps says done. Prints one JSON line: each file and its size.
"""

from __future__ import annotations

import json
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from dialfred_performer.model import SHIPPED_CHECKPOINT, load_checkpoint
from dialfred_questioner.policy import LearnedQuestioner, share_visual
from dialfred_sim.dataclass_cli import arg, parse
from dialfred_sim.metrics import write_text_atomically

from ..paths import REPO
from .document import stage_times
from .plan import RL_RUNS, SHIPPED_QUESTIONERS, SHIPPED_RUN

SHIPPED_STAGES = ('perception', 'performer', 'pretrain', 'rl')


@dataclass(frozen=True)
class ShipConfig:
    """Copy a finished reproduce run's performer and questioners over the shipped checkpoints."""

    run: str = arg('out/reproduce', 'the run folder of a full ./dialfred reproduce')
    dry_run: bool = arg(False, 'check the run and say what would be written, write nothing')
    into: str = arg('', "write et.pt and the questioners side by side into this folder instead of the packages' "
                        "checkpoint folders (a quick run's models may go here, never over the shipped ones)")


def finished_times(run: Path) -> dict:
    """The record `ship` writes: {stage: its time and machine} for each stage of `run` whose stamp says done."""
    return {stage: {k: v for k, v in t.items() if k != 'done'} for stage, t in stage_times(run).items() if t['done']}


def ship(cfg: ShipConfig) -> dict:
    run = Path(cfg.run) if Path(cfg.run).is_absolute() else REPO / cfg.run
    for stage in SHIPPED_STAGES:
        try:
            stamp = json.loads((run / 'stamps' / f'{stage}.json').read_text())
        except (OSError, ValueError):
            raise ValueError(f'{run}: the {stage} stage has no stamp (is this a reproduce run folder?)') from None
        if stamp.get('status') != 'done':
            raise ValueError(f'{run}: the {stage} stage is not done ({stamp.get("status")})')
        if not cfg.into and stamp.get('inputs', {}).get('config', {}).get('limit'):
            raise ValueError(f'{run} is a quick run: its models are not for shipping')
    performer = run / 'performer' / 'best.pt'
    questioners = {name: run / 'questioner' / 'pretrain' / 'best.pt' if name == 'pretrained'
                   else run / 'questioner' / name / 'final.pt' for name in ('pretrained', *RL_RUNS)}
    missing = [str(p) for p in (performer, *questioners.values()) if not p.is_file()]
    if missing:
        raise FileNotFoundError(f'the run lacks {", ".join(missing)}')
    load_checkpoint(performer)                           # refuses a damaged file before anything is replaced
    into = Path(cfg.into).resolve() if cfg.into else None
    et = into / 'et.pt' if into else SHIPPED_CHECKPOINT
    targets = {name: (into or SHIPPED_QUESTIONERS) / f'{name}.pt' for name in questioners}
    if cfg.dry_run:
        return {'performer': {str(performer): str(et)},
                'questioners': {str(questioners[n]): str(t) for n, t in targets.items()}, 'written': False}
    et.parent.mkdir(parents=True, exist_ok=True)
    tmp = et.with_name(et.name + '.tmp')
    shutil.copyfile(performer, tmp)
    tmp.replace(et)
    for name, source in questioners.items():
        share_visual(source, targets[name], et)
        LearnedQuestioner.from_checkpoint(targets[name])  # loads, with the encoder from et.pt
    record = into / SHIPPED_RUN.name if into else SHIPPED_RUN
    write_text_atomically(record, json.dumps({'stages': finished_times(run)}, indent=1, sort_keys=True) + '\n')
    sizes = {str(p): p.stat().st_size for p in (et, *targets.values())}
    return {'files': sizes, 'bytes': sum(sizes.values()), 'times': str(record), 'written': True}


def main(argv: Optional[list[str]] = None) -> int:
    cfg = parse(ShipConfig, argv, prog='python -m dialfred_bringup.reproduce.ship')
    try:
        print(json.dumps(ship(cfg)))
    except (FileNotFoundError, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
