"""A reader of answers in a person's words: the facts of the oracle's fields from free text (no ROS).

`language.parse_answer` reads the oracle's templates exactly. A person says "it's on the counter behind
you, to the right", "greyish", "turn around and walk forward". `read_answer` reads such words by what they
name, with no template:

- a direction answer: staying ("you don't need to move", "stay where you are", "you're there"), turning
  around ("turn around", "the other way", "180"), a side ("left", "right": never "right" as in "right
  here" or "right behind you"), going on ("straight", "ahead", "forward");
- a location answer: held ("you're holding it", "in your hand"); a direction bin from the words for a
  side, the back and the front ("behind you on the left" is the rear left, "ahead and to the right" the
  front right, "slightly to your left" the front left) or a clock position ("at 3 o'clock", "at ten
  o'clock"); a receptacle, any object of the catalog the answer names other than the one asked about (the
  catalog's own everyday names: "refrigerator", "cupboard", "trash can", and EVERYDAY_NAMES: "worktop",
  "couch", "hob"), in it or on it (unsaid: as things lie in a receptacle of its kind, the catalog's);
- an appearance answer: a colour of the palette, or other colour words ("grey", "greyish", "dark blue",
  "crimson", "pale pink"): their sRGB, mixed, darker, lighter or duller, read as the nearest palette colour.

A word of the reader's misspelt (a letter dropped, doubled or two swapped: "rihgt", "fridgge") is read as
that word, where the misspelling is no word itself and could be no other of them. What the words do not
say stays unsaid (a location without a side, say): the fact has what was read. Its vocabulary is the
catalog's, the palette's and everyday English. It was written against the annotator's paraphrases; its
second version (misspellings, everyday names, hours in words, "right" as in correct, colour words by
sRGB, in or on by the catalog) was written after its first misreads on the held-out wording
(dialfred_oracle.wording) had been seen, which `./dialfred bench answer_reading` measures it on: that
figure is no longer one of words never seen.
"""

from __future__ import annotations

import dataclasses
import functools
import re
from typing import Optional

import numpy as np
from dialfred_oracle.answers import DIRECTION_BINS
from dialfred_sim.catalog import load_catalog
from dialfred_sim.palette import COLOUR_NAMES, PALETTE

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
HOURS = {'one': 1, 'two': 2, 'three': 3, 'four': 4, 'five': 5, 'six': 6, 'seven': 7, 'eight': 8, 'nine': 9, 'ten': 10,
         'eleven': 11, 'twelve': 12}
# "right" says correct, not a side, after these words ("if I remember right", "that's right", "all right").
CORRECT_BEFORE = {'remember', 'recall', 'is', "that's", 'thats', 'all', 'quite', 'exactly', 'just', 'it'}
# Everyday names of receptacles that the catalog's nouns do not list, British and American (-> object type).
EVERYDAY_NAMES = {'worktop': 'CounterTop', 'benchtop': 'CounterTop', 'work surface': 'CounterTop',
                  'kitchen counter': 'CounterTop', 'icebox': 'Fridge', 'fridge freezer': 'Fridge',
                  'hob': 'StoveBurner', 'cooktop': 'StoveBurner', 'stovetop': 'StoveBurner', 'cooker': 'StoveBurner',
                  'stove': 'StoveBurner', 'loo': 'Toilet', 'lavatory': 'Toilet', 'washbasin': 'SinkBasin',
                  'tub': 'BathtubBasin', 'couch': 'Sofa', 'settee': 'Sofa', 'hamper': 'LaundryHamper',
                  'laundry basket': 'LaundryHamper', 'coffee maker': 'CoffeeMachine', 'dustbin': 'GarbageCan',
                  'rubbish bin': 'GarbageCan', 'wastebin': 'GarbageCan', 'mattress': 'Bed',
                  'bedside table': 'SideTable', 'easy chair': 'ArmChair', 'recliner': 'ArmChair',
                  'dinner table': 'DiningTable', 'microwave oven': 'Microwave'}
