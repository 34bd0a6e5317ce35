"""The Gymnasium environment over the household world: `reset(seed=, options=)` and `step()`.

Observations are first-person RGB, depth (metres), instance segmentation (pybullet body ids; the
table of ids is in `info['instances']`) and the agent pose. Actions are ALFRED's 13 low-level actions
with a target pixel for interactions. An episode ends at Stop or after `max_failures` failed actions
(terminated), or after `max_steps` steps (truncated), the limits of the DialFRED paper.
"""

from __future__ import annotations

import contextlib
from typing import Any, Optional

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .actions import ACTION_NAMES, Action, ActionResult, execute, parse_action
from .protocol import BODY, DEFAULT_PROTOCOL, MAX_FAILURES, MAX_STEPS, PROTOCOLS
from .tasks import get_task
from .tasks.expert import replay
from .tasks.generator import apply_setup
from .tasks.goals import DEFAULT_GOAL_RULE, check_goal_rule, conditions_met, goal_progress, under_rule
from .tasks.schema import Task
from .world.bullet import bullet_client, pybullet, quiet_stdout
from .world.rooms import all_scenes, room_layout, scene_number
from .world.camera import FAR, FOV_DEG, HORIZON_MAX, HORIZON_MIN, NEAR
from .world.scene import World

DEFAULT_RESOLUTION = BODY.resolution   # see docs/figures.md: 4x the frame rate of 300x300 on this CPU
# pybullet 3.2.7 keeps about 0.5 KB for every body made and removed (0.14 MB per reset here) and
# frees it only with its client, so the world moves to a fresh client every so many rooms. A fresh
# client hands out the same body ids, so frames and segmentation do not change (tested).
CLIENT_RECYCLE_BUILDS = 200


def parse_step_action(action, resolution: int) -> tuple[Action, tuple[int, int]]:
    """What `DialfredEnv.step` takes, as (the action, its target pixel): an action name, or a dict with an
    'action' key and, for an interaction, a 'pixel' of two integers inside the resolution x resolution
    frame ((-1, -1) for any other action). ValueError saying what is wrong otherwise."""
    pixel: Any = (-1, -1)
    if isinstance(action, dict):
        if 'action' not in action:
            raise ValueError("action dict needs an 'action' key")
        name, pixel = action['action'], action.get('pixel', (-1, -1))
    else:
        name = action
    act = parse_action(name)
    if act.is_interaction:
        # Exactly two integers: a float, a digit string or a bool is a caller's bug, not a pixel.
        values = list(pixel) if isinstance(pixel, (tuple, list, np.ndarray)) else None
        if values is None or len(values) != 2 or not all(_is_integer(v) for v in values):
            raise ValueError(f'{act.name} needs a target pixel (x, y) of two integers, got {pixel!r}')
        px, py = int(values[0]), int(values[1])
        if not (0 <= px < resolution and 0 <= py < resolution):
            raise ValueError(f'pixel ({px}, {py}) is outside the {resolution}x{resolution} frame')
        return act, (px, py)
    return act, (-1, -1)


