"""Held-out wording: the oracle's answers said in words no performer was trained on (ROS-free).

The performers learn from the oracle's template answers, and the questioner's data from the synthetic
annotator's paraphrases (dialfred_oracle.annotator). A person says things otherwise. `HeldOutWording`
is an answerer (dialfred_oracle.answerers; `--answers dialfred_oracle.wording:HeldOutWording`) written
apart from both, to measure what a performer makes of other words for the same facts:

- its own phrases for where things are (clock positions, "off to the left", "back the way you came"),
  for turns ("hang a left", "do a 180") and for looks ("greyish", "metal, kind of grey");
- its own synonyms for the receptacles (a worktop for the counter, a cupboard for the cabinet, the bin
  for the garbage can) and the colours;
- other word orders (the receptacle first, the direction last);
- hedges and fillers ("hmm", "if I remember right", "pretty sure");
- answers that leave out a detail (only the receptacle, only the direction, only the colour) or add
  one that carries no fact ("you can't miss it");
- misspellings (a letter dropped, doubled or swapped) and a person's casing and punctuation.

Nothing here changes what is true: every answer says a part of what the oracle said, in other words,
and never something the oracle did not say. Each answer is drawn from a generator seeded by the task,
the question and the oracle's own answer, so the same question in the same state is always answered
the same way (runs repeat exactly; a copy of a question the transport sends again gets the same words).
"""

from __future__ import annotations

import zlib
from typing import NamedTuple, Optional, Sequence

import numpy as np

from .annotator import AnswerContent

# Where a thing is, by the oracle's direction bin ('held': in a receptacle the agent carries).
WHERE = {
    'in front of you': ('dead ahead', 'just forward of you', "at twelve o'clock", 'straight on',
                        'right there ahead'),
    'to your front left': ('a bit left of straight ahead', "at about eleven o'clock", 'forward and a little left',
                           'up ahead, leftish', 'ahead, off to the left a bit'),
    'to your left': ('off to the left', 'on your left-hand side', "at nine o'clock", 'left side of you',
                     'over on the left'),
    'to your rear left': ('back there on the left', "at seven o'clock", 'behind you, left side',
                          'back and off to the left', 'over your left shoulder, sort of'),
    'behind you': ('back the way you came', "at six o'clock", 'at your back', 'directly behind you',
                   'the other way, behind'),
    'to your rear right': ('back there on the right', "at five o'clock", 'behind you, right side',
                           'back and off to the right', 'over your right shoulder, sort of'),
    'to your right': ('off to the right', 'on your right-hand side', "at three o'clock", 'right side of you',
                      'over on the right'),
    'to your front right': ('a bit right of straight ahead', "at about one o'clock", 'forward and a little right',
                            'up ahead, rightish', 'ahead, off to the right a bit'),
}
# The oracle's direction answers (annotator.AnswerContent.where of a direction question) in other words.
TURNS = {
    'in front of you': ('keep forward', 'move ahead', 'carry on straight', 'no turning, go on ahead',
                        'forward is right'),
    'to your left': ('hang a left', 'swing left', 'rotate left', 'left turn', 'face left', 'you want the left'),
    'to your right': ('hang a right', 'swing right', 'rotate right', 'right turn', 'face right', 'you want the right'),
    'behind you': ('do a 180', 'about face', 'spin round', 'the other way', 'face the opposite way',
                   'wrong way, go back'),
    '': ("you're fine where you are", 'stop, you are there', 'this is the spot', 'nowhere, you made it',
         'stay put'),
}
# Other names for receptacles and objects the oracle names (by its noun); a noun not here is said as it is.
SYNONYMS = {
    'counter': ('worktop', 'kitchen counter', 'countertop'), 'dining table': ('table', 'big table', 'dinner table'),
    'fridge': ('refrigerator', 'icebox'), 'garbage can': ('bin', 'trash can', 'rubbish bin'),
    'cabinet': ('cupboard',), 'sink': ('basin', 'kitchen sink'), 'stove': ('hob', 'cooker'),
    'stove burner': ('hob', 'burner'), 'microwave': ('microwave oven',), 'coffee machine': ('coffee maker',),
    'sofa': ('couch',), 'side table': ('end table', 'little table'), 'dresser': ('chest of drawers',),
    'bathtub': ('tub', 'bath'), 'coffee table': ('low table',), 'shelf': ('shelving',), 'desk': ('writing desk',),
    'armchair': ('easy chair',), 'toilet': ('loo',), 'drawer': ('drawers',), 'bed': ('mattress',),
    'ottoman': ('footstool',), 'tv stand': ('tv cabinet',), 'laundry hamper': ('hamper', 'laundry basket'),
}
COLOURS = {'gray': ('greyish', 'slate', 'grey-ish'), 'navy': ('deep blue', 'navy-ish'), 'maroon': ('wine red', 'burgundy'),
           'tan': ('sandy', 'biscuit coloured'), 'beige': ('off-white', 'oatmeal'), 'olive': ('khaki green', 'drab green'),
           'teal': ('turquoise',), 'silver': ('silver-grey', 'metallic'), 'gold': ('goldish',), 'white': ('whitish',),
           'black': ('blackish', 'dark'), 'brown': ('brownish',), 'red': ('reddish',), 'green': ('greenish',),
           'blue': ('bluish',), 'yellow': ('yellowish',), 'orange': ('orangey',), 'pink': ('rosy', 'pinkish'),
           'purple': ('violet', 'purplish')}
