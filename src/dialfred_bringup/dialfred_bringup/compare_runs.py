#!/usr/bin/env python3
"""Compare two `./dialfred reproduce` runs: the same tables, episodes, weights and caches?

    ./dialfred env python -m dialfred_bringup.compare_runs out/reproduce out/reproduce_b [--parts tables,episodes,weights,caches]

A second run that is independent of the first needs its own caches; point them into its run folder:

    DIALFRED_DEMO_DIR=out/reproduce_b/cache/demonstrations \\
    DIALFRED_DIALOGUE_DIR=out/reproduce_b/cache/dialogues \\
    DIALFRED_QUESTIONER_CACHE=out/reproduce_b/cache/questioner \\
        ./dialfred reproduce --out out/reproduce_b

What is compared (each part says `same` true/false, with the first differences):

- `tables`: `results.md` from "## Table II" up to "## Run times" (every table, what holds, the
  questions, the dialogues), with each run folder's path taken out. The settings above it name the
  checkpoints' file hashes, which differ with the run folder written into each checkpoint's command;
  the run times always differ.
- `episodes`: every results file under `eval/` and `check/`, episode by episode, every field but the
  wall time and the agent's name (it carries the checkpoint's file hash, see above).
- `weights`: the perception network (`perception/perception.pt`), the performer (`performer/best.pt`), the pre-trained questioner and every RL questioner:
  each tensor of the state dict (and the questioner's frozen visual encoder), the config and the
  vocabularies.
- `caches` (asked for with `--parts ...,caches`): the files of the demonstrations, dialogues and first-frames caches that
  the stamps name, by sha256 (the demonstrations are about 3 GB: some seconds); a JSON file (the
  demonstrations' meta.json) without its top-level 'seconds...' timings.

`--parts` picks what to compare (default tables,episodes,weights): a run still under way can be
compared on what it has made so far, e.g. `--parts caches,weights` after its training stages.
Prints one JSON object; exit status 0 when every part compared is the same, 1 when something differs,
2 when a run folder or a part that was asked for is missing.
"""

from __future__ import annotations

import hashlib
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from dialfred_sim.dataclass_cli import REQUIRED, arg, parse

TABLES_FROM, TABLES_TO = '## Table II', '## Run times'
IGNORED_FIELDS = ('wall_s', 'code', 'agent')   # RUN_FIELDS (dialfred_sim.metrics) and the agent's name


class MissingPart(Exception):
    """A run folder, or a file that both runs must have, is absent or unreadable."""


def tables_text(run: Path) -> str:
    """The part of a run's results.md that must not depend on the run: Table II up to the run times,
    with the run folder's path removed."""
    path = run / 'results.md'
    try:
        text = path.read_text()
    except OSError as exc:
        raise MissingPart(f'{path}: {exc.strerror or exc}') from None
    if TABLES_FROM not in text or TABLES_TO not in text:
        raise MissingPart(f'{path} has no "{TABLES_FROM}" ... "{TABLES_TO}" part (an unfinished run?)')
    part = text.split(TABLES_FROM, 1)[1].split(TABLES_TO, 1)[0]
    for form in (str(run.resolve()), str(run)):
        part = part.replace(form, '<run>')
    return part


def compare_tables(a: Path, b: Path, show: int) -> dict:
    ta, tb = tables_text(a).splitlines(), tables_text(b).splitlines()
    differing = [(i, x, y) for i, (x, y) in enumerate(zip(ta, tb)) if x != y]
    same = ta == tb
    return {'same': same, 'lines': len(ta), 'differing_lines': len(differing) + abs(len(ta) - len(tb)),
            'first': [{'a': x, 'b': y} for _, x, y in differing[:show]]}


def read_episodes(path: Path) -> dict:
    """{task_id: record without the ignored fields} of one results file (a cut-off last line is dropped,
    as the evaluation drops it)."""
    out = {}
    lines = path.read_text().splitlines()
    for n, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except ValueError:
            if n == len(lines) - 1:
                break
            raise MissingPart(f'{path}:{n + 1}: not JSON') from None
        out[record['task_id']] = {k: v for k, v in record.items() if k not in IGNORED_FIELDS}
    return out


