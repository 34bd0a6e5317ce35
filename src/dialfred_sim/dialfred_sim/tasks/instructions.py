"""The words of DialFRED's instructions: a primitive as a phrase, the verb synonyms, and tokens.

As in the paper's "Instruction augmentation": each low-level primitive has a template and a task's
step-by-step instructions concatenate them; the main instruction names only the task's main action
(e.g. "Open the microwave." for 'Move & Open'), so the agent must use the room to fill in the rest.
Each task type says its main action itself (`types.TaskType.clause`); `types.make_instructions`
makes a task's sentences. Verbs are drawn from DialFRED's synonym lists; all randomness comes from
the caller's Generator.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

# The schema owns the primitive kinds; re-exported here.
from .schema import PRIMITIVE_KINDS as STEP_KINDS


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

PLEASE_P = 0.08       # "Please ..." frame on the main instruction
NOW_P = 0.05          # "Now ..." frame
MOVE_SAID_P = 0.35    # 'Move & X' main also says where to go ("Go to the sink basin, wash the ladle.")


def verb(kind: str, rng: np.random.Generator) -> str:
    """One of the synonyms of `kind` (SYNONYMS), drawn from `rng`."""
    options = SYNONYMS[kind]
    return options[int(rng.integers(len(options)))]


def sentence(clause: str) -> str:
    """Capitalise the first letter only (nouns keep their case) and end with a period."""
    return clause[:1].upper() + clause[1:] + '.'


def article(noun: str) -> str:
    """'a' or 'an' before `noun`."""
    return 'an' if noun[:1].lower() in 'aeiou' else 'a'


def with_pronoun(phrase: str) -> str:
    """'open' -> 'open it'; phrasal verbs put the pronoun before their particle ('switch it on')."""
    words = phrase.split(' ')
    if len(words) == 2 and words[1] in ('up', 'on', 'off'):
        return f'{words[0]} it {words[1]}'
    return f'{phrase} it'


def step_clause(step: StepPhrase, rng: np.random.Generator) -> str:
    """The primitive as a lower-case clause: "open the fridge", "put the mug on the plate"."""
    if step.kind == 'put':
        return f'{verb("put", rng)} the {step.noun} {step.preposition} the {step.receptacle_noun}'
    return f'{verb(step.kind, rng)} the {step.noun}'


_WORD = re.compile(r"[a-z0-9]+(?:'[a-z]+)?")


def tokenize(text: str) -> list[str]:
    """Lower-cased word tokens of a sentence, punctuation stripped ("Go to the sink." -> go, to, the, sink)."""
    return _WORD.findall(text.lower())


def vocabulary(sentences) -> set[str]:
    """The set of distinct tokens over an iterable of sentences."""
    return {token for sentence in sentences for token in tokenize(sentence)}