HEDGES = ('hmm,', 'if I remember right,', 'pretty sure', 'from the video,', "I'd say", 'um', 'kinda')
FILLERS = ("you can't miss it", 'easy to spot', 'that should do it', 'hope that helps', 'as far as I saw')
P_HEDGE, P_FILLER, P_TYPO, P_LOWER, P_LEAVE_OUT = 0.25, 0.15, 0.2, 0.3, 0.25


def _one(rng: np.random.Generator, options: Sequence[str]) -> str:
    return options[int(rng.integers(len(options)))]


def _a(word: str) -> str:
    return ('an ' if word[:1].lower() in 'aeiou' else 'a ') + word


def _name(noun: str, rng: np.random.Generator) -> str:
    """`noun` or one of its other names (half the time, where it has some)."""
    others = SYNONYMS.get(noun.lower())
    return _one(rng, others) if others and rng.random() < 0.5 else noun


def location_words(c: AnswerContent, rng: np.random.Generator) -> tuple[str, frozenset]:
    """The words and the fields they leave unsaid ('bin', 'receptacle')."""
    o = _name(c.noun, rng)
    if c.held or (c.where == 'held' and not c.receptacle):
        return _one(rng, ("it's already in your hands", 'you have got it already', f'the {o}? you are carrying it',
                          'look in your hand')), frozenset()
    r = _name(c.receptacle, rng) if c.receptacle else ''
    p = {'in': _one(rng, ('inside', 'within', 'in')), 'on': _one(rng, ('on', 'sitting on', 'resting on', 'atop'))}.get(
        c.preposition, c.preposition or 'on')
    if c.where == 'held':
        return _one(rng, (f'{p} the {r} you carry', f'check the {r} in your hands', f'your {r}, {p} it')), frozenset()
    w = _one(rng, WHERE[c.where]) if c.where in WHERE else ''
    if r and w and rng.random() < P_LEAVE_OUT:           # one detail left out
        w, r = (w, '') if rng.random() < 0.5 else ('', r)
    if r and w:
        return _one(rng, (f'{p} the {r}, {w}', f'{w}, {p} the {r}', f'the {r} {w} has it', f'{o} is {w}, {p} the {r}',
                          f'go {w} to the {r}, it is {p} there', f'{p} that {r} {w}')), frozenset()
    if r:
        return _one(rng, (f'{p} the {r}', f'the {r} has it', f'{o} is {p} the {r}', f'try the {r}')), frozenset({'bin'})
    if w:
        return _one(rng, (w, f'{o} is {w}', f'from where you stand, {w}', f'look {w}')), frozenset({'receptacle'})
    return c.oracle_text.rstrip('.'), frozenset()


