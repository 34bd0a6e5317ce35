"""ALFRED's low-level actions and their effects on the world (ROS-free).

Navigation moves the agent on the 0.25 m grid; an interaction names a pixel of the current frame and
acts on the object under it. Every failed precondition returns an `ActionResult` with success False
and a clear error, and leaves the world exactly as it was.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .protocol import ACTIONS, BODY
from .world.rooms import AGENT_RADIUS, GRID, footprint
from .world.camera import HORIZON_MAX, HORIZON_MIN
from .world.objects import COLD, HOT, WorldObject
from .world.scene import SLICES_PER_OBJECT, DEFAULT_SLICES, World

REACH = BODY.reach            # metres from the agent's vertical axis to the point under the target pixel
LOOK_STEP = BODY.look_step    # degrees per LookUp / LookDown


# The 13 actions, in the order of the Gymnasium action space: protocol.ACTIONS, numbered from 0.
Action = enum.IntEnum('Action', [(name, k) for k, name in enumerate(ACTIONS)], module=__name__, qualname='Action')
Action.is_interaction = property(lambda self: Action.Pickup <= self <= Action.Slice)
ACTION_NAMES: tuple[str, ...] = ACTIONS
NAVIGATION = (Action.MoveAhead, Action.RotateLeft, Action.RotateRight, Action.LookUp, Action.LookDown)


def parse_action(value) -> Action:
    """An Action from its index or its ALFRED name; ValueError naming the valid ones otherwise."""
    if isinstance(value, Action):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        if 0 <= int(value) < len(Action):
            return Action(int(value))
        raise ValueError(f'unknown action index {int(value)}: expected 0-{len(Action) - 1}')
    if isinstance(value, str):
        for a in Action:
            if value == a.name:
                return a
        raise ValueError(f'unknown action {value!r}: expected one of {", ".join(ACTION_NAMES)}')
    raise ValueError(f'unknown action {value!r}')


@dataclass(frozen=True)
class ActionResult:
    success: bool
    error: str = ''
    target: Optional[str] = None


def _fail(msg: str, target: Optional[str] = None) -> ActionResult:
    return ActionResult(False, msg, target)


# ---------------------------------------------------------------------- navigation

def move_ahead(world: World) -> ActionResult:
    cell = world.agent.forward_cell()
    if cell not in world.layout.navigable:
        return _fail(f'MoveAhead blocked by {_blocker(world, cell)}')
    door = world.open_blocker(*cell)
    if door is not None:
        return _fail(f'MoveAhead blocked by {door}, which is open')
    hit = _carry_obstacle(world, cell[0], cell[1], world.agent.rotation)
    if hit:
        return _fail(f'MoveAhead blocked: the {world.held} in hand would pass into {hit}')
    world.agent.i, world.agent.j = cell
    world.update_held_pose()
    return ActionResult(True)


def _carry_obstacle(world: World, i: int, j: int, rotation: int, obj: Optional[WorldObject] = None) -> str:
    """What `obj` (the held object by default) would pass into, wherever the hand of an agent on
    (i, j) facing `rotation` carried it: 'the wall' or a fixture's id; '' if there is room."""
    obj = obj if obj is not None else world.objects.get(world.held) if world.held else None
    if obj is None:
        return ''
    spot, hit = world.carry_spot(obj, i, j, rotation)
    return '' if spot is not None else hit


def _blocker(world: World, cell) -> str:
    x, y = cell[0] * GRID, cell[1] * GRID
    for fx in world.layout.fixtures:
        if not fx.blocks_floor:
            continue
        r = footprint(fx.position, fx.yaw, fx.spec.size)
        dx = max(r[0] - x, 0.0, x - r[2])
        dy = max(r[1] - y, 0.0, y - r[3])
        if dx * dx + dy * dy < AGENT_RADIUS ** 2:
            return fx.object_id
    return 'a wall'


def rotate(world: World, degrees: int) -> ActionResult:
    a = world.agent
    hit = _carry_obstacle(world, a.i, a.j, (a.rotation + degrees) % 360)
    if hit:
        name = 'RotateLeft' if degrees > 0 else 'RotateRight'
        return _fail(f'{name} blocked: the {world.held} in hand would pass into {hit}')
    world.agent.rotation = (world.agent.rotation + degrees) % 360
    world.update_held_pose()
    return ActionResult(True)


