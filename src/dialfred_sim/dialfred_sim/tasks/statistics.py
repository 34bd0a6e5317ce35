"""How the world and a split compare with AI2-THOR's and ALFRED's (no ROS): the figures of
`./dialfred bench world_statistics` and of the dataset card's table.

Per room type, over all 30 floor plans of the type: free 0.25 m grid points (`navigable_points`),
receptacle fixtures (`receptacles`: furniture and appliances that hold things, as ALFRED's
FloorPlan*-openable.json lists them) and openable fixtures (`openable_fixtures`: cabinets, drawers,
fridges, microwaves, safes); and over a split's episodes in rooms of the type, the small (pickupable)
objects in the room when an episode starts (`small_objects`, after its set-up).

Per split, from the expert's episodes: the actions of a go-to (`goto_actions`, of which `goto_moves`,
`goto_turns`, `goto_looks`), the expert's actions before its first interaction
(`actions_before_first_interaction`), and of the first object the expert picks up (else acts on):
the share with a second instance of its type in the room (`first_target_multi_instance`), the share
inside a closed receptacle (`first_target_in_closed`), and its floor distance from the agent's start
(`first_target_distance_m`); and of the tasks, the share whose first object shows in the first frame
(`target_visible_at_task_start`).

`REFERENCE` holds AI2-THOR's values, measured from ALFRED's own files: gen/layouts/FloorPlan*-
{layout.npy, objects.json, openable.json} of all 120 floor plans, and the expert trajectories
(`traj_data.json`) of ALFRED 2.1.0's 255 valid_unseen episodes (docs/dataset.md gives each source).
"""

from __future__ import annotations

import math
from collections import defaultdict

from ..actions import Action
from ..env import DialfredEnv
from ..catalog import load_catalog
from ..world.rooms import GRID, SCENE_RANGES, room_layout
from .generator import rebuild

# AI2-THOR / ALFRED, measured from ALFRED's files (see the docstring and docs/dataset.md).
REFERENCE = {
    'rooms': {
        'navigable_points': {'kitchen': 110, 'living_room': 216, 'bedroom': 107, 'bathroom': 55},
        'receptacles': {'kitchen': 23.1, 'living_room': 13.9, 'bedroom': 12.5, 'bathroom': 8.9},
        'openable_fixtures': {'kitchen': 18.2, 'living_room': 4.4, 'bedroom': 5.9, 'bathroom': 4.0},
        'small_objects': {'kitchen': 47.5, 'living_room': 22.1, 'bedroom': 25.0, 'bathroom': 17.5},
    },
    'split': {
        'goto_actions': 13.5, 'goto_moves': 9.0, 'goto_turns': 2.6, 'goto_looks': 1.85,
        'actions_before_first_interaction': 17.8, 'first_target_multi_instance': 0.635,
        'first_target_in_closed': 0.110, 'first_target_distance_m': 2.67, 'small_objects': 38.4,
    },
}
OPENABLE_FIXTURES = ('Cabinet', 'Drawer', 'Fridge', 'Microwave', 'Safe')
MOVES = {'MoveAhead'}
TURNS = {'RotateLeft', 'RotateRight'}
LOOKS = {'LookUp', 'LookDown'}


def with_reference(value: float, reference) -> dict:
    out = {'value': round(value, 3)}
    if reference is not None:
        out['reference'] = reference
        out['ratio'] = round(value / reference, 3) if reference else None
    return out


def is_listed_receptacle(fixture, catalog) -> bool:
    """Whether ALFRED's openable.json would list `fixture` as a receptacle: a receptacle type with a
    surface to put things on (not a counter's rim around a sink), and a bathtub once, by its basin
    (ALFRED's `Bathtub|...|BathtubBasin`)."""
    return catalog[fixture.type_name].receptacle and bool(fixture.spec.surfaces) and fixture.type_name != 'Bathtub'