def appearance_words(c: AnswerContent, rng: np.random.Generator) -> str:
    col = _one(rng, COLOURS[c.colour]) if c.colour in COLOURS and rng.random() < 0.6 else c.colour
    m, o = c.material, _name(c.noun, rng)
    if m and rng.random() < P_LEAVE_OUT:
        return _one(rng, (f'{col}', f'{_a(col)} {o}', f'colour-wise {col}', f'it looks {col}'))
    if not m:
        return _one(rng, (f'{col}', f'it looks {col}'))
    return _one(rng, (f'{m}, {col}', f'{col}, {m} I think', f'{_a(m)} one, {col}', f'{m} and {col}',
                      f'colour {col}, material {m}', f'the {o} is {_a(col)} {m} thing'))


def direction_words(c: AnswerContent, rng: np.random.Generator) -> Optional[str]:
    return _one(rng, TURNS[c.where]) if c.where in TURNS else None


def misspell(text: str, rng: np.random.Generator) -> str:
    """One word of four letters or more with a letter dropped, doubled or two swapped."""
    words = text.split(' ')
    long = [k for k, w in enumerate(words) if len(w) >= 4 and w.isalpha()]
    if not long:
        return text
    k = long[int(rng.integers(len(long)))]
    w, i = words[k], int(rng.integers(1, len(words[k]) - 1))
    kind = int(rng.integers(3))
    words[k] = w[:i] + w[i + 1:] if kind == 0 else w[:i] + w[i] + w[i:] if kind == 1 else \
        w[:i - 1] + w[i] + w[i - 1] + w[i + 1:]
    return ' '.join(words)


def dress(text: str, rng: np.random.Generator) -> str:
    """Hedge, filler, typo, casing and end mark, as people type."""
    if rng.random() < P_HEDGE:
        text = f'{_one(rng, HEDGES)} {text}'
    if rng.random() < P_FILLER:
        text = f'{text}, {_one(rng, FILLERS)}'
    if rng.random() < P_TYPO:
        text = misspell(text, rng)
    if rng.random() < P_LOWER:
        return text.lower()
    return text[:1].upper() + text[1:] + _one(rng, ('.', '', '!', '.'))


class Spoken(NamedTuple):
    """Held-out words for an answer, and the fields of the oracle's answer they leave unsaid ('bin': the
    direction, 'receptacle': the place with in or on): a reader cannot read those back."""

    text: str
    unsaid: frozenset = frozenset()


class HeldOutWording:
    """The answerer (`say(asked, content)`): the oracle's answer in held-out words; None (the oracle's own)
    for an answer its templates do not cover."""

    def say(self, asked, content: AnswerContent) -> Optional[str]:
        spoken = self.spoken(asked, content)
        return spoken.text if spoken else None

    def spoken(self, asked, content: AnswerContent) -> Optional[Spoken]:
        """`say`'s words with what they leave unsaid (benchmarks/answer_reading.py scores a reader on the
        fields said)."""
        rng = np.random.default_rng(zlib.crc32('|'.join((asked.task_id, asked.question_type, asked.object_noun,
                                                         content.oracle_text)).encode()))
        unsaid = frozenset()
        if asked.question_type == 'location' and (content.held or content.where or content.receptacle):
            words, unsaid = location_words(content, rng)
        elif asked.question_type == 'appearance' and content.colour:
            words = appearance_words(content, rng)
        elif asked.question_type == 'direction':
            words = direction_words(content, rng)
        else:
            words = None
        return Spoken(dress(words, rng), unsaid) if words else None