def look(world: World, delta: float) -> ActionResult:
    new = world.agent.horizon + delta
    if new < HORIZON_MIN - 1e-6 or new > HORIZON_MAX + 1e-6:
        side = 'up' if delta < 0 else 'down'
        return _fail(f'cannot look {side} further (camera pitch limits {HORIZON_MIN:g} to {HORIZON_MAX:g} degrees)')
    world.agent.horizon = new
    return ActionResult(True)


# ---------------------------------------------------------------------- interaction

def target_at(world: World, px: int, py: int, depth: np.ndarray, seg: np.ndarray):
    """The object under pixel (px, py) of the last frame, the 3-D point there, or an error."""
    body = int(seg[py, px])
    object_id = world.body_to_object.get(body)
    if object_id is None:
        what = world.structure_bodies.get(body, 'nothing')
        return None, None, _fail(f'no object at pixel ({px}, {py}) ({what.lower()} is there)')
    point, _ = world.pixel_point(px, py, depth)
    dist = world.axis_distance(point)
    if dist > REACH:
        away = math.ceil(dist * 100) / 100      # rounded up: 1.5004 m reads 1.51, never the reach itself
        return None, None, _fail(f'{object_id} is out of reach ({away:.2f} m away; reach is {REACH:.2f} m)', object_id)
    return world.objects[object_id], point, None


def pickup(world: World, obj: WorldObject) -> ActionResult:
    if world.held is not None:
        return _fail(f'hand is full (holding {world.held})', obj.object_id)
    if obj.held:
        return _fail(f'{obj.object_id} is already held', obj.object_id)
    if not obj.otype.pickupable or obj.fixture:
        return _fail(f'{obj.object_id} cannot be picked up', obj.object_id)
    closed = world.enclosed_by_closed(obj)
    if closed is not None:
        return _fail(f'{obj.object_id} is inside {closed.object_id}, which is closed', obj.object_id)
    a = world.agent
    hit = _carry_obstacle(world, a.i, a.j, a.rotation, obj)
    if hit:
        return _fail(f'no room to hold {obj.object_id} here: it would pass into {hit}', obj.object_id)
    world.hold(obj)
    return ActionResult(True, target=obj.object_id)


def put(world: World, receptacle: WorldObject, point) -> ActionResult:
    if world.held is None:
        return _fail('nothing in hand to put', receptacle.object_id)
    obj = world.objects[world.held]
    rid = receptacle.object_id
    if not receptacle.otype.receptacle or not receptacle.spec.surfaces:
        return _fail(f'{rid} is not a receptacle', rid)
    if receptacle.object_id == obj.object_id or receptacle in world.descendants(obj):
        return _fail(f'cannot put {obj.object_id} into itself', rid)
    if receptacle.otype.openable and not receptacle.is_open:
        return _fail(f'{rid} is closed', rid)
    closed = world.enclosed_by_closed(receptacle)
    if closed is not None:
        return _fail(f'{rid} is inside {closed.object_id}, which is closed', rid)
    accepts = receptacle.otype.accepts
    if accepts and obj.type_name not in accepts:
        return _fail(f'{obj.type_name} cannot be put {receptacle.otype.preposition} {receptacle.type_name}', rid)
    if not world.place(obj, receptacle, near=point):
        return _fail(f'no free spot for {obj.object_id} {receptacle.otype.preposition} {rid}', rid)
    _apply_location_effects(world, obj)
    world.update_held_pose()
    return ActionResult(True, target=rid)


def _apply_location_effects(world: World, obj: WorldObject) -> None:
    """Effects of arriving somewhere: under a running faucet, on a lit burner, in a running microwave."""
    for r in world.container_chain(obj):
        if r.type_name == 'SinkBasin' and _faucet_running(world, r):
            for o in [obj, *world.descendants(obj)]:
                o.is_dirty = False
        if r.type_name in ('StoveBurner', 'Microwave') and r.is_on:
            for o in [obj, *world.descendants(obj)]:
                o.temperature = HOT


def _faucet_running(world: World, basin: WorldObject) -> bool:
    return any(o.controls == basin.object_id and o.is_on for o in world.objects.values())


def open_close(world: World, obj: WorldObject, want_open: bool) -> ActionResult:
    oid = obj.object_id
    if not obj.otype.openable or obj.spec.articulation is None:
        return _fail(f'{oid} cannot be opened or closed', oid)
    if obj.is_open == want_open:
        return _fail(f'{oid} is already {"open" if want_open else "closed"}', oid)
    if want_open and world.would_hit_agent(obj):
        return _fail(f'{oid} would hit you as it opens; step back first', oid)
    world.set_open(obj, want_open)
    if want_open and obj.type_name == 'Microwave' and obj.is_on:
        obj.is_on = False   # opening a running microwave stops it
    if not want_open and obj.type_name == 'Fridge':
        for o in world.descendants(obj):
            if not o.fixture:
                o.temperature = COLD
    return ActionResult(True, target=oid)


