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
from dataclasses import asdict, dataclass, replace
from importlib import resources
from pathlib import Path
from typing import Callable, Iterable, Optional, Sequence

import numpy as np

from dialfred_sim.ground_truth import snapshot
from dialfred_sim.protocol import PAPER_QUESTION_TYPES, names_object, question_text
from dialfred_sim.tasks.instructions import tokenize
from dialfred_sim.tasks.split_files import SPLIT_CODES
from dialfred_sim.catalog import object_type

from .answers import answer as oracle_answer
from .questions import DIRECTION_BINS, Answer, AnswerContent, direction_bin, oracle_question, oracle_questions
from .questions.base import one_of


def categories() -> tuple[str, ...]:
    """What an annotator chooses among, and what two annotators' agreement is measured on: 'none' and
    each registered question type with rules, in the protocol's order."""
    return ('none',) + tuple(q.name for q in oracle_questions())


# The paper's human figures (Table of question types; Sec. "Hybrid data collection"); the share of each
# of its types is that type's `human_share` (questions/).
PAPER_HUMAN = {'type_shares': {t: oracle_question(t).human_share for t in PAPER_QUESTION_TYPES},
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
    """How strongly the situation calls for each of `categories()`: none (a clear instruction, the target
    in view or in hand), then each type's `OracleQuestion.evidence`."""
    none = float(s.clear) + 0.5 * float(s.target_held)
    return np.array([none, *(q.evidence(s) for q in oracle_questions())])


@dataclass(frozen=True)
class ChoiceModel:
    """P(choice | situation) = softmax(bias + strength * evidence(situation)) over `categories()`.

    Each annotator draws independently from it, so `strength` sets how much two annotators agree
    (strength 0: kappa 0) and `bias` sets the shares of question types (one per category, 'none' first)."""

    strength: float
    bias: tuple[float, ...]

    def probabilities(self, s: Situation) -> np.ndarray:
        return self.probabilities_from(evidence(s)[None])[0]

    def probabilities_from(self, evidences: np.ndarray) -> np.ndarray:
        """Rows of choice probabilities for rows of evidence (N x categories)."""
        if evidences.shape[1] != len(self.bias):
            raise ValueError(f'{len(self.bias)} intercepts for {evidences.shape[1]} categories of evidence')
        z = np.asarray(self.bias) + self.strength * evidences
        p = np.exp(z - z.max(axis=1, keepdims=True))
        return p / p.sum(axis=1, keepdims=True)


def target_choice_shares(shares: Optional[dict] = None,
                         questions_per_task: float = PAPER_HUMAN['questions_per_task']) -> np.ndarray:
    """The shares of `categories()` that the paper's humans give: none = 1 - questions per task; `shares`
    of the question types (default: each type's `human_share`)."""
    shares = {q.name: q.human_share for q in oracle_questions()} if shares is None else shares
    return np.array([1.0 - questions_per_task] + [questions_per_task * shares[t] for t in categories()[1:]])


def expected_statistics(model: ChoiceModel, situations: Sequence[Situation]) -> tuple[np.ndarray, float]:
    """Expected shares of `categories()` and expected Fleiss' kappa of two annotators over `situations`
    (a list of Situations or their N x categories evidence matrix)."""
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


# Fitted with `scripts/annotate_dialogues.py --fit` on the situations of valid_seen + valid_unseen; the
# intercepts of the question types are theirs (`OracleQuestion.choice_bias`), 'none' is 0.
CHOICE_STRENGTH = 1.3209


def choice_model() -> ChoiceModel:
    """The fitted choice model over the registered types (CHOICE_STRENGTH, each type's `choice_bias`)."""
    return ChoiceModel(CHOICE_STRENGTH, (0.0, *(q.choice_bias for q in oracle_questions())))


def necessary_p() -> dict[str, tuple[float, float]]:
    """P(the annotator says asking was necessary | question type, whether the situation called for it), by
    type (`OracleQuestion.necessary_p`). The paper reports no such figure; these express "necessary when it
    helped" with some disagreement."""
    return {q.name: q.necessary_p for q in oracle_questions()}


# ---------------------------------------------------------------------- free-form answers

def answer_content(oracle: Answer, question_type: str, noun: str) -> AnswerContent:
    """The parts of the oracle's templated answer (its type's `OracleQuestion.parts`), to be reworded.

    An answer the templates do not cover keeps its text (`oracle_text`) and is said as it is."""
    base = AnswerContent(question_type, oracle.object_noun or noun, bool(oracle.valid), oracle_text=oracle.text)
    rules = oracle_question(question_type)
    if not oracle.valid or rules is None:
        return base
    parts = rules.parts(oracle.text)
    if parts is None:
        return base
    return replace(base, **{k: v for k, v in parts.items() if k != 'noun'})


# Answer lengths: a target drawn per answer, 1 + Gamma(shape, mean - 1); the candidate wording closest
# to it is said. LENGTH_MEAN is tuned so that the realised mean is the paper's 6.73 words.
LENGTH_MEAN, LENGTH_SHAPE, CANDIDATES = 7.15, 3.0, 12
HEDGES = ('I think', 'I believe', 'probably', 'maybe', 'it seems', 'I guess')


def _invalid_candidate(c: AnswerContent, rng: np.random.Generator) -> str:
    return one_of(rng, ("sorry, I don't know", "I couldn't tell", f"I didn't see the {c.noun}",
                      "I'm not sure", 'no idea, sorry', f"I couldn't find the {c.noun} in the video"))


def _dress(text: str, rng: np.random.Generator) -> str:
    """Optional hedge, capital letter, end mark: the small variations people type."""
    u = rng.random()
    if u < 0.10:
        text = f'{one_of(rng, HEDGES)} {text}'
    elif u < 0.14:
        text = f'{text}, I think'
    text = text[0].upper() + text[1:] if text else text
    return text + ('.' if rng.random() < 0.6 else '')


def paraphrase(content: AnswerContent, rng: np.random.Generator, distractor: bool = False) -> str:
    """A free-form answer saying `content` in other words: CANDIDATES wordings are drawn (template,
    synonyms, hedge) and the one whose length is closest to a drawn target length is returned."""
    target = 1.0 + rng.gamma(LENGTH_SHAPE, (LENGTH_MEAN - 1.0) / LENGTH_SHAPE)
    rules = oracle_question(content.question_type)
    best, best_gap = '', np.inf
    for _ in range(CANDIDATES):
        if not content.valid:
            text = _invalid_candidate(content, rng)
        elif rules is None or not rules.covered(content):
            text = content.oracle_text.rstrip('.')
        else:
            text = rules.candidate(content, rng, distractor)
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
    `Situation.of(task, snapshot)`. model: the choice model (`choice_model()`). answer_fn: the oracle,
    `answer(snapshot, question_type, object_noun) -> Answer`. Returns an Annotation: the chosen
    question (or none), its free-form answer and the necessity flag."""
    situation = situation or Situation.of(task, snapshot)
    p = (model or choice_model()).probabilities(situation)
    choices = categories()
    category = choices[int(rng.choice(len(choices), p=p))]
    if category == 'none':
        return Annotation(annotator_id, None)
    rules = oracle_question(category)
    noun = rules.pick_noun(situation, rng) if names_object(category) else ''
    oracle = answer_fn(snapshot, category, noun)
    content = answer_content(oracle, category, noun)
    text = paraphrase(content, rng, distractor=noun in situation.distractor_nouns)
    lo, hi = rules.necessary_p
    necessary = bool(rng.random() < (hi if rules.called_for(noun, situation) else lo))
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
    changes nothing in the world (the oracle renders the asked object's look only for a question of a
    type that reads looks: appearance)."""
    snap = snapshot(env)
    situation = Situation.of(task, snap)

    def oracle(s, question_type: str, noun: str) -> Answer:
        rules = oracle_question(question_type)
        if rules is not None and rules.reads_looks and noun in s.task_objects:
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
    necessary_fraction (of questions); fleiss_kappa over `categories()` (needs >= 2 annotators a task)."""
    flat = [a for task in annotations for a in task]
    questions = [a for a in flat if a.question_type is not None]
    if not flat:
        raise ValueError('no annotations')
    choices = categories()
    by_type = {t: sum(a.question_type == t for a in questions) for t in choices[1:]}
    table = [[sum(a.category == c for a in task) for c in choices] for task in annotations]
    kappa = fleiss_kappa(table) if min(len(task) for task in annotations) >= 2 else None
    return {
        'tasks': len(annotations),
        'annotations': len(flat),
        'questions': len(questions),
        'questions_per_task': round(len(questions) / len(flat), 4),
        'type_shares': {t: round(by_type[t] / max(len(questions), 1), 4) for t in choices[1:]},
        'answer_words': round(float(np.mean([answer_words(a.answer) for a in questions])), 3) if questions else 0.0,
        'answer_vocabulary': len({w for a in questions for w in tokenize(a.answer)}),
        'necessary_fraction': round(sum(bool(a.necessary) for a in questions) / max(len(questions), 1), 4),
        'fleiss_kappa': None if kappa is None else round(kappa, 4),
    }
