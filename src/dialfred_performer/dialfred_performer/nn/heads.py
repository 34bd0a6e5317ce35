"""Outputs of the multimodal encoder at a step: the next action, and the target pixel as a pointer.

Why a pointer over the agent's own RGB features rather than Mask R-CNN (as E.T./DialFRED used): no
pretrained detector can be had here, and a class-level detector would not help where DialFRED needs
help most anyway: with two objects of the same class ("the apple" and another apple), the class mask
cannot tell which one is meant, while an appearance answer ("the apple is red") can. The pointer scores
every cell of the frame's CNN feature grid against a query made from the transformer output at that
step, which has read the instruction and the QAs; so "red" in the dialogue can move the query toward
the red apple's cells. The chosen pixel is the centre of the best cell, scaled to the frame size; the
simulator takes the object under that pixel as the target.
"""

from __future__ import annotations

import math

import torch
from torch import nn


class ActionHead(nn.Module):
    def __init__(self, d_model: int, n_actions: int):
        super().__init__()
        self.linear = nn.Linear(d_model, n_actions)

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        """h: [..., d_model] -> action logits [..., n_actions]."""
        return self.linear(h)


class PointerHead(nn.Module):
    def __init__(self, d_model: int, d_key: int = 0, project_keys: bool = True):
        """Queries of size `d_key` (default d_model) from the step's output; the cells' keys projected
        by a linear layer, or taken as they come (`project_keys=False`: made already)."""
        super().__init__()
        d_key = d_key or d_model
        self.query = nn.Linear(d_model, d_key)
        self.key = nn.Linear(d_key, d_key) if project_keys else nn.Identity()
        self.scale = 1.0 / math.sqrt(d_key)

    def forward(self, h: torch.Tensor, grid: torch.Tensor) -> torch.Tensor:
        """h: [..., d_model] (the step's output), grid: [..., C, d_model] (its frame's cells) ->
        logits over the C cells [..., C] (a heatmap after softmax)."""
        return torch.einsum('...d,...cd->...c', self.query(h), self.key(grid)) * self.scale


def cell_centre_pixel(cell: int, grid_size: int, width: int, height: int | None = None) -> tuple[int, int]:
    """The pixel (x, y) at the centre of grid cell `cell` (row-major) in a width x height frame
    (square if no height)."""
    height = width if height is None else height
    row, col = divmod(int(cell), grid_size)
    return (min(width - 1, int((col + 0.5) * width / grid_size)),
            min(height - 1, int((row + 0.5) * height / grid_size)))


def pixel_cell(x: int, y: int, grid_size: int, frame_size: int) -> int:
    """The grid cell (row-major) that holds pixel (x, y) of a frame_size x frame_size frame; -1 for no pixel."""
    if x < 0 or y < 0:
        return -1
    return (int(y) * grid_size // frame_size) * grid_size + int(x) * grid_size // frame_size
