"""A reader of answers in a person's words: the facts of the oracle's fields from free text (no ROS).

`language.parse_answer` reads the oracle's templates exactly. A person says "it's on the counter behind
you, to the right", "greyish", "turn around and walk forward". `read_answer` reads such words by what they
name, with no template:

- a direction answer: staying ("you don't need to move", "stay where you are", "you're there"), turning
  around ("turn around", "the other way", "180"), a side ("left", "right": never "right" as in "right
  here" or "right behind you"), going on ("straight", "ahead", "forward");
- a location answer: held ("you're holding it", "in your hand"); a direction bin from the words for a
  side, the back and the front ("behind you on the left" is the rear left, "ahead and to the right" the
  front right, "slightly to your left" the front left) or a clock position ("at 3 o'clock"); a receptacle,
  any object of the catalog the answer names other than the one asked about (the catalog's own everyday
  names: "refrigerator", "cupboard", "trash can"), in it or on it;
- an appearance answer: a colour of the palette, or an everyday word for one ("grey", "greyish",
  "dark blue", "golden").

What the words do not say stays unsaid (a location without a side, say): the fact has what was read.
Its vocabulary is the catalog's, the palette's and everyday English; it was not fitted to the held-out
wording (dialfred_oracle.wording), which `./dialfred bench answer_reading` measures it on.
"""

from __future__ import annotations

import functools
import re
from typing import Optional

from dialfred_oracle.answers import DIRECTION_BINS
from dialfred_sim.palette import COLOUR_NAMES

from .language import Fact, InstructionError, _noun_types, object_type, parse_answer

# Everyday words for the palette's colours (the palette's own names are read as they are).
COLOUR_WORDS = {'grey': 'gray', 'dark blue': 'navy', 'navy blue': 'navy', 'dark red': 'maroon', 'burgundy': 'maroon',
                'light brown': 'tan', 'cream': 'beige', 'off-white': 'beige', 'olive green': 'olive',
                'blue green': 'teal', 'turquoise': 'teal', 'golden': 'gold', 'silvery': 'silver',
                'metallic': 'silver', 'violet': 'purple', 'rosy': 'pink', 'orangey': 'orange'}
# "right" says how near, not which side, before these words ("right here", "right behind you").
INTENSIFIED = {'here', 'there', 'behind', 'in', 'on', 'at', 'by', 'next', 'beside', 'ahead', 'where', 'now',
               'under', 'above', 'over', 'near', 'infront', 'before'}
STAY = ("don't need to move", 'do not need to move', 'no need to move', "don't move", 'do not move', 'stay',
        'already there', 'you are there', "you're there", 'right here', 'you made it', 'this is the spot',
        'where you are', "you're fine", 'you are fine', 'stop')
AROUND = ('around', 'round', '180', 'other way', 'opposite', 'about face', 'behind you', 'back')
ON_WAY = ('straight', 'ahead', 'forward', 'forwards', 'keep going', 'go on', 'carry on')
HELD = ('holding', 'in your hand', 'in your hands', 'carrying', 'already have', 'you have it', "you've got it",
        'you have got it', 'got it already')
# Clock positions: the hour -> the direction bin (12: ahead, 3: right, 6: behind, 9: left).
CLOCK = {12: 0, 1: 7, 2: 7, 3: 6, 4: 5, 5: 5, 6: 4, 7: 3, 8: 3, 9: 2, 10: 1, 11: 1}


def _tokens(text: str) -> list[str]:
    return re.findall(r"[a-z0-9']+", text.lower().replace('-', ' '))


def _has(text: str, phrases) -> bool:
    return any(re.search(rf'(?<![a-z]){re.escape(p)}(?![a-z])', text) for p in phrases)


def _side(tokens: list[str]) -> str:
    """'left', 'right' or '' (a 'right' that intensifies the next word is no side)."""
    for k, t in enumerate(tokens):
        if t in ('left', 'leftish', 'lefthand'):
            return 'left'
        if t in ('right', 'rightish', 'righthand'):
            after = tokens[k + 1] if k + 1 < len(tokens) else ''
            if t != 'right' or after not in INTENSIFIED:
                return 'right'
    return ''


