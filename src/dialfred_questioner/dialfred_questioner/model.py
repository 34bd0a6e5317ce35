"""The learned questioner (DialFRED paper, "Questioner"): a seq2seq model that decides whether to ask
and what, with a value head for actor-critic fine-tuning. ROS-free, torch.

The paper's model: an LSTM encoder over the instruction's tokens; an LSTM decoder fed the current
frame's image feature and the previous output token, with dot-product attention over the encoder's
states; a question is two tokens, its type (location / appearance / direction) and its object, or a
single `none` token. Where this one goes further: the original read only the instruction,
so it could ask the same question twice; here the encoder reads the instruction **and the dialogue so
far** (each QA with its type and the step it was asked, through `dialfred_performer.preprocess`, the
performer's own path from text to tokens), and the decoder also gets the step (actions taken so far).

Output tokens (`OUTPUT_TOKENS`): first a choice among none / location / appearance / direction; after
location or appearance, an object noun of `nouns` (the catalogue's nouns: asking about an object the
instruction does not name is allowed and is what the oracle answers as invalid); a direction question
names no object. `Questioner.decide` gives the distribution at each of the (at most) two decisions,
`sample`/`greedy` a question with its log-probability, and `value` the critic's estimate of the state.

The image feature is the frame embedding of a visual encoder (`dialfred_performer.nn.VisualEncoder`),
copied from a performer checkpoint and frozen, so the questioner sees the frame as the performer does.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Optional, Sequence

import torch
from torch import nn

from dialfred_performer.preprocess import n_token_types
from dialfred_sim.protocol import object_question_types, question_types

NO_QUESTION = 'none'
START = '<start>'


def type_tokens() -> tuple[str, ...]:
    """The type head's outputs for the registered question types: 'none', 'location', 'appearance', ..."""
    return (NO_QUESTION, *question_types())


@dataclass(frozen=True)
class QuestionerConfig:
    """Sizes of the questioner; the vocabularies come with it."""

    embedding: int = 64          # word / output-token embeddings
    hidden: int = 128            # LSTM states (the encoder is bidirectional: hidden / 2 each way)
    image: int = 128             # the frame embedding's size (the performer's d_model)
    max_steps: int = 64          # step embeddings: steps >= this share the last one
    dropout: float = 0.1


def output_tokens(nouns: Sequence[str], types: Optional[Sequence[str]] = None) -> tuple[str, ...]:
    """The decoder's vocabulary: <start>, the type tokens (`type_tokens()` unless given), then the object nouns."""
    nouns = list(dict.fromkeys(nouns))
    types = type_tokens() if types is None else tuple(types)
    clash = set(nouns) & {START, *types}
    if clash:
        raise ValueError(f'object nouns may not be named like the type tokens: {sorted(clash)}')
    return (START, *types, *nouns)


