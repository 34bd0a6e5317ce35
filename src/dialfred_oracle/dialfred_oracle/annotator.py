"""A SYNTHETIC annotator that plays DialFRED's human annotation protocol (ROS-free).

The paper's 53K human questions and answers cannot be had here, so this module stands in for the
crowd workers, clearly labelled as synthetic. It follows the paper's hybrid data collection: at a
task's start the annotator sees the instruction and the room, picks one of the predefined questions
(location / appearance of an object of the instruction, or the direction to turn) or none, watches
the expert (the oracle's answer holds what the demonstration shows), answers its own question in its
own words and says whether asking was necessary.

Choices follow the situation with noise (`ChoiceModel`): a multinomial logit over {none, location,
appearance, direction} whose evidence is the situation (target out of view -> location, a same-class
distractor -> appearance, target behind the agent -> direction, clear instruction and visible target
-> none). Its intercepts and signal strength are fitted (`fit_choice_model`) so that, over the valid
splits, the question-type shares and questions per task are the paper's human figures and two
independent annotators agree about as little as the paper's did (Fleiss' kappa 0.13). Answers
paraphrase the oracle's content with several templates, synonyms and hedges, with lengths drawn
around the paper's 6.73 words. See docs/dialogue_data.md.
"""

from __future__ import annotations

import gzip
import json
import os
import re
from dataclasses import asdict, dataclass, replace
from importlib import resources
from pathlib import Path
from typing import Callable, Iterable, Optional, Sequence

import numpy as np

from dialfred_sim.ground_truth import snapshot
from dialfred_sim.protocol import QUESTION_TYPES, question_text
from dialfred_sim.tasks.instructions import tokenize
from dialfred_sim.tasks.split_files import SPLIT_CODES
from dialfred_sim.catalog import object_type

from .answers import DIRECTION_BINS, GO_STRAIGHT, STAY, TURN_AROUND, TURN_LEFT, TURN_RIGHT, Answer, direction_bin
from .answers import answer as oracle_answer

CATEGORIES = ('none',) + QUESTION_TYPES       # what the two annotators' agreement is measured on
# The paper's human figures (Table of question types; Sec. "Hybrid data collection").
PAPER_HUMAN = {'type_shares': {'location': 0.72, 'appearance': 0.22, 'direction': 0.06},
               'questions_per_task': 0.66, 'answer_words': 6.73, 'fleiss_kappa': 0.13}
# "Behind the agent": the oracle's direction bins at the back (rear left, behind, rear right).
REAR_BINS = tuple(b for b in DIRECTION_BINS if 'rear' in b or 'behind' in b)


# ---------------------------------------------------------------------- the situation at the start

@dataclass(frozen=True)
class Situation:
    """What an annotator can tell from the first video clip and the instruction.

    main_noun: the task's main target (the object of its first non-walking step; for a put, the
    receptacle), as the generator's `target_visible_at_start` defines it. nouns: the task's object
    nouns, main first. target_direction: direction bin of the main target seen from the start pose.
    """

    main_noun: str
    nouns: tuple[str, ...]
    target_visible: bool
    target_behind: bool
    target_direction: str
    target_enclosed: bool          # inside a closed receptacle
    target_held: bool
    distractor_nouns: tuple[str, ...]   # task nouns with another object of the same class in the room
    instruction_complete: bool     # the main instruction names every object of the task
    held_nouns: tuple[str, ...] = ()    # task nouns of what the agent holds

    @property
    def main_has_distractor(self) -> bool:
        return self.main_noun in self.distractor_nouns

    @property
    def clear(self) -> bool:
        """Nothing to ask: complete instruction, target in view, no look-alike."""
        return self.instruction_complete and self.target_visible and not self.distractor_nouns

    @classmethod
    def of(cls, task, snapshot, bin_of: Callable = direction_bin, rear_bins: Sequence[str] = REAR_BINS) -> 'Situation':
        """Features of `task` at its start from the ground-truth `snapshot` (a dialfred_sim.ground_truth
        Snapshot); bin_of(agent_xy, rotation_deg, target_xy) names the target's direction bin."""
        facts = snapshot.objects
        main_id = main_target_id(task)
        main = facts.get(main_id)
        nouns = [n for n in task.object_nouns if n in snapshot.task_objects]
        main_noun = main.noun if main is not None else (nouns[-1] if nouns else task.object_nouns[-1])
        nouns = tuple([main_noun] + [n for n in nouns if n != main_noun])
        distractors = tuple(n for n in nouns if _has_twin(facts, snapshot.task_objects.get(n)))
        x, y, rotation = snapshot.agent[0], snapshot.agent[1], snapshot.agent[2]
        direction = bin_of((x, y), rotation, tuple(main.position[:2])) if main is not None else ''
        enclosed = main is not None and _enclosed(facts, main)
        instruction = task.instruction.lower()
        held = tuple(n for n in nouns if n in snapshot.task_objects and facts[snapshot.task_objects[n]].held)
        return cls(main_noun, nouns, bool(task.target_visible_at_start), direction in rear_bins, direction,
                   enclosed, bool(main is not None and main.held), distractors,
                   all(n in instruction for n in task.object_nouns), held)

    def to_json(self) -> dict:
        d = asdict(self)
        for key in ('nouns', 'distractor_nouns', 'held_nouns'):
            d[key] = list(d[key])
        return d

    @classmethod
    def from_json(cls, d: dict) -> 'Situation':
        return cls(**{**d, **{k: tuple(d[k]) for k in ('nouns', 'distractor_nouns', 'held_nouns')}})


