"""The chained protocol's core (dialfred_sim.chained, DialfredEnv.continue_task; no ROS): an episode's tasks
in order on the state the agent's own actions left, success that never ends a task, tasks whose goal held at
their start, the expert's stretches, the per-episode figures, and results lines of either protocol."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from dialfred_sim.agents import ExpertAgent
from dialfred_sim.chained import (chain_episodes, episode_metrics, expert_reference, reference_length, segment)
from dialfred_sim.env import DialfredEnv
from dialfred_sim.metrics import CHAINED_FIELDS, EpisodeResult
from dialfred_sim.tasks import load_split


@pytest.fixture(scope='module')
def env128():
    e = DialfredEnv(resolution=128)      # the splits' own camera: the expert's clicks replay exactly
    yield e
    e.close()


@pytest.fixture(scope='module')
def episodes():
    return chain_episodes(enumerate(load_split('valid_unseen')[:40]))


def play_expert(env, tasks, k):
    """Task k of a chained episode played by the expert to its Stop: (its steps, the last info)."""
    expert = ExpertAgent(resolution=128)
    expert.reset(expert_reference(tasks, k))
    steps = 0
    while True:
        name, x, y = expert.act()
        _, _, terminated, truncated, info = env.step({'action': name, 'pixel': (x, y)})
        steps += 1
        if terminated or truncated:
            return steps, info


def test_an_episode_chains_its_tasks_in_the_order_they_were_cut(episodes):
    assert len(episodes) >= 5
    index = 0
    for e in episodes:
        ks = [k for k, _ in e.tasks]
        assert ks == list(range(index, index + len(ks)))      # the split's tasks, every one, in order
        index += len(ks)
        tasks = [t for _, t in e.tasks]
        assert len({t.episode.episode_id for t in tasks}) == 1
        # the expert's stretches join up, from the first task's start to the last task's last step
        spans = [segment(tasks, k) for k in range(len(tasks))]
        assert spans[0][0] == tasks[0].start and spans[-1][1] == tasks[-1].primitives[-1].end
        assert all(a[1] == b[0] for a, b in zip(spans, spans[1:]))
        assert all(reference_length(tasks, k) == end - start + 1 for k, (start, end) in enumerate(spans))


def test_an_episode_with_a_task_missing_in_the_middle_is_refused(episodes):
    e = next(e for e in episodes if len(e.tasks) >= 3)
    with pytest.raises(ValueError, match='not consecutive'):
        chain_episodes([e.tasks[0], e.tasks[2]])


def test_success_does_not_end_a_chained_task_only_its_stop_does_and_the_next_goes_on_from_there(env128, episodes):
    e = next(e for e in episodes if len(e.tasks) >= 3)
    tasks = [t for _, t in e.tasks]
    _, info = env128.reset(options={'task': tasks[0], 'protocol': 'chained'})
    assert env128.protocol == 'chained' and not info['held_at_start'] and info['goal_conditions_total'] > 0
    expert = ExpertAgent(resolution=128)
    expert.reset(expert_reference(tasks, 0))
    plan = expert._plan
    succeeded_at = None
    for k, (name, x, y) in enumerate(plan):
        _, reward, terminated, truncated, info = env128.step({'action': name, 'pixel': (x, y)})
        assert not terminated and not truncated            # the goal may hold: the task goes on
        if info['success'] and succeeded_at is None:
            succeeded_at = k
    assert succeeded_at is not None and succeeded_at + 1 == tasks[0].expert_length   # first met where it was cut
    _, _, terminated, _, info = env128.step('Stop')
    assert terminated and info['success'] and info['step_count'] == len(plan) + 1
    a = env128.world.agent
    pose = (a.i, a.j, a.rotation, a.horizon, env128.world.held)
    _, info = env128.continue_task(tasks[1])
    assert info['step_count'] == 0 and info['failed_actions'] == 0 and info['task_id'] == tasks[1].task_id
    assert not info['success'] and not info['held_at_start']
    assert (a.i, a.j, a.rotation, a.horizon, env128.world.held) == pose     # nothing moved
    steps, info = play_expert(env128, tasks, 1)
    assert info['success'] and steps == reference_length(tasks, 1)


def test_a_task_whose_goal_holds_at_its_chained_start_cannot_succeed(env128, episodes):
    """Done twice: the second time the goal holds from the start, so it scores as not done (GC has nothing
    to count), even though it holds when the agent stops."""
    tasks = [t for _, t in episodes[0].tasks]
    env128.reset(options={'task': tasks[0], 'protocol': 'chained'})
    _, info = play_expert(env128, tasks, 0)
    assert info['success']
    _, info = env128.continue_task(tasks[0])
    assert info['held_at_start'] and info['goal_conditions_total'] == 0 and not info['success']
    _, _, terminated, _, info = env128.step('Stop')
    assert terminated and not info['success'] and info['held_at_start']


def test_continue_task_needs_a_chained_episode_of_the_same_demonstration(env128, episodes):
    a, b = episodes[0], episodes[1]
    env128.reset(options={'task': a.tasks[0][1]})                       # the expert protocol
    with pytest.raises(ValueError, match='chained'):
        env128.continue_task(a.tasks[1][1])
    env128.reset(options={'task': a.tasks[0][1], 'protocol': 'chained'})
    with pytest.raises(ValueError, match='is of episode'):
        env128.continue_task(b.tasks[0][1])
    assert env128.task.task_id == a.tasks[0][1].task_id                 # nothing changed
    with pytest.raises(ValueError, match='unknown protocol'):
        env128.reset(options={'task': a.tasks[0][1], 'protocol': 'relay'})
    with pytest.raises(ValueError, match='with .task_id. or .task.'):
        env128.reset(options={'protocol': 'chained'})


def test_the_expert_protocol_still_ends_a_task_at_success(env128, episodes):
    task = episodes[0].tasks[0][1]
    env128.reset(options={'task': task})
    assert env128.protocol == 'expert'
    expert = ExpertAgent(resolution=128)
    expert.reset(task)
    for k, (name, x, y) in enumerate(expert._plan):
        _, _, terminated, _, info = env128.step({'action': name, 'pixel': (x, y)})
        assert terminated == (k == len(expert._plan) - 1)
    assert info['success']


def line(task_id, episode, success, questions=0, held=False):
    return EpisodeResult(task_id=task_id, task_type='Put', split='valid_unseen', success=success,
                         goal_conditions_met=int(success), goal_conditions_total=0 if held else 1, steps=3,
                         expert_length=3, questions=questions, end_reason='success' if success else 'stop',
                         protocol='chained', episode_id=episode, held_at_start=held)


def test_episode_metrics_count_whole_episodes_tasks_in_order_and_tasks_held_at_start():
    rows = [line('v/000001', 'v/a', True, 1), line('v/000000', 'v/a', True, 2), line('v/000002', 'v/a', False),
            line('v/000003', 'v/a', True),                       # after a failure: not in order
            line('v/000004', 'v/b', True, 4), line('v/000005', 'v/b', True),
            line('v/000006', 'v/c', False, 0, held=True), line('v/000007', 'v/c', True)]
    m = episode_metrics(rows)
    assert m['episodes'] == 3 and m['all_succeeded'] == pytest.approx(100 / 3)
    assert m['in_order'] == pytest.approx((2 + 2 + 0) / 3)
    assert m['questions_per_episode'] == pytest.approx(7 / 3) and m['tasks_per_episode'] == pytest.approx(8 / 3)
    assert m['held_at_start'] == 1 and m['episodes_with_held'] == 1
    assert episode_metrics([])['episodes'] == 0


def test_results_lines_record_their_protocol_and_the_expert_protocols_lines_are_as_before():
    expert = EpisodeResult(task_id='valid_unseen/000000', task_type='Put', split='valid_unseen', success=True,
                           goal_conditions_met=1, goal_conditions_total=1, steps=4, expert_length=4)
    data = json.loads(expert.to_json())
    assert not set(CHAINED_FIELDS) & set(data)                    # the fields of lines written before chaining
    assert EpisodeResult.from_json(expert.to_json()).protocol == 'expert'
    chained = line('valid_unseen/000000', 'valid_unseen/ep', False, held=True)
    back = EpisodeResult.from_json(chained.to_json())
    assert back == chained and back.held_at_start and json.loads(chained.to_json())['protocol'] == 'chained'
    with pytest.raises(ValueError, match='protocol must be one of'):
        replace(expert, protocol='relay')
    with pytest.raises(ValueError, match='belong to chained results'):
        replace(expert, episode_id='valid_unseen/ep')
