"""The DialFRED task types as objects, in a registry: each type owns its step pattern, its goal, its
main instruction and how strongly the generator prefers it where several types fit.

A `TaskType` is what the generator (`generator.cut_tasks`), the goals (`goals.goal_for`, `rule_goal`)
and the instructions (`make_instructions`) read about a type; none of them branches on a type's name.
The 25 types of the paper's table are registered here, in its order (`TASK_TYPES`); each 'Move & X'
is X with a go-to in front (`moving`). Adding a type is its module plus one `register(TaskType(...))`
call made before the tasks are cut (docs/tasks.md, "Adding a task type"); `task_types()` then lists
it after the paper's, and the generator draws it wherever its steps fit.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from .instructions import (MOVE_SAID_P, NOW_P, PLEASE_P, StepPhrase, article, sentence, step_clause, verb,
                           with_pronoun)
from ..registry import Registry
from .schema import PRIMITIVE_KINDS, Condition, Primitive

# goal(prims, world_types): the conditions of the type's object actions over its primitives (`world_types`
# maps object ids to type names: receptacles are matched by type, as ALFRED does). goals.goal_for adds
# the pose condition of a go-to.
GoalRule = Callable[[Sequence[Primitive], Mapping[str, str]], list[Condition]]
# clause(steps, rng): the main action as a lower-case clause ("heat the apple"); make_instructions frames it.
ClauseRule = Callable[[Sequence[StepPhrase], np.random.Generator], str]
# fits(prims, type_of): whether primitives of the type's kinds are about the objects the type says
# (the basin a Clean puts into is a sink); type_of(object id) is its type name, '' for none.
FitsRule = Callable[[Sequence[Primitive], Callable[[str], str]], bool]


def _always(prims: Sequence[Primitive], type_of: Callable[[str], str]) -> bool:
    return True


@dataclass(frozen=True)
class TaskType:
    """One task type. `steps`: the primitive kinds it is made of, in order; `goal`, `clause`, `fits`: see
    GoalRule, ClauseRule, FitsRule; `weight`: how strongly the generator prefers it where several types
    fit (rarer, longer ones are weighted up); `shows_target`: under the 'visible' goal rule its go-to
    wants the target in view and within reach (Move, Pick & Move) instead of being dropped."""

    name: str
    steps: tuple[str, ...]
    goal: GoalRule
    clause: ClauseRule
    weight: float = 1.0
    fits: FitsRule = field(default=_always)
    shows_target: bool = False

    def __post_init__(self):
        if not self.name.strip():
            raise ValueError('a task type needs a name')
        unknown = [k for k in self.steps if k not in PRIMITIVE_KINDS]
        if not self.steps or unknown:
            raise ValueError(f'task type {self.name!r}: steps must be primitive kinds of {PRIMITIVE_KINDS}, '
                             f'got {self.steps}')
        if not self.weight > 0:
            raise ValueError(f'task type {self.name!r}: weight must be > 0, got {self.weight}')

    @property
    def has_goto(self) -> bool:
        """Whether its steps include a go-to: its goal then includes DialFRED's pose condition."""
        return 'goto' in self.steps

    def instructions(self, steps: Sequence[StepPhrase], rng: np.random.Generator) -> tuple[list[str], str]:
        """(step_by_step, main): one sentence per primitive, in order, and the main-action instruction,
        sometimes framed by "Please ..." or "Now ...". ValueError for steps not of the type's kinds."""
        kinds = tuple(getattr(s, 'kind', None) for s in steps)
        if kinds != self.steps:
            raise ValueError(f'{self.name!r} expects step kinds {self.steps}, got {kinds}')
        step_by_step = [sentence(step_clause(step, rng)) for step in steps]
        clause = self.clause(steps, rng)
        frame = rng.random()
        if frame < PLEASE_P:
            clause = f'please {clause}'
        elif frame < PLEASE_P + NOW_P:
            clause = f'now {clause}'
        return step_by_step, sentence(clause)