def results_files(run: Path) -> dict:
    """{relative path: path} of the episode files of a run (eval/ and check/, not the .runs.jsonl logs)."""
    files = {}
    for folder in ('eval', 'check'):
        for p in sorted((run / folder).glob('*.jsonl')):
            if not p.name.endswith('.runs.jsonl'):
                files[f'{folder}/{p.name}'] = p
    return files


def compare_episodes(a: Path, b: Path, show: int) -> dict:
    fa, fb = results_files(a), results_files(b)
    if not fa and not fb:
        raise MissingPart(f'no results files under {a}/eval or {b}/eval')
    only = sorted(set(fa) ^ set(fb))
    files, episodes, differing = {}, 0, 0
    for name in sorted(set(fa) & set(fb)):
        ea, eb = read_episodes(fa[name]), read_episodes(fb[name])
        ids = sorted(set(ea) | set(eb))
        bad = [i for i in ids if ea.get(i) != eb.get(i)]
        episodes += len(ids)
        differing += len(bad)
        if bad:
            first = bad[0]
            fields = sorted(k for k in set(ea.get(first, {})) | set(eb.get(first, {}))
                            if ea.get(first, {}).get(k) != eb.get(first, {}).get(k))
            files[name] = {'episodes': len(ids), 'differing': len(bad), 'first': bad[:show],
                           'fields_of_first': fields}
    return {'same': not only and not differing, 'files': len(set(fa) & set(fb)), 'episodes': episodes,
            'differing': differing, 'only_in_one': only, 'differing_files': files}


def checkpoints(run: Path) -> dict:
    """{name: path} of the models a run has trained so far."""
    out = {'perception': run / 'perception' / 'perception.pt', 'performer': run / 'performer' / 'best.pt', 'pretrain': run / 'questioner' / 'pretrain' / 'best.pt'}
    for p in sorted((run / 'questioner').glob('*/final.pt')):
        out[p.parent.name] = p
    return {name: p for name, p in out.items() if p.is_file()}


def same_value(x, y) -> bool:
    import torch  # lazy: torch, which the rest of this module does without
    if isinstance(x, torch.Tensor) or isinstance(y, torch.Tensor):
        return isinstance(x, torch.Tensor) and isinstance(y, torch.Tensor) and x.dtype == y.dtype \
            and x.shape == y.shape and torch.equal(x, y)
    if isinstance(x, dict) and isinstance(y, dict):
        return x.keys() == y.keys() and all(same_value(x[k], y[k]) for k in x)
    return x == y


# what a checkpoint holds that must not depend on the run (its command and commit name the run folder)
MODEL_KEYS = ('format', 'config', 'vocab', 'nouns', 'state_dict', 'visual', 'visual_resolution', 'visual_config', 'timing',
              'reads_dialogue')


def compare_weights(a: Path, b: Path, show: int) -> dict:
    from dialfred_performer.model import read_state  # lazy: pybullet, torch, which the rest of this module does without
    ca, cb = checkpoints(a), checkpoints(b)
    models, only = {}, sorted(set(ca) ^ set(cb))
    for name in sorted(set(ca) & set(cb)):
        try:
            ma, mb = read_state(ca[name]), read_state(cb[name])
        except (OSError, ValueError) as exc:
            raise MissingPart(f'{name}: cannot load its checkpoint: {exc}') from None
        keys = [k for k in MODEL_KEYS if k in ma or k in mb]
        bad = [k for k in keys if not same_value(ma.get(k), mb.get(k))]
        tensors = [t for t in ma.get('state_dict', {})
                   if not same_value(ma['state_dict'][t], mb.get('state_dict', {}).get(t))]
        models[name] = {'same': not bad, 'differing': bad, 'first_tensors': tensors[:show]}
    return {'same': not only and all(m['same'] for m in models.values()), 'models': models, 'only_in_one': only}


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, 'rb') as f:
        for block in iter(lambda: f.read(1 << 22), b''):
            h.update(block)
    return h.hexdigest()


