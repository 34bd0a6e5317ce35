"""RGB frames -> a frame embedding and a grid of cell features, by a small CNN trained from scratch.

Three stride-2 convolutions take an R x R frame to an (R/8) x (R/8) grid of d_model-dimensional cell
features (8 x 8 at R = 64). The frame embedding (a token of the multimodal encoder) is the grid's
mean, projected; the grid itself is kept for the pointer head, which picks the interaction's target
cell. No pretrained weights can be had here (no torchvision, no ImageNet ResNet as E.T. used), so the
network is small enough to learn from the expert demonstrations alone.
"""

from __future__ import annotations

import torch
from torch import nn


class VisualEncoder(nn.Module):
    def __init__(self, d_model: int, resolution: int, channels: tuple[int, int] = (32, 64)):
        super().__init__()
        if resolution % 8:
            raise ValueError(f'the resolution must be a multiple of 8, got {resolution}')
        c1, c2 = channels
        self.d_model = d_model
        self.grid_size = resolution // 8
        self.cnn = nn.Sequential(
            nn.Conv2d(3, c1, 5, stride=2, padding=2), nn.GroupNorm(8, c1), nn.ReLU(inplace=True),
            nn.Conv2d(c1, c2, 3, stride=2, padding=1), nn.GroupNorm(8, c2), nn.ReLU(inplace=True),
            nn.Conv2d(c2, d_model, 3, stride=2, padding=1), nn.GroupNorm(8, d_model), nn.ReLU(inplace=True))
        self.cell_position = nn.Parameter(torch.zeros(self.grid_size * self.grid_size, d_model))
        self.project = nn.Sequential(nn.Linear(d_model, d_model), nn.LayerNorm(d_model))
        # Colour statistics of the raw frame normalised once, so the CNN sees zero-centred input.
        self.register_buffer('mean', torch.tensor([0.5, 0.5, 0.5]).view(1, 3, 1, 1), persistent=False)

    def forward(self, frames: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """frames: [N, 3, R, R] float in [0, 1] -> (embedding [N, d_model], grid [N, G*G, d_model])."""
        grid = self.cnn(frames - self.mean).flatten(2).transpose(1, 2)        # [N, G*G, d]
        grid = grid + self.cell_position[None]
        return self.project(grid.mean(1)), grid

    def embedding(self, frames: torch.Tensor) -> torch.Tensor:
        """The frame embeddings [N, d_model] alone."""
        return self(frames)[0]
