#!/usr/bin/env python3
"""Evaluation through the node graph: an agent plays (a part of) a split on simulator nodes.

`./dialfred launch eval ...` runs `--workers` simulator nodes, each in its own namespace
(/eval_<pid>/w0/sim/step, /eval_<pid>/w1/sim/step, ...), drives them all from this process with
asynchronous calls, appends each episode's result to the JSON-lines file as it ends (a rerun skips
the tasks already there), and prints SR / PWSR / GC / NQ overall and per task type; the summary also
goes to <out without .jsonl>.summary.json.

With `--questioner`, each worker also gets an oracle node in its namespace (.../w0/oracle/answer
answers from .../w0/sim/ground_truth). Before every action the agent may ask it questions, which
are counted (NQ, NQ_invalid).

With `--tasks PATH` (a split file of your own, such as a sealed test split) instead of `--split`,
every simulator node reads that file (its `tasks_file` parameter), and <out without .jsonl>.tasks.json
records the file's path and sha256: results of another file are refused, never mixed in.

With `--shard K/N`, only the tasks whose index in the split is K modulo N are played (seeded by that
index, as in a whole run) into <default name>_shardKofN.jsonl (or --out as given); `./dialfred merge` joins the shards' files
(dialfred_bringup/shards.py, docs/scaling.md).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from dialfred_performer.model_registry import PERFORMER_MODELS
from dialfred_oracle.answerers import resolved_spec
from dialfred_sim.chained import chain_episodes
from dialfred_sim.dataclass_cli import add_fields, from_args
from dialfred_sim.metrics import (ResultsFileError, append_result, failures, format_table, git_commit, load_results,
                                  played_at, played_through, results_by_task, results_lock, summarize, write_text_atomically)
from dialfred_sim.tasks.goals import under_rule
from dialfred_sim.traces import append_trace

from .eval_config import EvalConfig
from .eval_run import EvalRun
from .graph import Graph, discovery_spans_hosts, host_token
from .local import play_local
from .shards import shard_tasks
from .workers import (LiveHook, PerformerWorker, SimWorker, Supervisor, play_episodes, start_live_view,
                      worker_nodes)


@dataclass
class EvalReport:
    """What a run came to: the results of every selected task (in split order), and this run's share."""

    run: EvalRun
    results: list
    ran: int                # episodes played by this run (the others were in the file already)
    startup_s: float        # loading the tasks and the results file, starting the nodes until they answer
    wall_s: float           # the whole run, start-up included
    summary: dict
    restarts: int = 0       # workers restarted after a node died or hung (their episodes replayed)
    code: str = ''          # the commit the run started at ('+dirty': an edited checkout)
    replayed: int = 0       # episodes of this run taken from the silent episodes of a no-question run (silent.py)

    def to_json(self) -> dict:
        run, c = self.run, self.run.options
        loop_s = self.wall_s - self.startup_s
        return {
            'split': c.split, 'tasks_file': run.tasks_source.describe() if run.tasks_source else None,
            'agent': run.agent_name, 'privileged': any(r.privileged for r in self.results),
            'oracle': run.oracle, 'seed': c.seed, 'resolution': c.resolution, 'goal_rule': c.goal_rule,
            **({'protocol': c.protocol} if c.protocol != 'expert' else {}),
            'workers': c.workers,
            'through': played_through(self.results),
            'checkpoint': ({'path': str(run.checkpoint_path), 'sha256': run.checkpoint_sha256}
                           if c.agent in PERFORMER_MODELS else None),
            'limit': c.limit, 'shard': {'index': c.shard[0], 'count': c.shard[1]} if c.shard else None,
            'results_file': str(run.results_path), 'tasks': len(self.results),
            'played_at': played_at(self.results),
            'this_run': {'episodes': self.ran, 'startup_s': round(self.startup_s, 3), 'wall_s': round(self.wall_s, 3),
                         'episodes_per_s': round(self.ran / loop_s, 3) if self.ran and loop_s > 0 else None,
                         'restarts': self.restarts, 'replayed': self.replayed,
                         'code': self.code},
            'summary': self.summary,
            'failures': [{'task_id': r.task_id, 'task_type': r.task_type, 'end_reason': r.end_reason,
                          'error': r.error} for r in failures(self.results)],
        }


def run_namespace() -> str:
    """The namespace of this run's nodes (/eval_<pid>): no other run, even in the same ROS domain,
    can reach them or be reached by this one. Where discovery reaches other hosts (a shard per host,
    docs/scaling.md), the host's name goes in too (/eval_<host>_<pid>): a pid is unique on one host only."""
    return f'/eval_{host_token()}_{os.getpid()}' if discovery_spans_hosts() else f'/eval_{os.getpid()}'


