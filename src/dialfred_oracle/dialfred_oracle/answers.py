"""The oracle's rules: templated answers to location, appearance and direction questions.

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
tomato") is decided by nouns.py. Everything here is plain Python over a `Snapshot`
(dialfred_sim.ground_truth); the ROS node only adapts messages.
"""

from __future__ import annotations

import math
import re
import zlib
from dataclasses import dataclass, replace
from typing import Callable, Optional

import numpy as np

from dialfred_sim.protocol import QUESTION_KINDS, QUESTION_TYPES, names_object
from dialfred_sim.protocol import question_text as protocol_question_text
from dialfred_sim.ground_truth import ObjectFact, Snapshot

from .colours import colour_name
from .nouns import meanings

QUESTION_ALIASES = {q.token: q.name for q in QUESTION_KINDS}   # the short tokens: 'loc', 'app', 'dir'
MAX_NOUN_CHARS = 64
SAME_PLACE_M = 0.125         # the expert's end is "here" on the same grid point (steps are 0.25 m) ...
SAME_HEADING_DEG = 45.0      # ... and this heading difference

# The 8 bins of 45 degrees, counter-clockwise from straight ahead (+y is left when facing +x).
DIRECTION_BINS = ('in front of you', 'to your front left', 'to your left', 'to your rear left',
                  'behind you', 'to your rear right', 'to your right', 'to your front right')
GO_STRAIGHT = 'You should go straight ahead.'
TURN_LEFT = 'You should turn left.'
TURN_RIGHT = 'You should turn right.'
TURN_AROUND = 'You should turn around.'
STAY = "You don't need to move."
_MOVE_FOR_BIN = {'in front of you': GO_STRAIGHT, 'to your front left': GO_STRAIGHT, 'to your front right': GO_STRAIGHT,
                 'to your left': TURN_LEFT, 'to your right': TURN_RIGHT, 'to your rear left': TURN_AROUND,
                 'behind you': TURN_AROUND, 'to your rear right': TURN_AROUND}
WITHHELD = "I don't know."   # a withheld answer: the question was fine, the oracle does not say
_ARTICLES = ('the ', 'a ', 'an ')


@dataclass(frozen=True)
class Answer:
    """The oracle's reply. valid=False (with `reason`) when the question cannot be answered.

    colour_from_pixels: False when an appearance answer had no pixels of the object and named its
    colour from metadata instead."""

    valid: bool
    text: str = ''
    reason: str = ''
    question_type: str = ''
    object_noun: str = ''
    object_id: str = ''
    colour_from_pixels: bool = True


def question_text(question_type: str, noun: str = '') -> str:
    """The question as a person would ask it: 'Where is the apple?'. ValueError for an unknown type."""
    qtype = parse_question_type(question_type)
    if qtype is None:
        raise ValueError(f'unknown question type {question_type!r}; expected one of {QUESTION_TYPES}')
    return protocol_question_text(qtype, noun)


def parse_question_type(question_type) -> Optional[str]:
    """'location', 'appearance' or 'direction' for any spelling the oracle accepts ('Location',
    ' LOC ', 'dir'); None for anything else."""
    if not isinstance(question_type, str) or len(question_type) > 32:
        return None
    q = question_type.strip().lower()
    q = QUESTION_ALIASES.get(q, q)
    return q if q in QUESTION_TYPES else None


def _wrap(deg: float) -> float:
    """An angle in (-180, 180]."""
    d = math.fmod(deg, 360.0)
    if d <= -180.0:
        d += 360.0
    elif d > 180.0:
        d -= 360.0
    return d


def bearing(agent_xy, agent_rotation_deg: float, target_xy) -> float:
    """Where `target_xy` lies seen from the agent, in degrees: 0 ahead, positive to the left."""
    dx, dy = target_xy[0] - agent_xy[0], target_xy[1] - agent_xy[1]
    return _wrap(math.degrees(math.atan2(dy, dx)) - agent_rotation_deg)


def direction_bin(agent_xy, agent_rotation_deg: float, target_xy) -> str:
    """One of DIRECTION_BINS: the 45-degree sector, centred on the agent's heading, holding the
    target. Rotation 0 faces +x, counter-clockwise positive (facing +x, +y is to the left)."""
    k = math.floor((bearing(agent_xy, agent_rotation_deg, target_xy) + 22.5) / 45.0) % 8
    return DIRECTION_BINS[k]