def switched_together(world: World, obj: WorldObject) -> list[WorldObject]:
    """The toggleable objects that are one switch with `obj`: a stove knob and the burner it controls
    are on or off together, whichever of the two is toggled (a faucet and its basin are not: the
    basin has no on/off state)."""
    linked = [obj]
    controlled = world.objects.get(obj.controls) if obj.controls else None
    if controlled is not None and controlled.otype.toggleable:
        linked.append(controlled)
    linked += [o for o in world.objects.values()
               if o.controls == obj.object_id and o.otype.toggleable and o not in linked]
    return linked


def toggle(world: World, obj: WorldObject, want_on: bool) -> ActionResult:
    oid = obj.object_id
    if not obj.otype.toggleable:
        return _fail(f'{oid} cannot be turned on or off', oid)
    controlled = world.objects.get(obj.controls) if obj.controls else None
    if obj.is_on == want_on:
        return _fail(f'{oid} is already {"on" if want_on else "off"}', oid)
    if want_on and obj.type_name == 'Microwave' and obj.is_open:
        return _fail(f'{oid} is open; close it before turning it on', oid)
    for switch in switched_together(world, obj):   # a stove knob lights its burner, and back
        switch.is_on = want_on
    if want_on:
        heater = controlled if controlled is not None and controlled.type_name == 'StoveBurner' else obj
        if obj.type_name == 'Faucet' and controlled is not None:
            for o in world.descendants(controlled):
                o.is_dirty = False
        if heater.type_name in ('Microwave', 'StoveBurner'):
            for o in world.descendants(heater):
                if not o.fixture:
                    o.temperature = HOT
    return ActionResult(True, target=oid)


def slice_object(world: World, obj: WorldObject) -> ActionResult:
    oid = obj.object_id
    held = world.objects.get(world.held) if world.held else None
    if held is None or 'Knife' not in held.type_name:
        return _fail('Slice needs a knife in hand', oid)
    if not obj.otype.sliceable or obj.is_sliced:
        return _fail(f'{oid} cannot be sliced', oid)
    if obj.parent is None:
        return _fail(f'{oid} must rest on something to be sliced', oid)
    parent = world.objects[obj.parent]
    n = SLICES_PER_OBJECT.get(obj.type_name, DEFAULT_SLICES)
    length = obj.spec.size[0]
    x0, y0, z0 = obj.local
    surface, colour, state = obj.surface, obj.colour, (obj.is_dirty, obj.temperature)
    world.remove(oid)
    for k in range(n):
        piece = world.spawn(obj.otype.sliced_type, colour)
        piece.parent, piece.surface = parent.object_id, surface
        piece.local = (x0 + (k - (n - 1) / 2) * length / n, y0, z0)
        piece.is_dirty, piece.temperature = state
        piece.sliced_from = oid
        parent.contents.append(piece.object_id)
        world.update_pose(piece)
    return ActionResult(True, target=oid)


def interact(world: World, action: Action, obj: WorldObject, point) -> ActionResult:
    if obj.held and action != Action.Put:
        return _fail(f'{obj.object_id} is in your hand; target something else', obj.object_id)
    if action == Action.Pickup:
        return pickup(world, obj)
    if action == Action.Put:
        return put(world, obj, point)
    if action in (Action.Open, Action.Close):
        return open_close(world, obj, action == Action.Open)
    if action in (Action.ToggleOn, Action.ToggleOff):
        return toggle(world, obj, action == Action.ToggleOn)
    return slice_object(world, obj)


def execute(world: World, action: Action, pixel, depth: np.ndarray, seg: np.ndarray) -> ActionResult:
    """Carry out `action` (with its target `pixel` for interactions) on `world`."""
    if action == Action.MoveAhead:
        return move_ahead(world)
    if action == Action.RotateLeft:
        return rotate(world, BODY.turn_step)
    if action == Action.RotateRight:
        return rotate(world, -BODY.turn_step)
    if action == Action.LookUp:
        return look(world, -LOOK_STEP)
    if action == Action.LookDown:
        return look(world, LOOK_STEP)
    if action == Action.Stop:
        return ActionResult(True)
    obj, point, err = target_at(world, int(pixel[0]), int(pixel[1]), depth, seg)
    if err is not None:
        return err
    return interact(world, action, obj, point)