# Colour words beyond the palette's names, by their usual sRGB (X11/CSS values where those name them): a
# phrase of them is read as the palette colour nearest its colour (`_colour`).
COLOUR_RGB = {'grey': (128, 128, 128), 'slate': (112, 128, 144), 'charcoal': (54, 69, 79), 'ash': (178, 190, 181),
              'steel': (113, 121, 126), 'metallic': (190, 195, 205), 'chrome': (200, 205, 210),
              'wine': (114, 47, 55), 'burgundy': (128, 0, 32), 'crimson': (220, 20, 60), 'scarlet': (255, 36, 0),
              'cherry': (210, 4, 45), 'ruby': (155, 17, 30), 'rust': (183, 65, 14), 'brick': (178, 34, 34),
              'sand': (194, 178, 128), 'wheat': (245, 222, 179), 'biscuit': (255, 228, 196), 'buff': (240, 220, 130),
              'oatmeal': (222, 210, 185), 'cream': (255, 253, 208), 'ivory': (255, 255, 240), 'bone': (227, 218, 201),
              'drab': (150, 113, 23), 'lime': (50, 205, 50), 'mint': (152, 255, 152), 'emerald': (80, 200, 120),
              'forest': (34, 139, 34), 'sage': (188, 184, 138), 'turquoise': (64, 224, 208), 'cyan': (0, 200, 200),
              'aqua': (0, 200, 200), 'sky': (135, 206, 235), 'azure': (0, 127, 255), 'cobalt': (0, 71, 171),
              'royal': (65, 105, 225), 'indigo': (75, 0, 130), 'violet': (143, 0, 255), 'lavender': (181, 126, 220),
              'lilac': (200, 162, 200), 'magenta': (255, 0, 255), 'plum': (142, 69, 133), 'rose': (255, 102, 153),
              'salmon': (250, 128, 114), 'coral': (255, 127, 80), 'peach': (255, 203, 164), 'amber': (255, 191, 0),
              'mustard': (225, 173, 1), 'lemon': (255, 247, 0), 'chocolate': (123, 63, 0), 'coffee': (111, 78, 55),
              'caramel': (175, 111, 9), 'copper': (184, 115, 51), 'bronze': (205, 127, 50), 'brass': (181, 166, 66),
              'ebony': (40, 36, 32), 'jet': (20, 20, 20), 'snow': (250, 250, 250), 'golden': (212, 175, 55),
              'rosy': (255, 150, 190), 'silvery': (190, 195, 205)}
DARKEN, LIGHTEN, DULL = 0.7, 0.35, 0.4     # how much darker, lighter (towards white), duller (towards grey)
# Words that make a colour darker, lighter or duller ("deep blue", "pale green", "dusty pink").
DARKER, LIGHTER, DULLER = {'dark', 'deep', 'darkish'}, {'light', 'pale', 'pastel', 'lightish'}, \
    {'dull', 'muted', 'dusty', 'faded'}


def _tokens(text: str) -> list[str]:
    return re.findall(r"[a-z0-9']+", text.lower().replace('-', ' '))


def _has(text: str, phrases) -> bool:
    return any(re.search(rf'(?<![a-z]){re.escape(p)}(?![a-z])', text) for p in phrases)


def _side(tokens: list[str]) -> str:
    """'left', 'right' or '' (a 'right' that intensifies the next word, or says correct, is no side)."""
    for k, t in enumerate(tokens):
        if t in ('left', 'leftish', 'lefthand'):
            return 'left'
        if t in ('right', 'rightish', 'righthand'):
            after = tokens[k + 1] if k + 1 < len(tokens) else ''
            before = tokens[k - 1] if k else ''
            if t != 'right' or (after not in INTENSIFIED and before not in CORRECT_BEFORE):
                return 'right'
    return ''


def read_bin(text: str) -> Optional[int]:
    """The index into DIRECTION_BINS a location answer's words give, None if they give none."""
    low = text.lower()
    m = re.search(r'(\d{1,2}|[a-z]+)\s*o\s*\'?\s*clock', low)
    hour = (int(m.group(1)) if m.group(1).isdigit() else HOURS.get(m.group(1))) if m else None
    if hour in CLOCK:
        return CLOCK[hour]
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
def _names() -> dict[str, str]:
    """Every noun the reader knows (lower case) -> its object type: the catalog's, then EVERYDAY_NAMES."""
    return {**EVERYDAY_NAMES, **_noun_types()}