_REGISTRY: Registry[TaskType] = Registry('task type')


def register(kind: TaskType) -> TaskType:
    """Add `kind` to the registry (ValueError if its name is taken)."""
    return _REGISTRY.add(kind.name, kind)


def unregister(name: str) -> None:
    """Remove a type registered after the paper's (ValueError for one of the paper's or an unknown name)."""
    if name in TASK_TYPES:
        raise ValueError(f"{name!r} is one of the paper's task types and stays registered")
    _REGISTRY.remove(name)


def task_type(name: str) -> TaskType:
    """The registered type `name` (ValueError naming the known ones otherwise)."""
    return _REGISTRY.named(name)


def task_types() -> tuple[TaskType, ...]:
    """Every registered type: the paper's 25 in its table's order, then the others as registered."""
    return tuple(_REGISTRY.values())


def make_instructions(name: str, steps: Sequence[StepPhrase], rng: np.random.Generator) -> tuple[list[str], str]:
    """`TaskType.instructions` of the registered type `name`; ValueError for an unknown type."""
    return task_type(name).instructions(steps, rng)


# ------------------------------------------------------------------------------ building blocks

def _last(kind: str) -> GoalRule:
    """A goal of one condition `kind` on the object the last step acts on."""
    return lambda prims, types: [Condition(kind, prims[-1].target)]


def _put_in(step: int) -> GoalRule:
    """The object of the put at index `step` in a receptacle of the put's receptacle type."""
    return lambda prims, types: [Condition('in', prims[step].target, types[prims[step].receptacle])]


def _say(step: int) -> ClauseRule:
    """The main clause is the step at index `step` said alone ("open the microwave")."""
    return lambda steps, rng: step_clause(steps[step], rng)


def _appliance_goal(state: str) -> GoalRule:
    """Cool and Heat: the object picked up (second to last) in `state` and in hand, the appliance closed last."""
    def goal(prims, types):
        obj = prims[-2].target
        return [Condition(state, obj), Condition('holding', obj), Condition('closed', prims[-1].target)]
    return goal


def _appliance_fits(appliance: str) -> FitsRule:
    """Cool and Heat: the first step opens a `appliance`, and what goes in is what comes out."""
    def fits(prims, type_of):
        return (type_of(prims[0].target) == appliance and prims[1].receptacle == prims[0].target
                and prims[1].target == prims[-2].target)
    return fits


def _clean_goal(prims, types):
    # put in the basin, faucet on, faucet off, pick up
    obj = prims[-1].target
    return [Condition('clean', obj), Condition('holding', obj), Condition('off', prims[-3].target)]


def _carry_clause(steps, rng):
    return f'{verb("carry", rng)} the {steps[0].noun} to the {steps[1].noun}'


def _slice_with_clause(steps, rng):
    knife = steps[0].noun
    return f'{verb("slice", rng)} the {steps[2].noun} with {article(knife)} {knife}'


def moving(base: TaskType, weight: float = 1.0) -> TaskType:
    """'Move & X': a go-to to where X happens, then X. Its goal is X's (plus the go-to's pose); its main
    instruction is X's, and says where to go this often (MOVE_SAID_P): "Go to the sink basin, wash the
    ladle.", "Go to the microwave and open it."."""
    def clause(steps, rng):
        landmark = steps[0].noun
        said = base.clause(steps[1:], rng)
        if rng.random() < MOVE_SAID_P:
            goto = verb('goto', rng)
            suffix = f' the {landmark}'
            if said.endswith(suffix):    # not the microwave twice
                return f'{goto} the {landmark} and {with_pronoun(said[:-len(suffix)])}'
            return f'{goto} the {landmark}, {said}'
        return said
    return TaskType(f'Move & {base.name}', ('goto',) + base.steps,
                    goal=lambda prims, types: base.goal(prims[1:], types), clause=clause, weight=weight,
                    fits=lambda prims, type_of: base.fits(prims[1:], type_of))