def main_target_id(task) -> str:
    """The object id the task is mainly about: its first non-walking step's receptacle or object."""
    first = next((p for p in task.primitives if p.kind != 'goto'), task.primitives[0])
    return first.receptacle or first.target


def _has_twin(facts: dict, object_id: Optional[str]) -> bool:
    fact = facts.get(object_id) if object_id else None
    return fact is not None and any(f.noun == fact.noun and oid != object_id for oid, f in facts.items())


def _enclosed(facts: dict, fact) -> bool:
    seen = set()
    while fact is not None and fact.parent_id and fact.parent_id not in seen:
        seen.add(fact.parent_id)
        fact = facts.get(fact.parent_id)
        if fact is not None and _openable_closed(fact):
            return True
    return False


def _openable_closed(fact) -> bool:
    return object_type(fact.type_name).openable and not fact.is_open


# ---------------------------------------------------------------------- which question (noise model)

def evidence(s: Situation) -> np.ndarray:
    """How strongly the situation calls for each of CATEGORIES (none, location, appearance, direction)."""
    none = float(s.clear) + 0.5 * float(s.target_held)
    location = float(not s.target_visible) + 0.5 * float(s.target_enclosed) - float(s.target_held)
    appearance = float(s.main_has_distractor) + 0.5 * float(bool(s.distractor_nouns) and not s.main_has_distractor)
    direction = 2.0 * float(s.target_behind)     # rare overall, so it must stand out where it fits
    return np.array([none, location, appearance, direction])


@dataclass(frozen=True)
class ChoiceModel:
    """P(choice | situation) = softmax(bias + strength * evidence(situation)) over CATEGORIES.

    Each annotator draws independently from it, so `strength` sets how much two annotators agree
    (strength 0: kappa 0) and `bias` sets the shares of question types."""

    strength: float
    bias: tuple[float, float, float, float]

    def probabilities(self, s: Situation) -> np.ndarray:
        return self.probabilities_from(evidence(s)[None])[0]

    def probabilities_from(self, evidences: np.ndarray) -> np.ndarray:
        """Rows of choice probabilities for rows of evidence (N x 4)."""
        z = np.asarray(self.bias) + self.strength * evidences
        p = np.exp(z - z.max(axis=1, keepdims=True))
        return p / p.sum(axis=1, keepdims=True)


def target_choice_shares(shares: dict = PAPER_HUMAN['type_shares'],
                         questions_per_task: float = PAPER_HUMAN['questions_per_task']) -> np.ndarray:
    """The shares of CATEGORIES that the paper's humans give: none = 1 - questions per task."""
    return np.array([1.0 - questions_per_task] + [questions_per_task * shares[t] for t in QUESTION_TYPES])


def expected_statistics(model: ChoiceModel, situations: Sequence[Situation]) -> tuple[np.ndarray, float]:
    """Expected shares of CATEGORIES and expected Fleiss' kappa of two annotators over `situations`
    (a list of Situations or their N x 4 evidence matrix)."""
    e = situations if isinstance(situations, np.ndarray) else np.array([evidence(s) for s in situations])
    q = model.probabilities_from(e)
    shares = q.mean(axis=0)
    agree, chance = float((q ** 2).sum(axis=1).mean()), float((shares ** 2).sum())
    return shares, (agree - chance) / (1.0 - chance)


