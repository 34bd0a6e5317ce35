"""A picture of the map performer's belief (no ROS): what bags record as `/performer/map`, the live view
streams as `/w<k>/belief` and the report's GIFs show beside the camera.

Top-down, in the agent's own frame with its starting heading up: unknown cells grey, free floor
white, obstacles brown, every object class seen in a colour of its own (the current step's object
red, places given up on dimmed), the grid points visited blue, the agent a black arrow.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

PX_PER_CELL = 3                 # 0.125 m cells: 24 px per metre
MARGIN_CELLS = 6
MIN_CELLS = 40                  # the picture shows at least 5 m x 5 m

UNKNOWN = (226, 226, 222)
FREE = (252, 250, 244)
OBSTACLE = (150, 132, 110)
TARGET = (222, 36, 36)
VISITED = (70, 130, 200)
AGENT = (20, 20, 20)


def class_colour(name: str) -> tuple[int, int, int]:
    """A colour per object type, the same on every run (from the name's digest), never too pale."""
    d = hashlib.sha256(name.encode()).digest()
    return 40 + d[0] % 150, 60 + d[1] % 140, 40 + d[2] % 170


def belief_picture(agent) -> np.ndarray:
    """[H, W, 3] uint8: the MapAgent's map around what it has seen so far, and where it is."""
    m = agent.map
    free = m.free > 0
    occupied = m.obstacles()
    known = free | (m.occupied > 0)
    xs, ys = np.nonzero(known)
    agent_cell = m.node_cell(agent.pose.i, agent.pose.j)
    visited = [m.node_cell(i, j) for i, j in sorted(m.visited)]
    rows = np.concatenate([xs, [agent_cell[0]], [c[0] for c in visited]]).astype(int)
    cols = np.concatenate([ys, [agent_cell[1]], [c[1] for c in visited]]).astype(int)
    lo_x, hi_x = rows.min() - MARGIN_CELLS, rows.max() + MARGIN_CELLS + 1
    lo_y, hi_y = cols.min() - MARGIN_CELLS, cols.max() + MARGIN_CELLS + 1
    grow_x, grow_y = max(0, MIN_CELLS - (hi_x - lo_x)), max(0, MIN_CELLS - (hi_y - lo_y))
    lo_x, hi_x = max(lo_x - grow_x // 2, 0), min(hi_x + grow_x - grow_x // 2, m.n)
    lo_y, hi_y = max(lo_y - grow_y // 2, 0), min(hi_y + grow_y - grow_y // 2, m.n)
    window = (slice(lo_x, hi_x), slice(lo_y, hi_y))

    img = np.empty((hi_x - lo_x, hi_y - lo_y, 3), np.uint8)
    img[:] = UNKNOWN
    img[free[window]] = FREE
    img[occupied[window]] = OBSTACLE
    step = agent.decided
    target = agent.class_id.get(step.target) if step.kind != 'stop' else None
    for k in sorted(m.class_votes):
        cells = (m.class_votes[k] >= 1.0)[window]
        colour = np.array(TARGET if k == target else class_colour(agent.classes[k]), np.float32)
        if k in m.excluded:
            dim = cells & m.excluded[k][window]
            img[dim] = (0.35 * colour + 0.65 * np.array(FREE)).astype(np.uint8)
            cells &= ~m.excluded[k][window]
        img[cells] = colour.astype(np.uint8)
    # The agent's frame: x (its starting heading) up, y (its left) to the left.
    img = img[::-1, ::-1]
    img = np.repeat(np.repeat(img, PX_PER_CELL, 0), PX_PER_CELL, 1)

    def to_px(cell: tuple[int, int]) -> tuple[float, float]:
        r = (hi_x - 1 - cell[0] + 0.5) * PX_PER_CELL
        c = (hi_y - 1 - cell[1] + 0.5) * PX_PER_CELL
        return c, r

    from PIL import Image, ImageDraw  # lazy: PIL, which the rest of this module does without
    pic = Image.fromarray(np.ascontiguousarray(img))
    draw = ImageDraw.Draw(pic)
    for cell in visited:
        x, y = to_px(cell)
        draw.ellipse([x - 1.5, y - 1.5, x + 1.5, y + 1.5], fill=VISITED)
    x, y = to_px(agent_cell)
    yaw = math.radians(agent.pose.heading)          # 0: up; counter-clockwise
    tip = (x - 9 * math.sin(yaw), y - 9 * math.cos(yaw))
    left = (x - 5 * math.sin(yaw + 2.4), y - 5 * math.cos(yaw + 2.4))
    right = (x - 5 * math.sin(yaw - 2.4), y - 5 * math.cos(yaw - 2.4))
    draw.polygon([tip, left, right], fill=AGENT)
    return np.asarray(pic)
