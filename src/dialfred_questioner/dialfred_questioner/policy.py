"""The learned questioner as something that asks (no ROS): a rollout policy for RL fine-tuning, and a
`baselines.Questioner` (reset / ask / hear) for the evaluation and the questioner node.

`LearnedQuestioner.from_checkpoint(path)` loads a checkpoint of `checkpoint.save` (the model, its
vocabulary and nouns, and the frozen visual encoder copied from the performer). A decision reads the
current RGB frame (through that encoder), the instruction, the dialogue so far (each QA with the step
it was asked) and the step, and gives a `Question` or None. `greedy` (evaluation) takes the most
likely question; otherwise it samples from the policy with its own seeded generator (rollouts). As a
rollout policy it also returns the decision's `Record`: the model's inputs and its choice, from which
the fine-tuning recomputes log-probabilities, entropies and values in batches.

As a `Questioner` it asks at most once per step, and only at the chances its `timing` gives
(`rollout.Timing`: begin, anytime with a gap, or on the performer's confusion), exactly as a rollout
does, so an evaluation plays the episode its fine-tuning played. The timing is the checkpoint's
(`finetune.py` stores the one it was trained with; a pre-trained checkpoint asks at the start only)
unless one is given. With the confusion timing it needs the performer's top-2 action-probability gap:
in process from `attach(performer)`, in the questioner node from the request (`ask_given_gap`).

The shipped checkpoints live in `CHECKPOINTS` (installed with the package), one per name of
`SHIPPED_LEARNED` ('rl-anytime' -> checkpoints/rl_anytime.pt); `learned_questioner(name)` loads one of
those, or any checkpoint as 'learned:PATH', greedy with its own timing (`retimed` changes it).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional, Sequence

import torch

from dialfred_performer.model import PerformerConfig, build_visual, state_digest, visual_state
from dialfred_performer.nn import VisualEncoder
from dialfred_performer.preprocess import AskedQA, Vocabulary, encode_language, frame_tensor
from dialfred_sim.protocol import QA, ConfusionSource, Observation, Question, as_observation, names_object, top2_gap

from .data import pad_language
from .model import NO_QUESTION, Questioner, QuestionerConfig
from .rollout import Timing
from .shipped import CHECKPOINTS, SHIPPED_LEARNED  # noqa: F401 - the names policy's callers find here

# The timing of a checkpoint that stores none (a pre-trained one: its annotators asked at the start).
DEFAULT_TIMING = Timing('begin')

LEARNED_PREFIX = 'learned:'       # 'learned:PATH': the questioner of any checkpoint file


@dataclass(frozen=True)
class Record:
    lang_ids: tuple[int, ...]
    lang_types: tuple[int, ...]
    image: torch.Tensor           # [image] frame embedding (frozen encoder)
    step: int
    qtype: int                    # index into the model's type_tokens
    noun: int                     # index into the nouns, -1 when the type names none


class SharedVisualError(ValueError):
    """A questioner checkpoint whose frame encoder is kept in a performer checkpoint that is missing or
    holds other weights."""


def shared_visual(path: Path, state: dict) -> dict:
    """The frame encoder's weights of a questioner checkpoint written by share_visual: read from the
    performer checkpoint it names (relative to its own folder), checked against the digest it stores."""
    source = state.get('visual_source')
    if not isinstance(source, dict) or not isinstance(source.get('performer'), str):
        raise SharedVisualError(f'{path} has neither the frame encoder\'s weights nor a visual_source')
    performer = Path(path).parent / source['performer']
    try:
        weights = visual_state(performer)
    except (OSError, ValueError) as exc:
        raise SharedVisualError(f'{path} keeps its frame encoder in {performer}, which cannot be read: {exc}') from None
    if state_digest(weights) != source.get('sha256'):
        raise SharedVisualError(f'{path} was trained with another frame encoder than the one in {performer} '
                                f'(weights sha256 {state_digest(weights)[:12]}..., expected '
                                f'{str(source.get("sha256"))[:12]}...): the performer checkpoint was replaced')
    return weights


def share_visual(source: Path, target: Path, performer: Path) -> dict:
    """Write questioner checkpoint `source` to `target` without its copy of the frame encoder, naming the
    performer checkpoint that holds the same weights instead (relative to target's folder; its digest is
    stored and checked on every load). A shipped set of questioners then keeps the encoder once, in the
    performer they were trained with. Raises SharedVisualError if `performer`'s encoder differs."""
    state = torch.load(source, map_location='cpu', weights_only=True)
    own = state.get('visual')
    if own is None:
        raise SharedVisualError(f'{source} has no frame encoder weights of its own')
    theirs = visual_state(performer)
    if state_digest(own) != state_digest(theirs):
        raise SharedVisualError(f'{source}\'s frame encoder is not the one in {performer}')
    target = Path(target)
    state = {k: v for k, v in state.items() if k != 'visual'}
    state['visual_source'] = {'performer': os.path.relpath(Path(performer).resolve(), target.parent.resolve()),
                              'sha256': state_digest(own)}
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(target.name + '.tmp')
    torch.save(state, tmp)
    tmp.replace(target)
    return state['visual_source']


