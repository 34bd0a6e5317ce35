"""ALFRED's job types as objects, in a registry: each job owns the rooms it happens in, the objects it
needs, and how the expert plays it.

An episode (`generator.generate_episode`) draws one of the jobs registered for its room's type, by
`Job.rooms` weight; `plan_job` chooses the job's objects and returns what plays it. A job fetches its
object (or slices it first and takes a slice), does what is its own between fetching and delivering
(`Job.carry`: the sink, the microwave, a lamp, a movable receptacle), delivers it where it ends up,
and ends (`Job.finish`). Adding a job is a `Job` subclass and one `register(...)` call; `generator`
never branches on a job's name.
"""

from __future__ import annotations

from typing import Mapping, Optional

import numpy as np

from ..catalog import load_catalog
from ..registry import Registry
from ..world.objects import WorldObject
from ..world.scene import World
from .expert import Expert, ExpertFailed

# ALFRED's rooms and how often each job is drawn in them are the jobs' own (`Job.rooms`).
SLICE_PREFIX_P = 0.5           # jobs on a sliceable object start by slicing it (ALFRED's object_sliced)
FAVOURED_P = 0.4               # chance a job takes sliceable food (kitchens) or a laptop when there is one
# Add a same-class object of another colour when the room has none, this often: with the scatter's own
# copies, the share of first targets with a second instance comes near ALFRED's (63.5%, docs/dataset.md)
# on train's first 3,000 tasks (./dialfred bench world_statistics --file PATH).
DISTRACTOR_P = 0.25
LAMPS = ('DeskLamp', 'FloorLamp')


# ---------------------------------------------------------------------- the expert's moves

def _small(world: World, pred) -> list:
    return sorted((o for o in world.objects.values() if not o.fixture and pred(o)), key=lambda o: o.object_id)


def _receptacles(world: World, type_names, exclude=()) -> list:
    out = [o for o in world.objects.values() if o.type_name in type_names and o.spec.surfaces
           and o.object_id not in exclude and world.enclosed_by_closed(o) is None]
    return sorted(out, key=lambda o: o.object_id)


def _has_room(world: World, obj, receptacle) -> bool:
    return any(world.free_spots(receptacle, obj, k) for k in range(len(receptacle.spec.surfaces)))


def _pick(rng: np.random.Generator, items: list):
    return items[int(rng.integers(len(items)))] if items else None


def _landmark(world: World, oid: str) -> str:
    """What an instruction names when going to `oid`: its closed container, else the fixture it rests on."""
    obj = world.objects[oid]
    closed = world.enclosed_by_closed(obj)
    if closed is not None:
        return closed.object_id
    for r in world.container_chain(obj):
        if r.fixture:
            return r.object_id
    return oid


def _role_objects(world: World, role: str) -> list:
    return _small(world, lambda o: o.otype.pickupable and o.otype.task_roles.get(role, 0) > 0
                  and not o.otype.parent_type)