class Questioner(nn.Module):
    def __init__(self, config: QuestionerConfig, vocab_size: int, nouns: Sequence[str]):
        super().__init__()
        if config.hidden % 2:
            raise ValueError(f'hidden must be even (a bidirectional encoder), got {config.hidden}')
        self.config = config
        self.vocab_size = vocab_size
        self.type_tokens = type_tokens()      # the question types registered when it is made
        self.tokens = output_tokens(nouns, self.type_tokens)
        self.token_index = {t: k for k, t in enumerate(self.tokens)}
        self.n_types = len(self.type_tokens)
        e, h = config.embedding, config.hidden
        self.word = nn.Embedding(vocab_size, e, padding_idx=0)
        self.token_type = nn.Embedding(n_token_types(), e)
        self.encoder = nn.LSTM(e, h // 2, batch_first=True, bidirectional=True)
        self.step = nn.Embedding(config.max_steps, e)
        self.image = nn.Sequential(nn.Linear(config.image, e), nn.LayerNorm(e))
        self.init_state = nn.Linear(h + 2 * e, 2 * h)
        self.out_embedding = nn.Embedding(len(self.tokens), e)
        self.decoder = nn.LSTMCell(2 * e, h)
        self.attention = nn.Linear(h, h, bias=False)
        self.output = nn.Linear(2 * h, len(self.tokens))
        self.critic = nn.Sequential(nn.Linear(h + 2 * e, h), nn.Tanh(), nn.Linear(h, 1))
        self.dropout = nn.Dropout(config.dropout)

    # ------------------------------------------------------------------ the state

    def encode(self, lang_ids: torch.Tensor, lang_types: torch.Tensor, lang_valid: torch.Tensor,
               image: torch.Tensor, steps: torch.Tensor) -> dict:
        """Language [B, L] (ids, token types, valid), frame embeddings [B, image], steps [B] ->
        the encoder's states and the decoder's start state (a dict, the input of `decide`)."""
        x = self.dropout(self.word(lang_ids) + self.token_type(lang_types))
        lengths = lang_valid.sum(1).clamp(min=1).cpu()
        packed = nn.utils.rnn.pack_padded_sequence(x, lengths, batch_first=True, enforce_sorted=False)
        states, _ = self.encoder(packed)
        states, _ = nn.utils.rnn.pad_packed_sequence(states, batch_first=True, total_length=lang_ids.shape[1])
        valid = lang_valid.float()[..., None]
        pooled = (states * valid).sum(1) / valid.sum(1).clamp(min=1.0)
        context = torch.cat([pooled, self.image(image), self.step(steps.clamp(0, self.config.max_steps - 1))], -1)
        h0, c0 = torch.tanh(self.init_state(context)).chunk(2, -1)
        return {'states': states, 'valid': lang_valid, 'context': context, 'h': h0, 'c': c0,
                'image': self.image(image)}

    def value(self, encoded: dict) -> torch.Tensor:
        """The critic's estimate of the return from this state [B]."""
        return self.critic(encoded['context']).squeeze(-1)

    def _decode(self, encoded: dict, h, c, previous: torch.Tensor):
        h, c = self.decoder(torch.cat([encoded['image'], self.out_embedding(previous)], -1), (h, c))
        scores = torch.einsum('bld,bd->bl', encoded['states'], self.attention(h))
        scores = scores.masked_fill(~encoded['valid'], float('-inf'))
        attended = torch.einsum('bl,bld->bd', torch.softmax(scores, -1), encoded['states'])
        return self.output(self.dropout(torch.cat([h, attended], -1))), h, c

    def decide(self, encoded: dict, first: Optional[torch.Tensor] = None) -> tuple[torch.Tensor, torch.Tensor]:
        """Log-probabilities of the first token over the type tokens [B, types + 1], and of the object given the
        first token [B, n_nouns] (teacher-forced on `first` [B] type indices when given, else on the
        argmax; rows whose first token needs no object are still computed and must be ignored)."""
        B = encoded['h'].shape[0]
        start = torch.full((B,), self.token_index[START], dtype=torch.long, device=encoded['h'].device)
        logits, h, c = self._decode(encoded, encoded['h'], encoded['c'], start)
        type_logp = torch.log_softmax(logits[:, 1:1 + self.n_types], -1)
        if first is None:
            first = type_logp.argmax(-1)
        logits, _, _ = self._decode(encoded, h, c, first + 1)
        noun_logp = torch.log_softmax(logits[:, 1 + self.n_types:], -1)
        return type_logp, noun_logp

    # ------------------------------------------------------------------ questions

    @property
    def nouns(self) -> tuple[str, ...]:
        return self.tokens[1 + self.n_types:]

    def log_prob(self, encoded: dict, types: torch.Tensor, nouns: torch.Tensor) -> torch.Tensor:
        """log p(question) [B] of type indices [B] (into the type tokens) and noun indices [B] (into
        `nouns`; ignored for none and direction)."""
        type_logp, noun_logp = self.decide(encoded, types)
        lp = type_logp.gather(1, types[:, None]).squeeze(1)
        needs = needs_object(types, self.type_tokens)
        return lp + torch.where(needs, noun_logp.gather(1, nouns.clamp(min=0)[:, None]).squeeze(1),
                                torch.zeros_like(lp))

    def entropy(self, encoded: dict, types: torch.Tensor) -> torch.Tensor:
        """Entropy of the type choice plus, where the type needs one, of the object choice [B]."""
        type_logp, noun_logp = self.decide(encoded, types)
        h_type = -(type_logp.exp() * type_logp).sum(-1)
        h_noun = -(noun_logp.exp() * noun_logp).sum(-1)
        return h_type + torch.where(needs_object(types, self.type_tokens), h_noun, torch.zeros_like(h_noun))

    def sample(self, encoded: dict, generator: Optional[torch.Generator] = None,
               greedy: bool = False) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(type indices [B], noun indices [B] (-1 where none is needed), log p [B]) drawn from the
        policy (or its most likely question with `greedy`)."""
        B = encoded['h'].shape[0]
        start = torch.full((B,), self.token_index[START], dtype=torch.long, device=encoded['h'].device)
        logits, h, c = self._decode(encoded, encoded['h'], encoded['c'], start)
        type_logp = torch.log_softmax(logits[:, 1:1 + self.n_types], -1)
        types = type_logp.argmax(-1) if greedy else torch.multinomial(type_logp.exp(), 1, generator=generator)[:, 0]
        logits, _, _ = self._decode(encoded, h, c, types + 1)
        noun_logp = torch.log_softmax(logits[:, 1 + self.n_types:], -1)
        nouns = noun_logp.argmax(-1) if greedy else torch.multinomial(noun_logp.exp(), 1, generator=generator)[:, 0]
        needs = needs_object(types, self.type_tokens)
        lp = type_logp.gather(1, types[:, None]).squeeze(1) + torch.where(
            needs, noun_logp.gather(1, nouns[:, None]).squeeze(1), torch.zeros(B))
        return types, torch.where(needs, nouns, torch.full_like(nouns, -1)), lp


def needs_object(types: torch.Tensor, tokens: Optional[Sequence[str]] = None) -> torch.Tensor:
    """Which type indices (into `tokens`, a questioner's type tokens; `type_tokens()` unless given) name an
    object."""
    tokens = type_tokens() if tokens is None else tuple(tokens)
    named = object_question_types()
    return torch.isin(types, torch.tensor([k for k, t in enumerate(tokens) if t in named], dtype=types.dtype))


def config_dict(config: QuestionerConfig) -> dict:
    return dataclasses.asdict(config)