def fit_choice_model(situations: Sequence[Situation], kappa: float = PAPER_HUMAN['fleiss_kappa'],
                     target: Optional[np.ndarray] = None) -> ChoiceModel:
    """Intercepts matching the target shares (iterative proportional fitting) and the strength whose
    expected kappa is `kappa` (bisection), over the given situations."""
    target = target_choice_shares() if target is None else np.asarray(target)
    situations = np.array([evidence(s) for s in situations])

    def fit_bias(strength: float) -> ChoiceModel:
        model = ChoiceModel(strength, tuple(np.log(target)))
        for _ in range(500):
            shares, _ = expected_statistics(model, situations)
            b = np.asarray(model.bias) + np.log(target / shares)
            model = ChoiceModel(strength, tuple(float(v) for v in b - b[0]))
            if np.abs(shares - target).max() < 1e-6:
                break
        return model

    lo, hi = 0.0, 12.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if expected_statistics(fit_bias(mid), situations)[1] < kappa:
            lo = mid
        else:
            hi = mid
    model = fit_bias(0.5 * (lo + hi))
    return ChoiceModel(round(model.strength, 4), tuple(round(b, 4) for b in model.bias))


# Fitted with `scripts/annotate_dialogues.py --fit` on the situations of valid_seen + valid_unseen.
CHOICE_MODEL = ChoiceModel(strength=1.3209, bias=(0.0, 0.1941, -1.4978, -2.7161))

# P(the annotator says asking was necessary | question type, whether the situation called for it).
# The paper reports no such figure; these express "necessary when it helped" with some disagreement.
NECESSARY_P = {'location': (0.35, 0.85), 'appearance': (0.3, 0.8), 'direction': (0.3, 0.8)}


def _called_for(question_type: str, noun: str, s: Situation) -> bool:
    if question_type == 'location':
        return noun == s.main_noun and (not s.target_visible or s.target_enclosed)
    if question_type == 'appearance':
        return noun in s.distractor_nouns
    return s.target_behind


def _pick_noun(question_type: str, s: Situation, rng: np.random.Generator) -> str:
    """The noun asked about: mostly the main target; for appearance a noun with a look-alike; rarely
    what the agent already holds (a person sees it in the agent's hand)."""
    nouns = [n for n in s.nouns if n not in s.held_nouns or rng.random() < HELD_NOUN_P] or list(s.nouns)
    if question_type == 'appearance':
        look_alikes = [n for n in nouns if n in s.distractor_nouns]
        if look_alikes and rng.random() < 0.8:
            nouns = look_alikes
    main = s.main_noun if s.main_noun in nouns else nouns[0]
    others = [n for n in nouns if n != main]
    if not others or rng.random() < MAIN_NOUN_P:
        return main
    return others[int(rng.integers(len(others)))]


MAIN_NOUN_P = 0.7       # ask about the main target rather than another object of the instruction
HELD_NOUN_P = 0.1       # keep an object the agent holds among the candidates


# ---------------------------------------------------------------------- free-form answers

@dataclass(frozen=True)
class AnswerContent:
    """What the oracle's answer says, as parts to put in other words.

    location: where (direction bin of the object from the agent), preposition and receptacle noun,
    or held; appearance: colour and material; direction: where (the turn, '' = no need to move)."""

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


_BINS = '|'.join(re.escape(b) for b in DIRECTION_BINS)
_LOCATION = re.compile(rf'^The (?P<noun>.+?) is (?P<where>{_BINS})(?: (?P<prep>in|on) the (?P<recep>.+))?\.$')
_CARRIED = re.compile(r'^The (?P<noun>.+?) is (?P<prep>in|on) the (?P<recep>.+) you are holding\.$')
_HOLDING = re.compile(r'^You are holding the (?P<noun>.+)\.$')
_APPEARANCE = re.compile(r'^The (?P<noun>.+?) is (?P<colour>[a-z]+) and made of (?P<material>.+)\.$')
_MOVES = {GO_STRAIGHT: 'in front of you', TURN_LEFT: 'to your left', TURN_RIGHT: 'to your right',
          TURN_AROUND: 'behind you', STAY: ''}


