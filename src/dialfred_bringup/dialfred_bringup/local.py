"""Evaluation without ROS: the episodes `launch eval` plays through the graph, played in worker processes
that each hold a simulator, the oracle's rules and the agent (`./dialfred launch eval --local`).

Each worker plays the one episode loop (`dialfred_sim.episode.play`) that `workers.SimWorker` plays
through the simulator and oracle nodes, served here by `dialfred_oracle.in_process.EnvServer`: the simulator
resets to the task (`DialfredEnv.reset(options={'task': task})`, as the node's `/sim/reset` with a task
id does), the questions are answered by the oracle node's rules and perturbation, keyed on the same
situation. The EpisodeResult has the same fields and values as the graph's, but for `wall_s`;
tests/bringup/test_eval_local.py compares the two paths episode by episode for every kind of questioner.

What the graph adds is the system under test of a robotics user (nodes, services, actions, recording,
the live view, crash recovery); what this path adds is speed: no serialisation, no executor, one
process per core (docs/figures.md, `./dialfred bench eval_local`). `./dialfred reproduce` plays its
tables this way and checks a slice of every setting through the graph.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable, Optional

import torch

from dialfred_oracle.answers import Perturbation
from dialfred_oracle.in_process import EnvServer
from dialfred_oracle.answerers import speaking
from dialfred_oracle.swap import AnswerSwap
from dialfred_sim.agents import task_view
from dialfred_sim.chained import ChainedEpisode, expert_reference, reference_length
from dialfred_sim.env import DialfredEnv
from dialfred_sim.episode import play
from dialfred_sim.episode import run as run_episode
from dialfred_sim.metrics import dialogue_entry
from dialfred_sim.metrics import episode_result as result_line
from dialfred_sim.processes import worker_pool
from dialfred_sim.protocol import episode_seed, is_privileged
from dialfred_sim.traces import make_trace

from .silent import SeenBeforeActions, SilentEpisodes, replayable, silent_key, silent_throughout

_W: dict = {}


def _init_worker(run, silent: Optional[tuple[str, str]] = None) -> None:
    torch.set_num_threads(1)
    o = _W['run'] = run
    # (mode, folder): 'record' keeps each episode of this no-question run; 'replay' reuses them (silent.py)
    _W['silent'] = (silent[0], SilentEpisodes(Path(silent[1]), silent_key(run))) if silent else None
    # the sim node's defaults: protocol.MAX_STEPS, MAX_FAILURES
    _W['env'] = DialfredEnv(resolution=o.options.resolution, goal_rule=o.options.goal_rule)
    _W['agent'] = run.make_agent()
    _W['perturbation'] = (Perturbation(o.options.perturb_type, o.options.perturb_probability, o.options.seed)
                          if o.options.perturb_type else None)
    # whoever words the answers: the swap's other task, or an answerer (dialfred_oracle.answerers); None: the oracle
    _W['swap'] = (AnswerSwap(run.split_tasks(), o.options.resolution, o.options.goal_rule)
                  if o.options.answers == 'swapped' else speaking(run.answerer) if run.answerer else None)


def _play_any(job) -> list:
    """[(the EpisodeResult, whether it was replayed from the silent episodes)] of a job: (index, task)
    (`_play_job`), or a chained.ChainedEpisode, whose tasks are played in order in one world (`_play_chained`)."""
    return _play_chained(job) if isinstance(job, ChainedEpisode) else [_play_job(job)]


def _play_chained(job: ChainedEpisode) -> list:
    """`_play_any` of a chained episode: taken whole from the silent episodes when the questioner would ask
    nothing in any of its tasks (silent.py), else played, and kept there by a run without questions."""
    run, agent, silent = _W['run'], _W['agent'], _W['silent']
    tasks = [t for _, t in job.tasks]
    started = time.monotonic()
    if silent is not None and silent[0] == 'replay':
        kept = silent[1].load_chain(job.episode_id, len(tasks)) if replayable(agent) is not None else None
        if kept is not None and all(
                silent_throughout(agent, task_view(agent, expert_reference(tasks, k)),
                                  episode_seed(run.options.seed, index), kept[k][0])
                for k, (index, _) in enumerate(job.tasks)):
            share = (time.monotonic() - started) / len(tasks)
            return [(state_result(run, task, agent, state, share, expert_length=reference_length(tasks, k)), True)
                    for k, (task, (_, state)) in enumerate(zip(tasks, kept))]
    seen = SeenBeforeActions() if silent is not None and silent[0] == 'record' else None
    results, segments = [], []
    for k, (_, task), state in play_chain(run, _W['env'], agent, _W['perturbation'], job, _W['swap'],
                                          observers=[seen] if seen else ()):
        now = time.monotonic()
        results.append((state_result(run, task, agent, state, now - started,
                                     expert_length=reference_length(tasks, k)), False))
        if seen is not None:
            segments.append((seen.before_actions, state))
        started = now
    if seen is not None:
        silent[1].save_chain(job.episode_id, segments)
    return results


def _play_job(job: tuple):
    """(the EpisodeResult of (index, task), whether it was replayed from the silent episodes)."""
    index, task = job
    run, agent, silent = _W['run'], _W['agent'], _W['silent']
    started = time.monotonic()
    if silent is not None and silent[0] == 'replay':
        kept = silent[1].load(task.task_id) if replayable(agent) is not None else None
        if kept is not None and silent_throughout(agent, task_view(agent, task), episode_seed(run.options.seed, index),
                                                  kept[0]):
            return state_result(run, task, agent, kept[1], time.monotonic() - started), True
    seen = SeenBeforeActions() if silent is not None and silent[0] == 'record' else None
    state = play_state(run, _W['env'], agent, _W['perturbation'], index, task, _W['swap'],
                       observers=[seen] if seen else ())
    if seen is not None:
        silent[1].save(task.task_id, seen.before_actions, state)
    return state_result(run, task, agent, state, time.monotonic() - started), False


def play_state(run, env, agent, perturbation, index: int, task, swap=None, observers=()):
    """One episode of `task` (at `index` in the split) in `env` with `agent`, for `run` (an eval_run.EvalRun):
    the episode loop's final EpisodeState. `swap`: a dialfred_oracle.swap.AnswerSwap for --answers swapped, or an
    answerers.Speaking for an answerer of the user's: who words the oracle's answers."""
    episode = play(agent, seed=episode_seed(run.options.seed, index), told=task_view(agent, task), asks=run.asks,
                   max_questions=run.options.max_questions, observers=observers)
    return run_episode(episode, EnvServer(env, task, perturbation, swap, with_depth=False, with_segmentation=False))


def play_chain(run, env, agent, perturbation, episode: ChainedEpisode, swap=None, observers=()):
    """The tasks of a chained episode (dialfred_sim.chained) played in order in `env` with `agent`, for `run`:
    yields (k, (index, task), final EpisodeState) as each task ends. The first task is reset to its start, every
    later one goes on from the world the last one left; the expert is told its stretch of the demonstration,
    an agent that is protocol.Continuing carries on, any other is reset."""
    tasks = [t for _, t in episode.tasks]
    for k, (index, task) in enumerate(episode.tasks):
        told = task_view(agent, expert_reference(tasks, k))
        loop = play(agent, seed=episode_seed(run.options.seed, index), told=told, asks=run.asks,
                    max_questions=run.options.max_questions, observers=observers, carry_on=k > 0)
        server = EnvServer(env, task, perturbation, swap, with_depth=False, with_segmentation=False,
                           protocol='chained', continues=k > 0)
        yield k, (index, task), run_episode(loop, server)


def play_episode(run, env, agent, perturbation, index: int, task, swap=None):
    """`play_state`'s episode as its EpisodeResult (benchmarks/map_perception_ceiling.py plays so)."""
    started = time.monotonic()
    state = play_state(run, env, agent, perturbation, index, task, swap)
    return state_result(run, task, agent, state, time.monotonic() - started)