def read_bin(text: str) -> Optional[int]:
    """The index into DIRECTION_BINS a location answer's words give, None if they give none."""
    low = text.lower()
    m = re.search(r'(\d{1,2})\s*o\s*\'?\s*clock', low)
    if m and int(m.group(1)) in CLOCK:
        return CLOCK[int(m.group(1))]
    tokens = _tokens(low)
    side = _side(tokens)
    back = any(t in ('behind', 'back', 'rear', 'shoulder') for t in tokens)
    front = not back and (any(t in ('front', 'ahead', 'forward', 'straight') for t in tokens) or
                          (side and any(t in ('slightly', 'bit', 'little') for t in tokens)) or
                          any(t in ('leftish', 'rightish') for t in tokens))
    names = {(True, 'left'): 'to your rear left', (True, 'right'): 'to your rear right', (True, ''): 'behind you'}
    if back:
        return DIRECTION_BINS.index(names[(True, side)])
    if front:
        return DIRECTION_BINS.index({'left': 'to your front left', 'right': 'to your front right',
                                     '': 'in front of you'}[side])
    if side:
        return DIRECTION_BINS.index(f'to your {side}')
    return None


@functools.lru_cache(maxsize=1)
def _nouns_longest_first() -> tuple[str, ...]:
    return tuple(sorted(_noun_types(), key=len, reverse=True))


def named_objects(text: str) -> list[tuple[int, str]]:
    """(position, object type) of every catalog noun the text names (a longer noun over the shorter ones in
    it; a plural's 's' allowed), in the order they come."""
    low, found, taken = ' ' + ' '.join(_tokens(text)) + ' ', [], []
    table = _noun_types()
    for noun in _nouns_longest_first():
        for m in re.finditer(rf' {re.escape(noun)}s? ', low):
            span = (m.start(), m.end())
            if any(a < span[1] and span[0] < b for a, b in taken):
                continue
            taken.append(span)
            found.append((m.start(), table[noun]))
    return sorted(found)


def read_answer(question_type: str, text: str, noun: str = '') -> Optional[Fact]:
    """The fact in an answer to a question of `question_type` about `noun`: by the oracle's templates where
    they hold (language.parse_answer), else read from the words; None where they say nothing it can read
    ("I don't know", or words it does not know)."""
    fact = parse_answer(question_type, text)
    if fact is not None:
        return fact
    low = ' '.join(_tokens(text))
    if question_type == 'direction':
        if _has(low, STAY):
            return Fact('direction', turn_deg=0, stay=True)
        if _has(low, AROUND):
            return Fact('direction', turn_deg=180)
        side = _side(_tokens(low))
        if side:
            return Fact('direction', turn_deg=90 if side == 'left' else -90)
        if _has(low, ON_WAY):
            return Fact('direction', turn_deg=0)
        return None
    try:
        asked = object_type(noun) if noun else ''
    except InstructionError:
        asked = ''
    if question_type == 'appearance':
        colour = _colour(low)
        return Fact('appearance', asked, colour=colour) if colour and asked else None
    if question_type != 'location' or not asked:
        return None
    if _has(low, HELD):
        return Fact('held', asked)
    others = [(at, t) for at, t in named_objects(low) if t != asked and _named_as_a_thing(low, at)]
    receptacle, inside = '', False
    if others:
        at, receptacle = others[0]
        before = _tokens((' ' + low)[:at])[-3:]       # the words just before the receptacle says in or on
        inside = any(t in ('in', 'inside', 'within', 'into') for t in before) and \
            not any(t in ('on', 'atop', 'onto') for t in before)
    k = read_bin(low)
    if k is None and not receptacle:
        return None
    return Fact('location', asked, k * 45.0 if k is not None else None, receptacle, inside=inside)


# A catalog noun names a thing only after one of these ("you can find it" names no watering can).
BEFORE_A_THING = {'the', 'a', 'an', 'that', 'this', 'your', 'its', 'in', 'on', 'inside', 'within', 'into', 'onto',
                  'atop', 'at', 'by', 'near', 'beside', 'under', 'of', 'to', 'next', 'big', 'small', 'little',
                  'kitchen', 'top'}


def _named_as_a_thing(low: str, at: int) -> bool:
    before = _tokens((' ' + low)[:at])
    return not before or before[-1] in BEFORE_A_THING


def _colour(low: str) -> str:
    for phrase, name in sorted(COLOUR_WORDS.items(), key=lambda kv: -len(kv[0])):
        if _has(low, (phrase,)):
            return name
    for t in _tokens(low):
        base = t[:-3] if t.endswith('ish') else t
        for name in COLOUR_NAMES:
            if base in (name, name + 'd', name[:-1]) or (name == 'gray' and base in ('grey', 'gre')):
                return name
    return ''
