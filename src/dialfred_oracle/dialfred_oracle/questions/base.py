"""What a question type is to the oracle, its annotator and the agents that read its answers: the
`OracleQuestion` interface, the registry, and what the types share (the answer, its parts, the
direction bins). No ROS, no simulator: everything reads a `Snapshot` (dialfred_sim.ground_truth).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from dialfred_sim.ground_truth import ObjectFact, Snapshot
from dialfred_sim.protocol import QuestionType, question_kinds, register_question_type
from dialfred_sim.registry import Registry


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


@dataclass(frozen=True)
class AnswerContent:
    """What the oracle's answer says, as parts to put in other words (read back from its words by the
    type's `OracleQuestion.parts`).

    location: where (direction bin of the object from the agent; 'held' inside something the agent
    carries), preposition and receptacle noun, or held; appearance: colour and material; direction:
    where (the turn: 'in front of you', 'to your left', 'to your right', 'behind you'; '' = no need to
    move). A type of one's own may use the fields as it likes."""

    question_type: str
    noun: str
    valid: bool = True
    where: str = ''
    preposition: str = ''
    receptacle: str = ''
    held: bool = False
    colour: str = ''
    material: str = ''
    oracle_text: str = ''


# The 8 bins of 45 degrees, counter-clockwise from straight ahead (+y is left when facing +x).
DIRECTION_BINS = ('in front of you', 'to your front left', 'to your left', 'to your rear left',
                  'behind you', 'to your rear right', 'to your right', 'to your front right')


def wrap_deg(deg: float) -> float:
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
    return wrap_deg(math.degrees(math.atan2(dy, dx)) - agent_rotation_deg)


def direction_bin(agent_xy, agent_rotation_deg: float, target_xy) -> str:
    """One of DIRECTION_BINS: the 45-degree sector, centred on the agent's heading, holding the
    target. Rotation 0 faces +x, counter-clockwise positive (facing +x, +y is to the left)."""
    k = math.floor((bearing(agent_xy, agent_rotation_deg, target_xy) + 22.5) / 45.0) % 8
    return DIRECTION_BINS[k]


def one_of(rng: np.random.Generator, options: Sequence[str]) -> str:
    """One of `options`, drawn from `rng`."""
    return options[int(rng.integers(len(options)))]


def with_article(word: str) -> str:
    """'a cup', 'an apple'."""
    return ('an ' if word[:1] in 'aeiou' else 'a ') + word


MAIN_NOUN_P = 0.7       # the annotator asks about the main target rather than another object of the instruction
HELD_NOUN_P = 0.1       # and keeps an object the agent holds among the candidates this often


class OracleQuestion:
    """A question type whole: its entry in the protocol (`kind`: name, the question's wording, whether it
    names an object, its token), the oracle's rule (`answer`), the answer's wording written (by `answer`)
    and read back (`parts`, which agents and the annotator use), the check of an answer against the ground
    truth (`check`), and the synthetic annotator's rule (`human_share`, `choice_bias`, `evidence`,
    `necessary_p`, `called_for`, `narrow_nouns`, `candidate`). Subclass it and `register` an instance:
    docs/questioner.md, "Adding a question type".

    The annotator's choice is a multinomial logit over 'none' and the registered types: each type's
    intercept is its `choice_bias` and its evidence `evidence(situation)` (annotator.Situation)."""

    kind: QuestionType
    reads_looks = False              # its rule reads the rendered looks of the object it names (answer_now)
    human_share = 0.0                # the share of the paper's human questions of this type
    choice_bias = 0.0                # the annotator's fitted intercept for this type (annotator.fit_choice_model)
    necessary_p = (0.3, 0.8)         # P(the annotator says asking was necessary | not called for, called for)

    @property
    def name(self) -> str:
        return self.kind.name

    # ------------------------------------------------------------------ the oracle

    def answer(self, snapshot: Snapshot, object_id: str) -> Answer:
        """The oracle's answer in `snapshot` about object `object_id` ('' for a type that names none)."""
        raise NotImplementedError

    def parts(self, text: str) -> Optional[dict]:
        """The parts of an answer in the oracle's words (its template), as AnswerContent fields; None for
        words the templates do not cover ("I don't know."). Case and surrounding spaces do not matter."""
        return None

    def vocabulary(self) -> list[str]:
        """The fixed words of its answers (the templates without what fills them in), for a performer's
        vocabulary; the nouns, colours and materials of the catalogue come from the catalogue."""
        return []

    def check(self, snapshot: Snapshot, ans: Answer, fact: Optional[ObjectFact]) -> dict[str, Optional[bool]]:
        """Which of the checks ('receptacle_ok', 'direction_ok', 'colour_ok') the valid answer `ans` passes
        against the ground truth (`fact`: the object it is about); only those that apply to the type."""
        return {}

    # ------------------------------------------------------------------ the synthetic annotator

    def evidence(self, situation) -> float:
        """How strongly the situation at a task's start calls for a question of this type."""
        return 0.0

    def called_for(self, noun: str, situation) -> bool:
        """Whether asking it (about `noun`) helped here: the annotator then says it was necessary more often."""
        return False

    def narrow_nouns(self, nouns: list[str], situation, rng: np.random.Generator) -> list[str]:
        """The nouns an annotator would ask this type about, from those of the instruction."""
        return nouns

    def pick_noun(self, situation, rng: np.random.Generator) -> str:
        """The noun asked about: mostly the main target; rarely what the agent already holds (a person sees
        it in the agent's hand); `narrow_nouns` may narrow them first."""
        nouns = [n for n in situation.nouns if n not in situation.held_nouns or rng.random() < HELD_NOUN_P] \
            or list(situation.nouns)
        nouns = self.narrow_nouns(nouns, situation, rng)
        main = situation.main_noun if situation.main_noun in nouns else nouns[0]
        others = [n for n in nouns if n != main]
        if not others or rng.random() < MAIN_NOUN_P:
            return main
        return others[int(rng.integers(len(others)))]

    def covered(self, content: AnswerContent) -> bool:
        """Whether the content was read into parts that `candidate` can reword."""
        return False

    def candidate(self, content: AnswerContent, rng: np.random.Generator, distractor: bool) -> str:
        """One free-form wording of `content` (covered), without the hedge and end mark the annotator adds."""
        return content.oracle_text.rstrip('.')


_REGISTRY: Registry[OracleQuestion] = Registry('question type')


def register(question: OracleQuestion) -> OracleQuestion:
    """Add a question type's rules; its protocol entry is registered too unless it is there already
    (ValueError when the name has rules, or the entry clashes with another type's)."""
    if question.name in _REGISTRY:
        raise ValueError(f'the question type {question.name!r} has rules already')
    if question.kind not in question_kinds():
        register_question_type(question.kind)
    return _REGISTRY.add(question.name, question)


def unregister(name: str) -> None:
    """Remove a type's rules (its protocol entry stays: protocol.unregister_question_type removes it)."""
    _REGISTRY.remove(name)


def oracle_question(question_type: str) -> Optional[OracleQuestion]:
    """The rules of `question_type`; None for a type without any (the oracle refuses its questions)."""
    return _REGISTRY.get(question_type)


def oracle_questions() -> tuple[OracleQuestion, ...]:
    """The rules of every registered type that has them, in the protocol's order."""
    return tuple(_REGISTRY[q.name] for q in question_kinds() if q.name in _REGISTRY)
