"""Instructions for DialFRED tasks: templated step-by-step sentences and an augmented main instruction.

As in the paper's "Instruction augmentation": each low-level primitive has a template and a task's
step-by-step instructions concatenate them; the main instruction names only the task's main action
(e.g. "Open the microwave." for 'Move & Open'), so the agent must use the room to fill in the rest.
Verbs are drawn from DialFRED's synonym lists; all randomness comes from the caller's Generator.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

# The schema owns the 25 task types (table order) and primitive kinds; re-exported here.
from .schema import PRIMITIVE_KINDS as STEP_KINDS
from .schema import TASK_TYPES


@dataclass(frozen=True)
class StepPhrase:
    """One low-level primitive of a task, in words."""

    kind: str                   # one of STEP_KINDS
    noun: str                   # object acted on / gone to; for 'put' the held object
    receptacle_noun: str = ''   # for 'put': where it is put
    preposition: str = 'on'     # for 'put': 'in' or 'on'

    def __post_init__(self):
        if self.kind not in STEP_KINDS:
            raise ValueError(f'unknown step kind {self.kind!r}; expected one of {STEP_KINDS}')
        if not self.noun.strip():
            raise ValueError(f'{self.kind} step needs a noun')
        if self.kind == 'put' and not self.receptacle_noun.strip():
            raise ValueError('put step needs a receptacle_noun')
        if self.preposition not in ('in', 'on'):
            raise ValueError(f"preposition must be 'in' or 'on', not {self.preposition!r}")


# Verb synonyms of DialFRED's augment_data.py, widened a little (rinse, shut, warm up, walk/head to).
SYNONYMS = {
    'pickup': ('pick up', 'grab', 'take'),
    'put': ('put', 'place', 'leave'),
    'open': ('open', 'open up'),
    'close': ('close', 'shut'),
    'cool': ('cool', 'chill'),
    'heat': ('heat', 'cook', 'heat up', 'warm up'),
    'toggle_on': ('turn on', 'switch on', 'power on'),
    'toggle_off': ('turn off', 'switch off', 'power off'),
    'slice': ('slice', 'cut'),
    'clean': ('clean', 'wash', 'rinse'),
    'goto': ('go to', 'move to', 'walk to', 'head to'),
    'carry': ('take', 'bring', 'carry'),
}

_CLEAN = ('put', 'toggle_on', 'toggle_off', 'pickup')
_COOL = ('open', 'put', 'close', 'open', 'pickup', 'close')
_HEAT = ('open', 'put', 'close', 'toggle_on', 'toggle_off', 'open', 'pickup', 'close')
_SINGLE = {'Clean': _CLEAN, 'Close': ('close',), 'Cool': _COOL, 'Heat': _HEAT, 'Move': ('goto',),
           'Open': ('open',), 'Pick': ('pickup',), 'Put': ('put',), 'Slice': ('slice',),
           'Turn on': ('toggle_on',), 'Turn off': ('toggle_off',)}
# The primitive kinds each task type expands to, in the paper's table order.
TASK_STEP_KINDS: dict[str, tuple[str, ...]] = {
    **_SINGLE,
    **{f'Move & {name}': ('goto',) + _SINGLE[name]
       for name in ('Clean', 'Close', 'Cool', 'Heat', 'Open', 'Pick', 'Put', 'Slice', 'Turn on')},
    'Open & Pick & Close': ('open', 'pickup', 'close'),
    'Open & Put & Close': ('open', 'put', 'close'),
    'Pick & Move': ('pickup', 'goto'),
    'Pick & Move & Put': ('pickup', 'goto', 'put'),
    'Pick & Move & Slice': ('pickup', 'goto', 'slice'),
}

PLEASE_P = 0.08       # "Please ..." frame on the main instruction
NOW_P = 0.05          # "Now ..." frame
MOVE_SAID_P = 0.35    # 'Move & X' main also says where to go ("Go to the sink basin, wash the ladle.")


def _verb(kind: str, rng: np.random.Generator) -> str:
    options = SYNONYMS[kind]
    return options[int(rng.integers(len(options)))]


def _sentence(clause: str) -> str:
    """Capitalise the first letter only (nouns keep their case) and end with a period."""
    return clause[:1].upper() + clause[1:] + '.'


def _article(noun: str) -> str:
    return 'an' if noun[:1].lower() in 'aeiou' else 'a'


def _with_pronoun(verb: str) -> str:
    """'open' -> 'open it'; phrasal verbs put the pronoun before their particle ('switch it on')."""
    words = verb.split(' ')
    if len(words) == 2 and words[1] in ('up', 'on', 'off'):
        return f'{words[0]} it {words[1]}'
    return f'{verb} it'


def _step_clause(step: StepPhrase, rng: np.random.Generator) -> str:
    if step.kind == 'put':
        return f'{_verb("put", rng)} the {step.noun} {step.preposition} the {step.receptacle_noun}'
    return f'{_verb(step.kind, rng)} the {step.noun}'


def _check_steps(task_type: str, steps: Sequence[StepPhrase]) -> None:
    if task_type not in TASK_STEP_KINDS:
        raise ValueError(f'unknown task type {task_type!r}; expected one of {TASK_TYPES}')
    expected = TASK_STEP_KINDS[task_type]
    kinds = tuple(getattr(s, 'kind', None) for s in steps)
    if kinds != expected:
        raise ValueError(f'{task_type!r} expects step kinds {expected}, got {kinds}')


def _main_clause(base: str, steps: Sequence[StepPhrase], rng: np.random.Generator) -> str:
    """The main action of a task type without its leading goto, as a lower-case clause."""
    if base in ('Clean', 'Cool', 'Heat'):
        # The object is the one put into the sink / fridge / microwave, not the appliance.
        return f'{_verb(base.lower(), rng)} the {steps[1 if base != "Clean" else 0].noun}'
    if base in ('Put', 'Open & Put & Close', 'Pick & Move & Put'):
        put = steps[-1] if base != 'Open & Put & Close' else steps[1]
        return f'{_verb("put", rng)} the {put.noun} {put.preposition} the {put.receptacle_noun}'
    if base == 'Open & Pick & Close':
        return f'{_verb("pickup", rng)} the {steps[1].noun}'
    if base == 'Pick & Move':
        return f'{_verb("carry", rng)} the {steps[0].noun} to the {steps[1].noun}'
    if base == 'Pick & Move & Slice':
        knife = steps[0].noun
        return f'{_verb("slice", rng)} the {steps[2].noun} with {_article(knife)} {knife}'
    return _step_clause(steps[0], rng)    # single-primitive types: Close, Move, Open, Pick, ...


def make_instructions(task_type: str, steps: Sequence[StepPhrase],
                      rng: np.random.Generator) -> tuple[list[str], str]:
    """Returns (step_by_step, main): one sentence per primitive (templates concatenated, in order)
    and the augmented main-action-only instruction (one sentence).

    Raises ValueError for an unknown task type or steps whose kinds do not match it.
    """
    _check_steps(task_type, steps)
    step_by_step = [_sentence(_step_clause(step, rng)) for step in steps]

    if task_type.startswith('Move & '):
        landmark = steps[0].noun
        clause = _main_clause(task_type[len('Move & '):], steps[1:], rng)
        if rng.random() < MOVE_SAID_P:
            goto = _verb('goto', rng)
            suffix = f' the {landmark}'
            if clause.endswith(suffix):
                # "Go to the microwave and open it." rather than naming the microwave twice.
                clause = f'{goto} the {landmark} and {_with_pronoun(clause[:-len(suffix)])}'
            else:
                clause = f'{goto} the {landmark}, {clause}'
    else:
        clause = _main_clause(task_type, steps, rng)

    frame = rng.random()
    if frame < PLEASE_P:
        clause = f'please {clause}'
    elif frame < PLEASE_P + NOW_P:
        clause = f'now {clause}'
    return step_by_step, _sentence(clause)


_WORD = re.compile(r"[a-z0-9]+(?:'[a-z]+)?")


def tokenize(sentence: str) -> list[str]:
    """Lower-cased word tokens of a sentence, punctuation stripped ("Go to the sink." -> go, to, the, sink)."""
    return _WORD.findall(sentence.lower())


def vocabulary(sentences) -> set[str]:
    """The set of distinct tokens over an iterable of sentences."""
    return {token for sentence in sentences for token in tokenize(sentence)}
