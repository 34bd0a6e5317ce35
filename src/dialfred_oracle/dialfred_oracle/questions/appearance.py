"""The appearance question, "What does the apple look like?", whole: the oracle's rule and wording ("The
apple is red and made of food."), the words read back, the check against the ground truth, and the
synthetic annotator's rule (asked when a look-alike is about; reworded with colour synonyms).

The colour is named from the object's rendered pixels (Snapshot.appearances; a close-up when too little
of it is in view), from its metadata when there are none; the material from its metadata.
"""

from __future__ import annotations

import re
from typing import Optional

import numpy as np

from dialfred_sim.ground_truth import ObjectFact, Snapshot
from dialfred_sim.protocol import PAPER_QUESTION_KINDS

from ..colours import colour_name
from .base import Answer, AnswerContent, OracleQuestion, one_of, register, with_article

# The oracle's sentence, as written by `words` (matched without regard to case).
LOOKS = re.compile(r'^the (?P<noun>.+?) is (?P<colour>[a-z]+) and made of (?P<material>.+)\.$', re.I)
LOOK_ALIKE_P = 0.8          # the annotator asks about a noun with a look-alike, where there is one, this often
COLOUR_WORDS = {'gray': ('gray', 'grey'), 'navy': ('navy', 'navy blue', 'dark blue'),
                'maroon': ('maroon', 'dark red'), 'tan': ('tan', 'light brown'), 'beige': ('beige', 'cream'),
                'olive': ('olive', 'olive green'), 'teal': ('teal', 'blue green'), 'khaki': ('khaki',),
                'silver': ('silver', 'silvery'), 'gold': ('gold', 'golden'), 'pink': ('pink', 'light pink')}


def words(snapshot: Snapshot, fact: ObjectFact) -> tuple[str, bool]:
    """The oracle's sentence for how `fact` looks, and whether its colour came from pixels."""
    look = snapshot.appearances.get(fact.object_id)
    colour = colour_name(look.pixels) if look is not None and len(look.pixels) else None
    return f'The {fact.noun} is {colour or fact.colour} and made of {fact.material}.', colour is not None


class Appearance(OracleQuestion):
    kind = PAPER_QUESTION_KINDS[1]
    reads_looks = True
    human_share = 0.22
    choice_bias = -1.4978
    necessary_p = (0.3, 0.8)

    def answer(self, snapshot: Snapshot, object_id: str) -> Answer:
        fact = snapshot.objects[object_id]
        text, from_pixels = words(snapshot, fact)
        return Answer(True, text, question_type=self.name, object_noun=fact.noun, object_id=object_id,
                      colour_from_pixels=from_pixels)

    def parts(self, text: str) -> Optional[dict]:
        m = LOOKS.match(text.strip())
        return {'noun': m.group('noun'), 'colour': m.group('colour'), 'material': m.group('material')} if m else None

    def vocabulary(self) -> list[str]:
        return ['The is and made of.']

    def check(self, snapshot: Snapshot, ans: Answer, fact: Optional[ObjectFact]) -> dict[str, Optional[bool]]:
        """colour_ok: the answer names the object's colour variant."""
        parts = self.parts(ans.text)
        return {'colour_ok': parts is not None and parts['colour'] == fact.colour}

    def evidence(self, s) -> float:
        return float(s.main_has_distractor) + 0.5 * float(bool(s.distractor_nouns) and not s.main_has_distractor)

    def called_for(self, noun: str, s) -> bool:
        return noun in s.distractor_nouns

    def narrow_nouns(self, nouns: list[str], s, rng: np.random.Generator) -> list[str]:
        look_alikes = [n for n in nouns if n in s.distractor_nouns]
        return look_alikes if look_alikes and rng.random() < LOOK_ALIKE_P else nouns

    def covered(self, c: AnswerContent) -> bool:
        return bool(c.colour)

    def candidate(self, c: AnswerContent, rng: np.random.Generator, distractor: bool) -> str:
        o, m = c.noun, c.material
        col = one_of(rng, COLOUR_WORDS.get(c.colour, (c.colour,)))
        made = one_of(rng, ('made of', 'made out of'))
        forms = [col, f"it's {col}", f'the {col} one', f"it's {col} colored", f'it is {with_article(col)} {o}']
        if m:
            forms += [f'{col} {m}', f'it is {col} and {made} {m}', f'the {o} is {col} and {made} {m}',
                      f'{with_article(col)} {o} {made} {m}', f'look for the {col} {m} one',
                      f"it's the {col} one, {made} {m}", f'{col}, {made} {m}', f"it's {with_article(m)} {o}, {col} in color",
                      f'{col} and {m}']
        if distractor:
            forms += [f'the {col} {o}, not the other one', f'the {col} one, there are two of them',
                      f'pick the {col} {o}']
        return one_of(rng, forms)


APPEARANCE = register(Appearance())
