"""An evaluation in shards: which tasks a shard plays, and joining the shards' results (no ROS).

`launch eval --shard K/N` plays shard K of N of the selected tasks (`shard_tasks`: those whose index
in the split is K modulo N, each seeded by that index as in a whole run) and writes
`<results>_shardKofN.jsonl` and its `.summary.json`. On one host or many (docs/scaling.md), the
shards' files are then joined:

    ./dialfred merge out/eval/valid_unseen_expert_shard0of2.jsonl out/eval/valid_unseen_expert_shard1of2.jsonl
    # -> out/eval/valid_unseen_expert.jsonl and .summary.json, as one run of all the tasks writes them

`merge_shards` checks that the files come from one run's configuration (split or tasks file, agent
with its checkpoint and questioner, oracle, seed, resolution, path through the graph, --limit, the
number of shards), refuses a shard given twice, a task twice, a task in the wrong shard's file, a
corrupt or cut-off line, and reports the tasks no file holds. The merged results are in the split's
task order, and the summary's `summary` and `failures` are `metrics.summarize` and
`metrics.failures` of them: those of a single run of the same tasks.
"""

from __future__ import annotations

import json
import re
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

from dialfred_sim.chained import chain_episodes
from dialfred_sim.dataclass_cli import REQUIRED, arg, parse
from dialfred_sim.metrics import (DEFAULT_PROTOCOL, EpisodeResult, ResultsFileError, TruncatedResultsWarning, failures, format_table, load_results,
                      played_at, same_episode, summarize, write_text_atomically)
from dialfred_sim.tasks import load_split
from dialfred_sim.traces import load_traces, trace_path

SHARD_NAME = re.compile(r'_shard(\d+)of(\d+)$')


# ---------------------------------------------------------------------------------------- selection

def check_shard(shard) -> None:
    """ValueError unless `shard` is None (the whole run) or (K, N) with integers 0 <= K < N."""
    if shard is None:
        return
    try:
        k, n = shard
    except (TypeError, ValueError):
        raise ValueError(f'a shard is (K, N), got {shard!r}') from None
    if not (type(k) is int and type(n) is int and 0 <= k < n):
        raise ValueError(f'a shard is K/N with integers 0 <= K < N (e.g. 0/2), got {k}/{n}')


def parse_shard(text: str) -> tuple[int, int]:
    """'K/N' -> (K, N); ValueError saying what a shard is otherwise."""
    parts = text.split('/')
    try:
        k, n = (int(p) for p in parts)
    except ValueError:
        raise ValueError(f'a shard is K/N with integers 0 <= K < N (e.g. 0/2), got {text!r}') from None
    check_shard((k, n))
    return k, n


def show_shard(shard: tuple[int, int]) -> str:
    """(K, N) -> 'K/N', as --shard takes it."""
    return f'{shard[0]}/{shard[1]}'


def shard_suffix(shard) -> str:
    """'_shardKofN' for shard (K, N), '' for a whole run: the shards' results files never collide."""
    return f'_shard{shard[0]}of{shard[1]}' if shard else ''


def shard_tasks(tasks: Sequence, shard) -> list[tuple[int, object]]:
    """[(index in the split, task)] of shard (K, N) of `tasks` (the split's tasks after --limit);
    every task for None.

    Interleaved: shard K takes the tasks whose index is K modulo N. The index is the task's place in
    the split, so the episode seeds (agents.episode_seed(seed, index)), and hence the episodes, are
    those of a whole run. Interleaved rather than contiguous blocks because (1) a task's shard does
    not depend on --limit, so a shard rerun with a longer --limit resumes its own file (blocks would
    move), and (2) consecutive tasks are the sub-tasks of one expert episode in one room (runs of
    2-6), so interleaved shards get the same mix of rooms and task types, and sizes within 1."""
    check_shard(shard)
    indexed = list(enumerate(tasks))
    if shard is None:
        return indexed
    k, n = shard
    return [(i, t) for i, t in indexed if i % n == k]