def batch_records(records: Sequence[Record]) -> dict:
    """Records as a padded batch: lang_ids / lang_types / lang_valid [B, L], image [B, d], steps,
    types, nouns [B]."""
    ids, types, valid = pad_language([r.lang_ids for r in records], [r.lang_types for r in records])
    return {'lang_ids': ids, 'lang_types': types, 'lang_valid': valid,
            'image': torch.stack([r.image for r in records]), 'steps': torch.tensor([r.step for r in records]),
            'types': torch.tensor([r.qtype for r in records]), 'nouns': torch.tensor([r.noun for r in records])}


# Tokens per chunk of `score_records`.
TOKEN_BUDGET = 16_384


def length_chunks(lengths: Sequence[int], token_budget: int = TOKEN_BUDGET) -> list[list[int]]:
    """Indices of `lengths` grouped by equal length (in increasing order), each group cut into chunks of
    at most `token_budget` tokens (a row longer than the budget is a chunk of its own). On CPU the
    backward pass of a packed LSTM over rows of different lengths grows with rows x length squared;
    over rows of one length it is linear."""
    order = sorted(range(len(lengths)), key=lambda k: (lengths[k], k))
    chunks, current = [], []
    for k in order:
        if current and (lengths[k] != lengths[current[0]] or (len(current) + 1) * lengths[k] > token_budget):
            chunks.append(current)
            current = []
        current.append(k)
    if current:
        chunks.append(current)
    return chunks


