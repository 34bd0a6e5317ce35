"""The one path from a task and its dialogue to the performer's input (no ROS, no torch model).

Training (`data.py`) and the agent at evaluation (`agent.py`) both call `encode_language` and
`frame_tensor`, so the tokens a model trains on are the tokens it sees when it acts. (The original
DialFRED split its QA markers one way at training and another at evaluation; here a marker is
inserted as one vocabulary token by `qa_tokens`, and `tokenize` also keeps any `<marker>` whole.)

The language input is the task's main-action instruction followed by every QA of the dialogue so
far, in the order asked, each as

    <q> <loc> apple <a> the apple is to your left in the fridge .

and each token carries its type (instruction, or the QA's question type) and the step at which it
became known (0 for the instruction; for a QA, the number of actions taken before it was asked).
The multimodal encoder lets the decision at step t see a QA only if it was asked at a step <= t.
"""

from __future__ import annotations

import json
import re
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Collection, Iterable, Optional, Sequence

import numpy as np

from dialfred_sim.protocol import PAPER_QUESTION_KINDS, QA, Question, question_kinds, question_types

PAD, UNK = '<pad>', '<unk>'
QUESTION_MARK, ANSWER_MARK, INVALID_MARK = '<q>', '<a>', '<invalid>'
# Every vocabulary starts with these: the marks, and those of the paper's question types ('<loc>', ...).
FIXED_TOKENS = (PAD, UNK, QUESTION_MARK, ANSWER_MARK, INVALID_MARK, *(f'<{q.token}>' for q in PAPER_QUESTION_KINDS))

# Token types, the language encoder's type embedding: 0 = padding, 1 = instruction, 2.. = a QA's type.
TYPE_PAD, TYPE_INSTRUCTION = 0, 1


def type_marks() -> dict[str, str]:
    """The mark of each registered question type in the performer's input: '<loc>', '<app>', '<dir>', ..."""
    return {q.name: f'<{q.token}>' for q in question_kinds()}


def special_tokens() -> tuple[str, ...]:
    """The tokens a vocabulary built now starts with: FIXED_TOKENS, then the marks of types registered after
    the paper's."""
    return (*FIXED_TOKENS, *(m for m in type_marks().values() if m not in FIXED_TOKENS))


def type_of_question() -> dict[str, int]:
    """The token type of a QA of each registered question type (2, 3, ...)."""
    return {q: 2 + k for k, q in enumerate(question_types())}


def n_token_types() -> int:
    """The size of the language encoder's type embedding for the registered question types."""
    return 2 + len(question_types())

_TOKEN_RE = re.compile(r"<[a-z_]+>|[a-z0-9]+(?:'[a-z]+)?|[^\sa-z0-9]")


def tokenize(text: str) -> list[str]:
    """Lower-cased words and punctuation marks of `text`; a `<marker>` stays one token."""
    return _TOKEN_RE.findall(text.lower())


@dataclass(frozen=True)
class AskedQA:
    """A QA of the dialogue and the step at which it was asked (actions taken before it)."""

    qa: QA
    step: int


class Vocabulary:
    """Word <-> id. Ids 0.. are FIXED_TOKENS (<pad> = 0, <unk> = 1; `special_tokens()` when built), then
    words by frequency."""

    def __init__(self, words: Sequence[str]):
        if tuple(words[:len(FIXED_TOKENS)]) != FIXED_TOKENS:
            raise ValueError(f'a vocabulary starts with {FIXED_TOKENS}, got {tuple(words[:len(FIXED_TOKENS)])}')
        if len(set(words)) != len(words):
            raise ValueError('a vocabulary has no repeated words')
        self.words = tuple(words)
        self.index = {w: k for k, w in enumerate(self.words)}

    @classmethod
    def build(cls, texts: Iterable[str], min_count: int = 1) -> 'Vocabulary':
        """A vocabulary of every token of `texts` seen at least `min_count` times (ties by spelling)."""
        counts = Counter(tok for text in texts for tok in tokenize(text))
        special = special_tokens()
        words = sorted((w for w, c in counts.items() if c >= min_count and w not in special),
                       key=lambda w: (-counts[w], w))
        return cls([*special, *words])

    def __len__(self) -> int:
        return len(self.words)

    def extended(self, texts: Iterable[str], min_count: int = 1) -> 'Vocabulary':
        """This vocabulary with the new tokens of `texts` (seen at least `min_count` times) after its own
        words, by frequency: every word keeps its id."""
        counts = Counter(tok for text in texts for tok in tokenize(text) if tok not in self.index)
        new = sorted((w for w, c in counts.items() if c >= min_count), key=lambda w: (-counts[w], w))
        return Vocabulary([*self.words, *new])

    def __eq__(self, other) -> bool:
        return isinstance(other, Vocabulary) and self.words == other.words

    def ids(self, tokens: Sequence[str]) -> list[int]:
        unk = self.index[UNK]
        return [self.index.get(t, unk) for t in tokens]

    def to_json(self) -> list[str]:
        return list(self.words)

    @classmethod
    def from_json(cls, words: Sequence[str]) -> 'Vocabulary':
        return cls(list(words))

    def save(self, path: Path) -> None:
        Path(path).write_text(json.dumps(self.to_json()) + '\n')

    @classmethod
    def load(cls, path: Path) -> 'Vocabulary':
        return cls.from_json(json.loads(Path(path).read_text()))


