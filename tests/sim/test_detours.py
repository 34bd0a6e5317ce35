"""Detours (dialfred_sim.tasks.detours; build_demonstrations(detours=True)).

Claims: every task of valid_unseen's first 12 with a go-to strays at a step of one of its go-tos, makes
its wrong moves (not imitation targets) and is brought back by the expert; from where it rejoins, its
actions and frames are the expert's own (the same pose renders the same frame); each still reaches its
goal; a task without a go-to is played as the expert played it; the plan is drawn from the seed alone;
the way back to where the agent stands is no move at all. A guided walk does what its advice says, takes
the expert's way where a move it is told is blocked, gives up on a pose it stood on, is over when told
"here", and then rejoins the expert's actions (tests/performer/test_answer_streams.py: the oracle's).
"""

from __future__ import annotations

import numpy as np
import pytest

from dialfred_sim.tasks.demonstrations import build_demonstrations, load_demonstrations
from dialfred_sim.tasks.detours import DETOUR_MOVES, DETOUR_ROWS, detour_plan, guided_plan, rejoin_step, way_back
from dialfred_sim.tasks.splits import load_split

TASKS = 12


@pytest.fixture(scope='module')
def builds(tmp_path_factory):
    root = tmp_path_factory.mktemp('detours')
    build_demonstrations('valid_unseen', 64, root / 'plain', limit=TASKS, progress=False)
    build_demonstrations('valid_unseen', 64, root / 'detours', limit=TASKS, progress=False, detours=True)
    return load_demonstrations(root / 'plain'), load_demonstrations(root / 'detours')


def test_a_detour_strays_inside_a_go_to_and_rejoins_the_experts_own_actions_and_frames(builds):
    plain, detoured = builds
    tasks = load_split('valid_unseen')[:TASKS]
    strayed = 0
    for task, a, b in zip(tasks, plain.tasks, detoured.tasks):
        assert b['success'], task.task_id
        if b.get('detour') is None:
            assert not any(p.kind == 'goto' for p in task.primitives) or detour_plan(task, np.random.default_rng(0)) is None
            assert b['actions'] == a['actions']
            continue
        strayed += 1
        at, wrong, back = b['detour']
        assert DETOUR_MOVES[0] <= wrong <= DETOUR_MOVES[1] and back >= 0
        assert b['targets'] == [True] * at + [False] * wrong + [True] * (len(b['actions']) - at - wrong)
        assert b['actions'][:at] == a['actions'][:at]
        rejoin = rejoin_step(task, at)
        rest = len(a['actions']) - rejoin
        assert b['actions'][len(b['actions']) - rest:] == a['actions'][rejoin:]
        mine = detoured.frames_of(detoured.tasks.index(b))
        theirs = plain.frames_of(plain.tasks.index(a))
        assert np.array_equal(mine[len(mine) - rest - 1:], theirs[rejoin:])      # the same poses, the same frames
        assert np.array_equal(mine[:at + 1], theirs[:at + 1])
    assert strayed >= 5


def test_tasks_without_a_go_to_are_played_as_the_expert_played_them(builds):
    plain, detoured = builds
    for a, b in zip(plain.tasks, detoured.tasks):
        if b.get('detour') is None:
            assert b['actions'] == a['actions'] and 'targets' not in b


def test_the_plan_is_drawn_from_the_seed_alone_and_the_way_back_from_here_is_nothing():
    from dialfred_sim.env import DialfredEnv
    task = next(t for t in load_split('valid_unseen') if t.task_type == 'Move')
    assert detour_plan(task, np.random.default_rng([11, 0])) == detour_plan(task, np.random.default_rng([11, 0]))
    env = DialfredEnv(resolution=64)
    env.reset(options={'task': task})
    a = env.world.agent
    assert way_back(env.world, (a.i, a.j, a.rotation, a.horizon)) == []
    assert way_back(env.world, (10_000, 10_000, 0, 0.0)) is None
    env.close()


def test_joined_rows_read_as_the_concatenation_would():
    from dialfred_sim.tasks.demonstrations import JoinedRows
    a, b = np.arange(12).reshape(6, 2), np.arange(100, 108).reshape(4, 2)
    whole = np.concatenate([a, b])
    rows = JoinedRows([a, b])
    assert rows.shape == whole.shape and len(rows) == 10
    for key in (3, -1, slice(1, 4), slice(4, 9), slice(None, None, 3), [9, 0, 6, 5], np.array([7, 7, 2])):
        assert np.array_equal(rows[key], whole[key]), key
    with pytest.raises(IndexError):
        rows[[10]]


def _guided(task, advise):
    from dialfred_sim.env import DialfredEnv
    from dialfred_sim.tasks.demonstrations import play_demonstration
    env = DialfredEnv(resolution=32)
    frames = np.zeros((len(task.expert_actions) + 1 + DETOUR_ROWS, 32, 32, 3), np.uint8)
    try:
        return play_demonstration(env, task, frames, guide=advise)
    finally:
        env.close()


def test_a_guided_walk_does_what_it_is_told_until_told_here_or_back_where_it_stood():
    tasks = load_split('valid_unseen')
    move = next(t for t in tasks if t.task_type == 'Move' and len(t.expert_actions) >= 6)
    at, rejoin = guided_plan(move)
    assert at == 0 and rejoin == move.primitives[-1].end - move.start     # the go-to's end: where the answers point
    here = _guided(move, lambda env: 'Stop')        # told "here" at once: the expert's way from the start
    assert here['guided'][:2] == [0, 0] and here['success']
    assert here['failed_actions'] == 0 and len(here['actions']) <= len(move.expert_actions)   # the shortest way
    spin = _guided(move, lambda env: 'RotateLeft')  # four turns bring it back to where it stood: then the expert's way
    assert spin['guided'][1] == 4 and [a[0] for a in spin['actions'][:4]] == ['RotateLeft'] * 4
    assert spin['success'] and spin['targets'] == [True] * len(spin['actions'])
    ahead = _guided(move, lambda env: 'MoveAhead')  # a wall ahead: the expert's moves for a while, not a bump
    assert ahead['failed_actions'] == 0 and ahead['success']


def test_a_task_without_a_last_go_to_ending_where_the_expert_ends_has_no_guided_walk():
    tasks = load_split('valid_unseen')[:40]
    plain = [t for t in tasks if not any(p.kind == 'goto' for p in t.primitives)]
    assert plain and all(guided_plan(t) is None for t in plain)
    record = _guided(plain[0], lambda env: 'MoveAhead')
    assert record['guided'] is None and [a[0] for a in record['actions']] == [a.action for a in plain[0].expert_actions]