# ------------------------------------------------------------------------------ the paper's 25 types

_CLEAN = TaskType('Clean', ('put', 'toggle_on', 'toggle_off', 'pickup'), _clean_goal, weight=3.0,
                  clause=lambda steps, rng: f'{verb("clean", rng)} the {steps[0].noun}',
                  fits=lambda prims, type_of: (type_of(prims[0].receptacle) == 'SinkBasin'
                                               and prims[0].target == prims[3].target))
_CLOSE = TaskType('Close', ('close',), _last('closed'), _say(0), weight=0.5)
_COOL = TaskType('Cool', ('open', 'put', 'close', 'open', 'pickup', 'close'), _appliance_goal('cold'),
                 lambda steps, rng: f'{verb("cool", rng)} the {steps[1].noun}', weight=3.0,
                 fits=_appliance_fits('Fridge'))
_HEAT = TaskType('Heat', ('open', 'put', 'close', 'toggle_on', 'toggle_off', 'open', 'pickup', 'close'),
                 _appliance_goal('hot'), lambda steps, rng: f'{verb("heat", rng)} the {steps[1].noun}',
                 weight=3.0, fits=_appliance_fits('Microwave'))
_MOVE = TaskType('Move', ('goto',), lambda prims, types: [], _say(0), weight=0.4, shows_target=True)
_OPEN = TaskType('Open', ('open',), _last('open'), _say(0), weight=0.6)
_PICK = TaskType('Pick', ('pickup',), _last('holding'), _say(0), weight=0.5)
_PUT = TaskType('Put', ('put',), _put_in(-1), _say(-1), weight=0.5)
_SLICE = TaskType('Slice', ('slice',), _last('sliced'), _say(0), weight=1.5)
_TURN_ON = TaskType('Turn on', ('toggle_on',), _last('on'), _say(0))
_TURN_OFF = TaskType('Turn off', ('toggle_off',), _last('off'), _say(0))

for _kind in (_CLEAN, _CLOSE, _COOL, _HEAT, _MOVE, _OPEN, _PICK, _PUT, _SLICE, _TURN_ON, _TURN_OFF):
    register(_kind)
for _base, _weight in ((_CLEAN, 2.0), (_CLOSE, 3.0), (_COOL, 2.0), (_HEAT, 2.0), (_OPEN, 0.7), (_PICK, 1.0),
                       (_PUT, 1.0), (_SLICE, 2.0), (_TURN_ON, 1.5)):
    register(moving(_base, _weight))
register(TaskType('Open & Pick & Close', ('open', 'pickup', 'close'),
                  lambda prims, types: [Condition('holding', prims[1].target), Condition('closed', prims[-1].target)],
                  _say(1), fits=lambda prims, type_of: prims[0].target == prims[2].target))
register(TaskType('Open & Put & Close', ('open', 'put', 'close'),
                  lambda prims, types: _put_in(1)(prims, types) + [Condition('closed', prims[-1].target)],
                  _say(1), fits=lambda prims, type_of: prims[0].target == prims[2].target == prims[1].receptacle))
register(TaskType('Pick & Move', ('pickup', 'goto'), lambda prims, types: [Condition('holding', prims[0].target)],
                  _carry_clause, weight=1.5, shows_target=True))
register(TaskType('Pick & Move & Put', ('pickup', 'goto', 'put'), _put_in(-1), _say(-1), weight=1.6,
                  fits=lambda prims, type_of: prims[0].target == prims[2].target))
register(TaskType('Pick & Move & Slice', ('pickup', 'goto', 'slice'),
                  lambda prims, types: [Condition('sliced', prims[-1].target), Condition('holding', prims[0].target)],
                  _slice_with_clause, weight=4.0, fits=lambda prims, type_of: 'Knife' in type_of(prims[0].target)))

# The paper's 25 task types, in the order of its table (what the metrics' tables sort by).
TASK_TYPES: tuple[str, ...] = tuple(_REGISTRY)