def direction_advice(agent, expert_end) -> str:
    """What to do to get from pose `agent` to pose `expert_end` (x, y, rotation, horizon)."""
    if math.hypot(expert_end[0] - agent[0], expert_end[1] - agent[1]) < SAME_PLACE_M:
        turn = _wrap(expert_end[2] - agent[2])
        if abs(turn) <= SAME_HEADING_DEG:
            return STAY
        if abs(turn) >= 180.0 - SAME_HEADING_DEG:
            return TURN_AROUND
        return TURN_LEFT if turn > 0 else TURN_RIGHT
    return _MOVE_FOR_BIN[direction_bin(agent[:2], agent[2], expert_end[:2])]


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

def _location(snapshot: Snapshot, fact: ObjectFact) -> str:
    if fact.held:
        return f'You are holding the {fact.noun}.'
    parent = snapshot.objects.get(fact.parent_id) if fact.parent_id else None
    if parent is not None and parent.held:
        return f'The {fact.noun} is {fact.preposition} the {fact.parent_noun} you are holding.'
    where = direction_bin(snapshot.agent[:2], snapshot.agent[2], fact.where[:2])
    if fact.parent_id:
        return f'The {fact.noun} is {where} {fact.preposition} the {fact.parent_noun}.'
    return f'The {fact.noun} is {where}.'


def _appearance(snapshot: Snapshot, fact: ObjectFact) -> tuple[str, bool]:
    look = snapshot.appearances.get(fact.object_id)
    colour = colour_name(look.pixels) if look is not None and len(look.pixels) else None
    from_pixels = colour is not None
    return f'The {fact.noun} is {colour or fact.colour} and made of {fact.material}.', from_pixels


def answer(snapshot: Snapshot, question_type, object_noun='') -> Answer:
    """The oracle's answer to a question of `question_type` ('location', 'appearance',
    'direction'; or the tokens 'loc', 'app', 'dir') about `object_noun`. Never raises."""
    qtype = parse_question_type(question_type)
    if qtype is None:
        shown = question_type[:32] if isinstance(question_type, str) else type(question_type).__name__
        return Answer(False, reason=f'unknown question type {shown!r}; expected one of {", ".join(QUESTION_TYPES)}')
    if qtype not in RULES:
        return Answer(False, reason=f'the oracle has no rule for {qtype!r} questions', question_type=qtype)
    if not names_object(qtype):
        return RULES[qtype](snapshot, '')
    object_id, reason = resolve_object(snapshot, object_noun)
    if not object_id:
        return Answer(False, reason=reason, question_type=qtype)
    return RULES[qtype](snapshot, object_id)


def direction_answer(snapshot: Snapshot, object_id: str = '') -> Answer:
    if snapshot.expert_end is None:
        return Answer(False, reason='there is no task, so there is no way to go', question_type='direction')
    return Answer(True, direction_advice(snapshot.agent, snapshot.expert_end), question_type='direction')


def location_answer(snapshot: Snapshot, object_id: str) -> Answer:
    fact = snapshot.objects[object_id]
    return Answer(True, _location(snapshot, fact), question_type='location', object_noun=fact.noun,
                  object_id=object_id)


def appearance_answer(snapshot: Snapshot, object_id: str) -> Answer:
    fact = snapshot.objects[object_id]
    text, from_pixels = _appearance(snapshot, fact)
    return Answer(True, text, question_type='appearance', object_noun=fact.noun, object_id=object_id,
                  colour_from_pixels=from_pixels)


# The oracle's rule of each question type: (snapshot, the id of the object the question names, '' for a
# type that names none) -> Answer. A type of protocol.QUESTION_KINDS without a rule here is refused.
RULES: dict[str, Callable[[Snapshot, str], Answer]] = {
    'location': location_answer, 'appearance': appearance_answer, 'direction': direction_answer}
# The types whose rule reads the rendered looks of the object it names (Snapshot.appearances): their
# answer is given from a snapshot that carries that object's pixels (`answer_now`).
READS_LOOKS: set[str] = {'appearance'}


