"""Evaluation without ROS: the episodes `launch eval` plays through the graph, played in worker processes
that each hold a simulator, the oracle's rules and the agent (`./dialfred launch eval --local`).

Each worker plays the one episode loop (`dialfred_sim.episode.play`) that `workers.SimWorker` plays
through the simulator and oracle nodes, served here by `dialfred_oracle.local.EnvServer`: the simulator
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
from typing import Callable

from dialfred_sim.metrics import dialogue_entry
from dialfred_sim.metrics import episode_result as result_line
from dialfred_sim.processes import worker_pool
from dialfred_sim.protocol import is_privileged

_W: dict = {}


def _init_worker(config) -> None:
    import torch

    from dialfred_oracle.answers import Perturbation
    from dialfred_oracle.swap import AnswerSwap
    from dialfred_sim.env import DialfredEnv
    torch.set_num_threads(1)
    _W['config'] = config
    # the sim node's defaults: protocol.MAX_STEPS, MAX_FAILURES
    _W['env'] = DialfredEnv(resolution=config.resolution, goal_rule=config.goal_rule)
    _W['agent'] = config.make_agent()
    _W['perturbation'] = (Perturbation(config.perturb_type, config.perturb_probability, config.seed)
                          if config.perturb_type else None)
    _W['swap'] = (AnswerSwap(config.split_tasks(), config.resolution, config.goal_rule)
                  if config.answers == 'swapped' else None)


def _play_job(job: tuple):
    index, task = job
    return play_episode(_W['config'], _W['env'], _W['agent'], _W['perturbation'], index, task, _W['swap'])


def play_episode(config, env, agent, perturbation, index: int, task, swap=None):
    """One episode of `task` (at `index` in the split) in `env` with `agent`: its EpisodeResult. `swap`: a
    dialfred_oracle.swap.AnswerSwap for --answers swapped."""
    from dialfred_oracle.local import EnvServer
    from dialfred_sim.agents import task_view
    from dialfred_sim.episode import play, run
    from dialfred_sim.protocol import episode_seed
    started = time.monotonic()
    episode = play(agent, seed=episode_seed(config.seed, index), told=task_view(agent, task), asks=config.asks,
                   max_questions=config.max_questions)
    state = run(episode, EnvServer(env, task, perturbation, swap, with_depth=False, with_segmentation=False))
    return state_result(config, task, agent, state, time.monotonic() - started)


def state_result(config, task, agent, state, wall_s: float):
    """The results line of an episode played by `config`'s run (an EvalConfig) to `state` (the episode loop's
    EpisodeState), in this process or through the simulator and oracle nodes (workers.SimWorker)."""
    return result_line(task, state, [dialogue_entry(qa.question.question_type, qa.question.object_noun, bool(qa.valid),
                                                    qa.answer) for qa in state.dialogue],
                       wall_s=wall_s, privileged=is_privileged(agent), **config.identity)


def play_local(config, jobs: list, on_result: Callable) -> None:
    """Play every (index, task) of `jobs` in `config.workers` processes; `on_result(result)` as each
    episode ends (in the order they end)."""
    if not jobs:
        return
    workers = max(1, min(config.workers, len(jobs)))
    with worker_pool(workers, initializer=_init_worker, initargs=(config,)) as pool:
        for result in pool.imap_unordered(_play_job, jobs, chunksize=1):
            on_result(result)
