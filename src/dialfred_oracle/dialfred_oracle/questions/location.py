"""The location question, "Where is the apple?", whole: the oracle's rule and wording ("The apple is to
your left in the fridge."), the words read back, the check against the ground truth, and the synthetic
annotator's rule (asked when the target is out of view or shut in; reworded with synonyms).

The direction is the 45-degree bin of the part of the object the agent sees when it is in view, else
of its centre (ObjectFact.where); the receptacle is the one that holds it, "in" for containers and
"on" otherwise.
"""

from __future__ import annotations

import re
from typing import Optional

import numpy as np

from dialfred_sim.ground_truth import ObjectFact, Snapshot
from dialfred_sim.protocol import PAPER_QUESTION_KINDS

from .base import DIRECTION_BINS, Answer, AnswerContent, OracleQuestion, direction_bin, one_of, register, \
    with_article

_BINS = '|'.join(re.escape(b) for b in DIRECTION_BINS)
# The oracle's three sentences, as written by `words` (matched without regard to case).
PLACED = re.compile(rf'^the (?P<noun>.+?) is (?P<where>{_BINS})(?: (?P<prep>in|on) the (?P<recep>.+))?\.$', re.I)
CARRIED = re.compile(r'^the (?P<noun>.+?) is (?P<prep>in|on) the (?P<recep>.+) you are holding\.$', re.I)
HOLDING = re.compile(r'^you are holding the (?P<noun>.+)\.$', re.I)

PREPOSITIONS = {'in': ('in', 'inside'), 'on': ('on', 'on top of')}


def words(snapshot: Snapshot, fact: ObjectFact) -> str:
    """The oracle's sentence for where `fact` is, seen from the agent of `snapshot`."""
    if fact.held:
        return f'You are holding the {fact.noun}.'
    parent = snapshot.objects.get(fact.parent_id) if fact.parent_id else None
    if parent is not None and parent.held:
        return f'The {fact.noun} is {fact.preposition} the {fact.parent_noun} you are holding.'
    where = direction_bin(snapshot.agent[:2], snapshot.agent[2], fact.where[:2])
    if fact.parent_id:
        return f'The {fact.noun} is {where} {fact.preposition} the {fact.parent_noun}.'
    return f'The {fact.noun} is {where}.'


def where_phrases(where: str) -> tuple[str, ...]:
    """Ways to say a direction bin ('left', 'behind right', 'front', ...) relative to the listener."""
    w = where.replace('_', ' ').lower()
    side = 'left' if 'left' in w else 'right' if 'right' in w else ''
    back = any(k in w for k in ('behind', 'back', 'around', 'rear'))
    front = not back and any(k in w for k in ('front', 'ahead', 'forward', 'straight'))
    if back and side:
        return (f'behind you on the {side}', f'back and to your {side}', f'behind you to the {side}',
                f'over your {side} shoulder')
    if back:
        return ('behind you', 'at your back', 'right behind you', 'back behind you')
    if front and side:
        return (f'ahead on your {side}', f'in front of you to the {side}', f'slightly to your {side}',
                f'ahead and to the {side}')
    if front:
        return ('in front of you', 'straight ahead', 'ahead of you', 'right in front of you')
    if side:
        return (f'to your {side}', f'on your {side}', f'on the {side}', f'to the {side}', f'{side} of you')
    return ('',)


