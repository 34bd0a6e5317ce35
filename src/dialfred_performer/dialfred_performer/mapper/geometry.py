"""Where the map performer is, and where what it sees lies on the floor.

The agent's pose is kept by dead reckoning of its own actions and whether each succeeded (ALFRED's
actions are discrete: a step is 0.25 m, a turn 90 degrees, a look 15 degrees), in a frame of its
own: it starts at (0, 0) facing +x, +y to its left. The camera's pitch at the start of a task is
not known (a task starts where the expert left off), so `estimate_horizon` finds it from the first
frame's predicted floor: the pitch under which the floor pixels lie at floor height.

A frame's predicted depth (metres along the optical axis, on the perception network's grid of
cells) becomes points in that frame by the pinhole camera of the simulator (90 degree field of
view, camera 1.5 m above the floor): `points_in_agent_frame`, then `to_map_frame`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dialfred_sim.protocol import BODY

# The robot's body (protocol.BODY) in the mapper's names.
STEP_M = BODY.grid_step        # MoveAhead
TURN_DEG = BODY.turn_step      # RotateLeft (+) / RotateRight (-)
LOOK_DEG = BODY.look_step      # LookDown (+) / LookUp (-): positive looks down
CAMERA_HEIGHT_M = BODY.camera_height
HORIZON_MIN, HORIZON_MAX = BODY.horizon_min, BODY.horizon_max
HORIZONS = tuple(float(h) for h in range(int(HORIZON_MIN), int(HORIZON_MAX) + 1, int(LOOK_DEG)))


@dataclass
class Pose:
    """Grid position (i, j) in steps of STEP_M, heading in degrees (multiple of 90, counter-
    clockwise from the start's +x), camera horizon in degrees (positive: down)."""

    i: int = 0
    j: int = 0
    heading: int = 0
    horizon: float = 30.0

    @property
    def xy(self) -> tuple[float, float]:
        return self.i * STEP_M, self.j * STEP_M

    def forward(self) -> tuple[int, int]:
        """The grid point a MoveAhead goes to."""
        di, dj = HEADING_STEPS[self.heading % 360]
        return self.i + di, self.j + dj

    def after(self, action: str) -> 'Pose':
        """The pose after `action` succeeds (interactions leave it as it is)."""
        p = Pose(self.i, self.j, self.heading, self.horizon)
        if action == 'MoveAhead':
            p.i, p.j = self.forward()
        elif action == 'RotateLeft':
            p.heading = (self.heading + TURN_DEG) % 360
        elif action == 'RotateRight':
            p.heading = (self.heading - TURN_DEG) % 360
        elif action == 'LookDown':
            p.horizon = min(self.horizon + LOOK_DEG, HORIZON_MAX)
        elif action == 'LookUp':
            p.horizon = max(self.horizon - LOOK_DEG, HORIZON_MIN)
        return p


HEADING_STEPS = {0: (1, 0), 90: (0, 1), 180: (-1, 0), 270: (0, -1)}


def points_in_agent_frame(depth: np.ndarray, horizon: float) -> np.ndarray:
    """depth [S, S] (metres along the optical axis) -> points [S, S, 3] (forward, left, height above
    the floor) for a camera pitched `horizon` degrees down."""
    u, v = BODY.pixel_rays(depth.shape[0], depth.shape[0])
    pitch = math.radians(-horizon)
    cp, sp = math.cos(pitch), math.sin(pitch)
    forward = depth * (cp - v * sp)
    left = -depth * u
    height = CAMERA_HEIGHT_M + depth * (sp + v * cp)
    return np.stack([forward, left, height], -1)


def to_map_frame(points: np.ndarray, pose: Pose) -> np.ndarray:
    """Points in the agent's frame [..., 3] -> the map frame (x, y, height)."""
    yaw = math.radians(pose.heading)
    c, s = math.cos(yaw), math.sin(yaw)
    x0, y0 = pose.xy
    f, l = points[..., 0], points[..., 1]
    return np.stack([x0 + c * f - s * l, y0 + s * f + c * l, points[..., 2]], -1)


def ray_distance(depth: np.ndarray) -> np.ndarray:
    """Distance from the eye to each cell's point (how far out the map takes points)."""
    return depth * BODY.ray_lengths(depth.shape[0], depth.shape[0])


def axis_distance(points: np.ndarray) -> np.ndarray:
    """Distance of each point in the agent's frame [..., 3] (`points_in_agent_frame`) from the agent's
    vertical axis (what the simulator's reach is measured on, as AI2-THOR's)."""
    return np.hypot(points[..., 0], points[..., 1])


def estimate_horizon(depth: np.ndarray, floor: np.ndarray, default: float = 30.0) -> float:
    """The camera pitch (one of HORIZONS) under which the cells `floor` [S, S] bool, predicted to be
    floor, lie nearest floor height; `default` when fewer than 8 floor cells are seen."""
    if int(floor.sum()) < 8:
        return default
    best, best_err = default, float('inf')
    for h in HORIZONS:
        heights = points_in_agent_frame(depth, h)[..., 2][floor]
        err = float(np.median(np.abs(heights)))
        if err < best_err - 1e-9:
            best, best_err = h, err
    return best


def bearing_deg(pose: Pose, x: float, y: float) -> float:
    """The bearing of map point (x, y) from the agent, counter-clockwise from its heading, in (-180, 180]."""
    x0, y0 = pose.xy
    b = (math.degrees(math.atan2(y - y0, x - x0)) - pose.heading + 180.0) % 360.0 - 180.0
    return 180.0 if b == -180.0 else b


def off_bearing(at: Pose, bearing: float, x, y) -> np.ndarray:
    """Degrees (0-180) between `bearing` and the bearing of each map point in arrays (x, y) seen from
    `at` (`bearing_deg` of each point, measured from `bearing`)."""
    x0, y0 = at.xy
    seen = np.degrees(np.arctan2(np.asarray(y, dtype=float) - y0, np.asarray(x, dtype=float) - x0)) - at.heading
    return np.abs((seen - bearing + 180.0) % 360.0 - 180.0)