def short_commit(code: str) -> str:
    """A commit as people read it: 12 hex digits, and '+dirty' if it has it."""
    return code if code in ('unrecorded', 'unknown') else code[:12] + ('+dirty' if code.endswith('+dirty') else '')


def warn_of_other_code(path, results, code: str) -> None:
    """Say on stderr when a resumed results file holds episodes played at another commit than `code`."""
    others = played_at([r for r in results if r.code != code])
    if others:
        print(f'warning: {path} holds {sum(others.values())} episodes played at other commits '
              f'({", ".join(f"{short_commit(c)}: {n}" for c, n in others.items())}); this run is at {short_commit(code)}; '
              'they are kept (choose another --out to play every episode at this commit)', file=sys.stderr)


def resumable_results(run: EvalRun, task_ids: list) -> dict:
    """{task_id: result} already in the results file for the selected tasks (a cut-off last line is
    dropped from the file); ResultsFileError if the file is corrupt or holds another split, agent or seed."""
    path, config = run.results_path, run.options
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        try:
            existing = load_results(path, drop_truncated=True)
        except ValueError as exc:
            raise ResultsFileError(str(exc)) from None
    for w in caught:
        print(f'warning: {w.message}', file=sys.stderr)
    for r in existing:
        if (r.split, r.agent, r.oracle, r.seed) != (config.split, run.agent_name, run.oracle, config.seed):
            raise ResultsFileError(f'{path} holds results of split {r.split!r}, agent {r.agent!r}, '
                                   f'oracle {r.oracle!r}, seed {r.seed}, not {config.split!r}, {run.agent_name!r}, '
                                   f'{run.oracle!r}, '
                                   f'{config.seed}: choose another --out')
        if r.protocol != config.protocol:
            raise ResultsFileError(f'{path} holds results of the {r.protocol!r} protocol, not {config.protocol!r}: '
                                   'choose another --out')
        if r.goal_rule != config.goal_rule:
            held = repr(r.goal_rule) if r.goal_rule else "'visible' (written before results recorded the rule)"
            raise ResultsFileError(f'{path} holds results judged by the goal rule {held}, not {config.goal_rule!r}: '
                                   'choose another --out')
    check_tasks_record(run, bool(existing))
    check_run_record(run, bool(existing))
    return results_by_task(existing, task_ids)


def run_record(run: EvalRun) -> dict:
    """What a results file's episodes were played with beyond what each result line records."""
    record = {'resolution': int(run.options.resolution), 'max_questions': int(run.options.max_questions)}
    if run.answerer:      # where `score` finds the answerer again
        record['answers'] = resolved_spec(run.answerer)
    return record


def check_run_record(run: EvalRun, has_results: bool) -> None:
    """Results are kept with a record of the camera and the question limit they were played with
    (<results>.run.json): ResultsFileError, naming the difference, if a run would add episodes played
    otherwise. Writes the record for a new results file (and for one made before records were kept)."""
    path, want = run.results_path.with_suffix('.run.json'), run_record(run)
    held = None
    if has_results and path.exists():
        try:
            held = json.loads(path.read_text())
        except ValueError:
            held = None
        if not isinstance(held, dict):
            raise ResultsFileError(f'{path} is not a record of a run: choose another --out')
        differ = [f'{k} {held.get(k)!r}, not {v!r}' for k, v in want.items() if held.get(k) != v]
        if differ:
            raise ResultsFileError(f'{run.results_path} holds episodes played with {"; ".join(differ)}: '
                                   'choose another --out (or the same settings)')
    if held != want:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomically(path, json.dumps(want, indent=1) + '\n')


def check_tasks_record(run: EvalRun, has_results: bool) -> None:
    """Results of a tasks file are kept with a record of that file (<results>.tasks.json: path, sha256):
    ResultsFileError if the results file holds results of another tasks file, or of a shipped split
    while a tasks file is given (or the other way round). Writes the record for a new results file."""
    record_path, source, split = run.tasks_record_path, run.tasks_source, run.options.split
    record = _read_tasks_record(record_path)
    if has_results and (record or {}).get('sha256') != (source.sha256 if source else None):
        held = (f"tasks file {record['path']} (sha256 {record['sha256'][:12]}...)" if record
                else f'tasks of the shipped split {split!r}')
        wanted = f'tasks file {source.path} (sha256 {source.sha256[:12]}...)' if source else \
            f'the shipped split {split!r}'
        raise ResultsFileError(f'{run.results_path} holds results of {held}, not of {wanted}: '
                               'choose another --out')
    if not has_results:
        if source:
            record_path.parent.mkdir(parents=True, exist_ok=True)
            write_text_atomically(record_path, json.dumps(source.describe(), indent=1) + '\n')
        elif record is not None:
            record_path.unlink()      # left from results that are gone


