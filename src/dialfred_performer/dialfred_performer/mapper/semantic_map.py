"""The map performer's belief about the room, and paths on it.

`SemanticMap` is a top-down grid of CELL_M cells in the agent's own frame (see geometry). Every frame
votes: floor points for free space, points between OBSTACLE_MIN_M and OBSTACLE_MAX_M above the floor
that are not floor for obstacles, and each object class predicted at a point for that class there
(with the point's height, which decides how far to pitch the camera to it). A MoveAhead that
failed marks the grid point ahead as blocked, whatever the map says.

Paths: the agent moves on the grid of STEP_M points; a point is free when no obstacle cell lies
around it (SAFE_CELLS; where that leaves no way, the tighter TIGHT_CELLS). `distance_field(goals)`
is the number of moves from every grid point to the nearest goal point over points believed free
(unknown counts as free, so the agent explores optimistically), by breadth-first waves over the
whole grid at once (numpy: a few milliseconds on one core). `next_action` turns the field into the
agent's next move. A point a MoveAhead failed into is never free, nor a goal.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from dialfred_sim.protocol import BODY

from .geometry import HEADING_STEPS, STEP_M, Pose

CELL_M = 0.125                 # map cell
NODE_CELLS = int(round(STEP_M / CELL_M))
MAP_M = 32.0                   # the map spans MAP_M x MAP_M metres centred on the start
OBSTACLE_MIN_M, OBSTACLE_MAX_M = 0.08, 1.8
MAX_RANGE_M = 4.0              # predicted depth further than this is not mapped
CLOSE_M = 1.6                  # a surface seen from nearer than this has been looked at closely
UNREACHABLE = 1 << 20
# The cells (offsets from the cell whose corner is a grid point) whose obstacles block the point: the
# agent's 0.2 m disc is taken as the 3 x 3 cells from one cell before the point to two after it, and,
# where that leaves the agent no way to a goal, as the 2 x 2 cells centred on the point.
SAFE_CELLS = tuple((dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1))
TIGHT_CELLS = tuple((dx, dy) for dx in (-1, 0) for dy in (-1, 0))


class SemanticMap:
    """Free space, obstacles and object classes seen, on a grid centred on the agent's start."""

    def __init__(self, n_classes: int, map_m: float = MAP_M):
        self.n = int(round(map_m / CELL_M))
        self.nodes = self.n // NODE_CELLS
        self.n_classes = n_classes
        self.free = np.zeros((self.n, self.n), np.float32)
        self.occupied = np.zeros((self.n, self.n), np.float32)
        self.class_votes: dict[int, np.ndarray] = {}       # class -> votes [n, n]
        self.class_height: dict[int, np.ndarray] = {}      # class -> sum of heights [n, n]
        self.blocked: set[tuple[int, int]] = set()         # grid points a MoveAhead failed into
        self.visited: set[tuple[int, int]] = set()
        self.excluded: dict[int, np.ndarray] = {}          # class -> cells given up on [n, n] bool
        self.close_seen = np.zeros((self.n, self.n), bool)  # cells seen from within CLOSE_M

    # ------------------------------------------------------------------ frames of reference

    def cell_of(self, x, y):
        """Map cell indices (row for x, column for y) of map points; may fall outside the map."""
        c = self.n // 2
        return (np.floor(np.asarray(x) / CELL_M).astype(np.int64) + c,
                np.floor(np.asarray(y) / CELL_M).astype(np.int64) + c)

    def node_offset(self) -> int:
        return self.nodes // 2

    def node_cell(self, i: int, j: int) -> tuple[int, int]:
        """The map cell holding grid point (i, j)."""
        cx, cy = self.cell_of(i * STEP_M + 1e-6, j * STEP_M + 1e-6)
        return int(cx), int(cy)

    def cell_centre(self, cx, cy):
        c = self.n // 2
        return (np.asarray(cx) - c + 0.5) * CELL_M, (np.asarray(cy) - c + 0.5) * CELL_M

    # ------------------------------------------------------------------ votes

    def update(self, points: np.ndarray, labels: np.ndarray, confidence: np.ndarray, ray: np.ndarray,
               floor_class: int, structure_classes: int) -> None:
        """One frame: points [S, S, 3] in the map frame, the predicted class of each [S, S] with its
        probability, and the distance from the eye [S, S]."""
        ok = (ray < MAX_RANGE_M) & np.isfinite(points).all(-1)
        cx, cy = self.cell_of(points[..., 0], points[..., 1])
        ok &= (cx >= 0) & (cx < self.n) & (cy >= 0) & (cy < self.n)
        h = points[..., 2]
        floor = ok & (labels == floor_class)
        np.add.at(self.free, (cx[floor], cy[floor]), 1.0)
        obstacle = ok & ~floor & (h > OBSTACLE_MIN_M) & (h < OBSTACLE_MAX_M)
        np.add.at(self.occupied, (cx[obstacle], cy[obstacle]), 1.0)
        close = ok & (ray < CLOSE_M)
        self.close_seen[cx[close], cy[close]] = True
        objects = ok & (labels >= structure_classes) & (confidence > 0.5)
        for k in np.unique(labels[objects]).tolist():
            m = objects & (labels == k)
            if k not in self.class_votes:
                self.class_votes[k] = np.zeros((self.n, self.n), np.float32)
                self.class_height[k] = np.zeros((self.n, self.n), np.float32)
            np.add.at(self.class_votes[k], (cx[m], cy[m]), 1.0)
            np.add.at(self.class_height[k], (cx[m], cy[m]), h[m])

    def object_cells(self, k: int, min_votes: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(cx, cy, mean height) of the cells where class k was seen and not given up on."""
        votes = self.class_votes.get(k)
        if votes is None:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.float32)
        mask = votes >= min_votes
        if k in self.excluded:
            mask &= ~self.excluded[k]
        cx, cy = np.nonzero(mask)
        return cx, cy, self.class_height[k][cx, cy] / votes[cx, cy]

    def exclude(self, k: int, x: float, y: float, radius_m: float = 0.5) -> None:
        """Give up on class k's cells within radius_m of map point (x, y)."""
        if k not in self.excluded:
            self.excluded[k] = np.zeros((self.n, self.n), bool)
        xs, ys = self.cell_centre(np.arange(self.n), np.arange(self.n))
        near = ((xs[:, None] - x) ** 2 + (ys[None, :] - y) ** 2) <= radius_m ** 2
        self.excluded[k] |= near

    # ------------------------------------------------------------------ grid points

    def obstacles(self) -> np.ndarray:
        """[n, n] bool: cells believed occupied (seen as an obstacle twice, and more often than as floor)."""
        return (self.occupied >= 2.0) & (self.occupied > 0.5 * self.free)

    def traversable(self, cells: tuple = SAFE_CELLS) -> np.ndarray:
        """[nodes, nodes] bool: grid points believed free for the agent (unknown counts as free): no
        obstacle in `cells` around them, no MoveAhead failed into them, or stood on."""
        occ = self.obstacles()
        near = np.zeros_like(occ)
        pad = np.pad(occ, 2)
        for dx, dy in cells:
            near |= pad[2 + dx:2 + dx + self.n, 2 + dy:2 + dy + self.n]
        off = self.node_offset()
        ii = np.arange(self.nodes) - off
        cx, cy = self.cell_of(ii * STEP_M + 1e-6, ii * STEP_M + 1e-6)
        cx, cy = np.clip(cx, 0, self.n - 1), np.clip(cy, 0, self.n - 1)
        free = ~near[cx[:, None], cy[None, :]]
        for (i, j) in self.blocked:
            a, b = i + off, j + off
            if 0 <= a < self.nodes and 0 <= b < self.nodes:
                free[a, b] = False
        for (i, j) in self.visited:                          # where it stood is free, whatever it saw
            a, b = i + off, j + off
            if 0 <= a < self.nodes and 0 <= b < self.nodes and (i, j) not in self.blocked:
                free[a, b] = True
        return free

    def known(self) -> np.ndarray:
        """[nodes, nodes] bool: grid points whose cell has been seen (free or occupied)."""
        seen = (self.free + self.occupied) > 0
        off = self.node_offset()
        ii = np.arange(self.nodes) - off
        cx, cy = self.cell_of(ii * STEP_M + 1e-6, ii * STEP_M + 1e-6)
        cx, cy = np.clip(cx, 0, self.n - 1), np.clip(cy, 0, self.n - 1)
        return seen[cx[:, None], cy[None, :]]


def distance_field(free: np.ndarray, goals: np.ndarray, max_waves: int = 400,
                   until: Optional[tuple[int, int]] = None) -> np.ndarray:
    """Moves (4-connected over `free`) from every grid point to the nearest `goals` point; goal
    points count even where not free. UNREACHABLE where none can be reached. With `until` (a grid
    point), the waves stop once they reach it: every point nearer the goals than it, and it, have
    their distance, farther ones may be left UNREACHABLE (enough for `next_move` from there, which
    reads the point and its neighbours: one of them is nearer, and a farther one is never chosen)."""
    dist = np.full(free.shape, UNREACHABLE, np.int64)
    frontier = goals.copy()
    dist[frontier] = 0
    passable = free | goals
    unknown = dist == UNREACHABLE
    for wave in range(1, max_waves):
        if until is not None and not unknown[until]:
            break
        grown = np.zeros_like(frontier)
        grown[1:, :] |= frontier[:-1, :]
        grown[:-1, :] |= frontier[1:, :]
        grown[:, 1:] |= frontier[:, :-1]
        grown[:, :-1] |= frontier[:, 1:]
        grown &= passable & unknown
        if not grown.any():
            break
        dist[grown] = wave
        unknown &= ~grown
        frontier = grown
    return dist


def next_move(dist: np.ndarray, pose: Pose, offset: int) -> Optional[str]:
    """The action that brings the agent nearer the goals of `dist`: MoveAhead when the point ahead
    is nearer, else the turn towards the nearest neighbour (left on a tie); None at a goal or when
    none can be reached."""
    a, b = pose.i + offset, pose.j + offset
    n = dist.shape[0]
    if not (0 <= a < n and 0 <= b < n):
        return None
    here = dist[a, b]
    if here == 0:
        return None
    best, best_heading = UNREACHABLE, None
    for heading, (di, dj) in HEADING_STEPS.items():
        x, y = a + di, b + dj
        if 0 <= x < n and 0 <= y < n and dist[x, y] < best:
            best, best_heading = dist[x, y], heading
    if best_heading is None or best >= here:
        return None
    if best_heading == pose.heading:
        return 'MoveAhead'
    turn = (best_heading - pose.heading) % 360
    return 'RotateRight' if turn == 270 else 'RotateLeft'


def reach_goals(smap: SemanticMap, cx: np.ndarray, cy: np.ndarray,
                margin_m: float = 0.3, facing_deg: Optional[float] = None) -> np.ndarray:
    """[nodes, nodes] bool: grid points from which one of the cells (cx, cy) is within reach (BODY.reach
    from the agent's vertical axis less `margin_m`, at any height, as in AI2-THOR), and not nearer than
    one step."""
    goals = np.zeros((smap.nodes, smap.nodes), bool)
    if len(cx) == 0:
        return goals
    xs, ys = smap.cell_centre(cx, cy)
    horizontal = np.full(len(cx), BODY.reach - margin_m)
    off = smap.node_offset()
    ii = (np.arange(smap.nodes) - off) * STEP_M
    for x, y, r in zip(xs.tolist(), ys.tolist(), horizontal.tolist()):
        if r <= 0:
            continue
        lo_i, hi_i = int(math.floor((x - r) / STEP_M)) + off, int(math.ceil((x + r) / STEP_M)) + off
        lo_j, hi_j = int(math.floor((y - r) / STEP_M)) + off, int(math.ceil((y + r) / STEP_M)) + off
        lo_i, lo_j = max(lo_i, 0), max(lo_j, 0)
        hi_i, hi_j = min(hi_i, smap.nodes - 1), min(hi_j, smap.nodes - 1)
        if lo_i > hi_i or lo_j > hi_j:
            continue
        dx, dy = x - ii[lo_i:hi_i + 1, None], y - ii[None, lo_j:hi_j + 1]
        d2 = dx ** 2 + dy ** 2
        near = (d2 <= r * r) & (d2 >= 0.2 ** 2)
        if facing_deg is not None:          # the cell lies near one of the four headings from the point
            near &= np.abs((np.degrees(np.arctan2(dy, dx)) + 45.0) % 90.0 - 45.0) <= facing_deg
        goals[lo_i:hi_i + 1, lo_j:hi_j + 1] |= near
    for (i, j) in smap.blocked:                 # a MoveAhead failed into it: no goal, however near
        if 0 <= i + off < smap.nodes and 0 <= j + off < smap.nodes:
            goals[i + off, j + off] = False
    return goals


def unexamined_goals(smap: SemanticMap, free: np.ndarray, reach_m: float = 1.0) -> np.ndarray:
    """[nodes, nodes] bool: free grid points within reach_m of an obstacle cell (furniture, where
    objects lie) that has not yet been seen from close by."""
    occ = (smap.occupied >= 2.0) & (smap.occupied > 0.5 * smap.free) & ~smap.close_seen
    goals = np.zeros((smap.nodes, smap.nodes), bool)
    cx, cy = np.nonzero(occ)
    if len(cx) == 0:
        return goals
    off = smap.node_offset()
    xs, ys = smap.cell_centre(cx, cy)
    # Bin the cells on the node grid, then dilate by reach_m.
    hit = np.zeros((smap.nodes, smap.nodes), bool)
    ai = np.clip(np.round(xs / STEP_M).astype(np.int64) + off, 0, smap.nodes - 1)
    aj = np.clip(np.round(ys / STEP_M).astype(np.int64) + off, 0, smap.nodes - 1)
    hit[ai, aj] = True
    r = int(math.ceil(reach_m / STEP_M))
    near = np.zeros_like(hit)
    for di in range(-r, r + 1):
        for dj in range(-r, r + 1):
            if di * di + dj * dj > r * r:
                continue
            near |= np.roll(np.roll(hit, di, 0), dj, 1)
    return near & free
