"""Task types and ALFRED jobs as objects (no ROS): the registries, a type of one's own generated and
played by the expert, and no branching on a type's or a job's name in the generator or the goals."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from dialfred_sim.env import DialfredEnv
from dialfred_sim.metrics import has_goto, type_order
from dialfred_sim.tasks import load_split
from dialfred_sim.tasks import generator, goals
from dialfred_sim.tasks.generator import cut_tasks
from dialfred_sim.tasks.jobs import job_named, room_jobs
from dialfred_sim.tasks.schema import Condition
from dialfred_sim.tasks.types import TASK_TYPES, TaskType, register, task_type, task_types, unregister


def _fetch_clause(steps, rng):
    return f'fetch the {steps[1].noun} and bring it to the {steps[2].noun}'


# A type of one's own: go to an object, pick it up, and carry it to the next place, in one task.
FETCH = TaskType('Fetch', ('goto', 'pickup', 'goto'),
                 goal=lambda prims, types: [Condition('holding', prims[1].target)],
                 clause=_fetch_clause, weight=1000.0)


@pytest.fixture
def fetch_registered():
    register(FETCH)
    try:
        yield FETCH
    finally:
        unregister(FETCH.name)


def test_the_papers_25_types_are_registered_in_its_order():
    assert tuple(k.name for k in task_types()) == TASK_TYPES and len(TASK_TYPES) == 25
    assert task_type('Move & Heat').steps == ('goto',) + task_type('Heat').steps
    assert [k.name for k in task_types() if k.shows_target] == ['Move', 'Pick & Move']
    assert {k.name for k in task_types() if k.has_goto} == {n for n in TASK_TYPES if 'Move' in n}


def test_a_type_of_ones_own_is_generated_and_the_expert_solves_it(fetch_registered):
    assert task_types()[-1] is FETCH and type_order('Fetch') == (25, '') < type_order('Juggle')
    assert has_goto('Fetch')
    tasks = load_split('valid_unseen')
    env = DialfredEnv(resolution=tasks[0].resolution)
    try:
        episodes = list(dict.fromkeys(t.episode.episode_id for t in tasks))[:4]
        fetched = []
        for episode_id in episodes:
            episode = next(t.episode for t in tasks if t.episode.episode_id == episode_id)
            fresh = cut_tasks(env, episode, np.random.default_rng(episode.seed + 1), 0, 50)
            fetched += [t for t in fresh if t.task_type == 'Fetch']
        assert fetched, f'no Fetch task cut from {episodes}'
        task = fetched[0]
        assert [p.kind for p in task.primitives] == ['goto', 'pickup', 'goto']
        assert [c.kind for c in task.goal] == ['holding', 'near']      # the go-to's pose, added by goal_for
        assert re.fullmatch(r'(Please |Now )?[Ff]etch the [a-z ]+ and bring it to the [a-z ]+\.', task.instruction)
        assert len(task.step_instructions) == 3
        _, info = env.reset(options={'task': task})
        assert not info['success'] and info['goal_conditions_met'] == 0
        for a in task.expert_actions:
            _, _, terminated, truncated, info = env.step({'action': a.action, 'pixel': (a.x, a.y)})
            assert info['last_action_success'], a
        assert info['success'] and info['goal_conditions_met'] == info['goal_conditions_total'] == 2
    finally:
        env.close()


def test_the_registry_refuses_what_it_cannot_use():
    with pytest.raises(ValueError, match='registered already'):
        register(TaskType('Open', ('open',), goal=lambda p, t: [], clause=lambda s, r: 'open it'))
    with pytest.raises(ValueError, match="unknown task type 'Juggle'"):
        task_type('Juggle')
    with pytest.raises(ValueError, match='primitive kinds'):
        TaskType('Juggle', ('juggle',), goal=lambda p, t: [], clause=lambda s, r: 'juggle')
    with pytest.raises(ValueError, match='weight'):
        TaskType('Juggle', ('pickup',), goal=lambda p, t: [], clause=lambda s, r: 'juggle', weight=0)
    with pytest.raises(ValueError, match="paper's task types"):
        unregister('Open')
    with pytest.raises(ValueError, match='no task type'):
        unregister('Juggle')


def test_jobs_own_their_rooms():
    assert room_jobs('bathroom') == {'pick_and_place_simple': 1.0, 'pick_clean_then_place_in_recep': 1.2,
                                     'pick_two_obj_and_place': 0.8}
    assert not job_named('look_at_obj_in_light').places and not job_named('pick_two_obj_and_place').may_slice
    with pytest.raises(ValueError, match='unknown job'):
        job_named('juggle')


def test_the_generator_and_the_goals_never_branch_on_a_type_or_a_job():
    names = set(TASK_TYPES) | {'Move & '} | set(room_jobs('kitchen')) | set(room_jobs('bedroom'))
    for module in (generator, goals):
        source = Path(module.__file__).read_text()
        said = sorted(n for n in names if f"'{n}'" in source or f'"{n}"' in source)
        assert not said, f'{module.__name__} names {said}'


def test_a_registry_keeps_its_order_names_the_known_ones_and_refuses_a_taken_name():
    from dialfred_sim.registry import Registry
    r = Registry('widget', sorted_names=True)
    r.add('b', 2), r.add('a', 1)
    assert list(r) == ['b', 'a'] and r.named('a') == 1 and 'a' in r and r.get('c') is None and len(r) == 2
    with pytest.raises(ValueError, match="a widget named 'a' is registered already"):
        r.add('a', 3)
    with pytest.raises(ValueError, match="unknown widget 'c'; expected one of a, b"):
        r.named('c')
    assert r.remove('b') == 2 and list(r) == ['a']
    with pytest.raises(ValueError, match="no widget named 'b' is registered"):
        r.remove('b')
    with pytest.raises(TypeError):
        r['z'] = 0                                   # only add() registers