# ---------------------------------------------------------------------------------------- one shard's files

# What must be the same in every shard's .summary.json (EvalReport.to_json of dialfred_bringup/evaluation.py) for
# their results to be one run's; `workers`, `this_run` and the file names may differ.
SAME_RUN = ('split', 'tasks_file', 'agent', 'oracle', 'seed', 'resolution', 'goal_rule', 'through', 'checkpoint',
            'limit', 'shard_count', 'protocol')


@dataclass
class ShardFile:
    """One shard's results file and the summary its run wrote beside it."""

    path: Path
    index: int
    count: int
    run: dict                         # its .summary.json
    results: list[EpisodeResult]

    @property
    def label(self) -> str:
        return f'shard {self.index}/{self.count} ({self.path})'

    def settings(self) -> dict:
        """The run's configuration as SAME_RUN names it (files by content, not by path)."""
        run = self.run
        tasks_file = run.get('tasks_file')
        checkpoint = run.get('checkpoint')
        return {'split': run.get('split'), 'tasks_file': tasks_file['sha256'] if tasks_file else None,
                'agent': run.get('agent'), 'oracle': run.get('oracle'), 'seed': run.get('seed'),
                'resolution': run.get('resolution'), 'goal_rule': run.get('goal_rule'), 'through': run.get('through'),
                'checkpoint': checkpoint['sha256'] if checkpoint else None, 'limit': run.get('limit'),
                'shard_count': self.count, 'protocol': run.get('protocol', DEFAULT_PROTOCOL)}


def summary_path(results_path: Path) -> Path:
    return Path(results_path).with_suffix('.summary.json')


def read_shard(path) -> ShardFile:
    """A shard's results and summary; ResultsFileError if either is missing, corrupt or cut off.

    Nothing is changed on disk: a cut-off last line (an interrupted write) is an error here, where a
    rerun of the shard (which resumes and drops that line) would play its task again."""
    path = Path(path)
    if not path.is_file():
        raise ResultsFileError(f'{path}: no such results file')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        try:
            results = load_results(path)
        except ValueError as exc:
            raise ResultsFileError(str(exc)) from None
    for w in caught:
        if issubclass(w.category, TruncatedResultsWarning):
            raise ResultsFileError(f'{w.message}: the file was cut off in a write. Run that shard again with '
                                   'the same command (it resumes, dropping the cut line), then merge') from None
    run_path = summary_path(path)
    try:
        run = json.loads(run_path.read_text())
    except FileNotFoundError:
        raise ResultsFileError(f'{run_path}: no summary beside {path.name}; a run writes it when it ends: run '
                               'that shard to its end (the same command resumes), then merge') from None
    except ValueError as exc:
        raise ResultsFileError(f'{run_path} is not a summary JSON ({exc})') from None
    if not isinstance(run, dict) or 'summary' not in run or 'agent' not in run:
        raise ResultsFileError(f'{run_path} is not the summary of an evaluation')
    if run.get('shards') is not None:
        raise ResultsFileError(f'{path} is a merged file (of {len(run["shards"])} shards), not a shard: '
                               'merge the shards themselves')
    shard = run.get('shard') or {'index': 0, 'count': 1}         # a whole run: its one shard
    try:
        index, count = int(shard['index']), int(shard['count'])
        check_shard((index, count))
    except (KeyError, TypeError, ValueError) as exc:
        raise ResultsFileError(f'{run_path}: bad shard {shard!r} ({exc})') from None
    for number, r in enumerate(results, start=1):
        held, wanted = (r.split, r.agent, r.oracle, r.seed), (run['split'], run['agent'], run['oracle'], run['seed'])
        if held != wanted:
            raise ResultsFileError(f'{path}: result {number} ({r.task_id}) is of split, agent, oracle, seed {held}, '
                                   f'its summary of {wanted}: the file mixes runs')
    return ShardFile(path, index, count, run, results)


# ---------------------------------------------------------------------------------------- merging

