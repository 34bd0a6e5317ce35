"""Previous actions -> vectors. The action token of step t holds the action taken at step t - 1
(a <start> id at step 0), so it never shows the action being predicted. With `failures`, an action
that failed in the world has an id of its own (`failed_id`): the performer is told that its click
did nothing, as an ALFRED agent is told by the simulator's success flag."""

from __future__ import annotations

import torch
from torch import nn


def failed_id(action: int, n_actions: int) -> int:
    """The id of `action` (0..n_actions - 1) that failed: after <start> (n_actions)."""
    return n_actions + 1 + action


class ActionEmbedding(nn.Module):
    def __init__(self, n_actions: int, d_model: int, failures: bool = False):
        super().__init__()
        self.start_id = n_actions                 # the id of <start>, the "previous action" of step 0
        self.embedding = nn.Embedding(n_actions + 1 + (n_actions if failures else 0), d_model)

    def forward(self, previous_actions: torch.Tensor) -> torch.Tensor:
        """previous_actions: [B, T] long in 0..n_actions (and the failed ids with `failures`) -> [B, T, d_model]."""
        return self.embedding(previous_actions)