def answer_content(oracle: Answer, question_type: str, noun: str) -> AnswerContent:
    """The parts of the oracle's templated answer (dialfred_oracle.answers), to be reworded.

    An answer the templates do not cover keeps its text (`oracle_text`) and is said as it is."""
    base = AnswerContent(question_type, oracle.object_noun or noun, bool(oracle.valid), oracle_text=oracle.text)
    if not oracle.valid:
        return base
    text = oracle.text
    if question_type == 'direction':
        return replace(base, where=_MOVES[text]) if text in _MOVES else base
    if question_type == 'appearance':
        m = _APPEARANCE.match(text)
        return replace(base, colour=m.group('colour'), material=m.group('material')) if m else base
    if _HOLDING.match(text):
        return replace(base, held=True)
    m = _CARRIED.match(text)
    if m:
        return replace(base, preposition=m.group('prep'), receptacle=m.group('recep'), where='held')
    m = _LOCATION.match(text)
    if m:
        return replace(base, where=m.group('where'), preposition=m.group('prep') or '',
                       receptacle=m.group('recep') or '')
    return base


# Answer lengths: a target drawn per answer, 1 + Gamma(shape, mean - 1); the candidate wording closest
# to it is said. LENGTH_MEAN is tuned so that the realised mean is the paper's 6.73 words.
LENGTH_MEAN, LENGTH_SHAPE, CANDIDATES = 7.15, 3.0, 12
HEDGES = ('I think', 'I believe', 'probably', 'maybe', 'it seems', 'I guess')
COLOUR_WORDS = {'gray': ('gray', 'grey'), 'navy': ('navy', 'navy blue', 'dark blue'),
                'maroon': ('maroon', 'dark red'), 'tan': ('tan', 'light brown'), 'beige': ('beige', 'cream'),
                'olive': ('olive', 'olive green'), 'teal': ('teal', 'blue green'), 'khaki': ('khaki',),
                'silver': ('silver', 'silvery'), 'gold': ('gold', 'golden'), 'pink': ('pink', 'light pink')}
PREPOSITIONS = {'in': ('in', 'inside'), 'on': ('on', 'on top of')}


def _one(rng: np.random.Generator, options: Sequence[str]) -> str:
    return options[int(rng.integers(len(options)))]


def _a(word: str) -> str:
    return ('an ' if word[:1] in 'aeiou' else 'a ') + word


def _where_phrases(where: str) -> tuple[str, ...]:
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


def _location_candidate(c: AnswerContent, rng: np.random.Generator) -> str:
    o, w = c.noun, _one(rng, _where_phrases(c.where))
    if c.held:
        return _one(rng, ("you're holding it", 'it is in your hand', 'you already have it',
                          f'you are already holding the {o}', f'the {o} is in your hand already'))
    if not c.receptacle:
        if not w:
            return _one(rng, ('right here', f"the {o} is right here", "it's close by"))
        return _one(rng, (w, f"it's {w}", f'the {o} is {w}', f'look {w}', f'you will see the {o} {w}'))
    p, r = _one(rng, PREPOSITIONS.get(c.preposition, (c.preposition or 'on',))), c.receptacle
    if c.where == 'held':
        return _one(rng, (f"{p} the {r} you're holding", f'{p} the {r} in your hand', f"it's {p} the {r} you carry",
                          f'the {o} is {p} the {r} you are holding'))
    forms = [f'{p} the {r}', f"it's {p} the {r}", f'it should be {p} the {r}', f'check {p} the {r}',
             f'the {o} is {p} the {r}', f'you can find it {p} the {r}']
    if w:
        forms += [f'{p} the {r} {w}', f'{w}, {p} the {r}', f"it's {w} {p} the {r}", f'the {o} is {w} {p} the {r}',
                  f'the {o} is {p} the {r} {w}', f'you can find it {p} the {r} {w}', f'look {w}, {p} the {r}',
                  f'there is {_a(o)} {p} the {r} {w}', f'the {o} is sitting {p} the {r} {w}',
                  f'go to the {r} {w}, the {o} is {p} it']
    return _one(rng, forms)