class Location(OracleQuestion):
    kind = PAPER_QUESTION_KINDS[0]
    human_share = 0.72
    choice_bias = 0.1941
    necessary_p = (0.35, 0.85)

    def answer(self, snapshot: Snapshot, object_id: str) -> Answer:
        fact = snapshot.objects[object_id]
        return Answer(True, words(snapshot, fact), question_type=self.name, object_noun=fact.noun,
                      object_id=object_id)

    def parts(self, text: str) -> Optional[dict]:
        text = text.strip()
        m = HOLDING.match(text)
        if m:
            return {'noun': m.group('noun'), 'held': True}
        m = CARRIED.match(text)
        if m:
            return {'noun': m.group('noun'), 'preposition': m.group('prep'), 'receptacle': m.group('recep'),
                    'where': 'held'}
        m = PLACED.match(text)
        if m:
            return {'noun': m.group('noun'), 'where': m.group('where'), 'preposition': m.group('prep') or '',
                    'receptacle': m.group('recep') or ''}
        return None

    def vocabulary(self) -> list[str]:
        return [*DIRECTION_BINS, 'The is in on the you are holding. You are holding the.']

    def check(self, snapshot: Snapshot, ans: Answer, fact: Optional[ObjectFact]) -> dict[str, Optional[bool]]:
        """receptacle_ok: the object's parent receptacle with the right preposition (or none for an object
        without one, or held when it is); direction_ok: the direction bin recomputed from the geometry."""
        parts = self.parts(ans.text)
        if parts is None:
            return {'receptacle_ok': False, 'direction_ok': False}
        if parts.get('held'):
            return {'receptacle_ok': fact.held}
        parent = snapshot.objects.get(fact.parent_id)
        if parts['where'] == 'held':
            return {'receptacle_ok': (parent is not None and parent.held and parts['receptacle'] == fact.parent_noun
                                      and parts['preposition'] == fact.preposition)}
        if not parts['receptacle']:
            receptacle_ok = not fact.parent_id and not fact.held
        else:
            receptacle_ok = parts['receptacle'] == fact.parent_noun and parts['preposition'] == fact.preposition
        return {'receptacle_ok': receptacle_ok,
                'direction_ok': parts['where'] == direction_bin(snapshot.agent[:2], snapshot.agent[2],
                                                                fact.where[:2])}

    def evidence(self, s) -> float:
        return float(not s.target_visible) + 0.5 * float(s.target_enclosed) - float(s.target_held)

    def called_for(self, noun: str, s) -> bool:
        return noun == s.main_noun and (not s.target_visible or s.target_enclosed)

    def covered(self, c: AnswerContent) -> bool:
        return c.held or bool(c.where or c.receptacle)

    def candidate(self, c: AnswerContent, rng: np.random.Generator, distractor: bool) -> str:
        o, w = c.noun, one_of(rng, where_phrases(c.where))
        if c.held:
            return one_of(rng, ("you're holding it", 'it is in your hand', 'you already have it',
                                f'you are already holding the {o}', f'the {o} is in your hand already'))
        if not c.receptacle:
            if not w:
                return one_of(rng, ('right here', f"the {o} is right here", "it's close by"))
            return one_of(rng, (w, f"it's {w}", f'the {o} is {w}', f'look {w}', f'you will see the {o} {w}'))
        p, r = one_of(rng, PREPOSITIONS.get(c.preposition, (c.preposition or 'on',))), c.receptacle
        if c.where == 'held':
            return one_of(rng, (f"{p} the {r} you're holding", f'{p} the {r} in your hand',
                                f"it's {p} the {r} you carry", f'the {o} is {p} the {r} you are holding'))
        forms = [f'{p} the {r}', f"it's {p} the {r}", f'it should be {p} the {r}', f'check {p} the {r}',
                 f'the {o} is {p} the {r}', f'you can find it {p} the {r}']
        if w:
            forms += [f'{p} the {r} {w}', f'{w}, {p} the {r}', f"it's {w} {p} the {r}", f'the {o} is {w} {p} the {r}',
                      f'the {o} is {p} the {r} {w}', f'you can find it {p} the {r} {w}', f'look {w}, {p} the {r}',
                      f'there is {with_article(o)} {p} the {r} {w}', f'the {o} is sitting {p} the {r} {w}',
                      f'go to the {r} {w}, the {o} is {p} it']
        return one_of(rng, forms)


LOCATION = register(Location())