def qa_tokens(qa: QA) -> list[str]:
    """`<q> <type> noun words <a> answer words` (`<a> <invalid>` when the oracle could not answer)."""
    q = qa.question
    marks = type_marks()
    if q.question_type not in marks:
        raise ValueError(f'unknown question type {q.question_type!r}; expected one of {question_types()}')
    answer = tokenize(qa.answer) if qa.valid else [INVALID_MARK]
    return [QUESTION_MARK, marks[q.question_type], *tokenize(q.object_noun), ANSWER_MARK, *answer]


def qa_text(qa: QA) -> str:
    """The QA as the model reads it, for people: '<q> <loc> apple <a> the apple is ... .'."""
    return ' '.join(qa_tokens(qa))


# A language token's `until` when no later answer supersedes it: it stays known to the episode's end.
NEVER = 1 << 20


@dataclass(frozen=True)
class LanguageInput:
    """Token ids with, per token, its type (TYPE_*) and the step from which it is known. An answer
    stream (`encode_language(stream=True)`) also gives each token its position in the language encoder
    and the step from which a newer answer supersedes it (`NEVER`: none does); else both are None
    (positions are the tokens' indices; no token is superseded)."""

    ids: tuple[int, ...]
    types: tuple[int, ...]
    steps: tuple[int, ...]
    positions: Optional[tuple[int, ...]] = None
    until: Optional[tuple[int, ...]] = None

    def __len__(self) -> int:
        return len(self.ids)


def encode_language(vocab: Vocabulary, instruction: str, dialogue: Sequence[AskedQA] = (),
                    max_tokens: int | None = None, stream: bool = False, table: int | None = None,
                    fresh: Collection[str] = ()) -> LanguageInput:
    """The instruction, then every QA of `dialogue` in order, as ids, types and steps. With
    `max_tokens`, the instruction is kept and the oldest QAs are dropped first until it fits.

    With `stream` (a performer trained on answers at any step, `PerformerConfig.stream_answers`): a
    QA that repeats the answer its (type, noun) last got adds nothing; a newer answer of a (type,
    noun) supersedes the older one from its step on (the older tokens' `until`); each (type, noun)
    owns STREAM_SLOT positions after the instruction, in the order the stream first asks it, and each of
    its answers is placed there (positions restart at its slot), so that the stream may grow without
    outgrowing the position table (`table`, default `max_tokens` or 256: slots wrap where more would
    not fit) and the answers heard together never share a position; over `max_tokens` the oldest
    superseded QAs give way first, then the oldest QAs. An answer of a type in `fresh` (a stream's; a direction
    answer says where to go from where the agent stands when it hears it) holds for the step it is heard at
    only: it is gone from the next step on, and a repeat of it there is heard again."""
    if stream:
        return _encode_stream(vocab, instruction, dialogue, max_tokens, table or max_tokens or STREAM_TABLE, fresh)
    if fresh:
        raise ValueError('fresh answers are a kind of answer stream: they need stream=True')
    ins = tokenize(instruction)
    ids, types, steps = vocab.ids(ins), [TYPE_INSTRUCTION] * len(ins), [0] * len(ins)
    parts, token_type = [], type_of_question()
    for asked in dialogue:
        if asked.step < 0:
            raise ValueError(f'a QA is asked at a step >= 0, got {asked.step}')
        toks = qa_tokens(asked.qa)
        parts.append((vocab.ids(toks), [token_type[asked.qa.question.question_type]] * len(toks),
                      [asked.step] * len(toks)))
    if max_tokens is not None:
        ids, types, steps = ids[:max_tokens], types[:max_tokens], steps[:max_tokens]
        while parts and len(ids) + sum(len(p[0]) for p in parts) > max_tokens:
            parts.pop(0)
    for p_ids, p_types, p_steps in parts:
        ids, types, steps = ids + p_ids, types + p_types, steps + p_steps
    return LanguageInput(tuple(ids), tuple(types), tuple(steps))


def qa_key(asked: AskedQA) -> tuple[str, str]:
    """(question type, object noun): what a newer answer supersedes (in a stream, and in a task's log)."""
    return asked.qa.question.question_type, asked.qa.question.object_noun