@dataclass
class Merged:
    """The joined results (split order), their summary JSON, and what was missing."""

    results: list[EpisodeResult]
    run: dict                          # the summary JSON of the merged file
    missing: list[str] = field(default_factory=list)     # task ids no shard file holds
    ignored: int = 0                   # results in the files of tasks beyond --limit (as a run ignores them)
    traces: dict = field(default_factory=dict)           # task id -> its trace (dialfred_sim.traces), where kept
    record: Optional[dict] = None      # the shards' <results>.run.json (camera, question limit), where kept


def split_tasks(settings: dict, run: dict, tasks_path: Optional[Path] = None) -> list:
    """Every task of the split the shards came from (before --limit): the shipped split's, or those of
    its tasks file (at `tasks_path`, else where the run read it), checked by sha256."""
    if settings['tasks_file'] is None:
        tasks = load_split(settings['split'])
    else:
        # lazy: pybullet, which the rest of this module does without
        from dialfred_sim.tasks.splits import read_tasks_file
        path = Path(tasks_path) if tasks_path else Path(run['tasks_file']['path'])
        try:
            source = read_tasks_file(path)
        except (FileNotFoundError, ValueError) as exc:
            raise ResultsFileError(f'the shards were run on a tasks file: {exc} (give its copy here with --tasks PATH)') \
                from None
        if source.sha256 != settings['tasks_file']:
            raise ResultsFileError(f'{path} is not the tasks file the shards were run on (sha256 '
                                   f'{source.sha256[:12]}..., not {settings["tasks_file"][:12]}...)')
        tasks = source.tasks
    return tasks


def merge_shards(paths: Sequence, out: Path, partial: bool = False, tasks_path: Optional[Path] = None) -> Merged:
    """Join the shard files `paths` into the results and summary of a whole run, `out` naming the merged
    file (recorded in the summary; nothing is written here). ResultsFileError for files of different
    runs, a shard given twice, a task twice or in another shard's file, and (unless `partial`) for
    tasks that no file holds."""
    if not paths:
        raise ResultsFileError('no shard files to merge')
    shards = [read_shard(p) for p in paths]
    first = shards[0]
    for s in shards[1:]:
        a, b = first.settings(), s.settings()
        diff = {k: (a[k], b[k]) for k in SAME_RUN if a[k] != b[k]}
        if diff:
            raise ResultsFileError(f'{first.path} and {s.path} are not shards of one run; they differ in '
                                   + ', '.join(f'{k} ({x!r} vs {y!r})' for k, (x, y) in diff.items()))
    by_index: dict[int, ShardFile] = {}
    for s in shards:
        if s.index in by_index:
            raise ResultsFileError(f'shard {s.index}/{s.count} is given twice: {by_index[s.index].path} and {s.path}')
        by_index[s.index] = s
    settings, count = first.settings(), first.count
    every = split_tasks(settings, first.run, tasks_path)
    in_split = {t.task_id for t in every}
    tasks = every[:settings['limit']]
    index_of = {t.task_id: i for i, t in enumerate(tasks)}
    if settings['protocol'] == 'chained':
        # A chained run's shards take whole episodes (episode n of the selected tasks to shard n mod N).
        shard_of = {tid: n % count for n, e in enumerate(chain_episodes(enumerate(tasks))) for tid in e.task_ids}
    else:
        shard_of = {tid: i % count for tid, i in index_of.items()}
    found: dict[str, EpisodeResult] = {}
    ignored = 0
    for s in shards:
        seen: dict[str, EpisodeResult] = {}
        for r in s.results:
            if r.task_id in seen:
                same = same_episode(r, seen[r.task_id])
                raise ResultsFileError(f'{s.path}: task {r.task_id} appears twice'
                                       + ('' if same else ', with different results (a conflict)'))
            seen[r.task_id] = r
            i = index_of.get(r.task_id)
            if i is None:
                if r.task_id not in in_split:
                    raise ResultsFileError(f'{s.path}: task {r.task_id} is not a task of {settings["split"]}')
                ignored += 1           # beyond --limit: a longer run's result, which the run itself ignores too
                continue
            if shard_of[r.task_id] != s.index:
                raise ResultsFileError(f'{s.path}: task {r.task_id} (index {i}) belongs to shard {shard_of[r.task_id]}/{count}, '
                                       f'not {s.index}/{count}: was another shard run with the same --out?')
            found[r.task_id] = r
    missing = [t.task_id for t in tasks if t.task_id not in found]
    if missing and not partial:
        raise ResultsFileError(missing_message(missing, index_of, by_index, count))
    results = [found[t.task_id] for t in tasks if t.task_id in found]
    traces, records = {}, []
    for s in shards:
        try:
            traces.update(load_traces(s.path))
        except ValueError as exc:
            raise ResultsFileError(str(exc)) from None
        record = s.path.with_suffix('.run.json')
        records.append(json.loads(record.read_text()) if record.exists() else None)
    if any(r != records[0] for r in records[1:]):
        raise ResultsFileError('the shards were played with other cameras or question limits (their .run.json differ)')
    traces = {r.task_id: traces[r.task_id] for r in results if r.task_id in traces}
    return Merged(results, merged_run(shards, results, out, missing), missing, ignored, traces, records[0])