def _appearance_candidate(c: AnswerContent, rng: np.random.Generator, distractor: bool) -> str:
    o, m = c.noun, c.material
    col = _one(rng, COLOUR_WORDS.get(c.colour, (c.colour,)))
    made = _one(rng, ('made of', 'made out of'))
    forms = [col, f"it's {col}", f'the {col} one', f"it's {col} colored", f'it is {_a(col)} {o}']
    if m:
        forms += [f'{col} {m}', f'it is {col} and {made} {m}', f'the {o} is {col} and {made} {m}',
                  f'{_a(col)} {o} {made} {m}', f'look for the {col} {m} one', f"it's the {col} one, {made} {m}",
                  f'{col}, {made} {m}', f"it's {_a(m)} {o}, {col} in color", f'{col} and {m}']
    if distractor:
        forms += [f'the {col} {o}, not the other one', f'the {col} one, there are two of them',
                  f'pick the {col} {o}']
    return _one(rng, forms)


def _direction_candidate(c: AnswerContent, rng: np.random.Generator) -> str:
    w = c.where.replace('_', ' ').lower()
    side = 'left' if 'left' in w else 'right' if 'right' in w else ''
    if any(k in w for k in ('behind', 'back', 'around')):
        forms = ['turn around', 'turn back', 'turn all the way around', "it's behind you, turn around",
                 'you need to turn around', 'turn around and walk forward']
        if side:
            forms += [f'turn around to your {side}', f'turn {side} twice']
    elif side:
        forms = [f'turn {side}', f'go {side}', f'you should turn {side}', f'turn to your {side}',
                 f'turn {side} and walk forward', f'turn {side}, then go straight', f'head {side}',
                 f'make a {side} turn', f'turn {side} and keep walking']
    elif any(k in w for k in ('front', 'ahead', 'forward', 'straight')):
        forms = ['go straight', 'walk straight ahead', 'keep going straight', "don't turn, just go forward",
                 'straight ahead of you', 'no need to turn, walk forward']
    else:
        forms = ["you don't need to move", 'stay where you are', 'no need to move', 'you are already there',
                 "don't move, it's right here", 'just stay here']
    return _one(rng, forms)


def _invalid_candidate(c: AnswerContent, rng: np.random.Generator) -> str:
    return _one(rng, ("sorry, I don't know", "I couldn't tell", f"I didn't see the {c.noun}",
                      "I'm not sure", 'no idea, sorry', f"I couldn't find the {c.noun} in the video"))


def _covered(c: AnswerContent) -> bool:
    """Whether the content was parsed into parts that the templates can reword."""
    if c.question_type == 'location':
        return c.held or bool(c.where or c.receptacle)
    if c.question_type == 'appearance':
        return bool(c.colour)
    return c.oracle_text in _MOVES


def _dress(text: str, rng: np.random.Generator) -> str:
    """Optional hedge, capital letter, end mark: the small variations people type."""
    u = rng.random()
    if u < 0.10:
        text = f'{_one(rng, HEDGES)} {text}'
    elif u < 0.14:
        text = f'{text}, I think'
    text = text[0].upper() + text[1:] if text else text
    return text + ('.' if rng.random() < 0.6 else '')


def paraphrase(content: AnswerContent, rng: np.random.Generator, distractor: bool = False) -> str:
    """A free-form answer saying `content` in other words: CANDIDATES wordings are drawn (template,
    synonyms, hedge) and the one whose length is closest to a drawn target length is returned."""
    target = 1.0 + rng.gamma(LENGTH_SHAPE, (LENGTH_MEAN - 1.0) / LENGTH_SHAPE)
    best, best_gap = '', np.inf
    for _ in range(CANDIDATES):
        if not content.valid:
            text = _invalid_candidate(content, rng)
        elif not _covered(content):
            text = content.oracle_text.rstrip('.')
        elif content.question_type == 'location':
            text = _location_candidate(content, rng)
        elif content.question_type == 'appearance':
            text = _appearance_candidate(content, rng, distractor)
        else:
            text = _direction_candidate(content, rng)
        text = _dress(text, rng)
        gap = abs(len(tokenize(text)) - target)
        if gap < best_gap:
            best, best_gap = text, gap
    return best


# ---------------------------------------------------------------------- one annotation