def score_records(model: Questioner, records: Sequence[Record],
                  token_budget: int = TOKEN_BUDGET) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(log p of each record's question, the policy's entropy, the critic's value) [B], in the records'
    order, computed over chunks of records of one length (`length_chunks`): the same numbers as one
    padded batch, at a cost that grows with the tokens read, not with rows x the longest squared."""
    if not records:
        return torch.empty(0), torch.empty(0), torch.empty(0)
    parts = []
    for chunk in length_chunks([len(r.lang_ids) for r in records], token_budget):
        b = batch_records([records[k] for k in chunk])
        enc = model.encode(b['lang_ids'], b['lang_types'], b['lang_valid'], b['image'], b['steps'])
        parts.append((torch.tensor(chunk), model.log_prob(enc, b['types'], b['nouns']),
                      model.entropy(enc, b['types']), model.value(enc)))
    index = torch.cat([p[0] for p in parts])
    inverse = torch.empty_like(index)
    inverse[index] = torch.arange(len(index))
    return tuple(torch.cat([p[j] for p in parts])[inverse] for j in (1, 2, 3))


class LearnedQuestioner:
    name = 'learned'

    def __init__(self, model: Questioner, vocab: Vocabulary, visual: VisualEncoder, resolution: int,
                 greedy: bool = True, seed: int = 0, timing: Timing = DEFAULT_TIMING):
        if len(vocab) != model.vocab_size:
            raise ValueError(f'the vocabulary has {len(vocab)} words, the model {model.vocab_size}')
        self.model, self.vocab, self.visual, self.resolution = model, vocab, visual.eval(), resolution
        self.greedy = greedy
        self.timing = timing
        self.generator = torch.Generator().manual_seed(seed)
        self.performer = None
        self.task = None
        self.dialogue: list[AskedQA] = []
        self._step = 0
        self._asked_at = -1
        # False: the original DialFRED questioner's input, the instruction only (an ablation)
        self.reads_dialogue = True

    @property
    def needs_gap(self) -> bool:
        """Whether a decision needs the performer's top-2 action-probability gap (confusion timing)."""
        return self.timing.mode == 'confusion'

    @classmethod
    def from_checkpoint(cls, path: Path, greedy: bool = True, seed: int = 0,
                        timing: Optional[Timing] = None) -> 'LearnedQuestioner':
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f'no questioner checkpoint at {path}')
        try:
            state = torch.load(path, map_location='cpu', weights_only=True)
            config = QuestionerConfig(**state['config'])
            vocab = Vocabulary.from_json(state['vocab'])
            model = Questioner(config, len(vocab), state['nouns'])
            model.load_state_dict(state['state_dict'])
            if state.get('visual_config'):         # the performer's config: its kind of frame encoder
                visual = build_visual(PerformerConfig(**state['visual_config']))
            else:                                  # checkpoints from before visual_config: the 3-conv encoder
                visual = VisualEncoder(config.image, int(state['visual_resolution']))
            visual.load_state_dict(state['visual'] if 'visual' in state else shared_visual(path, state))
            saved = Timing(**state['timing']) if state.get('timing') else DEFAULT_TIMING
        except SharedVisualError:
            raise
        except Exception as exc:  # noqa: BLE001 - a damaged file raises many kinds
            raise ValueError(f'{path} is not a questioner checkpoint ({type(exc).__name__}: {exc})') from exc
        q = cls(model.eval(), vocab, visual, int(state['visual_resolution']), greedy, seed, timing or saved)
        q.reads_dialogue = bool(state.get('reads_dialogue', True))
        return q

    @torch.no_grad()
    def record_of(self, rgb, instruction: str, dialogue: Sequence[AskedQA], step: int) -> Record:
        """The model's inputs for a decision (qtype / noun still -1)."""
        lang = encode_language(self.vocab, instruction, dialogue if self.reads_dialogue else ())
        image = self.visual.embedding(frame_tensor(rgb, self.resolution)[None])[0]
        return Record(lang.ids, lang.types, image, step, -1, -1)

    @torch.no_grad()
    def decide(self, rgb, instruction: str, dialogue: Sequence[AskedQA], step: int) -> tuple[Optional[Question], Record]:
        r = self.record_of(rgb, instruction, dialogue, step)
        b = batch_records([r])
        was = self.model.training
        self.model.eval()
        enc = self.model.encode(b['lang_ids'], b['lang_types'], b['lang_valid'], b['image'], b['steps'])
        qtypes, nouns, _ = self.model.sample(enc, generator=self.generator, greedy=self.greedy)
        self.model.train(was)
        qtype, noun = int(qtypes[0]), int(nouns[0])
        r = Record(r.lang_ids, r.lang_types, r.image, step, qtype, noun)
        name = self.model.type_tokens[qtype]
        if name == NO_QUESTION:
            return None, r
        return Question(name, self.model.nouns[noun] if names_object(name) else ''), r

    # ---- a rollout policy
    def __call__(self, rgb, task, dialogue: Sequence[AskedQA], step: int) -> tuple[Optional[Question], Record]:
        return self.decide(rgb, task.instruction, dialogue, step)

    # ---- a baselines.Questioner
    def attach(self, performer: Any) -> None:
        """The performer whose confusion the confusion timing watches (in process)."""
        if self.needs_gap and not isinstance(performer, ConfusionSource):
            raise ValueError(f'a questioner with the confusion timing needs a performer with '
                             f'action_probabilities(); {performer!r} has none')
        self.performer = performer

    def reset(self, task: Any, seed: int) -> None:
        self.task, self.dialogue, self._step, self._asked_at = task, [], 0, -1
        self.generator.manual_seed(seed)

    def ask(self, observation: Observation, step: int) -> Optional[Question]:
        """A question or None before action `step` + 1: at most one per step, at the timing's chances.
        The confusion timing reads the attached performer's top-2 gap."""
        gap = None
        if self.needs_gap and step != self._asked_at:
            if self.performer is None:
                raise RuntimeError('the confusion timing needs attach(performer) or the performer\'s gap')
            gap = top2_gap(self.performer.action_probabilities(observation))
        return self.ask_given_gap(observation, step, gap)

    def ask_given_gap(self, observation: Observation, step: int, gap: Optional[float]) -> Optional[Question]:
        """ask(), with the performer's top-2 gap given (the questioner node gets it in the request)."""
        if step == self._asked_at:
            return None
        if self.needs_gap:
            if gap is None:
                raise ValueError('a questioner with the confusion timing needs the performer\'s top-2 gap')
            chance = gap < self.timing.epsilon
        else:
            chance = self.timing.chance(step, None, None)
        if not chance:
            return None
        # The frame is read (and a bad one refused) before the step is marked: a refused request
        # leaves this step's chance to ask as it was.
        question = self.decide(as_observation(observation).rgb, self.task.instruction, self.dialogue, step)[0]
        self._asked_at, self._step = step, step
        return question

    def hear(self, qa: QA) -> None:
        self.dialogue.append(AskedQA(qa, self._step))


