"""What the map performer reads: the instruction as a plan of steps, and the oracle's answers as facts.

The instruction names the task's main action only ("Heat the potato.", "Put the mug in the
cabinet.", "Go to the sink basin, wash the ladle."). `parse_instruction` reads it with DialFRED's
verb lists (`dialfred_sim.tasks.instructions.SYNONYMS`) and turns it into `Step`s the agent can
carry out, filling in what the main action implies as ALFRED's task types do: heating is done in a
microwave, cooling in a fridge, washing in a sink basin under its faucet; a put into a closed
container opens and closes it. Object phrases are resolved to object types by the oracle's reading
of nouns (`dialfred_oracle.nouns.meanings`), so "the TV" or "apples" work as they do for questions.

The templates are DialFRED's own, so a rule-based reader is enough here; a phrasing outside them
("could you warm my potato up") raises `InstructionError` naming the sentence. Another benchmark's
phrasings would need a learned reader (a sequence tagger from words to verb and object spans)
trained on its instructions; the `Step` plan below is the interface such a reader would fill.

`parse_answer` reads the oracle's templated answers (`dialfred_oracle.answers`, whose direction bins
and advice it uses): a location answer
becomes a direction bin from the agent and a receptacle type, an appearance answer a colour, a
direction answer a turn.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from typing import Optional

from dialfred_oracle.questions import DIRECTION_BINS, oracle_question
from dialfred_oracle.nouns import meanings
from dialfred_sim.tasks.instructions import SYNONYMS
from dialfred_sim.catalog import load_catalog

# Steps the agent carries out; every one but 'stop' names the object type it acts on.
STEP_KINDS = ('goto', 'pickup', 'put', 'open', 'close', 'toggle_on', 'toggle_off', 'slice', 'stop')


class InstructionError(ValueError):
    """An instruction the reader cannot turn into steps."""


@dataclass(frozen=True)
class Step:
    kind: str                 # one of STEP_KINDS
    target: str = ''          # object type acted on or gone to ('Microwave')
    held: str = ''            # for put: the type put down
    close: bool = False       # for put into a container: close it afterwards even if it was open
    search: bool = False      # an open (and its close) to look inside for what a location answer put there

    def __post_init__(self):
        if self.kind not in STEP_KINDS:
            raise ValueError(f'unknown step kind {self.kind!r}; expected one of {STEP_KINDS}')


@dataclass(frozen=True)
class Reading:
    """An instruction, read: the steps and the object types it names (first the one acted on)."""

    steps: tuple[Step, ...]
    objects: tuple[str, ...]
    action: str               # the main action's kind: goto, pickup, put, open, ..., heat, cool, clean, carry


@functools.lru_cache(maxsize=None)
def _noun_types() -> dict[str, str]:
    """Every catalog noun (lower case) -> its object type; a type's own noun wins over variants."""
    table: dict[str, str] = {}
    catalog = load_catalog()
    for name, t in sorted(catalog.items()):
        for noun in t.nouns[1:]:
            table.setdefault(noun.lower(), name)
    for name, t in sorted(catalog.items()):
        table[t.noun.lower()] = name
        table.setdefault(name.lower(), name)
    return table


def object_type(phrase: str) -> str:
    """The object type a noun phrase names ('sink basin' -> 'SinkBasin', 'apples' -> 'Apple');
    InstructionError if none."""
    text = phrase.strip().lower()
    table = _noun_types()
    if text in table:
        return table[text]
    catalog = load_catalog()
    for meaning in meanings(text):
        if meaning.types:
            return sorted(meaning.types)[0]
        for name, t in sorted(catalog.items()):
            if meaning.matches(t.noun, name):
                return name
    raise InstructionError(f'no object type is called {phrase!r}')


def _verb_pattern(kind: str) -> str:
    return '|'.join(re.escape(v) for v in sorted(SYNONYMS[kind], key=len, reverse=True))


_NOUN = r'(?:the |a |an )?(?P<{}>[a-z][a-z \-]*?)'