@dataclass(frozen=True)
class Annotation:
    """One synthetic annotator's question and answer for a task (question_type None: no question)."""

    annotator_id: int
    question_type: Optional[str]
    object_noun: str = ''
    question: str = ''
    answer: str = ''
    necessary: Optional[bool] = None
    oracle_answer: str = ''          # the oracle's templated answer the free-form one paraphrases
    valid: bool = True               # whether the oracle could answer

    @property
    def category(self) -> str:
        return self.question_type or 'none'

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict) -> 'Annotation':
        return cls(**d)


def annotate(task, snapshot, rng: np.random.Generator, annotator_id: int, *,
             situation: Optional[Situation] = None, model: Optional[ChoiceModel] = None,
             answer_fn: Callable = oracle_answer) -> Annotation:
    """Play the annotation protocol on `task` at its start (`snapshot`: the ground truth there).

    rng: this annotator's generator (all its randomness comes from it). situation: the precomputed
    `Situation.of(task, snapshot)`. model: the choice model (CHOICE_MODEL). answer_fn: the oracle,
    `answer(snapshot, question_type, object_noun) -> Answer`. Returns an Annotation: the chosen
    question (or none), its free-form answer and the necessity flag."""
    situation = situation or Situation.of(task, snapshot)
    p = (model or CHOICE_MODEL).probabilities(situation)
    category = CATEGORIES[int(rng.choice(len(CATEGORIES), p=p))]
    if category == 'none':
        return Annotation(annotator_id, None)
    noun = '' if category == 'direction' else _pick_noun(category, situation, rng)
    oracle = answer_fn(snapshot, category, noun)
    content = answer_content(oracle, category, noun)
    text = paraphrase(content, rng, distractor=noun in situation.distractor_nouns)
    lo, hi = NECESSARY_P[category]
    necessary = bool(rng.random() < (hi if _called_for(category, noun, situation) else lo))
    return Annotation(annotator_id, category, noun, question_text(category, noun), text,
                      necessary, oracle.text, bool(oracle.valid))


# ---------------------------------------------------------------------- storage

@dataclass(frozen=True)
class TaskDialogues:
    """The annotations of one task (one line of a dialogue file)."""

    task_id: str
    task_type: str
    instruction: str
    situation: Situation
    annotations: tuple[Annotation, ...]

    def to_json(self) -> dict:
        return {'task_id': self.task_id, 'task_type': self.task_type, 'instruction': self.instruction,
                'situation': self.situation.to_json(), 'annotations': [a.to_json() for a in self.annotations]}

    @classmethod
    def from_json(cls, d: dict) -> 'TaskDialogues':
        return cls(d['task_id'], d['task_type'], d['instruction'], Situation.from_json(d['situation']),
                   tuple(Annotation.from_json(a) for a in d['annotations']))


ANNOTATION_SEED = 20220226     # the dialogue data's root seed
ANNOTATORS = (0, 1)            # two annotators per task, as in the paper
ANNOTATION_RESOLUTION = 128    # the frame the annotators see (the simulator's default, DialfredEnv())


def annotator_rng(task_id: str, annotator_id: int) -> np.random.Generator:
    """The generator of one annotator on one task: independent streams from (split, number, annotator)."""
    split, number = task_id.split('/')
    return np.random.default_rng(np.random.SeedSequence([ANNOTATION_SEED, SPLIT_CODES[split], int(number),
                                                         annotator_id]))


def annotate_task(env, task) -> TaskDialogues:
    """Both annotators on `task` (a dialfred_sim Task), with `env` (a DialfredEnv) reset to it and
    still at its start. The same row whatever ran before (its randomness comes from the task id);
    changes nothing in the world (the oracle renders the asked object's look only for an appearance
    question)."""
    snap = snapshot(env)
    situation = Situation.of(task, snap)

    def oracle(s, question_type: str, noun: str) -> Answer:
        if question_type == 'appearance' and noun in s.task_objects:
            s = snapshot(env, [s.task_objects[noun]])
        return oracle_answer(s, question_type, noun)

    annotations = tuple(annotate(task, snap, annotator_rng(task.task_id, k), k, situation=situation,
                                 answer_fn=oracle) for k in ANNOTATORS)
    return TaskDialogues(task.task_id, task.task_type, task.instruction, situation, annotations)


DIALOGUE_CACHE_ENV = 'DIALFRED_DIALOGUE_DIR'     # where generated dialogue files (train) are kept
SHIPPED_SPLITS = ('valid_seen', 'valid_unseen')