def missing_message(missing: list, index_of: dict, by_index: dict, count: int) -> str:
    lines = [f'{len(missing)} task(s) are in no shard file:']
    for k in range(count):
        of_shard = [t for t in missing if index_of[t] % count == k]
        if not of_shard:
            continue
        where = (f'{len(of_shard)} missing from {by_index[k].path} (run shard {k}/{count} to its end: the same '
                 'command resumes)') if k in by_index else f'no file of shard {k}/{count} was given'
        lines.append(f'  shard {k}/{count}: {where}; first: {", ".join(of_shard[:3])}')
    lines.append('(--partial writes what there is, with the missing tasks listed in the summary)')
    return '\n'.join(lines)


def merged_run(shards: list[ShardFile], results: list[EpisodeResult], out: Path, missing: list) -> dict:
    """The merged file's summary JSON: the keys of a single run's (EvalReport.to_json), with `workers` and
    `this_run` summed over the shards (its wall time the longest shard's: they run side by side), and
    `shards` (each file's shard, tasks, workers and run) and `missing` added."""
    first = shards[0].run
    runs = [s.run.get('this_run') or {} for s in shards]
    episodes = sum(r.get('episodes') or 0 for r in runs)
    wall = max((r.get('wall_s') or 0.0 for r in runs), default=0.0)
    return {
        'split': first.get('split'), 'tasks_file': first.get('tasks_file'), 'agent': first.get('agent'),
        'privileged': any(r.privileged for r in results), 'oracle': first.get('oracle'), 'seed': first.get('seed'),
        'resolution': first.get('resolution'), 'goal_rule': first.get('goal_rule'),
        **({'protocol': first['protocol']} if first.get('protocol', DEFAULT_PROTOCOL) != DEFAULT_PROTOCOL else {}),
        'workers': sum(s.run.get('workers') or 0 for s in shards),
        'through': first.get('through'), 'checkpoint': first.get('checkpoint'), 'limit': first.get('limit'),
        'shard': None, 'results_file': str(out), 'tasks': len(results), 'played_at': played_at(results),
        'this_run': {'episodes': episodes, 'startup_s': max((r.get('startup_s') or 0.0 for r in runs), default=0.0),
                     'wall_s': wall, 'episodes_per_s': round(episodes / wall, 3) if episodes and wall > 0 else None},
        'summary': summarize(results),
        'failures': [{'task_id': r.task_id, 'task_type': r.task_type, 'end_reason': r.end_reason, 'error': r.error}
                     for r in failures(results)],
        'shards': [{'file': str(s.path), 'index': s.index, 'count': s.count, 'tasks': len(s.results),
                    'workers': s.run.get('workers'), 'this_run': s.run.get('this_run')}
                   for s in sorted(shards, key=lambda s: s.index)],
        'missing': missing,
    }


