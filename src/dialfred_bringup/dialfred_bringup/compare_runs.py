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

`--shipped` compares one run with what the repository ships instead of with another run: its models
with the shipped checkpoints (the perception network with the one inside `et.pt`, the performer with
`et.pt`, each questioner with its file, whose frame encoder is named by digest), and its tables with
`docs/results.md`. No second run is needed to tell whether a `./dialfred reproduce` gave the shipped
models bit for bit; the models the run has not made yet are listed, not counted as differences.
Training repeats bit for bit on one kind of CPU, not across kinds: `machines` names the CPU of the run's
training stages and of the shipped run's (`reproduce/shipped_run.json`), and says when they differ.

    ./dialfred env python -m dialfred_bringup.compare_runs out/reproduce --shipped [--parts weights]

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

from .paths import REPO

TABLES_FROM, TABLES_TO = '## Table II', '## Run times'
IGNORED_FIELDS = ('wall_s', 'code', 'agent')   # RUN_FIELDS (dialfred_sim.metrics) and the agent's name


class MissingPart(Exception):
    """A run folder, or a file that both runs must have, is absent or unreadable."""


# How the shipped document names the run it was written from (document._relative of the default run folder)
SHIPPED_RUN_FOLDER = 'out/reproduce'


def tables_text(run: Path, path: Optional[Path] = None) -> str:
    """The part of a run's results.md (or of `path`, a document written from a run) that must not depend
    on the run: Table II up to the run times, with the run folder's path removed."""
    path = run / 'results.md' if path is None else path
    try:
        text = path.read_text()
    except OSError as exc:
        raise MissingPart(f'{path}: {exc.strerror or exc}') from None
    if TABLES_FROM not in text or TABLES_TO not in text:
        raise MissingPart(f'{path} has no "{TABLES_FROM}" ... "{TABLES_TO}" part (an unfinished run?)')
    part = text.split(TABLES_FROM, 1)[1].split(TABLES_TO, 1)[0]
    forms = {str(run.resolve()), str(run), SHIPPED_RUN_FOLDER}
    if run.resolve().is_relative_to(REPO):
        forms.add(str(run.resolve().relative_to(REPO)))         # as the document names a run folder of the repository
    for form in sorted(forms, key=len, reverse=True):            # the longest first: out/reproduce_b before out/reproduce
        part = part.replace(form, '<run>')
    return part


def compare_tables(a: Path, b: Path, show: int) -> dict:
    return _compare_lines(tables_text(a).splitlines(), tables_text(b).splitlines(), show)


def _compare_lines(ta: list, tb: list, show: int) -> dict:
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


def _load(name: str, path: Path) -> dict:
    from dialfred_performer.model import read_state  # lazy: pybullet, torch, which the rest of this module does without
    try:
        return read_state(path)
    except (OSError, ValueError) as exc:
        raise MissingPart(f'{name}: cannot load its checkpoint: {exc}') from None


def compare_models(ma: dict, mb: dict, show: int) -> dict:
    """Two checkpoints' dicts, on what must not depend on the run (MODEL_KEYS): {'same', 'differing' (the
    keys), 'first_tensors' (of the state dict)}."""
    keys = [k for k in MODEL_KEYS if k in ma or k in mb]
    bad = [k for k in keys if not same_value(ma.get(k), mb.get(k))]
    sa, sb = ma.get('state_dict', {}), mb.get('state_dict', {})
    tensors = [t for t in sorted(set(sa) | set(sb)) if not same_value(sa.get(t), sb.get(t))]
    return {'same': not bad, 'differing': bad, 'first_tensors': tensors[:show]}


def compare_weights(a: Path, b: Path, show: int) -> dict:
    ca, cb = checkpoints(a), checkpoints(b)
    models, only = {}, sorted(set(ca) ^ set(cb))
    for name in sorted(set(ca) & set(cb)):
        models[name] = compare_models(_load(name, ca[name]), _load(name, cb[name]), show)
    return {'same': not only and all(m['same'] for m in models.values()), 'models': models, 'only_in_one': only}


# ---------------------------------------------------------------------- a run against the shipped models

PERCEPTION_PREFIX = 'visual.net.'       # where the performer's state dict holds its frozen perception network


def shipped_checkpoints() -> dict:
    """{name (as `checkpoints` names a run's models): path} of the shipped checkpoints: the performer (et.pt,
    which also holds the perception network) and every questioner."""
    from dialfred_performer.shipped import SHIPPED_CHECKPOINT  # lazy: as above
    from .reproduce.plan import SHIPPED_QUESTIONERS  # lazy: the plan imports torch and pybullet
    out = {'performer': Path(SHIPPED_CHECKPOINT)}
    for p in sorted(Path(SHIPPED_QUESTIONERS).glob('*.pt')):
        out['pretrain' if p.stem == 'pretrained' else p.stem] = p
    return out


def perception_of(performer: dict) -> dict:
    """The perception network inside a performer checkpoint's dict, as its own checkpoint holds it: config
    and state dict."""
    net = performer.get('config', {}).get('perception_net')
    return {'config': json.loads(net) if net else None,
            'state_dict': {k[len(PERCEPTION_PREFIX):]: v for k, v in performer.get('state_dict', {}).items()
                           if k.startswith(PERCEPTION_PREFIX)}}