def _read_tasks_record(path: Path) -> Optional[dict]:
    if not path.exists():
        return None
    try:
        record = json.loads(path.read_text())
    except ValueError:
        record = None
    if not (isinstance(record, dict) and isinstance(record.get('path'), str) and isinstance(record.get('sha256'), str)):
        raise ResultsFileError(f'{path} is not a record of a tasks file: choose another --out')
    return record


def progress_bar(total: int, done: int, enabled: bool):
    from dialfred_sim.progress import progress_bar as _bar  # lazy: tqdm, which the rest of this module does without
    return _bar(total=total, initial=done, unit='ep', disable=not enabled,
                smoothing=0.05)


def run_eval(config: EvalConfig | EvalRun, progress: bool = True, traces: Optional[dict] = None,
             silent: Optional[tuple[str, Path]] = None) -> EvalReport:
    """Evaluate the agent of `config` (options, or a run made of them) on the split's tasks through its
    `workers` simulator nodes (or, with `local`, processes).

    Results go to the JSON-lines file as each episode ends; tasks already there are skipped (resume).
    Writes the summary JSON next to it and returns the report of every selected task. `traces`: a
    dict to fill with each played task's actions, {task_id: [(name, x, y), ...]} (the performer path
    takes them from the goals' feedback). The results file is this run's alone while it runs
    (`metrics.results_lock`: a second run into it is refused, naming this one). `silent` (the local path
    only): ('record', folder) keeps this no-question run's episodes in folder; ('replay', folder) takes an
    episode from there whenever the run's questioner would ask nothing in it (`dialfred_bringup.silent`).
    """
    # An unknown agent or questioner, or a bad setting, fails here before any node starts.
    run = config if isinstance(config, EvalRun) else EvalRun(config)
    if silent is not None and (not run.options.local or silent[0] not in ('record', 'replay')):
        raise ValueError(f"silent episodes are ('record' | 'replay', folder) of a local run, got {silent!r}")
    if silent is not None and silent[0] == 'record' and run.asks:
        raise ValueError('silent episodes are recorded by a run without questions')
    with results_lock(run.results_path):
        return _run_eval(run, progress, traces, silent)


def _jobs(run: EvalRun) -> tuple[list, dict, list]:
    """(the run's tasks, the results its file holds already {task_id: result}, the jobs left to play: (index
    in the split, task) pairs, or whole chained.ChainedEpisodes under the chained protocol)."""
    config = run.options
    tasks = run.split_tasks()[:config.limit]
    tasks = [under_rule(t, config.goal_rule) for t in tasks]      # goals and expert lengths as the run judges them
    if config.protocol == 'chained':
        # A job is a whole episode (its tasks in order, in one world); shards take whole episodes.
        episodes = chain_episodes(enumerate(tasks))
        if config.shard:
            episodes = [e for n, e in enumerate(episodes) if n % config.shard[1] == config.shard[0]]
        selected = [pair for e in episodes for pair in e.tasks]
    else:
        selected = shard_tasks(tasks, config.shard)       # (index in the split, task): the index seeds the episode
    tasks = [t for _, t in selected]
    done = resumable_results(run, [t.task_id for t in tasks])
    if config.protocol == 'chained':
        # An episode cut off before its last task is played again from its start (the world of its later
        # tasks is the one its earlier ones left); only the tasks missing from the file are written.
        jobs = [e for e in episodes if any(tid not in done for tid in e.task_ids)]
    else:
        jobs = [(k, t) for k, t in selected if t.task_id not in done]
    if done:
        unit = 'episodes' if config.protocol == 'chained' else 'tasks'
        print(f'resuming: {len(done)} of {len(tasks)} tasks are already in {run.results_path}; '
              f'{len(jobs)} {unit} to play', file=sys.stderr)
    return tasks, done, jobs