def room_statistics() -> dict:
    """Per room type, the means over its 30 floor plans of the layout's fixed figures."""
    catalog = load_catalog()
    out = {}
    for room, numbers in SCENE_RANGES.items():
        counts = defaultdict(list)
        for n in numbers:
            layout = room_layout(f'FloorPlan{n}')
            counts['navigable_points'].append(len(layout.navigable))
            counts['receptacles'].append(sum(is_listed_receptacle(f, catalog) for f in layout.fixtures))
            counts['openable_fixtures'].append(sum(f.type_name in OPENABLE_FIXTURES for f in layout.fixtures))
        out[room] = {k: sum(v) / len(v) for k, v in counts.items()}
    return out


def episode_statistics(episodes: list, env) -> tuple[dict, dict]:
    """(per room type {small_objects}, per split figures) of the expert's `episodes`."""
    small = defaultdict(list)
    gotos, before, multi, closed, distance = [], [], [], [], []
    for episode in episodes:
        rebuild(env, episode, 0)
        world = env.world
        small[world.layout.room_type].append(sum(1 for o in world.objects.values()
                                                 if not o.fixture and o.otype.pickupable))
        for p in episode.primitives:
            if p.kind == 'goto':
                names = [a.action for a in episode.actions[p.start:p.end]]
                gotos.append((len(names), sum(n in MOVES for n in names), sum(n in TURNS for n in names),
                              sum(n in LOOKS for n in names)))
        first = next((k for k, a in enumerate(episode.actions) if Action[a.action].is_interaction), None)
        if first is not None:
            before.append(first)
        target = next((p.target for p in episode.primitives if p.kind == 'pickup'), None) or \
            next((p.target for p in episode.primitives if p.kind != 'goto'), None)
        obj = world.objects.get(target) if target else None
        if obj is not None:
            multi.append(sum(o.type_name == obj.type_name for o in world.objects.values()) >= 2)
            closed.append(world.enclosed_by_closed(obj) is not None)
            i, j = episode.poses[0][:2]
            distance.append(math.hypot(obj.position[0] - i * GRID, obj.position[1] - j * GRID))

    def mean(values) -> float:
        return sum(values) / len(values) if values else float('nan')
    split = {
        'goto_actions': mean([g[0] for g in gotos]), 'goto_moves': mean([g[1] for g in gotos]),
        'goto_turns': mean([g[2] for g in gotos]), 'goto_looks': mean([g[3] for g in gotos]),
        'actions_before_first_interaction': mean(before), 'first_target_multi_instance': mean(multi),
        'first_target_in_closed': mean(closed), 'first_target_distance_m': mean(distance),
        'small_objects': mean([n for v in small.values() for n in v]),
        'gotos': len(gotos),
    }
    return {room: {'small_objects': mean(v), 'episodes': len(v)} for room, v in small.items()}, split




def world_statistics(tasks: list, episodes_limit=None) -> dict:
    """The figures of `tasks` (Task objects of one split) and their episodes (the first
    `episodes_limit` of them, if given), each with AI2-THOR's value and the ratio where it has one."""
    episodes = list({t.episode.episode_id: t.episode for t in tasks}.values())
    if episodes_limit is not None:
        episodes = episodes[:episodes_limit]
        kept = {e.episode_id for e in episodes}
        tasks = [t for t in tasks if t.episode.episode_id in kept]
    rooms = room_statistics()
    env = DialfredEnv(resolution=tasks[0].resolution)
    try:
        small, split = episode_statistics(episodes, env)
    finally:
        env.close()
    split['target_visible_at_task_start'] = sum(t.target_visible_at_start for t in tasks) / len(tasks)
    ref_rooms, ref_split = REFERENCE['rooms'], REFERENCE['split']
    return {
        'episodes': len(episodes), 'tasks': len(tasks),
        'rooms': {room: {**{k: with_reference(v, ref_rooms[k].get(room)) for k, v in figures.items()},
                         'small_objects': with_reference(small.get(room, {}).get('small_objects', float('nan')),
                                                         ref_rooms['small_objects'].get(room)),
                         'episodes': small.get(room, {}).get('episodes', 0)}
                  for room, figures in rooms.items()},
        'per_split': {k: (with_reference(v, ref_split.get(k)) if k != 'gotos' else v) for k, v in split.items()},
    }
