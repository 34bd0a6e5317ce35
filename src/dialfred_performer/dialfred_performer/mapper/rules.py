"""The map performer's rules of thumb (its constants) and small helpers of its parts (no state)."""

from __future__ import annotations

import math

import numpy as np

from .geometry import CAMERA_HEIGHT_M

STRUCTURE = 4                    # label classes below this are nothing, Floor, Wall, Ceiling
FLOOR = 1
REACH_M = 1.3                    # stay inside the simulator's 1.5 m by more than the predicted depth's usual error
MIN_TARGET_CELLS = 1
PUT_CHANGE = 30.0                # _where_put: mean change of a cell's RGB (summed over channels) taken as a change
PLACED_M = 0.15                  # _inside_opened: how near the point of its own Put a cell must lie
INSIDE_P = 0.03                   # _inside_opened: the least probability of the target's type taken as it
MAX_STEP_ACTIONS = 120           # actions on one step of the plan before the agent gives up and stops
STAND_MAX_ACTIONS = 16           # moves, turns and looks of the last stand (wayfinding._stand) at most
SCAN_TURNS = 3                   # turns of the first look around
SURE, WALKING, EXPLORING = 0.9, 0.7, 0.35
ANSWER_CONE_DEG = 67.5           # half a location answer's 45-degree direction bin, and one bin more either side
REPLAN = 'replan'                # _navigate changed the plan: decide again
THERE = 'there'                  # _follow: the direction answer says the agent stands where the expert ended
INTERACTIONS = {'pickup': 'Pickup', 'put': 'Put', 'open': 'Open', 'close': 'Close', 'toggle_on': 'ToggleOn',
                'toggle_off': 'ToggleOff', 'slice': 'Slice'}
HAND_M = (0.42, -0.16, 0.95)      # where the simulator's hand carries an object (ahead, left, height)
CARRIED_M = (0.8, 0.45, 0.45)       # a held object's points: nearer ahead, to either side, higher than these


def carried_volume(local: np.ndarray) -> np.ndarray:
    """[S, S] bool: the points (in the agent's frame: forward, left, height) where an object carried
    in the hand may be seen (HAND_M, give or take the largest pickupable object's half size)."""
    ahead, side, low = CARRIED_M
    return (local[..., 0] < ahead) & (np.abs(local[..., 1]) < side) & (local[..., 2] > low)


def hand_cell(horizon: float, size: int) -> tuple[int, int]:
    """(row, col) of the cell where the hand's object appears in a size x size grid at `horizon`."""
    pitch = math.radians(-horizon)
    cp, sp = math.cos(pitch), math.sin(pitch)
    f, l, up = HAND_M[0], HAND_M[1], HAND_M[2] - CAMERA_HEIGHT_M
    z = f * cp + up * sp
    u = -l / z
    v = (-f * sp + up * cp) / z
    col = int(round((u + 1) / 2 * size - 0.5))
    row = int(round((1 - v) / 2 * size - 0.5))
    return min(max(row, 0), size - 1), min(max(col, 0), size - 1)


def mask_components(mask: np.ndarray) -> list[np.ndarray]:
    """The 4-connected components of a small bool mask, largest first."""
    seen = np.zeros_like(mask)
    out = []
    h, w = mask.shape
    for r0, c0 in zip(*np.nonzero(mask)):
        if seen[r0, c0]:
            continue
        comp = np.zeros_like(mask)
        stack = [(r0, c0)]
        seen[r0, c0] = True
        while stack:
            r, c = stack.pop()
            comp[r, c] = True
            for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                a, b = r + dr, c + dc
                if 0 <= a < h and 0 <= b < w and mask[a, b] and not seen[a, b]:
                    seen[a, b] = True
                    stack.append((a, b))
        out.append(comp)
    out.sort(key=lambda m: -int(m.sum()))
    return out
