"""Frames through the pretrained, frozen perception network (dialfred_performer.perception): a frame
embedding for the transformer and a pointer key for every pixel.

The embedding is made from the network's coarse map average-pooled to 4 x 4 (where things are, not
only what: the way ahead, what is within reach). Each pixel's key is made from the decoder's map
(upsampled to full resolution: what the pixel belongs to) beside the full-resolution stem (its
colour and edges), so that the pointer can pick one pixel of a three-pixel key chain, and a query
that has read "the red one" can prefer red pixels. The perception weights stay as trained; only the
embedding and the key layers learn with the performer.
"""

from __future__ import annotations

from typing import Optional

import torch
import torch.nn.functional as F
from torch import nn

POOLED = 4          # the coarse map is pooled to POOLED x POOLED cells for the frame embedding


class PerceivedFrames(nn.Module):
    def __init__(self, d_model: int, d_key: int, net: nn.Module):
        """`net`: a dialfred_performer.perception.Perception (its weights are loaded into it later)."""
        super().__init__()
        self.net = net
        self.net.requires_grad_(False)
        c = net.config
        self.d_model = d_model
        self.embed = nn.Sequential(nn.Linear(c.c3 * POOLED * POOLED, d_model), nn.LayerNorm(d_model))
        self.key = nn.Conv2d(c.decoder + c.c1, d_key, 1)

    def train(self, mode: bool = True):
        super().train(mode)
        self.net.eval()               # frozen: always as it was trained
        return self

    def forward(self, frames: torch.Tensor, keys_for: Optional[torch.Tensor] = None):
        """frames [N, 3, R, R] -> (embedding [N, d], keys [N, R*R, k]); with `keys_for` (bool [N]), the
        keys of those frames only [K, R*R, k]."""
        with torch.no_grad():
            out = self.net(frames)
        emb = self._embed(out.coarse)
        fine, stem = out.fine, out.stem
        if keys_for is not None:
            fine, stem = fine[keys_for], stem[keys_for]
        fine = F.interpolate(fine, size=stem.shape[-2:], mode='bilinear', align_corners=False)
        keys = self.key(torch.cat([fine, stem], 1)).flatten(2).transpose(1, 2)
        return emb, keys

    def embedding(self, frames: torch.Tensor) -> torch.Tensor:
        """The frame embeddings [N, d] alone (the network's encoder only: no decoder, no pointer keys)."""
        with torch.no_grad():
            coarse = self.net.coarse(frames)
        return self._embed(coarse)

    def _embed(self, coarse: torch.Tensor) -> torch.Tensor:
        return self.embed(F.adaptive_avg_pool2d(coarse, POOLED).flatten(1))