def refusal_on_its_face(question_type, object_noun: str = '') -> tuple[Optional[str], Optional[Answer]]:
    """(the question type, None) for a question fit to put to the world; (None, the refusal) for one
    malformed on its face (an unknown type, an overlong noun), which never needs the simulator."""
    qtype = parse_question_type(question_type)
    if qtype is None:
        return None, answer(None, question_type, object_noun)
    if names_object(qtype) and len(object_noun) > MAX_NOUN_CHARS:
        return None, Answer(False, reason=f'the object noun is longer than {MAX_NOUN_CHARS} characters',
                            question_type=qtype)
    return qtype, None


def answer_now(snapshot_now: Snapshot, question_type: str, object_noun: str,
               with_looks: Callable[[str], Snapshot]) -> Answer:
    """The oracle's answer in the world's state `snapshot_now`, the one rule of both the node and the
    in-process oracle. A type of READS_LOOKS is answered again from `with_looks(object_id)`: the state
    with the rendered looks of the object the first answer resolved the noun to."""
    result = answer(snapshot_now, question_type, object_noun)
    if result.valid and parse_question_type(question_type) in READS_LOOKS and result.object_id:
        result = answer(with_looks(result.object_id), question_type, object_noun)
    return result


# ---------------------------------------------------------------------- checking answers

_BINS_RE = '|'.join(re.escape(b) for b in DIRECTION_BINS)
_LOCATION_RE = re.compile(rf'^The (?P<noun>.+?) is (?P<bin>{_BINS_RE})(?: (?P<prep>in|on) the (?P<recep>.+))?\.$')
_CARRIED_RE = re.compile(r'^The (?P<noun>.+?) is (?P<prep>in|on) the (?P<recep>.+) you are holding\.$')
_HOLDING_RE = re.compile(r'^You are holding the (?P<noun>.+)\.$')
_APPEARANCE_RE = re.compile(r'^The (?P<noun>.+?) is (?P<colour>[a-z]+) and made of (?P<material>.+)\.$')


def check_answer(snapshot: Snapshot, ans: Answer) -> dict[str, Optional[bool]]:
    """Whether an answer's text agrees with the ground truth of `snapshot` (for benchmarks).

    receptacle_ok: a location answer names the object's parent receptacle with the right
    preposition (or none for an object without one, or says it is held when it is);
    direction_ok: a location answer's direction bin, or a direction answer's advice, recomputed
    from the geometry (for an object in view, from the part the agent sees: ObjectFact.where);
    colour_ok: an appearance answer names the object's colour variant.
    None where a check does not apply (and for invalid answers)."""
    out: dict[str, Optional[bool]] = {'receptacle_ok': None, 'direction_ok': None, 'colour_ok': None}
    if not ans.valid:
        return out
    if ans.question_type == 'direction':
        out['direction_ok'] = (snapshot.expert_end is not None
                               and ans.text == direction_advice(snapshot.agent, snapshot.expert_end))
        return out
    fact = snapshot.objects.get(ans.object_id)
    if fact is None:
        return {k: False for k in out}
    if ans.question_type == 'appearance':
        m = _APPEARANCE_RE.match(ans.text)
        out['colour_ok'] = bool(m) and m.group('colour') == fact.colour
        return out
    parent = snapshot.objects.get(fact.parent_id)
    if _HOLDING_RE.match(ans.text):
        out['receptacle_ok'] = fact.held
        return out
    m = _CARRIED_RE.match(ans.text)
    if m:
        out['receptacle_ok'] = (parent is not None and parent.held and m.group('recep') == fact.parent_noun
                                and m.group('prep') == fact.preposition)
        return out
    m = _LOCATION_RE.match(ans.text)
    if not m:
        return {'receptacle_ok': False, 'direction_ok': False, 'colour_ok': None}
    if m.group('recep') is None:
        out['receptacle_ok'] = not fact.parent_id and not fact.held
    else:
        out['receptacle_ok'] = m.group('recep') == fact.parent_noun and m.group('prep') == fact.preposition
    out['direction_ok'] = m.group('bin') == direction_bin(snapshot.agent[:2], snapshot.agent[2], fact.where[:2])
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
            raise ValueError(f'unknown question type {question_type!r}; expected one of {QUESTION_TYPES} or ""')
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