def _noun(name: str) -> str:
    return _NOUN.format(name)


def _clause(action: str, verb: str, rest: str = '') -> tuple[str, re.Pattern]:
    return action, re.compile(rf'^(?:{_verb_pattern(verb)}) {_noun("obj")}{rest}$')


# Main clauses, tried in order: the forms with a second object first; 'take' is pickup unless 'to'
# follows, and 'slice ... with' before 'slice'.
_CLAUSES = [
    _clause('put', 'put', rf' (?:in|on) {_noun("recep")}'),
    _clause('carry', 'carry', rf' to {_noun("recep")}'),
    _clause('slice_with', 'slice', rf' with {_noun("tool")}'),
    *(_clause(kind, kind) for kind in ('heat', 'cool', 'clean', 'toggle_on', 'toggle_off', 'slice', 'open', 'close',
                                       'goto', 'pickup')),
]
# "turn on the lamp" / "switch it on" style particles: "turn the lamp on" is not a template, but
# "go to the lamp and switch it on" is: the pronoun forms.
_PRONOUN = re.compile(r'^(?P<verb>[a-z]+) it(?: (?P<particle>up|on|off))?$')
_GOTO_PREFIX = re.compile(rf'^(?:{_verb_pattern("goto")}) {_noun("place")}(?:, | and )(?P<rest>.+)$')


def _clean(sentence: str) -> str:
    text = sentence.strip().lower().rstrip('.').strip()
    for frame in ('please ', 'now '):
        if text.startswith(frame):
            text = text[len(frame):]
    return text


def _pronoun_clause(rest: str, place: str) -> str:
    """'open it' / 'switch it on' / 'leave the pot on it' after 'go to the X and' -> 'open the X' /
    'switch on the X' / 'leave the pot on the X'."""
    m = _PRONOUN.match(rest)
    if not m:
        return re.sub(r' (in|on|to) it$', rf' \1 the {place}', rest)    # "leave the pot on it"
    verb = m.group('verb') + (f' {m.group("particle")}' if m.group('particle') else '')
    return f'{verb} the {place}'


def _is_container(type_name: str) -> bool:
    t = load_catalog().get(type_name)
    return bool(t and t.openable and t.receptacle)


def _steps(action: str, obj: str, recep: str = '', tool: str = '') -> list[Step]:
    """The steps of a main action on object type `obj` (see the module)."""
    if action == 'goto':
        return [Step('goto', obj), Step('stop')]
    if action in ('pickup', 'open', 'close', 'toggle_on', 'toggle_off', 'slice'):
        return [Step(action, obj), Step('stop')]
    if action == 'slice_with':
        return [Step('pickup', tool), Step('slice', obj), Step('stop')]
    if action == 'carry':
        return [Step('pickup', obj), Step('goto', recep), Step('stop')]
    if action == 'put':
        return [Step('put', recep, held=obj), Step('stop')]
    if action == 'heat':
        return [Step('put', 'Microwave', held=obj, close=True), Step('toggle_on', 'Microwave'),
                Step('toggle_off', 'Microwave'), Step('open', 'Microwave'), Step('pickup', obj),
                Step('close', 'Microwave'), Step('stop')]
    if action == 'cool':
        return [Step('put', 'Fridge', held=obj, close=True), Step('open', 'Fridge'), Step('pickup', obj),
                Step('close', 'Fridge'), Step('stop')]
    if action == 'clean':
        return [Step('put', 'SinkBasin', held=obj), Step('toggle_on', 'Faucet'), Step('toggle_off', 'Faucet'),
                Step('pickup', obj), Step('stop')]
    raise InstructionError(f'no steps for the action {action!r}')


