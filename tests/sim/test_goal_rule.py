"""DialFRED's goal rule for a go-to: within 4 actions of the expert's end pose, counted over the
navigation graph (moves, turns and looks); and the 'visible' rule kept beside it (no ROS)."""

from __future__ import annotations

import dataclasses

import pytest

from dialfred_sim.env import DialfredEnv
from dialfred_sim.tasks import load_split
from dialfred_sim.tasks.goals import (GOAL_RULES, NEAR_ACTIONS, conditions_met, parse_pose_arg, pose_arg,
                                      rule_goal, under_rule)
from dialfred_sim.tasks.navigation import STEP, actions_to_pose
from dialfred_sim.world.camera import HORIZON_MAX, HORIZON_MIN

SPLIT = 'valid_unseen'


@pytest.fixture(scope='module')
def tasks():
    return load_split(SPLIT)



def near_of(task):
    return next(c for c in task.goal if c.kind == 'near')


def move_task_with_room_behind(tasks, env, steps: int = 5):
    """A Move task whose end pose has `steps` free points behind it and room to look 45 degrees
    either way, with the env reset to it."""
    for task in tasks:
        if task.task_type != 'Move':
            continue
        i, j, rot, horizon = parse_pose_arg(near_of(task).arg)
        env.reset(options={'task': task})
        free = env.world.free_floor()
        di, dj = STEP[rot]
        if all((i - k * di, j - k * dj) in free for k in range(steps + 1)):
            return task
    pytest.skip(f'no Move task of {SPLIT} has {steps} free points behind its end pose')


def look_sign(horizon: float) -> int:
    """The way the camera can pitch 45 degrees from `horizon`: -1 up, +1 down."""
    return -1 if horizon - 45 >= HORIZON_MIN else 1


def near_holds(env, task, i, j, rot, horizon) -> bool:
    env.teleport(i, j, rot, horizon)
    return conditions_met(env.world, [near_of(task)])[0]


def test_a_pose_4_moves_from_the_experts_end_pose_meets_the_goal_and_5_does_not(tasks, env):
    task = move_task_with_room_behind(tasks, env)
    i, j, rot, horizon = parse_pose_arg(near_of(task).arg)
    di, dj = STEP[rot]
    assert near_holds(env, task, i, j, rot, horizon)
    assert near_holds(env, task, i - 4 * di, j - 4 * dj, rot, horizon)
    assert actions_to_pose(env.world, (i, j, rot, horizon), 10) == 4
    assert not near_holds(env, task, i - 5 * di, j - 5 * dj, rot, horizon)
    assert actions_to_pose(env.world, (i, j, rot, horizon), 10) == 5


def test_on_the_right_spot_the_turns_and_looks_count(tasks, env):
    task = move_task_with_room_behind(tasks, env)
    i, j, rot, horizon = parse_pose_arg(near_of(task).arg)
    s = look_sign(horizon)
    assert HORIZON_MIN <= horizon + s * 45 <= HORIZON_MAX
    assert near_holds(env, task, i, j, (rot + 180) % 360, horizon + s * 30)       # 2 turns + 2 looks
    assert near_holds(env, task, i, j, (rot + 90) % 360, horizon + s * 45)        # 1 turn + 3 looks
    assert not near_holds(env, task, i, j, (rot + 180) % 360, horizon + s * 45)   # 2 + 3
    # one point behind, facing away and looking 30 degrees off: 2 turns, 1 move, 2 looks
    assert not near_holds(env, task, i - STEP[rot][0], j - STEP[rot][1], (rot + 180) % 360, horizon + s * 30)


def test_stepping_into_the_goal_ends_the_episode_with_success(tasks, env):
    task = move_task_with_room_behind(tasks, env)
    i, j, rot, horizon = parse_pose_arg(near_of(task).arg)
    di, dj = STEP[rot]
    env.reset(options={'task': task})
    env.teleport(i - 5 * di, j - 5 * dj, rot, horizon)
    _, reward, terminated, _, info = env.step('MoveAhead')
    assert info['success'] and terminated and reward == 1.0


def test_a_move_task_ends_4_actions_before_the_experts_go_to_does(tasks):
    moves = [t for t in tasks if t.task_type == 'Move']
    assert moves
    for t in moves:
        walked = t.primitives[-1].end - t.start
        assert walked > NEAR_ACTIONS, t.task_id       # a go-to of 4 actions or fewer is done before it starts
        assert t.expert_length == walked - NEAR_ACTIONS, t.task_id


