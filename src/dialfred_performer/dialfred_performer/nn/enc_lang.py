"""Language tokens -> vectors: word embedding + position in the input + token type (instruction or
a QA's question type; see dialfred_performer.preprocess). The tokens attend to each other inside the
multimodal encoder, under its step mask, so there is no separate language transformer here."""

from __future__ import annotations

import math

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

    def forward(self, ids: torch.Tensor, types: torch.Tensor) -> torch.Tensor:
        """ids, types: [B, L] long -> [B, L, d_model]."""
        if ids.shape[1] > self.position.num_embeddings:
            raise ValueError(f'{ids.shape[1]} language tokens; this model takes at most {self.position.num_embeddings}')
        pos = torch.arange(ids.shape[1], device=ids.device)
        x = self.word(ids) * math.sqrt(self.d_model) + self.position(pos)[None] + self.token_type(types)
        return self.dropout(self.norm(x))
