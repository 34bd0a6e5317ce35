"""The simulator core (no ROS): ALFRED's actions and world rules as the DialFRED paper states them.

Situations are set up deterministically: a test resets a known floor plan, clears the scattered
small objects where it needs a clean slate, spawns the objects it needs on known receptacles and
uses `face()` to stand where the target is visible within reach. Every failed action is checked to
leave the world and the agent exactly as they were and to count as a failed action.

This file: The Gymnasium environment: episodes, malformed actions and options, seeded repeats.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from dialfred_sim.actions import ACTION_NAMES

from helpers import act, agent_pose, reset, snapshot
from world_helpers import KITCHEN


# ---------------------------------------------------------------------------------------------- episodes

def test_stop_terminates_the_episode_and_stepping_after_it_raises(env):
    reset(env, KITCHEN)
    _, terminated, truncated, info = act(env, 'Stop')
    assert terminated and not truncated and info['last_action_success']
    before = snapshot(env)
    with pytest.raises(RuntimeError, match='episode is over'):
        env.step('MoveAhead')
    assert snapshot(env) == before


def test_ten_failed_actions_terminate_the_episode(env):
    reset(env, KITCHEN)
    env.teleport(*agent_pose(env)[:3], -30)
    for k in range(1, 11):
        _, terminated, truncated, info = act(env, 'LookUp')
        assert not info['last_action_success'] and info['failed_actions'] == k
        assert terminated == (k == 10) and not truncated
    with pytest.raises(RuntimeError):
        env.step('LookDown')


def test_the_step_limit_truncates_the_episode(make_env):
    e = make_env(max_steps=3)
    reset(e, KITCHEN)
    for k in range(1, 4):
        _, terminated, truncated, info = act(e, 'RotateLeft')
        assert info['step_count'] == k
        assert not terminated and truncated == (k == 3)
    with pytest.raises(RuntimeError):
        e.step('RotateLeft')


def test_step_before_reset_raises(make_env):
    e = make_env()
    with pytest.raises(RuntimeError, match='before reset'):
        e.step('MoveAhead')


MALFORMED = [
    pytest.param('Jump', id='unknown-name'),
    pytest.param('moveahead', id='wrong-case'),
    pytest.param(len(ACTION_NAMES), id='index-too-large'),
    pytest.param(-1, id='negative-index'),
    pytest.param(True, id='bool'),
    pytest.param({'pixel': (3, 3)}, id='no-action-key'),
    pytest.param({'action': 'Pickup'}, id='interaction-without-pixel'),
    pytest.param({'action': 'Put', 'pixel': None}, id='pixel-none'),
    pytest.param({'action': 'Open', 'pixel': (64, 10)}, id='pixel-right-of-frame'),
    pytest.param({'action': 'Open', 'pixel': (10, 64)}, id='pixel-below-frame'),
    pytest.param({'action': 'Slice', 'pixel': (-1, 10)}, id='pixel-negative'),
    pytest.param({'action': 'ToggleOn', 'pixel': (1, 2, 3)}, id='pixel-three-values'),
]


@pytest.mark.parametrize('action', MALFORMED)
def test_malformed_actions_raise_value_error_and_change_nothing(env, action):
    reset(env, KITCHEN)
    act(env, 'RotateLeft')
    before = snapshot(env)
    frame = env.render().copy()
    with pytest.raises(ValueError):
        env.step(action)
    assert snapshot(env) == before
    assert env.steps == 1 and env.failures == 0 and not env.done
    assert np.array_equal(env.render(), frame)
    _, _, _, info = act(env, 'RotateRight')
    assert info['step_count'] == 2 and info['failed_actions'] == 0


# A pixel is two integers. Anything else is a caller's bug that used to be coerced silently (3.9 -> 3,
# '3' -> 3, True -> 1) or to escape as OverflowError (inf).
NOT_A_PIXEL = [
    pytest.param((3.9, 5.9), id='floats'),
    pytest.param((3.0, 5.0), id='whole-floats'),
    pytest.param(('3', '5'), id='digit-strings'),
    pytest.param('35', id='a-string'),
    pytest.param((True, False), id='bools'),
    pytest.param((float('inf'), 3), id='inf'),
    pytest.param((float('nan'), 3), id='nan'),
    pytest.param(np.array([3.5, 5.0]), id='float-array'),
    pytest.param({3, 5}, id='a-set'),
    pytest.param(7, id='one-number'),
]


@pytest.mark.parametrize('pixel', NOT_A_PIXEL)
def test_a_pixel_that_is_not_two_integers_is_a_value_error_naming_it(env, pixel):
    reset(env, KITCHEN)
    before, frame = snapshot(env), env.render().copy()
    with pytest.raises(ValueError, match=r'Pickup needs a target pixel \(x, y\) of two integers, got ') as caught:
        env.step({'action': 'Pickup', 'pixel': pixel})
    assert repr(pixel) in str(caught.value)
    assert snapshot(env) == before and np.array_equal(env.render(), frame)
    assert env.steps == 0 and env.failures == 0 and not env.done


@pytest.mark.parametrize('pixel', [(3, 5), [3, 5], np.array([3, 5]), (np.int32(3), np.int64(5))])
def test_a_pixel_may_be_any_pair_of_python_or_numpy_integers(env, pixel):
    reset(env, KITCHEN)
    _, _, _, info = act(env, 'Pickup', pixel)
    assert info['step_count'] == 1     # taken as an action (it may fail: there may be nothing there)


BAD_LIMITS = [
    pytest.param({'max_steps': 0}, ValueError, id='max_steps-0'),
    pytest.param({'max_steps': -5}, ValueError, id='max_steps-negative'),
    pytest.param({'max_failures': 0}, ValueError, id='max_failures-0'),
    pytest.param({'max_steps': 2.5}, TypeError, id='max_steps-float'),
    pytest.param({'max_steps': '100'}, TypeError, id='max_steps-string'),
    pytest.param({'max_failures': True}, TypeError, id='max_failures-bool'),
    pytest.param({'max_failures': None}, TypeError, id='max_failures-none'),
    pytest.param({'dirty_probability': 1.5}, ValueError, id='dirty_probability-above-1'),
    pytest.param({'dirty_probability': float('nan')}, ValueError, id='dirty_probability-nan'),
    pytest.param({'dirty_probability': '0.2'}, TypeError, id='dirty_probability-string'),
]


@pytest.mark.parametrize('kwargs, error', BAD_LIMITS)
def test_episode_limits_must_be_positive_integers(make_env, kwargs, error):
    name, value = next(iter(kwargs.items()))
    with pytest.raises(error, match=rf'^{name} must .*got {re.escape(repr(value))}'):
        make_env(**kwargs)


BAD_RESET_OPTIONS = [
    pytest.param({'task_id': 12}, TypeError, r"task_id must be a string .*got 12 \(int\)", id='task_id-int'),
    pytest.param({'task_id': ''}, ValueError, r"task_id must name a task .*got ''", id='task_id-empty'),
    pytest.param({'task_id': None}, TypeError, r'task_id must be a string .*got None', id='task_id-none'),
    pytest.param({'task_id': 'valid_unseen/999999'}, ValueError, r"unknown task_id 'valid_unseen/999999'",
                 id='task_id-unknown'),
    pytest.param({'task': None}, TypeError, r'task must be a dialfred_sim.tasks.Task, got None', id='task-none'),
    pytest.param({'task': 'valid_unseen/000012'}, TypeError, r"task must be .*got 'valid_unseen/000012'",
                 id='task-a-string'),
    pytest.param({'task_id': 'valid_unseen/000012', 'scene': 'FloorPlan1'}, ValueError,
                 r"give 'task_id' or 'task' alone", id='task-and-scene'),
    pytest.param({'scene': 7}, TypeError, r"scene must be a string .*got 7", id='scene-int'),
    pytest.param({'scene': ''}, ValueError, r"unknown scene ''", id='scene-empty'),
    pytest.param({'scene': 'FloorPlan99'}, ValueError, r"unknown scene 'FloorPlan99'", id='scene-unknown'),
    pytest.param({'taskid': 'valid_unseen/000012'}, ValueError, r"unknown reset option\(s\) 'taskid'",
                 id='misspelt-key'),
    pytest.param({'dirty_probability': -0.1}, ValueError, r'dirty_probability must be in \[0, 1\], got -0.1',
                 id='dirty_probability-negative'),
    pytest.param(['scene', 'FloorPlan1'], TypeError, r'options must be a dict', id='options-a-list'),
]


@pytest.mark.parametrize('options, error, message', BAD_RESET_OPTIONS)
def test_bad_reset_options_are_a_clear_error_and_change_nothing(env, options, error, message):
    reset(env, KITCHEN)
    act(env, 'RotateLeft')
    before, frame = snapshot(env), env.render().copy()
    rng_state = env.np_random.bit_generator.state
    with pytest.raises(error, match=message):
        env.reset(seed=5, options=options)
    assert snapshot(env) == before and np.array_equal(env.render(), frame)
    assert env.np_random.bit_generator.state == rng_state      # not even reseeded
    assert env.task is None and env.steps == 1 and not env.done
    _, _, _, info = act(env, 'RotateRight')                    # the episode goes on
    assert info['step_count'] == 2 and info['scene'] == KITCHEN


def test_navigation_ignores_the_pixel(env):
    reset(env, KITCHEN)
    _, _, _, info = act(env, 'RotateLeft', (999, -5))
    assert info['last_action_success']


SCRIPT = [('MoveAhead', None), ('RotateLeft', None), ('LookDown', None), ('Pickup', (32, 40)),
          ('MoveAhead', None), ('RotateRight', None), ('Open', (32, 32)), ('LookUp', None),
          ('MoveAhead', None), ('Put', (30, 45)), ('ToggleOn', (32, 20)), ('RotateRight', None),
          ('MoveAhead', None), ('LookDown', None)]


def _play(e, seed):
    frames = []
    obs, info = e.reset(seed=seed)
    frames.append((obs['rgb'].copy(), obs['depth'].copy(), obs['segmentation'].copy(), obs['pose'].copy()))
    outcomes = []
    for action, px in SCRIPT:
        obs, _, terminated, truncated, info = e.step({'action': action, 'pixel': px} if px else action)
        frames.append((obs['rgb'].copy(), obs['depth'].copy(), obs['segmentation'].copy(), obs['pose'].copy()))
        outcomes.append((info['last_action_success'], info['last_action_error'], info['held_object']))
        if terminated or truncated:
            break
    return info['scene'], frames, outcomes, e.world.object_states()


def test_same_seed_same_episode_bit_for_bit(make_env):
    a, b = make_env(), make_env()
    scene_a, frames_a, out_a, states_a = _play(a, 11)
    scene_b, frames_b, out_b, states_b = _play(b, 11)
    assert scene_a == scene_b and out_a == out_b and states_a == states_b
    assert len(frames_a) == len(frames_b)
    for fa, fb in zip(frames_a, frames_b):
        for xa, xb in zip(fa, fb):
            assert xa.dtype == xb.dtype and xa.tobytes() == xb.tobytes()


def test_a_different_seed_gives_a_different_episode(make_env):
    e = make_env()
    obs_a, info_a = e.reset(seed=11)
    states_a, rgb_a = e.world.object_states(), obs_a['rgb'].copy()
    obs_b, info_b = e.reset(seed=12)
    assert info_a['scene'] != info_b['scene'] or e.world.object_states() != states_a
    assert not np.array_equal(rgb_a, obs_b['rgb'])
    # In one fixed floor plan the seed still changes where things are.
    reset(e, KITCHEN, seed=1)
    s1 = e.world.object_states()
    reset(e, KITCHEN, seed=2)
    assert e.world.object_states() != s1


def test_observations_match_the_observation_space(env):
    obs, info = reset(env, 'FloorPlan301')
    assert env.observation_space.contains(obs)
    assert obs['rgb'].shape == (64, 64, 3) and obs['rgb'].dtype == np.uint8
    assert obs['depth'].dtype == np.float32 and obs['segmentation'].dtype == np.int32
    ids, names = info['instances']
    assert set(np.unique(obs['segmentation']).tolist()) - {-1} <= set(ids)   # -1: nothing rendered
    assert names[ids.index(env.world.objects['Bed_0'].body)] == 'Bed_0'
    assert info['room_type'] == 'bedroom' and info['scene'] == 'FloorPlan301'


def test_frames_are_the_current_observations_images_and_none_before_reset(make_env):
    e = make_env()
    assert e.frames() is None
    obs, _ = reset(e, 'FloorPlan301')
    obs, *_ = e.step('RotateLeft')
    rgb, depth, segmentation = e.frames()
    assert np.array_equal(rgb, obs['rgb']) and np.array_equal(depth, obs['depth'])
    assert np.array_equal(segmentation, obs['segmentation'])


def test_gymnasium_env_checker_passes(env):
    from gymnasium.utils.env_checker import check_env
    check_env(env.unwrapped, skip_render_check=True)


