"""Episode and task generation: ALFRED-style jobs played by the expert, cut into DialFRED tasks.

An episode picks one of ALFRED's 7 job types (`jobs`) that suits the room (with a slicing prefix sometimes),
its objects and receptacles, makes the job possible (dirty objects for cleaning, lamps off for
look-at, a same-class distractor of another colour often), and lets the expert play it. The
expert's primitives are then partitioned into consecutive DialFRED tasks: at each point one of
the task types that fits is drawn (`types`: the paper's 25 and any registered), and kept only if
its goal does not already hold there. The jobs are `jobs.Job` objects, the types `types.TaskType`
objects; neither is branched on by name here.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from ..world.scene import World
from .expert import Expert, ExpertFailed, replay
from .goals import conditions_met, goal_for, min_pixels, needs_frame, rule_goal
from .instructions import StepPhrase
from .jobs import plan_job, room_jobs
from .schema import Episode, Primitive, Task
from .types import TaskType, task_types

# ---------------------------------------------------------------------- set-up

def apply_setup(world: World, setup: dict) -> None:
    """Make a job possible in a freshly built world: dirty objects, lamps off, distractors."""
    for oid in setup.get('dirty', ()):
        world.objects[oid].is_dirty = True
    for oid in setup.get('off', ()):
        world.objects[oid].is_on = False
    for oid in setup.get('open', ()):
        world.set_open(world.objects[oid], True)
    rng = np.random.default_rng(setup.get('place_seed', 0))
    for type_name, colour, receptacle in setup.get('distractors', ()):
        obj = world.spawn(type_name, colour)
        if not world.place(obj, world.objects[receptacle], rng=rng):
            world.remove(obj.object_id)


# ---------------------------------------------------------------------- episodes

def generate_episode(env, split: str, index: int, scene: str, seed: int) -> Optional[Episode]:
    """Play one job in `scene` with the expert; None if no job fits or the expert fails."""
    rng = np.random.default_rng(seed)
    env.reset(seed=seed, options={'scene': scene})
    world = env.world
    weights = room_jobs(world.layout.room_type)
    jobs = sorted(weights)
    p = np.array([weights[j] for j in jobs])
    job = jobs[int(rng.choice(len(jobs), p=p / p.sum()))]
    setup: dict = {}
    params, play = plan_job(world, job, rng, setup)
    if play is None:
        return None
    apply_setup(world, setup)
    expert = Expert(world)
    try:
        play(expert)
    except ExpertFailed:
        return None
    expert.finish()
    return Episode(f'{split}/ep{index:06d}', split, scene, seed, job, setup, expert.actions, expert.primitives,
                   expert.poses, world.width)


def rebuild(env, episode: Episode, upto: int) -> None:
    """Put `env` in the state the expert of `episode` was in before action `upto`."""
    env.reset(seed=episode.seed, options={'scene': episode.scene})
    world = env.world
    apply_setup(world, episode.setup)
    replay(world, episode.actions[:upto])
    i, j, rot, horizon = episode.poses[upto]
    world.agent.i, world.agent.j, world.agent.rotation, world.agent.horizon = i, j, rot, horizon
    world.update_held_pose()


# ---------------------------------------------------------------------- cutting episodes into tasks

def _phrases(prims: list[Primitive], world_nouns: dict[str, str], prepositions: dict[str, str]) -> list[StepPhrase]:
    out = []
    for p in prims:
        if p.kind == 'put':
            out.append(StepPhrase('put', world_nouns[p.target], world_nouns[p.receptacle], prepositions[p.receptacle]))
        else:
            out.append(StepPhrase(p.kind, world_nouns[p.target]))
    return out


def _fits(kind: TaskType, prims: list[Primitive], world: World) -> bool:
    """Whether `prims`, from where the cut stands, are a task of `kind`: its step kinds, about the
    objects it says."""
    if tuple(p.kind for p in prims) != kind.steps:
        return False

    def type_of(oid: str) -> str:
        o = world.objects.get(oid)
        return o.type_name if o is not None else ''
    return kind.fits(prims, type_of)


def cut_tasks(env, episode: Episode, rng: np.random.Generator, first_index: int, limit: int) -> list[Task]:
    """Partition the episode's primitives into tasks of the registered types (`types.task_types()`),
    checking each goal on the way."""
    rebuild(env, episode, 0)
    world = env.world
    nouns = {oid: o.otype.noun for oid, o in world.objects.items()}
    types = {oid: o.type_name for oid, o in world.objects.items()}
    preps = {oid: o.otype.preposition for oid, o in world.objects.items()}
    prims = episode.primitives
    kinds = task_types()
    tasks: list[Task] = []
    k, done = 0, 0          # next primitive, expert actions applied so far
    while k < len(prims) and len(tasks) < limit:
        options = [kind for kind in kinds if _fits(kind, prims[k:k + len(kind.steps)], world)]
        weights = np.array([kind.weight for kind in options])
        order = rng.choice(len(options), size=len(options), replace=False, p=weights / weights.sum())
        start = prims[k].start
        replay(world, episode.actions[done:start])
        done = start
        _set_pose(world, episode.poses[start])
        frame = world.render()
        chosen = None
        for idx in order:
            kind = options[int(idx)]
            name, chunk = kind.name, prims[k:k + len(kind.steps)]
            for oid in (q for p in chunk for q in (p.target, p.receptacle) if q):
                nouns.setdefault(oid, world.objects[oid].otype.noun if oid in world.objects else oid)
                types.setdefault(oid, world.objects[oid].type_name if oid in world.objects else '')
                preps.setdefault(oid, world.objects[oid].otype.preposition if oid in world.objects else 'on')
            goal = goal_for(name, chunk, types, episode.poses)
            if not all(conditions_met(world, goal, frame)):   # a task must have something left to do
                chosen = (kind, chunk, goal)
                break
        if chosen is None:          # every pattern here is already done: skip this primitive
            k += 1
            continue
        kind, chunk, goal = chosen
        name = kind.name
        # What the task's first object action is about, as the task starts.
        first = next((p for p in chunk if p.kind != 'goto'), chunk[0])
        focus = first.receptacle or first.target
        focus_obj = world.objects.get(focus)
        visible = focus_obj is not None and int((frame[2] == focus_obj.body).sum()) >= min_pixels(frame[2].shape)
        distractor = focus_obj is not None and any(
            o.type_name == focus_obj.type_name and o.object_id != focus for o in world.objects.values())
        end, visible_end = chunk[-1].end, None
        if any(c.kind == 'near' for c in goal):
            # The goal can hold before the expert's path ends (DialFRED's go-to is done 4 actions
            # before the expert's end pose; the target can come into view early): L* (for PWSR) is
            # the first moment the goal holds, under each goal rule.
            end, visible_end = _first_met(world, episode, start, chunk[-1].end,
                                          [goal, rule_goal(name, goal, 'visible')])
            done = chunk[-1].end
            if end is None:
                raise RuntimeError(f'{episode.episode_id}: the expert never meets the goal of its {name} task')
            if visible_end is None:
                # The target never showed enough on the expert's path (the object in hand hid it): the
                # 'visible' rule judges the task over the whole path, and the expert fails it there.
                visible_end = chunk[-1].end
            visible_end = None if visible_end == end else visible_end     # stored only where it differs
        step_by_step, main = kind.instructions(_phrases(chunk, nouns, preps), rng)
        object_nouns = list(dict.fromkeys(nouns[q] for p in chunk for q in (p.target, p.receptacle) if q))
        task = Task(f'{episode.split}/{first_index + len(tasks):06d}', name, episode, start, end, goal,
                    main, step_by_step, object_nouns, list(chunk), visible, distractor, visible_end)
        tasks.append(task)
        k += len(chunk)
    return tasks


def _first_met(world: World, episode: Episode, start: int, stop: int, goals: list) -> list[Optional[int]]:
    """Replay the expert's actions [start, stop) on `world` one by one; per goal of `goals`, one past
    the action after which it first holds (None if it never does)."""
    found: list[Optional[int]] = [None] * len(goals)
    for idx in range(start, stop):
        replay(world, episode.actions[idx:idx + 1])
        frame = None
        for g, goal in enumerate(goals):
            if found[g] is None:
                if frame is None and needs_frame(goal):
                    frame = world.render()
                if all(conditions_met(world, goal, frame)):
                    found[g] = idx + 1
    return found


def _set_pose(world: World, pose) -> None:
    i, j, rot, horizon = pose
    world.agent.i, world.agent.j, world.agent.rotation, world.agent.horizon = i, j, rot, horizon
    world.update_held_pose()