@functools.lru_cache(maxsize=1)
def _nouns_longest_first() -> tuple[str, ...]:
    return tuple(sorted(_names(), key=len, reverse=True))


# Short everyday words that a misspelling of the reader's words could look like: never corrected.
COMMON = {'her', 'hat', 'the', 'then', 'than', 'ten', 'bit', 'lit', 'let', 'lot', 'fit', 'sit', 'set', 'tight',
          'light', 'might', 'night', 'sight', 'fight', 'eight', 'weight', 'lift', 'loft', 'from', 'form', 'for',
          'four', 'our', 'out', 'bad', 'bag', 'back', 'bake', 'been', 'bean', 'one', 'once', 'see', 'seen', 'saw',
          'say', 'said', 'way', 'well', 'will', 'wall', 'when', 'where', 'were', 'wear', 'near', 'nearly', 'dear',
          'door', 'floor', 'flour', 'room', 'here', 'there', 'these', 'those', 'this', 'that', 'what', 'with',
          'have', 'has', 'had', 'hand', 'hands', 'and', 'any', 'all', 'also', 'just', 'must', 'most', 'sure',
          'pretty', 'think', 'thing', 'look', 'looks', 'like', 'kind', 'kinda', 'sort', 'spot', 'stop', 'top',
          'tops', 'pot', 'pan', 'can', 'cant', "can't", 'easy', 'miss', 'hope', 'helps', 'should', 'would',
          'could', 'video', 'made', 'make', 'maybe', 'yes', 'yeah', 'nope', 'know', 'now', 'how', 'not', 'nothing',
          'leave', 'lean', 'mean', 'meant', 'rest', 'resting', 'sitting', 'find', 'fine', 'five', 'mine', 'nine',
          'line', 'side', 'sided', 'wide', 'ride', 'rid', 'reed', 'red', 'read', 'bread', 'bled', 'blue', 'glue',
          'clue', 'true', 'grew', 'grey', 'gray', 'great', 'green', 'greet', 'tan', 'tin', 'ton', 'turn', 'turns',
          'burn', 'torn', 'tone', 'stone', 'store', 'stove', 'over', 'oven', 'open', 'even', 'ever', 'very', 'vary'}


def _lexicon() -> set[str]:
    """The words the reader reads by: its phrases', sides', names' and colours'."""
    phrases = (*STAY, *AROUND, *ON_WAY, *HELD, *INTENSIFIED, *CORRECT_BEFORE, *BEFORE_A_THING, *_names(),
               *COLOUR_NAMES, *COLOUR_WORDS, *COLOUR_RGB, *DARKER, *LIGHTER, *DULLER, *HOURS,
               'left', 'right', 'behind', 'rear', 'shoulder', 'front', 'ahead', 'forward', 'straight', 'slightly',
               'bit', 'little', 'clock', 'inside', 'within', 'into', 'onto', 'atop', 'turn', 'around')
    return {w for p in phrases for w in _tokens(p)}


@functools.lru_cache(maxsize=1)
def _misspellings() -> dict[str, str]:
    """A misspelling (a letter dropped, doubled or two swapped) of one of the reader's words of four letters or
    more -> that word; none that is a word itself, or a misspelling of two of them."""
    lexicon = _lexicon()
    known = lexicon | COMMON
    seen: dict[str, set[str]] = {}
    for w in (w for w in lexicon if len(w) >= 4 and w.isalpha()):
        variants = {w[:i] + w[i + 1:] for i in range(len(w))} | {w[:i] + w[i] + w[i:] for i in range(len(w))} | \
            {w[:i] + w[i + 1] + w[i] + w[i + 2:] for i in range(len(w) - 1)}
        for v in variants - {w}:
            seen.setdefault(v, set()).add(w)
    return {v: next(iter(ws)) for v, ws in seen.items() if len(ws) == 1 and v not in known and len(v) >= 3}


