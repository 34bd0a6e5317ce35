"""Language tokens -> vectors: word embedding + position in the input + token type (instruction or
a QA's question type; see dialfred_performer.preprocess). The tokens attend to each other inside the
multimodal encoder, under its step mask, so there is no separate language transformer here."""

from __future__ import annotations

import math
from typing import Optional

import torch
from torch import nn


class LanguageEncoder(nn.Module):
    def __init__(self, vocab_size: int, d_model: int, max_tokens: int, n_types: int, dropout: float = 0.0):
        super().__init__()
        self.d_model = d_model
        self.word = nn.Embedding(vocab_size, d_model, padding_idx=0)
        self.position = nn.Embedding(max_tokens, d_model)
        self.token_type = nn.Embedding(n_types, d_model)
        self.norm = nn.LayerNorm(d_model)
        self.dropout = nn.Dropout(dropout)

    def forward(self, ids: torch.Tensor, types: torch.Tensor, positions: Optional[torch.Tensor] = None) -> torch.Tensor:
        """ids, types: [B, L] long -> [B, L, d_model]. `positions` [B, L]: each token's position (an answer
        stream's restart after the instruction: preprocess.encode_language); None: its index."""
        if positions is None:
            if ids.shape[1] > self.position.num_embeddings:
                raise ValueError(f'{ids.shape[1]} language tokens; this model takes at most {self.position.num_embeddings}')
            pos = self.position(torch.arange(ids.shape[1], device=ids.device))[None]
        else:
            if positions.numel() and int(positions.max()) >= self.position.num_embeddings:
                raise ValueError(f'a language token at position {int(positions.max())}; this model takes at most '
                                 f'{self.position.num_embeddings}')
            pos = self.position(positions)
        x = self.word(ids) * math.sqrt(self.d_model) + pos + self.token_type(types)
        return self.dropout(self.norm(x))