def cache_paths(run: Path) -> dict:
    """{cache: path} from the run's stamps: the demonstrations folder, the dialogue file, the first frames."""
    def stamp(stage):
        try:
            return json.loads((run / 'stamps' / f'{stage}.json').read_text())
        except (OSError, ValueError):
            raise MissingPart(f'{run}/stamps/{stage}.json is missing or unreadable') from None
    return {'demonstrations': Path(stamp('demos')['inputs']['config']['out']),
            'dialogues': Path(stamp('dialogues')['report']['path']),
            'frames': Path(stamp('frames')['report']['path'])}


def digest(path: Path) -> str:
    """A file's sha256; of a JSON file (a cache's meta.json), of its content without the run's timings
    (top-level keys starting with 'seconds')."""
    if path.suffix == '.json':
        try:
            data = json.loads(path.read_text())
        except (OSError, ValueError):
            return sha256_file(path)
        if isinstance(data, dict):
            data = {k: v for k, v in data.items() if not k.startswith('seconds')}
        return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()
    return sha256_file(path)


def digests(path: Path) -> dict:
    if path.is_dir():
        return {p.name: digest(p) for p in sorted(path.iterdir()) if p.is_file()}
    if path.is_file():
        return {path.name: digest(path)}
    raise MissingPart(f'{path} is missing')


def compare_caches(a: Path, b: Path, show: int) -> dict:
    pa, pb = cache_paths(a), cache_paths(b)
    out = {}
    for name in pa:
        if pa[name].resolve() == pb[name].resolve():
            out[name] = {'same': None, 'note': f'both runs used {pa[name]}: nothing to compare'}
            continue
        da, db = digests(pa[name]), digests(pb[name])
        bad = sorted(k for k in set(da) | set(db) if da.get(k) != db.get(k))
        out[name] = {'same': not bad, 'files': len(set(da) | set(db)), 'differing': bad[:show]}
    return {'same': all(c['same'] is not False for c in out.values()), 'caches': out}


PARTS = {'tables': compare_tables, 'episodes': compare_episodes, 'weights': compare_weights, 'caches': compare_caches}
DEFAULT_PARTS = ('tables', 'episodes', 'weights')


def compare(a: Path, b: Path, parts=DEFAULT_PARTS, show: int = 5) -> dict:
    unknown = [p for p in parts if p not in PARTS]
    if unknown or not parts:
        raise ValueError(f'parts are some of {", ".join(PARTS)}, got {", ".join(parts) or "none"}')
    for run in (a, b):
        if not run.is_dir():
            raise MissingPart(f'{run} is not a run folder')
    report = {'a': str(a), 'b': str(b)}
    for part in PARTS:
        if part in parts:
            report[part] = PARTS[part](a, b, show)
    report['same'] = all(report[p]['same'] for p in PARTS if p in report)
    return report


@dataclass
class CompareConfig:
    """Compare two run folders of ./dialfred reproduce."""

    a: Path = arg(REQUIRED, 'a run folder of ./dialfred reproduce', positional=True)
    b: Path = arg(REQUIRED, 'another run folder', positional=True)
    parts: str = arg(','.join(DEFAULT_PARTS), f'what to compare, comma-separated: some of {", ".join(PARTS)}')
    show: int = arg(5, 'how many differences of each kind to list')


def main(argv: Optional[list[str]] = None) -> int:
    args = parse(CompareConfig, argv, prog='python -m dialfred_bringup.compare_runs',
                 description=__doc__.split('\n')[0])
    try:
        report = compare(args.a, args.b, tuple(p for p in args.parts.split(',') if p), args.show)
    except (MissingPart, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    print(json.dumps(report, indent=1))
    return 0 if report['same'] else 1


if __name__ == '__main__':
    sys.exit(main())