def _spelt(tokens: list[str]) -> list[str]:
    """`tokens` with each misspelling of the reader's words put right (`_misspellings`)."""
    table = _misspellings()
    return [table.get(t, t) for t in tokens]


def named_objects(text: str) -> list[tuple[int, str]]:
    """(position, object type) of every catalog noun the text names (a longer noun over the shorter ones in
    it; a plural's 's' allowed), in the order they come."""
    low, found, taken = ' ' + ' '.join(_tokens(text)) + ' ', [], []
    table = _names()
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
    if fact is not None and fact.kind == 'appearance' and fact.colour not in PALETTE:
        colour = _colour(fact.colour)
        return dataclasses.replace(fact, colour=colour) if colour else None
    if fact is not None:          # "The mug is grey and made of glass": the template's form, another word
        return fact
    low = ' '.join(_spelt(_tokens(text)))
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
        said_in = any(t in ('in', 'inside', 'within', 'into') for t in before)
        said_on = any(t in ('on', 'atop', 'onto') for t in before)
        # unsaid ("try the fridge"): as things lie in or on a receptacle of its kind (the catalog's)
        inside = said_in and not said_on if said_in or said_on else load_catalog()[receptacle].preposition == 'in'
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
    """The palette colour an answer's words name: a palette name said alone as it is; else the colour of the
    colour words said (COLOUR_WORDS, COLOUR_RGB, the palette's; "-ish" taken off), mixed, made darker, lighter
    or duller by the words before them, and the palette colour nearest it (CIELAB); '' if none."""
    for phrase, name in sorted(COLOUR_WORDS.items(), key=lambda kv: -len(kv[0])):
        phrase = ' '.join(_tokens(phrase))
        if _has(low, (phrase,)) and not _colour_words(_tokens(low.replace(phrase, ' '))):
            return name
    said = _colour_words(_tokens(low))
    if not said:
        return ''
    words = set(_tokens(low))
    if len(said) == 1 and said[0][0] in PALETTE and not words & (DARKER | LIGHTER | DULLER):
        return said[0][0]
    rgb = np.mean([c for _, c in said], axis=0)
    if words & DARKER:
        rgb = rgb * DARKEN
    if words & LIGHTER:
        rgb = rgb + (255.0 - rgb) * LIGHTEN
    if words & DULLER:
        rgb = rgb + (128.0 - rgb) * DULL
    lab = _lab(rgb)
    return min(_palette_lab().items(), key=lambda kv: float(np.sum((kv[1] - lab) ** 2)))[0]


@functools.lru_cache(maxsize=1)
def _palette_lab() -> dict[str, np.ndarray]:
    return {name: _lab(rgb) for name, rgb in PALETTE.items()}


def _colour_words(tokens: list[str]) -> list[tuple[str, tuple]]:
    """(word, sRGB) of each colour word among `tokens` ("greyish" and "reddish" as grey and red)."""
    out = []
    for t in tokens:
        for base in dict.fromkeys((t, t[:-3], t[:-4], t[:-1], t[:-2] + 'e' if t.endswith('ey') else t)):
            base = {'gre': 'grey', 'whit': 'white', 'purpl': 'purple', 'orang': 'orange', 'blu': 'blue'}.get(base, base)
            if base in PALETTE or base in COLOUR_RGB:
                out.append((base, PALETTE.get(base) or COLOUR_RGB[base]))
                break
    return out


def _lab(rgb) -> np.ndarray:
    """CIELAB (D65) of an sRGB colour in 0-255."""
    c = np.asarray(rgb, float) / 255.0
    c = np.where(c > 0.04045, ((c + 0.055) / 1.055) ** 2.4, c / 12.92)
    xyz = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]]) @ c
    xyz = xyz / np.array([0.9505, 1.0, 1.089])
    f = np.where(xyz > 0.008856, np.cbrt(xyz), 7.787 * xyz + 16 / 116)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])
