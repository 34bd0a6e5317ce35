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

from dialfred_sim.protocol import BODY

POOLED = 4          # the coarse map is pooled to POOLED x POOLED cells for the frame embedding


def pixel_ray_lengths(size: int) -> torch.Tensor:
    """[size, size]: the length of each pixel's ray per metre of view-axis depth (the camera's rays)."""
    return torch.from_numpy(BODY.ray_lengths(size, size)).float()


class PerceivedFrames(nn.Module):
    def __init__(self, d_model: int, d_key: int, net: nn.Module, distance: bool = False, precision: str = 'fp32'):
        """`net`: a dialfred_performer.perception.Perception (its weights are loaded into it later).
        With `distance`, each pixel's key carries one more channel, last: the network's predicted
        distance to what the pixel shows (metres along its ray), for the performer's reach input.
        `precision`: the frozen network's arithmetic (`precision` below)."""
        super().__init__()
        self.net = net
        self.net.requires_grad_(False)
        c = net.config
        self.d_model = d_model
        self.distance = distance
        self.embed = nn.Sequential(nn.Linear(c.c3 * POOLED * POOLED, d_model), nn.LayerNorm(d_model))
        self.key = nn.Conv2d(c.decoder + c.c1, d_key, 1)
        # The frozen network's arithmetic wherever it runs (training, the agent's steps, the questioner's
        # embeddings): 'bf16' runs its convolutions in bfloat16 (autocast; about half the time on a CPU with
        # AMX or AVX512-BF16), its outputs back in fp32. A runtime setting, not saved: `build_visual` sets it
        # from PerformerConfig.frozen_arithmetic and this CPU, training from TrainConfig.perception_precision.
        if precision not in ('fp32', 'bf16'):
            raise ValueError(f"precision must be 'fp32' or 'bf16', got {precision!r}")
        self.precision = precision
        # Whether `outputs` runs the network on channels-last tensors (`to_channels_last`). Not saved either.
        self.channels_last = False

    def to_channels_last(self) -> 'PerceivedFrames':
        """Run the frozen network in oneDNN's faster layout on a CPU (the same numbers up to rounding): its
        weights and, in `outputs`, its input frames channels-last. The agent and training both do
        (TrainConfig.perception_channels_last)."""
        self.channels_last = True
        self.net.to(memory_format=torch.channels_last)
        return self

    def train(self, mode: bool = True):
        super().train(mode)
        self.net.eval()               # frozen: always as it was trained
        return self

    def forward(self, frames: torch.Tensor, keys_for: Optional[torch.Tensor] = None):
        """frames [N, 3, R, R] -> (embedding [N, d], keys [N, R*R, k]); with `keys_for` (bool [N]), the
        keys of those frames only [K, R*R, k]. With `distance`, keys [.., R*R, k + 1] (`distances`)."""
        emb, keys, out = self.perceive(frames, keys_for)
        if not self.distance:
            return emb, keys
        fine = out.fine if keys_for is None else out.fine[keys_for]
        return emb, torch.cat([keys, self._distances(fine, out.stem.shape[-1])[..., None]], -1)

    def perceive(self, frames: torch.Tensor, keys_for: Optional[torch.Tensor] = None):
        """As forward without the distance channel, and the network's output (PerceptionOutput, without
        gradient) for `pointer_logits` and `distances`: (embedding, keys [.., R*R, k], output)."""
        return self.read(self.outputs(frames), keys_for)

    def outputs(self, frames: torch.Tensor, pooled: bool = False):
        """The frozen network's output for `frames` (PerceptionOutput, without gradient, fp32), in the
        arithmetic of `precision`. With `pooled`, its coarse map comes pooled to the embedding's cells
        (what `read` makes the embedding from, the same numbers; a quarter of the memory for a 64 px frame's)."""
        if self.channels_last:
            frames = frames.contiguous(memory_format=torch.channels_last)
        out = self._run(self.net, frames)
        return out._replace(coarse=F.adaptive_avg_pool2d(out.coarse, POOLED)) if pooled else out

    def _run(self, part, inputs):
        """`part` of the frozen network (the network, its `encode`, `decode` or `coarse`) on `inputs`, without
        gradient, in the arithmetic of `precision`; tensors out in fp32 (a tensor, or a tuple of them)."""
        device = inputs[0].device if isinstance(inputs, tuple) else inputs.device
        with torch.no_grad(), torch.autocast(device.type, dtype=torch.bfloat16, enabled=self.precision == 'bf16'):
            out = part(inputs)
        if self.precision != 'bf16':
            return out
        if isinstance(out, torch.Tensor):
            return out.float()
        floats = [t.float() for t in out]
        return type(out)(*floats) if hasattr(out, '_fields') else tuple(floats)

    def encode(self, frames: torch.Tensor) -> tuple:
        """The network's encoder maps of `frames` (what `keys_of` reads), in the arithmetic of `precision`."""
        return self._run(self.net.encode, frames)

    def read(self, out, keys_for: Optional[torch.Tensor] = None):
        """`perceive` of frames whose network output (`outputs`, pooled or not) is `out`."""
        fine, stem = out.fine, out.stem
        if keys_for is not None:
            fine, stem = fine[keys_for], stem[keys_for]
        return self._embed(out.coarse), self._keys(fine, stem), out

    def _keys(self, fine: torch.Tensor, stem: torch.Tensor) -> torch.Tensor:
        up = F.interpolate(fine, size=stem.shape[-2:], mode='bilinear', align_corners=False)
        return self.key(torch.cat([up, stem], 1)).flatten(2).transpose(1, 2)

    def embedding_and_encoded(self, frames: torch.Tensor) -> tuple[torch.Tensor, tuple]:
        """(the frame embeddings [N, d], the network's encoder maps): `keys_of` the maps gives the frames'
        keys later, without running the encoder again (the same numbers as `forward`)."""
        encoded = self.encode(frames)
        return self._embed(encoded[3]), encoded

    def embedding_and_output(self, frames: torch.Tensor) -> tuple[torch.Tensor, object]:
        """(the frame embeddings [N, d], the network's output) without the pointer keys: `pointer_logits` and
        `distances` read the output, `grid_of` makes the keys from it (the same numbers as `forward`)."""
        emb, _, out = self.perceive(frames, keys_for=torch.zeros(len(frames), dtype=torch.bool))
        return emb, out

    def grid_of(self, out) -> torch.Tensor:
        """`forward`'s keys [N, R*R, k] (with `distance`, [N, R*R, k + 1]) from the network's output."""
        keys = self._keys(out.fine, out.stem)
        return torch.cat([keys, self.distances(out)[..., None]], -1) if self.distance else keys

    def keys_of(self, encoded: tuple) -> torch.Tensor:
        """The keys [N, R*R, k] (no distance channel) of the frames whose encoder maps are `encoded`."""
        out = self._run(self.net.decode, encoded)
        return self._keys(out.fine, out.stem)

    @torch.no_grad()
    def _distances(self, fine: torch.Tensor, size: int) -> torch.Tensor:
        """[N, size * size]: the network's predicted distance (metres along each pixel's ray)."""
        depth = self.net.depth(fine)                               # [N, R/2, R/2] metres along the view axis
        depth = F.interpolate(depth[:, None], size=(size, size), mode='nearest')[:, 0]
        return (depth * pixel_ray_lengths(size).to(depth)).flatten(1)

    def distances(self, out) -> torch.Tensor:
        """Every frame's predicted distance per pixel [N, R*R] (the keys' last channel with `distance`)."""
        return self._distances(out.fine, out.stem.shape[-1])

    def pointer_logits(self, out, queries: torch.Tensor) -> torch.Tensor:
        """queries [N, k] against every pixel's key [N, R*R] (unscaled), without making the keys: the key
        layer and the bilinear upsampling are linear, so each query is folded into the layer's weights
        and applied to the decoder's half-resolution map before upsampling (about 50x fewer operations
        than keys for every frame; the same numbers up to rounding)."""
        w = self.key.weight[:, :, 0, 0]                            # [k, decoder + c1]
        c = out.fine.shape[1]
        small = torch.einsum('nc,nchw->nhw', queries @ w[:, :c], out.fine)
        up = F.interpolate(small[:, None], size=out.stem.shape[-2:], mode='bilinear', align_corners=False)[:, 0]
        full = up + torch.einsum('nc,nchw->nhw', queries @ w[:, c:], out.stem) + (queries @ self.key.bias)[:, None, None]
        return full.flatten(1)

    def embedding(self, frames: torch.Tensor) -> torch.Tensor:
        """The frame embeddings [N, d] alone (the network's encoder only: no decoder, no pointer keys)."""
        return self._embed(self._run(self.net.coarse, frames))

    def _embed(self, coarse: torch.Tensor) -> torch.Tensor:
        return self.embed(F.adaptive_avg_pool2d(coarse, POOLED).flatten(1))