class ExpertPlan:
    """The expert's moves that ALFRED's jobs are written in: fetch an object, deliver it, slice it first,
    and the clean / heat / cool expansions."""

    def __init__(self, world: World, expert: Expert, rng: np.random.Generator):
        self.world, self.expert, self.rng = world, expert, rng

    def fetch(self, oid: str) -> None:
        w, e = self.world, self.expert
        obj = w.objects[oid]
        closed = w.enclosed_by_closed(obj)
        landmark = _landmark(w, oid)
        if closed is not None:
            e.goto(landmark, [closed.object_id], inside=[oid])
            e.act('open', closed.object_id)
            e.act('pickup', oid)
            e.act('close', closed.object_id)
        else:
            try:
                e.goto(landmark, [oid, landmark])
            except ExpertFailed:     # the landmark is out of reach from wherever the object is
                e.goto(oid, [oid])
            if obj.otype.openable and obj.is_open:
                e.act('close', oid)  # ALFRED closes a laptop before picking it up
            e.act('pickup', oid)

    def deliver(self, oid: str, rid: str, walk: bool = True) -> None:
        w, e = self.world, self.expert
        if walk:
            e.goto(rid, [rid], put=oid)
        r = w.objects[rid]
        if r.otype.openable and not r.is_open:
            e.act('open', rid)
            e.act('put', oid, rid)
            e.act('close', rid)
        else:
            e.act('put', oid, rid)

    def slice_first(self, oid: str) -> str:
        """Fetch a knife, slice `oid`, set the knife down, and pick up a slice (its id is returned)."""
        w, e = self.world, self.expert
        knives = _small(w, lambda o: 'Knife' in o.type_name and w.enclosed_by_closed(o) is None)
        knife = _pick(self.rng, knives)
        if knife is None:
            raise ExpertFailed('no knife')
        self.fetch(knife.object_id)
        e.goto(_landmark(w, oid), [oid])
        e.act('slice', oid)
        table = _pick(self.rng, _receptacles(w, ('CounterTop', 'DiningTable')))
        if table is None:
            raise ExpertFailed('nowhere to put the knife')
        self.deliver(knife.object_id, table.object_id)
        pieces = sorted(o.object_id for o in w.objects.values() if o.sliced_from == oid)
        piece = pieces[len(pieces) // 2]
        self.fetch(piece)
        return piece

    def macro(self, kind: str, oid: str, appliance: str, faucet: str = '') -> None:
        """Clean in the sink, heat in the microwave, or cool in the fridge (ALFRED's expansions)."""
        e = self.expert
        if kind == 'clean':
            e.goto(appliance, [appliance, faucet], put=oid)
            e.act('put', oid, appliance)
            e.act('toggle_on', faucet)
            e.act('toggle_off', faucet)
            e.act('pickup', oid)
            return
        e.goto(appliance, [appliance], put=oid)
        e.act('open', appliance)
        e.act('put', oid, appliance)
        e.act('close', appliance)
        if kind == 'heat':
            e.act('toggle_on', appliance)
            e.act('toggle_off', appliance)
        e.act('open', appliance)
        e.act('pickup', oid)
        e.act('close', appliance)


class Job:
    """One ALFRED job type. `rooms`: the room types it happens in and how often it is drawn there
    (ALFRED's GOALS_VALID); `may_slice`: whether its object may be sliced first (ALFRED's
    object_sliced); `places`: whether it ends by putting what it carries somewhere. Subclasses
    choose their objects (`objects`) and play what comes between fetching and delivering (`carry`)
    and after it (`finish`)."""

    name = ''
    rooms: Mapping[str, float] = {}
    may_slice = True
    places = True

    def objects(self, world: World, rng: np.random.Generator, setup: dict) -> Optional[dict]:
        """The job's objects as params ('object', and what else it needs); None if the room lacks one.
        May fill `setup` (what the room must be like: dirty objects, lamps off)."""
        obj = _target(world, rng, 'object')
        return None if obj is None else {'object': obj.object_id}

    def carry(self, plan: ExpertPlan, oid: str, params: dict) -> str:
        """What the expert does with `oid` in hand before delivering it; returns what it delivers."""
        return oid

    def finish(self, plan: ExpertPlan, params: dict) -> None:
        """What the expert does after delivering."""

    def play(self, plan: ExpertPlan, params: dict) -> None:
        """The whole job: fetch (or slice) the object, `carry`, deliver, `finish`."""
        oid = params['object']
        if params['sliced']:
            oid = plan.slice_first(oid)
        else:
            plan.fetch(oid)
        oid = self.carry(plan, oid, params)
        if self.places:
            plan.deliver(oid, params['receptacle'])
        self.finish(plan, params)


class PickAndPlace(Job):
    name = 'pick_and_place_simple'
    rooms = {'kitchen': 1.0, 'living_room': 1.0, 'bedroom': 1.0, 'bathroom': 1.0}


class PickTwo(Job):
    """Two objects of the same type put in the same place."""

    name = 'pick_two_obj_and_place'
    rooms = {'kitchen': 0.6, 'living_room': 0.8, 'bedroom': 0.8, 'bathroom': 0.8}
    may_slice = False

    def objects(self, world, rng, setup):
        params = super().objects(world, rng, setup)
        if params is None:
            return None
        obj = world.objects[params['object']]
        twins = [o for o in _small(world, lambda o: o.type_name == obj.type_name) if o.object_id != obj.object_id]
        if not twins:
            return None
        params['second'] = _pick(rng, twins).object_id
        return params

    def finish(self, plan, params):
        plan.fetch(params['second'])
        plan.deliver(params['second'], params['receptacle'])


class Clean(Job):
    """Rinse the object in a sink basin (every cleanable object of the room starts dirty)."""

    name = 'pick_clean_then_place_in_recep'
    rooms = {'kitchen': 1.2, 'bathroom': 1.2}

    def objects(self, world, rng, setup):
        obj = _target(world, rng, 'object', lambda o: o.otype.cleanable)
        basins = _receptacles(world, ('SinkBasin',))
        faucets = {o.controls: o.object_id for o in world.objects.values() if o.type_name == 'Faucet'}
        basins = [b for b in basins if b.object_id in faucets]
        if obj is None or not basins:
            return None
        basin = _pick(rng, [b for b in basins if _has_room(world, obj, b)])
        if basin is None:
            return None
        setup['dirty'] = sorted(o.object_id for o in world.objects.values() if o.otype.cleanable and not o.fixture)
        return {'object': obj.object_id, 'appliance': basin.object_id, 'faucet': faucets[basin.object_id]}

    def carry(self, plan, oid, params):
        plan.macro('clean', oid, params['appliance'], params['faucet'])
        return oid


class Appliance(Job):
    """Heat in a microwave or cool in a fridge (`expansion`, `appliance`, and the object's `able` flag)."""

    rooms = {'kitchen': 1.5}
    expansion = ''
    appliance = ''

    def able(self, obj: WorldObject) -> bool:
        raise NotImplementedError

    def objects(self, world, rng, setup):
        appliance = _pick(rng, _receptacles(world, (self.appliance,)))
        obj = _target(world, rng, 'object', lambda o: self.able(o) and not world.enclosed_by_closed(o)
                      and appliance is not None and _has_room(world, o, appliance))
        if obj is None or appliance is None:
            return None
        return {'object': obj.object_id, 'appliance': appliance.object_id}

    def carry(self, plan, oid, params):
        plan.macro(self.expansion, oid, params['appliance'])
        return oid


class Heat(Appliance):
    name = 'pick_heat_then_place_in_recep'
    expansion, appliance = 'heat', 'Microwave'

    def able(self, obj):
        return obj.otype.heatable


class Cool(Appliance):
    name = 'pick_cool_then_place_in_recep'
    expansion, appliance = 'cool', 'Fridge'

    def able(self, obj):
        return obj.otype.coolable


class LookInLight(Job):
    """Hold the object and turn on a lamp (every lamp of the room starts off)."""

    name = 'look_at_obj_in_light'
    rooms = {'living_room': 1.0, 'bedroom': 1.0}
    may_slice = False
    places = False

    def objects(self, world, rng, setup):
        lamps = sorted((o for o in world.objects.values() if o.type_name in LAMPS), key=lambda o: o.object_id)
        obj = _target(world, rng, 'object')
        if obj is None or not lamps:
            return None
        setup['off'] = [o.object_id for o in lamps]
        return {'object': obj.object_id, 'lamp': _pick(rng, lamps).object_id}

    def carry(self, plan, oid, params):
        plan.expert.goto(params['lamp'], [params['lamp']])
        plan.expert.act('toggle_on', params['lamp'])
        return oid


class MovableReceptacle(Job):
    """Put the object in a movable receptacle (a bowl, a box), then carry that to where it ends up."""

    name = 'pick_and_place_with_movable_recep'
    rooms = {'kitchen': 0.8, 'living_room': 0.6, 'bedroom': 0.6}

    def objects(self, world, rng, setup):
        movers = _small(world, lambda o: o.otype.movable_receptacle and world.enclosed_by_closed(o) is None)
        mover = _pick(rng, movers)
        if mover is None:
            return None
        obj = _target(world, rng, 'object', lambda o: o.type_name in mover.otype.accepts
                      and o.object_id != mover.object_id and _has_room(world, o, mover)
                      and mover.object_id not in [r.object_id for r in world.container_chain(o)])
        if obj is None:
            return None
        return {'object': obj.object_id, 'mover': mover.object_id}

    def carry(self, plan, oid, params):
        plan.deliver(oid, params['mover'])
        plan.expert.act('pickup', params['mover'])
        return params['mover']


_REGISTRY: Registry[Job] = Registry('job', sorted_names=True)


def register(job: Job) -> Job:
    """Add `job` to the registry (ValueError if its name is taken or it names no room)."""
    if not job.name or not job.rooms:
        raise ValueError(f'a job needs a name and the rooms it happens in, got {job.name!r} {dict(job.rooms)}')
    return _REGISTRY.add(job.name, job)


def job_named(name: str) -> Job:
    """The registered job `name` (ValueError naming the known ones otherwise)."""
    return _REGISTRY.named(name)


def room_jobs(room_type: str) -> dict[str, float]:
    """The jobs of a room type and their weights, by name."""
    return {name: job.rooms[room_type] for name, job in sorted(_REGISTRY.items()) if room_type in job.rooms}


for _job in (PickAndPlace(), PickTwo(), Clean(), Heat(), Cool(), LookInLight(), MovableReceptacle()):
    register(_job)


# ---------------------------------------------------------------------- planning a job

def plan_job(world: World, job: str, rng: np.random.Generator, setup: dict) -> tuple[dict, callable]:
    """Choose the job's objects (filling `setup`) and return (params, play) where play(expert) runs it;
    play is None when this room cannot host the job. The choices draw from `rng` in a fixed order: the
    job's objects, then where it ends, then a distractor."""
    kind = job_named(job)
    laptops = sorted(o.object_id for o in world.objects.values() if o.type_name == 'Laptop')
    if laptops:
        setup['open'] = laptops     # AI2-THOR's laptops stand open
    params = kind.objects(world, rng, setup)
    if params is None or not _destination(world, kind, rng, params):
        return params or {}, None
    _distractor(world, rng, params, setup)
    return params, lambda expert: kind.play(ExpertPlan(world, expert, rng), params)


def _target(world: World, rng: np.random.Generator, role: str, pred=lambda o: True) -> Optional[WorldObject]:
    """An object for `role`, favouring what makes the rarer task types: sliceable food in kitchens,
    laptops elsewhere."""
    pool = [o for o in _role_objects(world, role) if pred(o)]
    favoured = [o for o in pool if (o.otype.sliced_type and world.layout.room_type == 'kitchen')
                or o.type_name == 'Laptop']
    if favoured and rng.random() < FAVOURED_P:
        return _pick(rng, favoured)
    return _pick(rng, pool)


def _destination(world: World, job: Job, rng: np.random.Generator, params: dict) -> bool:
    """Whether the object is sliced first, and where it all ends up: a receptacle that accepts the
    (possibly sliced, possibly carried) object and has room for it. False if there is none."""
    obj = world.objects[params['object']]
    carried = world.objects[params['mover']] if 'mover' in params else obj
    sliced = obj.otype.sliced_type and job.may_slice and rng.random() < SLICE_PREFIX_P
    final_type = obj.otype.sliced_type if sliced and 'mover' not in params else carried.type_name
    holders = set(load_catalog()[final_type].typical_receptacles) - {'SinkBasin', 'Microwave', 'Fridge'} \
        if job.places else set()
    exclude = {r.object_id for r in world.container_chain(carried)}
    targets = _receptacles(world, holders, exclude) if holders else []
    if job.places:
        target = _pick(rng, [t for t in targets if t.object_id not in (params.get('mover'), params['object'])
                             and _has_room(world, carried, t)])
        if target is None:
            return False
        params['receptacle'] = target.object_id
    params['sliced'] = bool(sliced)
    return True


def _distractor(world: World, rng: np.random.Generator, params: dict, setup: dict) -> None:
    """Sometimes another object of the target's type, in a colour the room does not have yet (where the
    room has one of that type only)."""
    obj = world.objects[params['object']]
    same = [o for o in world.objects.values() if o.type_name == obj.type_name]
    if len(same) < 2 and rng.random() < DISTRACTOR_P:
        colours = [c for c in obj.otype.colours if c not in {o.colour for o in same}]
        hosts = _receptacles(world, obj.otype.typical_receptacles, {params.get('receptacle', '')})
        if colours and hosts:
            setup['distractors'] = [[obj.type_name, colours[0], _pick(rng, hosts).object_id]]
            setup['place_seed'] = int(rng.integers(2 ** 31))