def learned_checkpoint(name: str) -> Optional[Path]:
    """The checkpoint file a learned questioner's name stands for (a name of `SHIPPED_LEARNED`, or
    'learned:PATH'), or None for a name that is no learned questioner's."""
    if name in SHIPPED_LEARNED:
        return CHECKPOINTS / (name.replace('-', '_') + '.pt')
    if name.startswith(LEARNED_PREFIX):
        path = name[len(LEARNED_PREFIX):]
        if not path:
            raise ValueError("questioner 'learned:' needs a checkpoint file: learned:PATH")
        return Path(path).expanduser()
    return None


def learned_questioner(name: str, timing: Optional[Timing] = None) -> LearnedQuestioner:
    """The greedy `LearnedQuestioner` of a shipped name or of 'learned:PATH', with the checkpoint's own
    timing unless `timing` is given; ValueError naming the file (and what makes it) when it is not there
    or is no questioner checkpoint."""
    path = learned_checkpoint(name)
    if path is None:
        raise ValueError(f'{name!r} names no learned questioner: one of {", ".join(SHIPPED_LEARNED)} or learned:PATH')
    if not path.is_file():
        if name in SHIPPED_LEARNED:
            module = 'pretrain' if name == 'pretrained' else 'finetune'
            raise ValueError(f'the {name!r} questioner\'s checkpoint {path} is not there: it is made by '
                             f'`python -m dialfred_questioner.{module}` (and shipped under that name)')
        raise ValueError(f'no questioner checkpoint at {path}')
    return LearnedQuestioner.from_checkpoint(path, greedy=True, timing=timing)


def retimed(timing: Timing, mode: str = '', gap: int = 0, epsilon: float = -1.0) -> Timing:
    """`timing` with the fields given changed: `mode` ('' keeps it), `gap` (0 keeps it), `epsilon`
    (< 0 keeps it). ValueError for a bad value."""
    if gap < 0:
        raise ValueError(f'gap must be at least 1 (0: the checkpoint\'s), got {gap}')
    return Timing(mode or timing.mode, gap or timing.gap, timing.epsilon if epsilon < 0 else float(epsilon))