def state_result(run, task, agent, state, wall_s: float, expert_length=None):
    """The results line of an episode played by `run` (an eval_run.EvalRun) to `state` (the episode loop's
    EpisodeState), in this process or through the simulator and oracle nodes (workers.SimWorker).
    `expert_length`: a chained task's reference length (chained.reference_length)."""
    return result_line(task, state, [dialogue_entry(qa.question.question_type, qa.question.object_noun, bool(qa.valid),
                                                    qa.answer) for qa in state.dialogue],
                       wall_s=wall_s, privileged=is_privileged(agent), expert_length=expert_length,
                       trace=make_trace(state.actions, state.asked_at), **run.identity)


def play_local(run, jobs: list, on_result: Callable, silent: Optional[tuple[str, Path]] = None) -> int:
    """Play every (index, task) of `jobs` (or chained.ChainedEpisode: its tasks in order, in one process) in
    `run.options.workers` processes; `on_result(result)` as each episode ends (in the order they end; a
    chained episode's tasks together, when its last ends). `silent`: ('record', folder) keeps the episodes of a run without
    questions there; ('replay', folder) takes an episode from there whenever the questioner would ask
    nothing in it (silent.py). Returns how many episodes were replayed."""
    if not jobs:
        return 0
    workers = max(1, min(run.options.workers, len(jobs)))
    replayed = 0
    initargs = (run, (silent[0], str(silent[1])) if silent else None)
    with worker_pool(workers, initializer=_init_worker, initargs=initargs) as pool:
        for results in pool.imap_unordered(_play_any, jobs, chunksize=1):
            for result, was_replayed in results:
                replayed += was_replayed
                on_result(result)
    return replayed
