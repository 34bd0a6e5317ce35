"""Previous actions -> vectors. The action token of step t holds the action taken at step t - 1
(a <start> id at step 0), so it never shows the action being predicted."""

from __future__ import annotations

import torch
from torch import nn


class ActionEmbedding(nn.Module):
    def __init__(self, n_actions: int, d_model: int):
        super().__init__()
        self.start_id = n_actions                 # the id of <start>, the "previous action" of step 0
        self.embedding = nn.Embedding(n_actions + 1, d_model)

    def forward(self, previous_actions: torch.Tensor) -> torch.Tensor:
        """previous_actions: [B, T] long in 0..n_actions -> [B, T, d_model]."""
        return self.embedding(previous_actions)