def parse_instruction(sentence: str) -> Reading:
    """The steps of a DialFRED main-action instruction (see the module); InstructionError if it is
    not one of the templates' forms."""
    text = _clean(sentence)
    m = _GOTO_PREFIX.match(text)
    place = ''
    if m:
        place = m.group('place')
        text = _pronoun_clause(m.group('rest'), place)
    for action, pattern in _CLAUSES:
        c = pattern.match(text)
        if not c:
            continue
        groups = c.groupdict()
        obj = object_type(groups['obj'])
        recep = object_type(groups['recep']) if groups.get('recep') else ''
        tool = object_type(groups['tool']) if groups.get('tool') else ''
        steps = _steps(action, obj, recep, tool)
        objects = tuple(t for t in (obj, recep, tool) if t)
        if place:
            where = object_type(place)
            if where not in objects:
                objects += (where,)
            if steps[0].target != where:
                steps = [Step('goto', where)] + steps
        return Reading(tuple(steps), objects, action)
    raise InstructionError(f'cannot read the instruction {sentence!r}')


# ---------------------------------------------------------------------- answers

# A direction answer's way to go (questions.direction.MOVES) as a turn, counter-clockwise; '' is staying.
_TURNS = {'to your left': 90, 'to your right': -90, 'behind you': 180, 'in front of you': 0, '': 0}


@dataclass(frozen=True)
class Fact:
    """What an answer says. kind: 'location' (bearing_deg from the agent's heading then, counter-
    clockwise, and receptacle type or '', inside it or on it), 'held', 'appearance' (colour), 'direction' (turn_deg,
    counter-clockwise; stay when the expert ends where the agent is)."""

    kind: str
    object_type: str = ''
    bearing_deg: Optional[float] = None
    receptacle: str = ''
    colour: str = ''
    turn_deg: Optional[int] = None
    stay: bool = False
    inside: bool = False      # location: in the receptacle (to be opened if it opens), not on it


def parse_answer(question_type: str, answer: str) -> Optional[Fact]:
    """The fact in an oracle answer, or None for an answer it cannot read ("I don't know."). The words
    are read by the question type's own reader (`OracleQuestion.parts`, where they are written); a type
    the map performer has no use for gives None."""
    rules = oracle_question(question_type)
    parts = rules.parts(answer) if rules is not None else None
    if parts is None:
        return None
    try:
        if question_type == 'direction':
            return Fact('direction', turn_deg=_TURNS[parts['where']], stay=parts['where'] == '')
        if question_type == 'location':
            noun = object_type(parts['noun'].lower())
            if parts.get('held'):
                return Fact('held', noun)
            if parts['where'] == 'held':
                return Fact('held', noun, receptacle=object_type(parts['receptacle'].lower()))
            recep = object_type(parts['receptacle'].lower()) if parts['receptacle'] else ''
            return Fact('location', noun, DIRECTION_BINS.index(parts['where'].lower()) * 45.0, recep,
                        inside=parts['preposition'].lower() == 'in')
        if question_type == 'appearance':
            return Fact('appearance', object_type(parts['noun'].lower()), colour=parts['colour'].lower())
    except InstructionError:
        return None
    return None


def describe_fact(fact: Optional[Fact]) -> str:
    """What a reader took from an answer, for a person to check: 'Fridge, to your left', 'Apple, in
    your hand', 'Mug: white', 'turn around'; 'nothing it can read' for None."""
    if fact is None:
        return 'nothing it can read'
    if fact.kind == 'direction':
        return 'stay here' if fact.stay else {90: 'turn left', -90: 'turn right', 180: 'turn around',
                                              0: 'go straight ahead'}.get(fact.turn_deg, f'turn {fact.turn_deg} deg')
    if fact.kind == 'held':
        return (f'{fact.object_type}, in the {fact.receptacle} in your hand' if fact.receptacle
                else f'{fact.object_type}, in your hand')
    if fact.kind == 'appearance':
        return f'{fact.object_type}: {fact.colour}'
    where = DIRECTION_BINS[int(round(fact.bearing_deg / 45.0)) % 8] if fact.bearing_deg is not None else ''
    place = f'{"in" if fact.inside else "on"} the {fact.receptacle}' if fact.receptacle else ''
    return ', '.join(part for part in (fact.object_type, where, place) if part)