def without_encoder(questioner: dict) -> dict:
    """A questioner checkpoint's dict with its frame encoder as a digest: its own copy (a run's) or the digest
    that names the performer's (a shipped file, dialfred_questioner.policy.share_visual)."""
    from dialfred_performer.model import state_digest  # lazy: as above
    out = {k: v for k, v in questioner.items() if k not in ('visual', 'visual_source')}
    if 'visual' in questioner:
        out['visual'] = state_digest(questioner['visual'])
    elif 'visual_source' in questioner:
        out['visual'] = questioner['visual_source'].get('sha256')
    return out


def compare_shipped_weights(run: Path, show: int, shipped: Optional[dict] = None) -> dict:
    """The run's models against the shipped ones (`shipped`: {name: path}, default shipped_checkpoints()):
    the ones the run has made; those it has not are listed in 'not_made'."""
    mine = checkpoints(run)
    theirs = shipped_checkpoints() if shipped is None else shipped
    if not mine:
        raise MissingPart(f'{run} has made no model yet')
    models = {}
    for name in sorted(mine):
        if name == 'perception':
            et = _load('performer', theirs['performer'])
            own = _load(name, mine[name])
            models[name] = compare_models({'config': own.get('config'), 'state_dict': own.get('state_dict', {})},
                                          perception_of(et), show)
        elif name in theirs:
            models[name] = compare_models(without_encoder(_load(name, mine[name])),
                                          without_encoder(_load(name, theirs[name])), show)
    extra = sorted(set(mine) - set(theirs) - {'perception'})
    return {'same': not extra and all(m['same'] for m in models.values()), 'models': models,
            'not_shipped': extra, 'not_made': sorted(set(theirs) - set(mine))}


def compare_shipped_tables(run: Path, show: int, doc: Optional[Path] = None) -> dict:
    doc = REPO / 'docs' / 'results.md' if doc is None else doc
    return _compare_lines(tables_text(run).splitlines(), tables_text(run, doc).splitlines(), show)


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


SHIPPED_PARTS = {'tables': compare_shipped_tables, 'weights': compare_shipped_weights}


def compare_with_shipped(run: Path, parts=tuple(SHIPPED_PARTS), show: int = 5) -> dict:
    """One run against the repository's shipped checkpoints and docs/results.md (see the module's doc)."""
    unknown = [p for p in parts if p not in SHIPPED_PARTS]
    if unknown or not parts:
        raise ValueError(f'with --shipped, parts are some of {", ".join(SHIPPED_PARTS)}, got {", ".join(parts) or "none"}')
    if not run.is_dir():
        raise MissingPart(f'{run} is not a run folder')
    report = {'a': str(run), 'b': 'shipped', 'machines': training_machines(run)}
    for part in SHIPPED_PARTS:
        if part in parts:
            report[part] = SHIPPED_PARTS[part](run, show)
    report['same'] = all(report[p]['same'] for p in SHIPPED_PARTS if p in report)
    return report


def training_machines(run: Path, shipped_run: Optional[Path] = None) -> dict:
    """The CPU the run's training stages ran on (from its stamps) and the shipped run's (shipped_run.json):
    training repeats bit for bit on one kind of CPU, not across kinds, so models trained on another are
    expected to differ (docs/evaluation.md)."""
    from .reproduce.plan import SHIPPED_RUN, TRAINING  # lazy: the plan imports torch and pybullet
    def cpus(stages: dict) -> list:
        return sorted({(s.get('machine') or {}).get('cpu') for s in stages.values() if (s.get('machine') or {}).get('cpu')})
    mine = {}
    for stage in TRAINING:
        try:
            mine[stage] = json.loads((run / 'stamps' / f'{stage}.json').read_text())
        except (OSError, ValueError):
            continue
    try:
        theirs = json.loads((shipped_run or SHIPPED_RUN).read_text()).get('stages', {})
    except (OSError, ValueError):
        theirs = {}
    out = {'run': cpus(mine), 'shipped': cpus(theirs)}
    out['same_cpu'] = bool(out['run']) and out['run'] == out['shipped']
    if not out['same_cpu']:
        out['note'] = ('the run trained on another CPU than the shipped models (or one of them is unknown): the last '
                       'bits of training differ across kinds of CPU, so different weights and tables are expected')
    return out


@dataclass
class CompareConfig:
    """Compare two run folders of ./dialfred reproduce, or one with the shipped models and tables."""

    a: Path = arg(REQUIRED, 'a run folder of ./dialfred reproduce', positional=True)
    b: str = arg('', 'another run folder (not with --shipped)', positional=True)
    shipped: bool = arg(False, "compare run `a` with the shipped checkpoints and docs/results.md instead "
                               "(parts: tables, weights)")
    parts: str = arg('', f'what to compare, comma-separated: some of {", ".join(PARTS)} (default '
                         f'{",".join(DEFAULT_PARTS)}; with --shipped: {",".join(SHIPPED_PARTS)})')
    show: int = arg(5, 'how many differences of each kind to list')


def main(argv: Optional[list[str]] = None) -> int:
    args = parse(CompareConfig, argv, prog='python -m dialfred_bringup.compare_runs',
                 description=__doc__.split('\n')[0])
    parts = tuple(p for p in args.parts.split(',') if p)
    try:
        if args.shipped == bool(args.b):
            raise ValueError('give a second run folder or --shipped (one of them)')
        if args.shipped:
            report = compare_with_shipped(args.a, parts or tuple(SHIPPED_PARTS), args.show)
        else:
            report = compare(args.a, Path(args.b), parts or DEFAULT_PARTS, args.show)
    except (MissingPart, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    print(json.dumps(report, indent=1))
    return 0 if report['same'] else 1


if __name__ == '__main__':
    sys.exit(main())