def dialogue_path(split: str) -> Path:
    """Where the synthetic dialogues of `split` live: the package for the valid splits, else the cache."""
    if split in SHIPPED_SPLITS:
        return Path(str(resources.files('dialfred_oracle') / 'data' / 'dialogues' / f'{split}.jsonl.gz'))
    cache = Path(os.environ.get(DIALOGUE_CACHE_ENV, Path.home() / '.cache' / 'dialfred' / 'dialogues'))
    return cache / f'{split}.jsonl.gz'


def load_dialogues(split: str) -> list[TaskDialogues]:
    """Every annotated task of `split`, in task order. FileNotFoundError names the command that makes it."""
    path = dialogue_path(split)
    if not path.exists():
        raise FileNotFoundError(f'{path} does not exist; make it with '
                                f'`./dialfred env python3 scripts/annotate_dialogues.py --splits {split}`')
    with gzip.open(path, 'rt') as f:
        return [TaskDialogues.from_json(json.loads(line)) for line in f]


def write_dialogues(path: Path, rows: Iterable[TaskDialogues]) -> int:
    """Write gzip JSON lines (mtime 0: the same rows give the same bytes); returns the row count."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp, n = path.with_name(path.name + '.tmp'), 0
    with open(tmp, 'wb') as raw, gzip.GzipFile(fileobj=raw, mode='wb', mtime=0) as f:
        for row in rows:
            f.write((json.dumps(row.to_json(), separators=(',', ':')) + '\n').encode())
            n += 1
    tmp.replace(path)        # a half-written file never replaces a good one
    return n


# ---------------------------------------------------------------------- statistics

def fleiss_kappa(table) -> float:
    """Fleiss' kappa of an N x k table: row i counts how many raters put subject i in category j
    (every row has the same number of raters n >= 2). 1 = perfect agreement, 0 = chance level."""
    counts = np.asarray(table, dtype=float)
    if counts.ndim != 2 or counts.shape[0] == 0:
        raise ValueError('expected a non-empty N x k table')
    n = counts.sum(axis=1)
    if n[0] < 2 or not np.all(n == n[0]):
        raise ValueError('every subject needs the same number (>= 2) of ratings')
    n = n[0]
    p_j = counts.sum(axis=0) / counts.sum()
    p_i = ((counts ** 2).sum(axis=1) - n) / (n * (n - 1))
    p_bar, p_e = p_i.mean(), (p_j ** 2).sum()
    if p_e == 1.0:
        return 1.0          # everyone used one category: agreement is perfect and chance is too
    return float((p_bar - p_e) / (1.0 - p_e))


def answer_words(text: str) -> int:
    return len(tokenize(text))


def dialogue_statistics(annotations: Sequence[Sequence[Annotation]]) -> dict:
    """Statistics of annotated tasks, one inner sequence (the annotators' Annotations) per task.

    Returns a JSON-ready dict: tasks, annotations, questions; questions_per_task (questions per task
    and annotator, the paper's NQ); type_shares (share of questions per type); answer_words (mean
    words per answer, tokens of `tokenize`); answer_vocabulary (distinct answer words);
    necessary_fraction (of questions); fleiss_kappa over CATEGORIES (needs >= 2 annotators a task)."""
    flat = [a for task in annotations for a in task]
    questions = [a for a in flat if a.question_type is not None]
    if not flat:
        raise ValueError('no annotations')
    by_type = {t: sum(a.question_type == t for a in questions) for t in QUESTION_TYPES}
    table = [[sum(a.category == c for a in task) for c in CATEGORIES] for task in annotations]
    kappa = fleiss_kappa(table) if min(len(task) for task in annotations) >= 2 else None
    return {
        'tasks': len(annotations),
        'annotations': len(flat),
        'questions': len(questions),
        'questions_per_task': round(len(questions) / len(flat), 4),
        'type_shares': {t: round(by_type[t] / max(len(questions), 1), 4) for t in QUESTION_TYPES},
        'answer_words': round(float(np.mean([answer_words(a.answer) for a in questions])), 3) if questions else 0.0,
        'answer_vocabulary': len({w for a in questions for w in tokenize(a.answer)}),
        'necessary_fraction': round(sum(bool(a.necessary) for a in questions) / max(len(questions), 1), 4),
        'fleiss_kappa': None if kappa is None else round(kappa, 4),
    }