def default_out(path: Path) -> Path:
    """The merged file's default name: the shard's without _shardKofN (that of a whole run)."""
    path = Path(path)
    stem = SHARD_NAME.sub('', path.stem)
    if stem == path.stem:
        raise ResultsFileError(f'{path.name} is not named <results>_shardKofN.jsonl: name the merged file with --out')
    return path.with_name(stem + path.suffix)


def write_merged(merged: Merged, out: Path) -> None:
    """The merged results (one line each, as `metrics.append_result` writes them), their traces and run record
    (so that `./dialfred score` replays the merged file) and summary, each written to a temporary file and
    renamed into place."""
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomically(trace_path(out), ''.join(json.dumps({'task_id': tid, **t}, separators=(',', ':')) + '\n'
                                                  for tid, t in merged.traces.items()))
    if merged.record is not None:
        write_text_atomically(out.with_suffix('.run.json'), json.dumps(merged.record, indent=1) + '\n')
    write_text_atomically(out, ''.join(r.to_json() + '\n' for r in merged.results))
    write_text_atomically(summary_path(out), json.dumps(merged.run, indent=1) + '\n')


def check_out(out: Path, inputs: Sequence[Path]) -> None:
    """ResultsFileError if writing `out` would overwrite a shard or a run's results (a merged file of
    an earlier merge may be replaced)."""
    resolved = {Path(p).resolve() for p in inputs}
    if out.resolve() in resolved or summary_path(out).resolve() in {summary_path(p) for p in resolved}:
        raise ResultsFileError(f'--out {out} is one of the shard files')
    if out.exists():
        try:
            run = json.loads(summary_path(out).read_text())
        except (OSError, ValueError):
            run = None
        if not (isinstance(run, dict) and run.get('shards') is not None):
            raise ResultsFileError(f'{out} exists and is not a merged file (a run\'s results?): '
                                   'choose another --out, or remove it')


@dataclass
class MergeConfig:
    """Join the results files of `launch eval --shard K/N` into the results of one run."""

    shards: list[Path] = arg(REQUIRED, 'the results files of `launch eval --shard K/N` (each with its .summary.json '
                             'beside it)', positional=True, metavar='SHARD.jsonl')
    out: Optional[Path] = arg(None, 'merged results file (none: the shards\' name without _shardKofN); its summary '
                              'goes to <out without .jsonl>.summary.json', metavar='PATH')
    partial: bool = arg(False, 'write the merge even if tasks are missing (listed in the summary\'s "missing")')
    tasks: Optional[Path] = arg(None, 'shards run with --tasks: that file here (none: the path the shards recorded)',
                                metavar='PATH')


def main(argv: Optional[Sequence[str]] = None) -> int:
    args = parse(MergeConfig, argv, prog='./dialfred merge',
                 epilog='docs/scaling.md: evaluating on several hosts')
    paths = args.shards
    try:
        out = args.out or default_out(paths[0])
        check_out(out, paths)
        merged = merge_shards(paths, out, partial=args.partial, tasks_path=args.tasks)
        write_merged(merged, out)
    except (ResultsFileError, FileNotFoundError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    run = merged.run
    print(f'{run["split"]}, {run["agent"]} agent, seed {run["seed"]}: {len(merged.results)} tasks from '
          f'{len(run["shards"])} shard file(s)')
    print(format_table(run['summary']))
    if merged.ignored:
        print(f'ignored {merged.ignored} result(s) of tasks beyond --limit {run["limit"]}')
    if merged.missing:
        print(f'warning: {len(merged.missing)} task(s) missing (--partial): {", ".join(merged.missing[:5])}'
              + (' ...' if len(merged.missing) > 5 else ''), file=sys.stderr)
    print(f'results: {out}\nsummary: {summary_path(out)}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
