"""Pre-training data of the learned questioner: the (SYNTHETIC) annotated dialogues of a split, each
annotator's choice at a task's start as a supervised target (no ROS).

An example is what the questioner sees when it decides (the instruction, the dialogue so far, the step,
the frame) and the question the annotator asked there (or none). The annotators of
`dialfred_oracle.annotator` ask at the task's start, so pre-training examples have step 0 and an empty
dialogue; RL fine-tuning (`finetune.py`) then asks at any step with the dialogue so far. The frame is
the task's first frame (`frames.build_first_frames`: the task's start state rendered, the state the
demonstrations and the evaluation start from), encoded by the performer's frozen visual encoder
(`frame_features`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
import torch

from dialfred_performer.preprocess import AskedQA, Vocabulary, encode_language, frame_tensor
from dialfred_sim.catalog import load_catalog
from dialfred_sim.protocol import names_object

from .model import type_tokens


def catalog_nouns() -> tuple[str, ...]:
    """Every object noun of the catalogue (the nouns a question may name), sorted."""
    return tuple(sorted({t.noun for t in load_catalog().values()}))


@dataclass(frozen=True)
class Example:
    task_id: str
    instruction: str
    frame: int                        # index into the demonstrations' frames
    qtype: int                        # index into model.type_tokens()
    noun: int                         # index into the nouns (-1: the type names no object)
    step: int = 0
    dialogue: tuple[AskedQA, ...] = ()


def target(question_type: Optional[str], noun: str, noun_index: dict) -> tuple[int, int]:
    """(type index, noun index) of an annotation; KeyError for a noun outside the catalogue."""
    qtype, tokens = question_type or 'none', type_tokens()
    if qtype not in tokens:
        raise ValueError(f'unknown question type {question_type!r}')
    return tokens.index(qtype), (noun_index[noun] if names_object(qtype) else -1)


def pretraining_examples(rows: Sequence, first_frame: dict, nouns: Sequence[str]) -> tuple[list[Example], int]:
    """(examples, annotations skipped) from TaskDialogues rows and {task id: index of its first frame}
    (`frames.FirstFrames.index`) of the same split; an annotation is skipped when its task has no
    frame or its noun is not in `nouns`."""
    index = {n: k for k, n in enumerate(nouns)}
    out, skipped = [], 0
    for row in rows:
        if row.task_id not in first_frame:
            skipped += len(row.annotations)
            continue
        for a in row.annotations:
            try:
                qtype, noun = target(a.question_type, a.object_noun, index)
            except KeyError:
                skipped += 1
                continue
            out.append(Example(row.task_id, row.instruction, first_frame[row.task_id], qtype, noun))
    return out, skipped


@torch.no_grad()
def frame_features(visual, frames: np.ndarray, resolution: int, batch: int = 512) -> torch.Tensor:
    """The frame embeddings [N, d] of uint8 RGB frames [N, H, W, 3] by a performer's (frozen) frame encoder
    (dialfred_performer.model.build_visual)."""
    visual.eval()
    parts = [visual.embedding(frame_tensor(np.asarray(frames[k:k + batch]), resolution))
             for k in range(0, len(frames), batch)]
    return torch.cat(parts) if parts else torch.zeros(0, visual.d_model)


def pad_language(ids: Sequence[Sequence[int]], types: Sequence[Sequence[int]]) -> tuple:
    """Token ids and types of a batch, padded: (ids, types [B, L] long, valid [B, L] bool)."""
    B, L = len(ids), max([len(x) for x in ids] + [1])
    out_ids = torch.zeros(B, L, dtype=torch.long)
    out_types = torch.zeros(B, L, dtype=torch.long)
    valid = torch.zeros(B, L, dtype=torch.bool)
    for b, (x, t) in enumerate(zip(ids, types)):
        out_ids[b, :len(x)] = torch.tensor(x, dtype=torch.long)
        out_types[b, :len(x)] = torch.tensor(t, dtype=torch.long)
        valid[b, :len(x)] = True
    return out_ids, out_types, valid


def collate(examples: Sequence[Example], vocab: Vocabulary, features: torch.Tensor, max_tokens: int = 256) -> dict:
    """A padded batch: lang_ids / lang_types / lang_valid [B, L], image [B, d] (features[example.frame]
    for a features table over the frames), steps, types, nouns [B]."""
    langs = [encode_language(vocab, e.instruction, e.dialogue, max_tokens) for e in examples]
    ids, types, valid = pad_language([x.ids for x in langs], [x.types for x in langs])
    return {'lang_ids': ids, 'lang_types': types, 'lang_valid': valid,
            'image': features[torch.tensor([e.frame for e in examples])],
            'steps': torch.tensor([e.step for e in examples]),
            'types': torch.tensor([e.qtype for e in examples]), 'nouns': torch.tensor([e.noun for e in examples])}