class DialfredEnv(gym.Env):
    """A household room, an agent with ALFRED's actions, and ground truth for tasks and the oracle.

    Args:
        resolution: frame width and height in pixels.
        scene: floor plan to use ('FloorPlan7'); None draws one of the 120 from the reset seed.
        max_steps, max_failures: episode limits.
        dirty_probability: chance that a cleanable object starts dirty.
        goal_rule: how a task's go-to is judged (tasks.goals.GOAL_RULES): 'dialfred', within 4 actions
            of the expert's end pose (DialFRED's rule, the default), or 'visible', the target in view
            and within reach.
    """

    metadata = {'render_modes': ['rgb_array'], 'render_fps': 5}

    def __init__(self, resolution: int = DEFAULT_RESOLUTION, scene: Optional[str] = None,
                 max_steps: int = MAX_STEPS, max_failures: int = MAX_FAILURES, dirty_probability: float = 0.25,
                 render_mode: Optional[str] = 'rgb_array', goal_rule: str = DEFAULT_GOAL_RULE):
        if not _is_integer(resolution) or not 16 <= resolution <= 1024:
            raise ValueError(f'resolution must be an integer in 16-1024, got {resolution!r}')
        if scene is not None:
            scene_number(scene)   # raises ValueError for an unknown scene
        _check_count('max_steps', max_steps)
        _check_count('max_failures', max_failures)
        _check_probability('dirty_probability', dirty_probability)
        self.goal_rule = check_goal_rule(goal_rule)
        self.resolution = int(resolution)
        self.scene = scene
        self.max_steps, self.max_failures = int(max_steps), int(max_failures)
        self.dirty_probability = float(dirty_probability)
        self.render_mode = render_mode
        self.client, self.world = None, None
        self._builds = 0
        self._connect()
        r = self.resolution
        self.observation_space = spaces.Dict({
            'rgb': spaces.Box(0, 255, (r, r, 3), np.uint8),
            'depth': spaces.Box(0.0, FAR, (r, r), np.float32),
            'segmentation': spaces.Box(-1, 2 ** 24, (r, r), np.int32),
            'pose': spaces.Box(np.array([0.0, 0.0, 0.0, HORIZON_MIN], np.float32),
                               np.array([20.0, 20.0, 360.0, HORIZON_MAX], np.float32), dtype=np.float32),
        })
        self.action_space = spaces.Dict({'action': spaces.Discrete(len(Action)),
                                         'pixel': spaces.MultiDiscrete([r, r])})
        self._frame: Optional[tuple[np.ndarray, np.ndarray, np.ndarray]] = None
        self.steps = 0
        self.failures = 0
        self.done = True
        self.last_result = ActionResult(True)
        self.task = None                  # the DialFRED task being played, if any
        self.goal_met: list[bool] = []             # per goal condition of the task: holds now
        self.goal_met_at_start: list[bool] = []    # ... held when the task started (GC leaves those out)
        self.protocol = DEFAULT_PROTOCOL  # how the task is played (protocol.PROTOCOLS): 'chained' goes on past success
        self.held_at_start = False        # the whole goal held when a chained task began: it cannot succeed

    # ------------------------------------------------------------------ Gymnasium API

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict[str, Any]] = None):
        """Start an episode. options: {'scene': 'FloorPlanN'} picks the floor plan and
        {'dirty_probability': p} overrides the constructor's; {'task_id': 'valid_unseen/000012'} (or
        {'task': Task}) starts that DialFRED task (the seed is then the task's, and no other option
        may be given but 'protocol'). With a task, {'protocol': 'chained'} plays it under the chained
        protocol: success does not end it (only Stop and the failure and step limits do), and the
        episode's later tasks follow with `continue_task`. Bad options raise TypeError (wrong type) or
        ValueError (unknown key, scene or task, a value out of range) and change nothing. A task whose start state the world refuses
        to rebuild (its split made under older rules) raises ValueError after the room was rebuilt:
        the env then needs a new reset."""
        options = _check_options(options)     # TypeError / ValueError before anything changes
        if 'task' in options:
            return self._reset_to_task(options['task'], options.get('protocol', DEFAULT_PROTOCOL))
        super().reset(seed=seed)
        self.task, self.goal_met, self.goal_met_at_start = None, [], []
        self.protocol, self.held_at_start = DEFAULT_PROTOCOL, False
        scene = options.get('scene') or self.scene
        if scene is None:
            scenes = all_scenes()
            scene = scenes[int(self.np_random.integers(len(scenes)))]
        self._build(room_layout(scene), options.get('dirty_probability', self.dirty_probability))
        self.steps, self.failures, self.done = 0, 0, False
        self.last_result = ActionResult(True)
        self._frame = self.world.render()
        return self._observation(), self._info()

    def step(self, action):
        """Act. `action`: {'action': index or name, 'pixel': (x, y)}, or an index / name alone.

        Raises ValueError for a malformed action (nothing changes) and RuntimeError after the episode
        ended or before reset.
        """
        if self._frame is None:
            raise RuntimeError('step() before reset()')
        if self.done:
            raise RuntimeError('the episode is over; call reset()')
        act, pixel = parse_step_action(action, self.resolution)
        _, depth, seg = self._frame
        result = execute(self.world, act, pixel, depth, seg)
        self.steps += 1
        self.last_result = result
        if not result.success:
            self.failures += 1
        self._frame = self.world.render()
        success = self._check_goal()
        ends = success and self.protocol == 'expert'     # a chained task is judged when it stops, never told
        terminated = ends or act == Action.Stop or self.failures >= self.max_failures
        truncated = not terminated and self.steps >= self.max_steps
        self.done = terminated or truncated
        return self._observation(), float(success), terminated, truncated, self._info()

    def continue_task(self, task):
        """Start `task`, the next task of the chained episode being played, in the world as the agent's
        actions left it (the chained protocol): its goal is checked now, the step and failure counts
        start again, and the observation's `last_action_success` is still the last action's. A task
        whose whole goal holds already is played but cannot succeed (`held_at_start`). Returns
        (observation, info) as reset does.

        ValueError (nothing changes) unless the env holds a chained episode (reset with {'task': ...,
        'protocol': 'chained'}) and `task` is of the same episode."""
        if self.protocol != 'chained' or self.task is None or self._frame is None:
            raise ValueError('continue_task() goes on from a chained task: reset(options={"task": ..., '
                             '"protocol": "chained"}) first')
        if not isinstance(task, Task):
            raise TypeError(f'task must be a dialfred_sim.tasks.Task, got {type(task).__name__}')
        if task.episode.episode_id != self.task.episode.episode_id or task.split != self.task.split:
            raise ValueError(f'task {task.task_id} is of episode {task.split}/{task.episode.episode_id}; this env '
                             f'plays {self.task.split}/{self.task.episode.episode_id}')
        self.task = under_rule(task, self.goal_rule)
        self.steps, self.failures, self.done = 0, 0, False
        # The same pixels, drawn again: a new frame is a new state to whoever caches the ground truth by
        # frame (ground_truth.GroundTruthCache: the simulator node's, whose answer key follows the task).
        self._frame = self.world.render()
        self._start_goal()
        return self._observation(), self._info()

    def _start_goal(self) -> None:
        """The task's goal as it starts: what holds (GC leaves it out), and whether all of it does."""
        self._check_goal()
        self.goal_met_at_start = list(self.goal_met)
        # Only a chained task can start with its goal met: the expert protocol's tasks are cut where something
        # is left to do (and are judged as they always were).
        self.held_at_start = self.protocol == 'chained' and bool(self.goal_met) and all(self.goal_met)

    def _reset_to_task(self, task, protocol: str = DEFAULT_PROTOCOL):
        """Rebuild the world as the expert left it at the task's first action (see tasks.generator)."""
        task = under_rule(task, self.goal_rule)    # its goal and expert length as this env judges them
        episode = task.episode
        super().reset(seed=episode.seed)
        self._build(room_layout(episode.scene), self.dirty_probability)
        apply_setup(self.world, episode.setup)
        try:
            replay(self.world, episode.actions[:task.start])
        except RuntimeError as exc:
            # The task's split was made under other rules (before a physics change): its start state
            # cannot be rebuilt. The room is half built, so the env needs a new reset.
            self.task, self.goal_met, self.goal_met_at_start = None, [], []
            self._frame, self.done = None, True
            raise ValueError(f'task {task.task_id} cannot be set up in this simulator: {exc}; its split '
                             'predates the simulator\'s rules and must be regenerated') from None
        a = self.world.agent
        a.i, a.j, a.rotation, a.horizon = task.start_pose
        self.world.update_held_pose()
        self.steps, self.failures, self.done = 0, 0, False
        self.last_result = ActionResult(True)
        self.task, self.protocol = task, protocol
        self._frame = self.world.render()
        self._start_goal()
        return self._observation(), self._info()

    def _check_goal(self) -> bool:
        """Update which goal conditions of the task hold; True when all do."""
        if self.task is None:
            return False
        self.goal_met = conditions_met(self.world, self.task.goal, self._frame)
        return all(self.goal_met)

    def teleport(self, i: int, j: int, rotation: int, horizon: float):
        """Put the agent on grid point (i, j) facing `rotation` degrees with camera pitch `horizon`.

        For experts, tests and tools (not an agent action; it does not count as a step). ValueError
        if the point is not free floor (furniture, walls, an open door) or the pose is off the action
        grid or leaves no room for the object in hand. Returns the observation.
        """
        if self._frame is None:
            raise RuntimeError('teleport() before reset()')
        if (i, j) not in self.world.layout.navigable:
            raise ValueError(f'grid point ({i}, {j}) is not free floor in {self.world.layout.scene}')
        if rotation % 90 or not HORIZON_MIN <= horizon <= HORIZON_MAX or horizon % 15:
            raise ValueError(f'rotation must be a multiple of 90 and horizon a multiple of 15 in '
                             f'[{HORIZON_MIN:g}, {HORIZON_MAX:g}], got {rotation}, {horizon}')
        door = self.world.open_blocker(i, j)
        if door is not None:
            raise ValueError(f'grid point ({i}, {j}) is taken by the open {door}')
        if self.world.held is not None:
            spot, hit = self.world.carry_spot(self.world.objects[self.world.held], i, j, int(rotation) % 360)
            if spot is None:
                raise ValueError(f'no room at ({i}, {j}, {rotation}) for the {self.world.held} in hand: '
                                 f'it would pass into {hit}')
        a = self.world.agent
        a.i, a.j, a.rotation, a.horizon = int(i), int(j), int(rotation) % 360, float(horizon)
        self.world.update_held_pose()
        self._frame = self.world.render()
        return self._observation()

    @contextlib.contextmanager
    def viewed_at(self, resolution: int):
        """For the `with` block, the env as a DialfredEnv of `resolution` would be in this same state:
        its frame (colour, depth, segmentation), `resolution` and the world's image size are those of
        that resolution; all restored after the block. Nothing in the world moves. For a tool that wants
        one look at another resolution without a second reset (the synthetic annotators see 128 px
        while the demonstrations are rendered at 64: dialfred_performer.data.AnnotatingProbe).
        Close-ups (ground_truth.closeup_pixels) are rendered at a fixed size, so their cache holds."""
        if self._frame is None:
            raise RuntimeError('viewed_at() before reset()')
        if not _is_integer(resolution) or not 16 <= resolution <= 1024:
            raise ValueError(f'resolution must be an integer in 16-1024, got {resolution!r}')
        world = self.world
        saved = (self.resolution, world.width, world.height, world.projection, self._frame)
        try:
            self.resolution = world.width = world.height = int(resolution)
            world.projection = self.client.computeProjectionMatrixFOV(FOV_DEG, 1.0, NEAR, FAR)
            self._frame = world.render()
            yield self
        finally:
            self.resolution, world.width, world.height, world.projection, self._frame = saved

    def pixel_of(self, object_id: str):
        """A pixel (x, y) of `object_id` in the current frame (the one nearest its mask's centre), or None."""
        obj = self.world.objects.get(object_id)
        if obj is None or self._frame is None:
            return None
        ys, xs = np.nonzero(self._frame[2] == obj.body)
        if len(xs) == 0:
            return None
        k = int(np.argmin((xs - xs.mean()) ** 2 + (ys - ys.mean()) ** 2))
        return int(xs[k]), int(ys[k])

    def render(self):
        return None if self._frame is None else self._frame[0]

    def frames(self) -> Optional[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """The current frame's colour (HxWx3 uint8), depth (HxW float32 metres) and segmentation (HxW int32
        body ids, -1 where none), or None before reset(). For privileged tools that read the simulator's
        own labels (the ground truth, benchmarks/map_perception_ceiling.py): the graph and the local path give agents RGB only."""
        return self._frame

    def _connect(self) -> None:
        """A new pybullet client (DIRECT, this env's own) and an empty world on it."""
        with quiet_stdout():
            self.client = bullet_client.BulletClient(connection_mode=pybullet.DIRECT)
        self.world = World(self.client, self.resolution, self.resolution)

    def _build(self, layout, dirty_probability: float) -> None:
        if self._builds and self._builds % CLIENT_RECYCLE_BUILDS == 0:
            self.close()
            self._connect()
        self._builds += 1
        self.world.build(layout, self.np_random, dirty_probability)

    def close(self):
        if self.client is not None:
            try:
                self.client.disconnect()
            except pybullet.error:
                pass
            self.client = None

    # ------------------------------------------------------------------ helpers

    def _observation(self) -> dict[str, np.ndarray]:
        rgb, depth, seg = self._frame
        a = self.world.agent
        pose = np.array([a.x, a.y, a.rotation, a.horizon], np.float32)
        return {'rgb': rgb, 'depth': depth, 'segmentation': seg, 'pose': pose}

    def _info(self) -> dict[str, Any]:
        ids, names = self.world.instance_table()
        achieved, to_achieve = goal_progress(self.goal_met, self.goal_met_at_start)
        return {
            'scene': self.world.layout.scene,
            'room_type': self.world.layout.room_type,
            'held_object': self.world.held or '',
            'last_action_success': self.last_result.success,
            'last_action_error': self.last_result.error,
            'last_action_target': self.last_result.target or '',
            'step_count': self.steps,
            'failed_actions': self.failures,
            'instances': (ids, names),
            'task_id': self.task.task_id if self.task is not None else '',
            'success': bool(self.goal_met) and all(self.goal_met) and not self.held_at_start,
            'held_at_start': self.held_at_start,
            # GC counts only the conditions that did not hold when the task started (tasks.goals)
            'goal_conditions_met': achieved,
            'goal_conditions_total': to_achieve,
        }


# ---------------------------------------------------------------------- argument checks

RESET_OPTIONS = ('scene', 'task_id', 'task', 'dirty_probability', 'protocol')


def _is_integer(value) -> bool:
    """A Python or numpy integer, and not a bool (True is an int to Python, never a count or a pixel)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _check_count(name: str, value) -> None:
    if not _is_integer(value):
        raise TypeError(f'{name} must be an integer, got {value!r} ({type(value).__name__})')
    if value < 1:
        raise ValueError(f'{name} must be at least 1, got {value!r}')


def _check_probability(name: str, value) -> None:
    if not isinstance(value, (int, float, np.integer, np.floating)) or isinstance(value, bool):
        raise TypeError(f'{name} must be a number, got {value!r} ({type(value).__name__})')
    if not 0.0 <= value <= 1.0:     # also refuses nan
        raise ValueError(f'{name} must be in [0, 1], got {value!r}')


def _check_options(options) -> dict:
    """reset()'s options, checked; a task is resolved to its Task under 'task'. Changes nothing."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise TypeError(f'options must be a dict, got {options!r} ({type(options).__name__})')
    unknown = sorted(map(repr, set(options) - set(RESET_OPTIONS)))
    if unknown:
        raise ValueError(f'unknown reset option(s) {", ".join(unknown)}: expected {", ".join(RESET_OPTIONS)}')
    checked = dict(options)
    if 'protocol' in options:
        if options['protocol'] not in PROTOCOLS:
            raise ValueError(f"unknown protocol {options['protocol']!r}: expected one of {', '.join(PROTOCOLS)}")
        if 'task_id' not in options and 'task' not in options:
            raise ValueError("a protocol is how a task is played: give it with 'task_id' or 'task'")
    if 'task_id' in options or 'task' in options:
        others = sorted(set(options) - {'task_id', 'task', 'protocol'})
        if others or ('task_id' in options and 'task' in options):
            raise ValueError(f"a task sets its own room and state: give 'task_id' or 'task' alone, got "
                             f"{sorted(options)}")
        if 'task_id' in options:
            task_id = checked.pop('task_id')
            if not isinstance(task_id, str):
                raise TypeError(f"task_id must be a string such as 'valid_unseen/000012', got {task_id!r} "
                                f'({type(task_id).__name__})')
            if not task_id:
                raise ValueError("task_id must name a task such as 'valid_unseen/000012', got '' "
                                 "(leave it out for free exploration)")
            checked['task'] = get_task(task_id)     # ValueError for an unknown id
        elif not isinstance(options['task'], Task):
            raise TypeError(f"task must be a dialfred_sim.tasks.Task, got {options['task']!r:.80} "
                            f"({type(options['task']).__name__})")
        return checked
    if 'scene' in options:
        scene = options['scene']
        if not isinstance(scene, str):
            raise TypeError(f"scene must be a string such as 'FloorPlan7', got {scene!r} ({type(scene).__name__})")
        scene_number(scene)      # ValueError for an unknown scene
    if 'dirty_probability' in options:
        _check_probability('dirty_probability', options['dirty_probability'])
    return checked


__all__ = ['DialfredEnv', 'ACTION_NAMES', 'DEFAULT_RESOLUTION']
