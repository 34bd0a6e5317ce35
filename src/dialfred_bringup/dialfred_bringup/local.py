"""Evaluation without ROS: the episodes `launch eval` plays through the graph, played in worker processes
that each hold a simulator, the oracle's rules and the agent (`./dialfred launch eval --local`).

Each worker plays an episode exactly as `dialfred_bringup.evaluation.SimWorker` drives the simulator and oracle
nodes: the simulator resets to the task (`DialfredEnv.reset(options={'task': task})`, as the node's
`/sim/reset` with a task id does), the agent is reset with the task's public view and the episode seed
of its index in the split, then before every action the agent may ask questions, answered by
`dialfred_oracle.local.answer_now` (the oracle node's rules and perturbation, keyed on the same
situation), and acts; the episode ends as the node reports it (success, Stop, too many failed actions,
the step limit). The EpisodeResult has the same fields and values as the graph's, but for `wall_s`;
tests/test_eval_local.py compares the two paths episode by episode for every kind of questioner.

What the graph adds is the system under test of a robotics user (nodes, services, actions, recording,
the live view, crash recovery); what this path adds is speed: no serialisation, no executor, one
process per core (docs/benchmarks.md, `./dialfred bench eval_local`). `./dialfred reproduce` plays its
tables this way and checks a slice of every setting through the graph.
"""

from __future__ import annotations

import multiprocessing
import time
from typing import Callable

_W: dict = {}


def _init_worker(config) -> None:
    import torch

    from dialfred_oracle.answers import Perturbation
    from dialfred_sim.env import DialfredEnv
    torch.set_num_threads(1)
    _W['config'] = config
    _W['env'] = DialfredEnv(resolution=config.resolution)     # the sim node's defaults: 1000 steps, 10 failures
    _W['agent'] = config.make_agent()
    _W['perturbation'] = (Perturbation(config.perturb_type, config.perturb_probability, config.seed)
                          if config.perturb_type else None)


def _play_job(job: tuple):
    index, task = job
    return play_episode(_W['config'], _W['env'], _W['agent'], _W['perturbation'], index, task)


def play_episode(config, env, agent, perturbation, index: int, task):
    """One episode of `task` (at `index` in the split) in `env` with `agent`: its EpisodeResult."""
    from dialfred_oracle.local import answer_now
    from dialfred_sim.agents import task_view
    from dialfred_sim.protocol import MAX_QUESTIONS, QA, episode_seed
    from dialfred_sim.metrics import EpisodeResult, dialogue_entry, end_reason
    started = time.monotonic()
    met, total = 0, 0
    questions = invalid = 0
    dialogue: list = []
    last_action = last_error = ''
    info: dict = {}

    def result(reason: str, success: bool = False, error: str = ''):
        return EpisodeResult(
            task_id=task.task_id, task_type=task.task_type, split=task.split, success=bool(success),
            goal_conditions_met=int(met), goal_conditions_total=int(total), steps=int(info.get('step_count', 0)),
            expert_length=int(task.expert_length), questions=questions, invalid_questions=invalid,
            failed_actions=int(info.get('failed_actions', 0)), end_reason=reason,
            error='' if success else (error or last_error), agent=config.agent_name, oracle=config.oracle,
            seed=config.seed, wall_s=round(time.monotonic() - started, 4),
            privileged=bool(getattr(agent, 'privileged', False)), dialogue=list(dialogue))

    try:
        obs, info = env.reset(options={'task': task})
    except (ValueError, FileNotFoundError) as exc:
        return result('error', error=str(exc))
    total = int(info['goal_conditions_total'])
    agent.reset(task_view(agent, task), episode_seed(config.seed, index))
    asks = bool(config.questioner)
    while True:
        in_a_row = 0
        while asks:
            question = agent.ask(obs)
            if question is None:
                break
            if in_a_row >= MAX_QUESTIONS:
                return result('error', error=f'the agent asked more than {MAX_QUESTIONS} questions without acting')
            in_a_row += 1
            ans = answer_now(env, question.question_type, question.object_noun, perturbation)
            questions += 1
            invalid += not ans.valid
            dialogue.append(dialogue_entry(question.question_type, question.object_noun, bool(ans.valid), ans.text))
            agent.hear(QA(question, bool(ans.valid), ans.text, ans.reason))
        name, x, y = agent.act(obs)
        last_action = name
        try:
            obs, _, terminated, truncated, info = env.step({'action': name, 'pixel': (int(x), int(y))})
        except (ValueError, RuntimeError) as exc:
            return result('error', error=str(exc))
        met, total = int(info['goal_conditions_met']), int(info['goal_conditions_total'])
        if not info['last_action_success']:
            last_error = info['last_action_error']
        if terminated or truncated:
            reason = end_reason(bool(info['success']), last_action, int(info['failed_actions']), bool(truncated))
            return result(reason, success=bool(info['success']))


def play_local(config, jobs: list, on_result: Callable) -> None:
    """Play every (index, task) of `jobs` in `config.workers` processes; `on_result(result)` as each
    episode ends (in the order they end)."""
    if not jobs:
        return
    workers = max(1, min(config.workers, len(jobs)))
    ctx = multiprocessing.get_context('spawn')
    with ctx.Pool(workers, initializer=_init_worker, initargs=(config,)) as pool:
        for result in pool.imap_unordered(_play_job, jobs, chunksize=1):
            on_result(result)
