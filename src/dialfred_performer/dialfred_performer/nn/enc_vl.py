"""The multimodal transformer over [language tokens | frame tokens | previous-action tokens].

Every token has a step: a language token the step from which it is known (0 for the instruction, the
step a QA was asked for its tokens), the frame and action tokens of step t the step t. The mask
(`attention_allowed`) lets a token attend to a token only if that token is known at its own step
(key step <= query step), so the decision at step t depends on nothing that comes later: no later
frame, no later action, no QA asked later. A language token of an answer stream may also have a step
from which a newer answer supersedes it (`until`): from then on no token attends to it. Language tokens attend to language tokens only (as
E.T.'s language encoder does); frame and action tokens attend to all three. Padding is never
attended to (a padding query attends to itself only, so no row of the softmax is empty).
"""

from __future__ import annotations

from typing import Optional

import torch
import torch.nn.functional as F
from torch import nn


def attention_allowed(lang_steps: torch.Tensor, lang_valid: torch.Tensor, step_valid: torch.Tensor,
                      lang_until: Optional[torch.Tensor] = None) -> torch.Tensor:
    """lang_steps, lang_valid: [B, L]; step_valid: [B, T]; lang_until [B, L] or None (never superseded)
    -> bool [B, S, S] (S = L + 2T), True where query i may attend to key j."""
    B, L = lang_steps.shape
    T = step_valid.shape[1]
    steps_t = torch.arange(T, device=lang_steps.device).expand(B, T)
    step = torch.cat([lang_steps, steps_t, steps_t], 1)                        # [B, S]
    valid = torch.cat([lang_valid, step_valid, step_valid], 1)
    is_lang = torch.zeros(step.shape[1], dtype=torch.bool, device=step.device)
    is_lang[:L] = True
    allowed = (step[:, None, :] <= step[:, :, None]) & valid[:, None, :]
    if lang_until is not None:            # a superseded language token: hidden from the step of its successor on
        allowed[:, :, :L] &= lang_until[:, None, :] > step[:, :, None]
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

    def forward_new(self, x: torch.Tensor, is_lang: torch.Tensor, past: 'LayerCache',
                    visible: Optional[torch.Tensor] = None) -> tuple:
        """The tokens of the current step only (x [N, d]; is_lang [N]), attending to the cached keys
        and values of every earlier step (`past`) and to each other under the same rule as
        `attention_allowed` (all of them have the current step: language sees language only; with
        `visible` [M + N], only to the keys it marks, and each to itself).
        Returns (outputs [N, d], their keys and values [heads, N, d / heads] each)."""
        N, D = x.shape
        q, k, v = self.qkv(self.norm1(x)).view(N, 3, self.heads, D // self.heads).permute(1, 2, 0, 3)
        keys, values = torch.cat([past.keys, k], 1), torch.cat([past.values, v], 1)
        key_is_lang = torch.cat([past.is_lang, is_lang])
        allowed = ~is_lang[:, None] | key_is_lang[None, :]                       # [N, M + N]
        if visible is not None:
            M = past.keys.shape[1]
            allowed = allowed & visible[None, :]
            allowed[torch.arange(N), M + torch.arange(N)] = True
        a = F.scaled_dot_product_attention(q[None], keys[None], values[None], attn_mask=allowed[None, None])[0]
        x = x + self.out(a.transpose(0, 1).reshape(N, D))
        return x + self.ff(self.norm2(x)), k, v


class LayerCache:
    """One layer's keys and values of the tokens of the steps already taken, which are language, and each
    language token's index in the language input (-1 for frame and action tokens)."""

    def __init__(self, heads: int, head_dim: int):
        self.keys = torch.zeros(heads, 0, head_dim)
        self.values = torch.zeros(heads, 0, head_dim)
        self.is_lang = torch.zeros(0, dtype=torch.bool)
        self.lang_index = torch.zeros(0, dtype=torch.long)

    def extended(self, keys: torch.Tensor, values: torch.Tensor, is_lang: torch.Tensor,
                 lang_index: torch.Tensor) -> 'LayerCache':
        out = LayerCache.__new__(LayerCache)
        out.keys, out.values = torch.cat([self.keys, keys], 1), torch.cat([self.values, values], 1)
        out.is_lang = torch.cat([self.is_lang, is_lang])
        out.lang_index = torch.cat([self.lang_index, lang_index])
        return out


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
                frames: torch.Tensor, actions: torch.Tensor, step_valid: torch.Tensor,
                lang_until: Optional[torch.Tensor] = None) -> torch.Tensor:
        """lang [B, L, d], frames and actions [B, T, d] (step t at index t), lang_until [B, L] or None
        (`attention_allowed`) -> the frame tokens' outputs [B, T, d], one per step."""
        L, T = lang.shape[1], frames.shape[1]
        if T > self.time.num_embeddings:
            raise ValueError(f'{T} steps; this model takes at most {self.time.num_embeddings}')
        t = self.time(torch.arange(T, device=frames.device))[None]
        x = torch.cat([lang, frames + t + self.modality.weight[0], actions + t + self.modality.weight[1]], 1)
        allowed = attention_allowed(lang_steps, lang_valid, step_valid, lang_until)
        for block in self.blocks:
            x = block(x, allowed)
        return self.norm(x[:, L:L + T])

    def empty_cache(self) -> list[LayerCache]:
        block = self.blocks[0]
        return [LayerCache(block.heads, block.qkv.in_features // block.heads) for _ in self.blocks]

    @torch.no_grad()
    def step(self, cache: list[LayerCache], lang_new: torch.Tensor, frame: torch.Tensor, action: torch.Tensor,
             t: int, lang_first: int = 0, lang_until: Optional[torch.Tensor] = None) -> tuple[torch.Tensor, list[LayerCache]]:
        """One step of an episode, incrementally (inference only: no dropout). `cache` holds the
        tokens of steps < t; lang_new [n, d] the language tokens that became known at step t (the
        instruction at step 0, the QAs asked at step t), frame and action [d] the step's tokens.
        Returns (the frame token's output [d], the cache extended with this step's tokens): the
        same numbers as `forward` over the whole episode, up to float rounding. `lang_first`: the
        index of lang_new's first token in the language input; `lang_until` [L]: each token's step of
        supersession over the whole language input (None: never). Only this step's
        tokens are computed; they attend to the cached ones, so a step costs O(episode) instead of
        the O(episode^2) of running `forward` again."""
        if t >= self.time.num_embeddings:
            raise ValueError(f'step {t}; this model takes at most {self.time.num_embeddings} steps')
        time = self.time.weight[t]
        x = torch.cat([lang_new, (frame + time + self.modality.weight[0])[None],
                       (action + time + self.modality.weight[1])[None]])
        n = lang_new.shape[0]
        is_lang = torch.zeros(x.shape[0], dtype=torch.bool)
        is_lang[:n] = True
        lang_index = torch.full((x.shape[0],), -1, dtype=torch.long)
        lang_index[:n] = torch.arange(lang_first, lang_first + n)
        visible = None
        if lang_until is not None:
            index = torch.cat([cache[0].lang_index, lang_index])
            visible = (index < 0) | (lang_until[index.clamp(min=0)] > t)
        new_cache = []
        for block, past in zip(self.blocks, cache):
            x, k, v = block.forward_new(x, is_lang, past, visible)
            new_cache.append(past.extended(k, v, is_lang, lang_index))
        return self.norm(x[n]), new_cache
