"""The multimodal transformer over [language tokens | frame tokens | previous-action tokens].

Every token has a step: a language token the step from which it is known (0 for the instruction, the
step a QA was asked for its tokens), the frame and action tokens of step t the step t. The mask
(`attention_allowed`) lets a token attend to a token only if that token is known at its own step
(key step <= query step), so the decision at step t depends on nothing that comes later: no later
frame, no later action, no QA asked later. Language tokens attend to language tokens only (as
E.T.'s language encoder does); frame and action tokens attend to all three. Padding is never
attended to (a padding query attends to itself only, so no row of the softmax is empty).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


def attention_allowed(lang_steps: torch.Tensor, lang_valid: torch.Tensor, step_valid: torch.Tensor) -> torch.Tensor:
    """lang_steps, lang_valid: [B, L]; step_valid: [B, T] -> bool [B, S, S] (S = L + 2T), True where
    query i may attend to key j."""
    B, L = lang_steps.shape
    T = step_valid.shape[1]
    steps_t = torch.arange(T, device=lang_steps.device).expand(B, T)
    step = torch.cat([lang_steps, steps_t, steps_t], 1)                        # [B, S]
    valid = torch.cat([lang_valid, step_valid, step_valid], 1)
    is_lang = torch.zeros(step.shape[1], dtype=torch.bool, device=step.device)
    is_lang[:L] = True
    allowed = (step[:, None, :] <= step[:, :, None]) & valid[:, None, :]
    allowed &= ~is_lang[:, None] | is_lang[None, :]                           # language sees language
    eye = torch.eye(step.shape[1], dtype=torch.bool, device=step.device)
    return allowed | eye[None]


class Block(nn.Module):
    """Pre-norm transformer block with a per-sample boolean attention mask."""

    def __init__(self, d_model: int, heads: int, ff: int, dropout: float):
        super().__init__()
        self.heads = heads
        self.norm1 = nn.LayerNorm(d_model)
        self.qkv = nn.Linear(d_model, 3 * d_model)
        self.out = nn.Linear(d_model, d_model)
        self.norm2 = nn.LayerNorm(d_model)
        self.ff = nn.Sequential(nn.Linear(d_model, ff), nn.GELU(), nn.Linear(ff, d_model))
        self.dropout = nn.Dropout(dropout)
        self.attn_dropout = dropout

    def forward(self, x: torch.Tensor, allowed: torch.Tensor) -> torch.Tensor:
        B, S, D = x.shape
        q, k, v = self.qkv(self.norm1(x)).view(B, S, 3, self.heads, D // self.heads).permute(2, 0, 3, 1, 4)
        a = F.scaled_dot_product_attention(q, k, v, attn_mask=allowed[:, None],
                                           dropout_p=self.attn_dropout if self.training else 0.0)
        x = x + self.dropout(self.out(a.transpose(1, 2).reshape(B, S, D)))
        return x + self.dropout(self.ff(self.norm2(x)))


class MultimodalEncoder(nn.Module):
    def __init__(self, d_model: int, heads: int, layers: int, ff: int, max_steps: int, dropout: float = 0.0):
        super().__init__()
        if d_model % heads:
            raise ValueError(f'd_model ({d_model}) must be a multiple of heads ({heads})')
        self.time = nn.Embedding(max_steps, d_model)
        self.modality = nn.Embedding(2, d_model)           # 0 = frame, 1 = previous action
        self.blocks = nn.ModuleList(Block(d_model, heads, ff, dropout) for _ in range(layers))
        self.norm = nn.LayerNorm(d_model)

    def forward(self, lang: torch.Tensor, lang_steps: torch.Tensor, lang_valid: torch.Tensor,
                frames: torch.Tensor, actions: torch.Tensor, step_valid: torch.Tensor) -> torch.Tensor:
        """lang [B, L, d], frames and actions [B, T, d] (step t at index t) -> the frame tokens'
        outputs [B, T, d], one per step."""
        L, T = lang.shape[1], frames.shape[1]
        if T > self.time.num_embeddings:
            raise ValueError(f'{T} steps; this model takes at most {self.time.num_embeddings}')
        t = self.time(torch.arange(T, device=frames.device))[None]
        x = torch.cat([lang, frames + t + self.modality.weight[0], actions + t + self.modality.weight[1]], 1)
        allowed = attention_allowed(lang_steps, lang_valid, step_valid)
        for block in self.blocks:
            x = block(x, allowed)
        return self.norm(x[:, L:L + T])