def test_every_task_with_a_go_to_wants_the_pose_where_the_expert_ended_it(tasks):
    with_goto = [t for t in tasks if any(p.kind == 'goto' for p in t.primitives)]
    assert len(with_goto) > 100
    for t in with_goto:
        near = [c for c in t.goal if c.kind == 'near']
        assert len(near) == 1, t.task_id
        assert parse_pose_arg(near[0].arg) == t.expert_end_pose, t.task_id
        assert near[0].obj == [p for p in t.primitives if p.kind == 'goto'][-1].target
    assert not any(c.kind == 'near' for t in tasks if t not in with_goto for c in t.goal)


def test_the_visible_rule_is_the_earlier_goal():
    from dialfred_sim.tasks.schema import Condition
    near = Condition('near', 'Sofa_0', pose_arg((3, 4, 90, 30.0)))
    holding = Condition('holding', 'Book_0')
    assert rule_goal('Move', [near], 'visible') == [Condition('reachable', 'Sofa_0')]
    assert rule_goal('Pick & Move', [holding, near], 'visible') == [holding, Condition('reachable', 'Sofa_0')]
    assert rule_goal('Move & Pick', [holding, near], 'visible') == [holding]
    assert rule_goal('Move & Pick', [holding, near], 'dialfred') == [holding, near]
    with pytest.raises(ValueError, match='unknown goal rule'):
        rule_goal('Move', [near], 'nearby')


def test_a_task_under_the_visible_rule_has_that_goal_and_its_own_expert_length(tasks):
    moved = [t for t in tasks if t.task_type in ('Move', 'Pick & Move')]
    for t in moved:
        v = under_rule(t, 'visible')
        assert v.goal_rule == 'visible' and [c.kind for c in v.goal][-1] == 'reachable'
        assert v.end == (t.visible_end if t.visible_end is not None else t.end)
        assert v.expert_end_pose == t.expert_end_pose       # the direction answers point to the same pose
        assert under_rule(v, 'visible') is v
    assert under_rule(t, 'dialfred') is t
    with pytest.raises(ValueError, match='only a task under'):
        under_rule(under_rule(t, 'visible'), 'dialfred')


@pytest.mark.parametrize('rule', GOAL_RULES)
def test_the_expert_meets_the_goal_under_either_rule_on_tasks_with_a_go_to(tasks, rule):
    """On the first 5 tasks with a go-to whose goal under `rule` does not hold at the start, the expert
    meets it at exactly the task's expert length. Under DialFRED's rule no task's goal holds at the start
    (the generator drops such tasks); under 'visible' it may (the target already in view and within
    reach, as in a short Move): those are left out, there being nothing for the expert to do."""
    with_goto = [t for t in tasks if any(p.kind == 'goto' for p in t.primitives)]
    env = DialfredEnv(resolution=with_goto[0].resolution, goal_rule=rule)
    played = 0
    try:
        for task in with_goto:
            if played == 5:
                break
            task = under_rule(task, rule)
            _, info = env.reset(options={'task': task})
            if rule != 'dialfred' and info['success']:
                continue
            assert not info['success'], task.task_id
            played += 1
            steps = 0
            for a in task.expert_actions:
                _, _, terminated, truncated, info = env.step({'action': a.action, 'pixel': (a.x, a.y)})
                steps += 1
                if terminated or truncated:
                    break
            assert info['success'] and steps == task.expert_length, (task.task_id, rule, steps, task.expert_length)
    finally:
        env.close()
    assert played == 5, f'only {played} tasks with a go-to of {SPLIT} have their {rule!r} goal left to do'


def test_an_unknown_goal_rule_is_refused_before_anything_starts():
    with pytest.raises(ValueError, match='unknown goal rule'):
        DialfredEnv(goal_rule='nearby')


def test_results_judged_by_another_goal_rule_are_not_mixed_in(tmp_path):
    from dialfred_bringup.evaluation import EvalConfig, EvalRun, resumable_results
    from dialfred_sim.metrics import EpisodeResult, ResultsFileError, append_result
    config = EvalConfig(split=SPLIT, agent='random', out=tmp_path / 'r.jsonl')
    row = EpisodeResult('valid_unseen/000000', 'Move', SPLIT, False, 0, 1, 3, 5, agent='random', goal_rule='visible')
    append_result(config.out, row)
    with pytest.raises(ResultsFileError, match="goal rule 'visible', not 'dialfred'"):
        resumable_results(EvalRun(config), ['valid_unseen/000000'])
    older = tmp_path / 'old.jsonl'
    append_result(older, dataclasses.replace(row, goal_rule=''))      # written before results recorded it
    with pytest.raises(ResultsFileError, match='written before results recorded the rule'):
        resumable_results(EvalRun(dataclasses.replace(config, out=older)), ['valid_unseen/000000'])
    assert EvalRun(EvalConfig(split=SPLIT, agent='random', goal_rule='visible')).results_path.name == \
        'valid_unseen_random_goal-visible.jsonl'