def _run_eval(run: EvalRun, progress: bool, traces: Optional[dict], silent=None) -> EvalReport:
    t0 = time.monotonic()
    config = run.options
    tasks, done, jobs = _jobs(run)
    ran, startup_s, restarts, replayed = 0, 0.0, 0, 0
    code = git_commit()
    warn_of_other_code(run.results_path, done.values(), code)

    def recorder(bar):
        """on_result of either path: the result line (stamped with the code's commit) written at once
        (resumable), counted, shown."""
        def record(result) -> None:
            nonlocal ran
            if result.task_id in done:       # a replayed chained episode's task that the file holds
                return
            result = dataclasses.replace(result, code=code, played=run.played)
            if result.trace is not None:     # first: a results line never lacks its trace
                append_trace(run.results_path, result.task_id, result.trace)
            append_result(run.results_path, result)
            done[result.task_id] = result
            ran += 1
            bar.update(1)
        return record

    if jobs and config.local:
        with progress_bar(len(tasks), len(done), progress) as bar:
            replayed = play_local(run, jobs, recorder(bar), silent)
    elif jobs:
        n = max(1, min(config.workers, len(jobs)))
        namespaces = [f'{run_namespace()}/w{k}' for k in range(n)]
        live = {'publish_observations': True} if config.foxglove is not None else {}
        nodes_of = {ns: worker_nodes(run, ns, **live) for ns in namespaces}
        nodes = [node for ns in namespaces for node in nodes_of[ns]]
        with Graph(nodes) as graph, contextlib.ExitStack() as cleanup:
            view = start_live_view(run, graph, namespaces, len(tasks)) if config.foxglove is not None else None
            if view is not None:
                cleanup.callback(view.close)

            def make_worker(ns: str):
                if config.performer:
                    worker = PerformerWorker(graph, ns, run)
                else:
                    worker = SimWorker(graph, ns, run.make_agent(), run, oracle=run.asks)
                if view is not None:
                    worker.live = LiveHook(view, f'w{namespaces.index(ns)}')
                return worker

            supervisor = Supervisor(graph, nodes_of, make_worker, config.max_restarts) if config.max_restarts else None
            workers = supervisor.start(namespaces) if supervisor else [make_worker(ns) for ns in namespaces]
            startup_s = time.monotonic() - t0
            with progress_bar(len(tasks), len(done), progress) as bar:
                play_episodes(graph, workers, jobs, recorder(bar), supervisor)
            restarts = supervisor.restarts if supervisor else 0
            if traces is not None:
                if config.performer:
                    graph.spin_until_any([], 0.5)     # feedback of the last steps may come after the result
                for w in workers:
                    traces.update(w.traces)
    results = [done[t.task_id] for t in tasks]
    report = EvalReport(run, results, ran, startup_s, time.monotonic() - t0, summarize(results), restarts, code,
                        replayed)
    if ran or not run.summary_path.exists():     # a run that played nothing leaves the summary as it was
        write_text_atomically(run.summary_path, json.dumps(report.to_json(), indent=1) + '\n')
    return report


def print_report(report: EvalReport) -> None:
    run, c, info = report.run, report.run.options, report.to_json()['this_run']
    rate = f', {info["episodes_per_s"]:.2f} episodes/s' if info['episodes_per_s'] else ''
    privileged = (' (PRIVILEGED: given the expert\'s plan; a reference, not a benchmark result)'
                  if any(r.privileged for r in report.results) else '')
    shard = f', shard {c.shard[0]}/{c.shard[1]}' if c.shard else ''
    shard += ', chained (each episode\'s tasks in order on the agent\'s own state)' if c.protocol == 'chained' else ''
    print(f'{c.split}{shard}, {run.agent_name} agent{privileged}, seed {c.seed}: {len(report.results)} tasks '
          f'({report.ran} played now in {report.wall_s:.1f} s{rate})')
    print(format_table(report.summary))
    if c.agent == 'expert':
        failed = failures(report.results)
        print(f'expert failures: {len(failed)}')
        for r in failed:
            print(f'  {r.task_id}  {r.task_type:<20} {r.end_reason:<12} {r.error}')
    print(f'results: {run.results_path}\nsummary: {run.summary_path}')
    if run.tasks_source:
        print(f'tasks:   {run.tasks_source.path} (sha256 {run.tasks_source.sha256[:12]}..., recorded in '
              f'{run.tasks_record_path})')


def run_eval_command(args) -> int:
    try:
        run = EvalRun(eval_config(args))
    except ValueError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    try:
        report = run_eval(run, progress=args.progress)
    except KeyboardInterrupt:
        if run.results_path.exists() and run.results_path.stat().st_size:
            print(f'interrupted: finished episodes are in {run.results_path}; the same command resumes',
                  file=sys.stderr)
        else:
            print('interrupted before the first episode ended: nothing was written', file=sys.stderr)
        raise
    print_report(report)
    return 0


def add_eval_parser(sub) -> argparse.ArgumentParser:
    """The `eval` subcommand: EvalConfig's fields and --no-progress."""
    ev = sub.add_parser('eval', help='evaluate an agent on a split; resumable JSON-lines results and a metrics table',
                        description=EvalConfig.__doc__.split('\n\n')[0])
    add_fields(EvalConfig, ev)
    ev.add_argument('--progress', action=argparse.BooleanOptionalAction, default=True,
                    help='a progress bar on stderr (default: --progress)')
    ev.set_defaults(config_parser=ev)
    return ev


def eval_config(args) -> EvalConfig:
    """The EvalConfig of `eval`'s parsed arguments."""
    return from_args(EvalConfig, args, args.config_parser)


