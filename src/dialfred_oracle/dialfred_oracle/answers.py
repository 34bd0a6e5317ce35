"""The oracle: templated answers to location, appearance and direction questions (and any type registered).

DialFRED's oracle (paper, "Generating answers") answers from the simulator's ground truth:
  Location:   "The apple is to your left in the fridge."   (direction from the agent, to the part
              of it the agent sees when in view, else to its centre; and the receptacle that holds
              it, "in" for containers and "on" otherwise)
  Appearance: "The apple is red and made of food."         (colour from rendered pixels, material
              from the object's metadata)
  Direction:  "You should turn left." / "You don't need to move."  (where the expert ends the task,
              seen from the agent now)
`answer(snapshot, question_type, noun)` never raises: a question it cannot answer gets
`Answer(valid=False, reason=...)`. Which object a phrase means ("apples", "the TV", "sliced
tomato") is decided by nouns.py; what each type answers, in which words, by its module in
`questions/` (the registry: `questions.oracle_question`). Everything here is plain Python over a
`Snapshot` (dialfred_sim.ground_truth); the ROS node only adapts messages.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import replace
from typing import Callable, Optional

import numpy as np

from dialfred_sim.protocol import object_question_types, question_kinds, question_types
from dialfred_sim.protocol import question_text as protocol_question_text
from dialfred_sim.ground_truth import ObjectFact, Snapshot

from .nouns import meanings
from .questions import DIRECTION_BINS, Answer, direction_bin, oracle_question
from .questions.base import bearing
from .questions.direction import GO_STRAIGHT, STAY, TURN_AROUND, TURN_LEFT, TURN_RIGHT
from .questions.direction import advice as direction_advice

__all__ = ['Answer', 'DIRECTION_BINS', 'GO_STRAIGHT', 'STAY', 'TURN_AROUND', 'TURN_LEFT', 'TURN_RIGHT', 'WITHHELD',
           'MAX_NOUN_CHARS', 'Perturbation', 'answer', 'answer_now', 'bearing', 'check_answer', 'direction_advice',
           'direction_bin', 'parse_question_type', 'question_aliases', 'question_text', 'refusal_on_its_face',
           'resolve_object', 'situation_key']

MAX_NOUN_CHARS = 64
WITHHELD = "I don't know."   # a withheld answer: the question was fine, the oracle does not say
_ARTICLES = ('the ', 'a ', 'an ')


def question_aliases() -> dict[str, str]:
    """The short tokens the oracle accepts for the registered types: 'loc' -> 'location', ..."""
    return {q.token: q.name for q in question_kinds()}


def question_text(question_type: str, noun: str = '') -> str:
    """The question as a person would ask it: 'Where is the apple?'. ValueError for an unknown type."""
    qtype = parse_question_type(question_type)
    if qtype is None:
        raise ValueError(f'unknown question type {question_type!r}; expected one of {question_types()}')
    return protocol_question_text(qtype, noun)


def parse_question_type(question_type) -> Optional[str]:
    """'location', 'appearance' or 'direction' for any spelling the oracle accepts ('Location',
    ' LOC ', 'dir'); None for anything else."""
    if not isinstance(question_type, str) or len(question_type) > 32:
        return None
    q = question_type.strip().lower()
    q = question_aliases().get(q, q)
    return q if q in question_types() else None


# ---------------------------------------------------------------------- which object is meant

def _noun_problem(noun) -> str:
    """Why `noun` cannot name an object ('' if it can)."""
    if not isinstance(noun, str):
        return 'the object noun must be text'
    if len(noun) > MAX_NOUN_CHARS:
        return f'the object noun is longer than {MAX_NOUN_CHARS} characters'
    if any(ord(ch) < 32 or 127 <= ord(ch) < 160 for ch in noun):
        return 'the object noun contains control characters'
    if not noun.isascii():
        return 'the object noun contains non-ASCII characters; object names are English words'
    if not _normalise(noun):
        return 'no object noun given'
    return ''


def _normalise(noun: str) -> str:
    """'  The Sink-Basin? ' -> 'sink-basin' (then compared as 'sinkbasin': nouns.key)."""
    n = ' '.join(noun.strip().strip('.,;:!?"\'()[]{}<>`').split()).lower()
    for article in _ARTICLES:
        n = n.removeprefix(article)
    return n.strip()


def _distance(snapshot: Snapshot, fact: ObjectFact) -> float:
    return math.hypot(fact.position[0] - snapshot.agent[0], fact.position[1] - snapshot.agent[1])


def resolve_object(snapshot: Snapshot, noun) -> tuple[str, str]:
    """(object id, '') of the object a question about `noun` is about, or ('', reason).

    The phrase's readings (nouns.meanings: as typed, catalog variants, everyday names, singular,
    without modifiers, slices of a sliced food) are tried in order. In free exploration the first
    reading that names an object in the scene wins, and the nearest such object is meant. In a task
    only the task's own objects are answered about (its instance, not a look-alike): the first
    reading that names one of them wins; if readings name only other objects, the reason says the
    object is not part of this task."""
    problem = _noun_problem(noun)
    if problem:
        return '', problem
    shown = _normalise(noun)
    facts = snapshot.objects.values()
    task_ids = list(dict.fromkeys(snapshot.task_objects.values())) if snapshot.task_id else None
    seen_elsewhere = False
    for meaning in meanings(shown):
        candidates = [f for f in facts if meaning.matches(f.noun, f.type_name)]
        if not candidates:
            continue
        if task_ids is None:
            return min(candidates, key=lambda f: (_distance(snapshot, f), f.object_id)).object_id, ''
        relevant = [f for f in candidates if f.object_id in task_ids]
        if relevant:
            return min(relevant, key=lambda f: task_ids.index(f.object_id)).object_id, ''
        seen_elsewhere = True
    if seen_elsewhere:
        return '', f'the {shown} is not part of this task'
    return '', f'there is no {shown} here'


# ---------------------------------------------------------------------- answers

def answer(snapshot: Snapshot, question_type, object_noun='') -> Answer:
    """The oracle's answer to a question of `question_type` ('location', 'appearance',
    'direction'; or the tokens 'loc', 'app', 'dir') about `object_noun`. Never raises."""
    qtype = parse_question_type(question_type)
    if qtype is None:
        shown = question_type[:32] if isinstance(question_type, str) else type(question_type).__name__
        return Answer(False, reason=f'unknown question type {shown!r}; expected one of {", ".join(question_types())}')
    rules = oracle_question(qtype)
    if rules is None:
        return Answer(False, reason=f'the oracle has no rule for {qtype!r} questions', question_type=qtype)
    if not rules.kind.names_object:
        return rules.answer(snapshot, '')
    object_id, reason = resolve_object(snapshot, object_noun)
    if not object_id:
        return Answer(False, reason=reason, question_type=qtype)
    return rules.answer(snapshot, object_id)


def refusal_on_its_face(question_type, object_noun: str = '') -> tuple[Optional[str], Optional[Answer]]:
    """(the question type, None) for a question fit to put to the world; (None, the refusal) for one
    malformed on its face (an unknown type, an overlong noun), which never needs the simulator."""
    qtype = parse_question_type(question_type)
    if qtype is None:
        return None, answer(None, question_type, object_noun)
    if qtype in object_question_types() and len(object_noun) > MAX_NOUN_CHARS:
        return None, Answer(False, reason=f'the object noun is longer than {MAX_NOUN_CHARS} characters',
                            question_type=qtype)
    return qtype, None


def answer_now(snapshot_now: Snapshot, question_type: str, object_noun: str,
               with_looks: Callable[[str], Snapshot]) -> Answer:
    """The oracle's answer in the world's state `snapshot_now`, the one rule of both the node and the
    in-process oracle. A type that `reads_looks` is answered again from `with_looks(object_id)`: the state
    with the rendered looks of the object the first answer resolved the noun to."""
    result = answer(snapshot_now, question_type, object_noun)
    rules = oracle_question(result.question_type)
    if result.valid and rules is not None and rules.reads_looks and result.object_id:
        result = answer(with_looks(result.object_id), question_type, object_noun)
    return result


# ---------------------------------------------------------------------- checking answers

def check_answer(snapshot: Snapshot, ans: Answer) -> dict[str, Optional[bool]]:
    """Whether an answer's text agrees with the ground truth of `snapshot` (for benchmarks): each type's
    `OracleQuestion.check`.

    receptacle_ok: a location answer names the object's parent receptacle with the right
    preposition (or none for an object without one, or says it is held when it is);
    direction_ok: a location answer's direction bin, or a direction answer's advice, recomputed
    from the geometry (for an object in view, from the part the agent sees: ObjectFact.where);
    colour_ok: an appearance answer names the object's colour variant.
    None where a check does not apply (and for invalid answers); all False for an answer about an
    object the snapshot does not hold."""
    out: dict[str, Optional[bool]] = {'receptacle_ok': None, 'direction_ok': None, 'colour_ok': None}
    rules = oracle_question(ans.question_type)
    if not ans.valid or rules is None:
        return out
    fact: Optional[ObjectFact] = None
    if rules.kind.names_object:
        fact = snapshot.objects.get(ans.object_id)
        if fact is None:
            return {k: False for k in out}
    out.update(rules.check(snapshot, ans, fact))
    return out


# ---------------------------------------------------------------------- the paper's ablation

class Perturbation:
    """Withhold answers of one question type with probability `probability` (the paper's ablation
    uses 0.5). question_type '' means every type; probability 0 never withholds.

    Whether a question is withheld is a pure function of `seed` and the question's `key` (the node
    uses the task, the question and the agent's pose): the same question in the same situation gets
    the same treatment, whichever process asks it, in whatever order, and asking again does not get
    an answer out of a withholding oracle."""

    def __init__(self, question_type: str = '', probability: float = 0.0, seed: int = 0):
        qtype = parse_question_type(question_type) if question_type else ''
        if qtype is None:
            raise ValueError(f'unknown question type {question_type!r}; expected one of {question_types()} or ""')
        if not 0.0 <= float(probability) <= 1.0:
            raise ValueError(f'probability must be in [0, 1], got {probability!r}')
        self.question_type, self.probability, self.seed = qtype, float(probability), int(seed)

    def withhold(self, question_type: str, key: str) -> bool:
        """Whether to withhold the answer to this question (type `question_type`, identified by `key`)."""
        qtype = parse_question_type(question_type)
        if qtype is None or self.probability <= 0.0 or self.question_type not in ('', qtype):
            return False
        digest = zlib.crc32(f'{qtype}|{key}'.encode('utf-8'))
        return bool(np.random.default_rng([self.seed, digest]).random() < self.probability)

    def apply(self, ans: Answer, key: str) -> Answer:
        """`ans`, or, when withheld, a valid "I don't know." (the question itself was fine)."""
        if ans.valid and self.withhold(ans.question_type, key):
            return replace(ans, text=WITHHELD, reason='')
        return ans


def situation_key(snapshot: Snapshot, question_type: str, object_noun: str) -> str:
    """What makes two questions the same for `Perturbation`: the task, the question, the agent's pose."""
    x, y, rotation, horizon = snapshot.agent
    return (f'{snapshot.task_id}|{parse_question_type(question_type)}|{_normalise(object_noun)}|'
            f'{x:.2f},{y:.2f},{rotation:.0f},{horizon:.0f}')