def stream_qas(dialogue: Sequence[AskedQA], fresh: Collection[str] = ()) -> list[tuple[AskedQA, int]]:
    """(QA, the step from which it is no longer heard, or NEVER) for each QA of `dialogue` that says something
    new: a QA repeating the answer its (type, noun) last got while that answer still holds is left out; a
    newer answer supersedes it from its step on; an answer of a type in `fresh` holds for its own step only."""
    kept: list[list] = []
    current: dict[tuple[str, str], int] = {}
    for asked in dialogue:
        if asked.step < 0:
            raise ValueError(f'a QA is asked at a step >= 0, got {asked.step}')
        q, key = asked.qa, qa_key(asked)
        last = current.get(key)
        if last is not None and kept[last][1] > asked.step:           # the last answer still holds
            old = kept[last][0].qa
            if (old.valid, old.answer) == (q.valid, q.answer):
                continue
            kept[last][1] = asked.step
        current[key] = len(kept)
        kept.append([asked, asked.step + 1 if q.question.question_type in fresh else NEVER])
    return [(a, until) for a, until in kept]


# An answer stream's positions: each (type, noun) owns this many after the instruction (the oracle's QAs are
# at most 19 tokens; a longer one runs into the next slot), in a table of STREAM_TABLE by default.
STREAM_SLOT, STREAM_TABLE = 24, 256


def _encode_stream(vocab: Vocabulary, instruction: str, dialogue: Sequence[AskedQA],
                   max_tokens: Optional[int], table: int, fresh: Collection[str] = ()) -> LanguageInput:
    ins = tokenize(instruction)[:max_tokens]
    token_type = type_of_question()
    slot_of: dict[tuple[str, str], int] = {}
    parts = []
    for a, until in stream_qas(dialogue, fresh):   # slots by first appearance, before any QA gives way
        parts.append((qa_tokens(a.qa), a, until, slot_of.setdefault(qa_key(a), len(slot_of))))
    slots = max(1, (table - len(ins)) // STREAM_SLOT)
    if max_tokens is not None:
        room = max_tokens - len(ins)
        order = [k for k, p in enumerate(parts) if p[2] != NEVER] + [k for k, p in enumerate(parts) if p[2] == NEVER]
        size, dropped = sum(len(p[0]) for p in parts), set()
        for k in order:
            if size <= room:
                break
            dropped.add(k)
            size -= len(parts[k][0])
        parts = [p for k, p in enumerate(parts) if k not in dropped]
    ids, types, steps = vocab.ids(ins), [TYPE_INSTRUCTION] * len(ins), [0] * len(ins)
    positions, until = list(range(len(ins))), [NEVER] * len(ins)
    for toks, asked, end, slot in parts:
        n, start = len(toks), len(ins) + (slot % slots) * STREAM_SLOT
        ids += vocab.ids(toks)
        types += [token_type[asked.qa.question.question_type]] * n
        steps += [asked.step] * n
        positions += [min(start + i, table - 1) for i in range(n)]
        until += [end] * n
    return LanguageInput(tuple(ids), tuple(types), tuple(steps), tuple(positions), tuple(until))


def qa_to_dict(asked: AskedQA) -> dict:
    """The JSON form of an asked QA (a line's entry in dialogues.jsonl)."""
    q = asked.qa
    return {'question_type': q.question.question_type, 'object_noun': q.question.object_noun,
            'valid': q.valid, 'answer': q.answer, 'reason': q.reason, 'step': asked.step}


def qa_from_dict(d: dict) -> AskedQA:
    return AskedQA(QA(Question(d['question_type'], d.get('object_noun', '')), bool(d['valid']),
                      d.get('answer', ''), d.get('reason', '')), int(d['step']))


def frame_tensor(rgb: np.ndarray, resolution: int):
    """An HxWx3 uint8 RGB frame (or a stack TxHxWx3) as a float tensor [3, R, R] (or [T, 3, R, R])
    in [0, 1] at R = `resolution`, resized by area averaging: the same for the frames of training
    and the frames the agent sees."""
    import torch  # lazy: torch, which the rest of this module does without
    import torch.nn.functional as F  # lazy: torch, which the rest of this module does without
    rgb = np.asarray(rgb)
    if rgb.ndim not in (3, 4) or rgb.shape[-1] != 3 or rgb.dtype != np.uint8:
        raise ValueError(f'expected HxWx3 uint8 RGB frames, got {rgb.dtype} {rgb.shape}')
    one = rgb.ndim == 3
    x = torch.from_numpy(np.array(rgb[None] if one else rgb)).permute(0, 3, 1, 2).float().div_(255.0)
    if x.shape[2:] != (resolution, resolution):
        x = F.interpolate(x, size=(resolution, resolution), mode='area')
    return x[0] if one else x
