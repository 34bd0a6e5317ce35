"""The agent's camera, with AI2-THOR's optics: where the eye is, the view pybullet draws from, the
frames it renders (colour, depth in metres, segmentation) and the world point behind a pixel.

`AgentView` is a part of `scene.World`, which inherits it: it reads the world's agent pose, image size,
projection and pybullet client. The camera's numbers are the robot body's (`protocol.BODY`).
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from ..protocol import BODY

# The camera's numbers come from the robot's body (protocol.BODY); the world keeps its own drawing constants.
CAMERA_HEIGHT = BODY.camera_height
FOV_DEG = BODY.fov_deg
NEAR, FAR = 0.05, 12.0       # clipping planes, metres
HORIZON_MIN, HORIZON_MAX = BODY.horizon_min, BODY.horizon_max
START_HORIZON = BODY.start_horizon
LIGHT_DIRECTION = (0.3, 0.5, 1.0)
EYE_SHIFT = 0.0007           # metres the drawn eye sits behind the true one (see AgentView.view_matrix)
pixel_rays, ray_lengths, reach_lengths = BODY.pixel_rays, BODY.ray_lengths, BODY.reach_lengths


class AgentView:
    """The agent's camera (a part of World)."""

    def camera(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Eye position and unit view direction of the agent's camera."""
        yaw = math.radians(self.agent.rotation)
        pitch = math.radians(-self.agent.horizon)
        eye = (self.agent.x, self.agent.y, CAMERA_HEIGHT)
        direction = (math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), math.sin(pitch))
        return eye, direction

    def view_matrix(self):
        """The camera drawn from EYE_SHIFT behind the eye, along its view (render() measures depth
        from the true eye). TinyRenderer divides by each vertex's view depth without clipping, so a
        box corner lying exactly in the camera's plane (with grid poses and whole-centimetre furniture:
        a 0.9 m counter top ending 0.6 m behind an eye 1.5 m up pitched 45 degrees) blackens its faces
        with NaN depth or drops them; the shift keeps every such corner off that plane."""
        eye, d = self.camera()
        eye = tuple(eye[k] - EYE_SHIFT * d[k] for k in range(3))
        target = (eye[0] + d[0], eye[1] + d[1], eye[2] + d[2])
        return self.client.computeViewMatrix(eye, target, (0.0, 0.0, 1.0))

    def render(self, width: Optional[int] = None, height: Optional[int] = None):
        """(rgb uint8 HxWx3, depth float32 HxW metres along the view axis, segmentation int32 HxW).

        A smaller `width` x `height` (same aspect) gives a cheap preview, as the expert uses."""
        w, h = width or self.width, height or self.height
        rgba_px, z, seg = self._camera_image(w, h, self.view_matrix())
        rgb = np.ascontiguousarray(np.asarray(rgba_px, dtype=np.uint8).reshape(h, w, 4)[:, :, :3])
        z = z.reshape(h, w)
        depth = (FAR * NEAR / (FAR - (FAR - NEAR) * z) - EYE_SHIFT).astype(np.float32)
        seg = np.asarray(seg, dtype=np.int32).reshape(h, w)
        return rgb, depth, seg

    def _camera_image(self, w: int, h: int, view):
        _, _, rgba_px, zbuf, seg = self.draw(w, h, view, self.projection)
        return rgba_px, np.asarray(zbuf, dtype=np.float32), seg

    def draw(self, width: int, height: int, view, projection, **flags):
        """pybullet's getCameraImage with TinyRenderer and the world's light, from any camera (`view`,
        `projection`): the objects wholly outside its view are left out of the draw (culling.py; the
        same image as a draw of everything). `flags`: getCameraImage's further keywords."""
        self.culling.prepare(view, projection, self.objects.values())
        return self.client.getCameraImage(width, height, view, projection, renderer=self.client.ER_TINY_RENDERER,
                                          shadow=0, lightDirection=LIGHT_DIRECTION, **flags)

    def pixel_point(self, px: int, py: int, depth: np.ndarray) -> tuple[tuple[float, float, float], float]:
        """The world point seen at pixel (px, py) and its distance from the eye."""
        eye, fwd = self.camera()
        yaw = math.radians(self.agent.rotation)
        right = (math.sin(yaw), -math.cos(yaw), 0.0)
        up = (right[1] * fwd[2] - right[2] * fwd[1], right[2] * fwd[0] - right[0] * fwd[2],
              right[0] * fwd[1] - right[1] * fwd[0])   # right x forward: the camera's up
        t = math.tan(math.radians(FOV_DEG) / 2)
        u = ((px + 0.5) / self.width * 2 - 1) * t * (self.width / self.height)
        v = (1 - (py + 0.5) / self.height * 2) * t
        ray = tuple(fwd[k] + u * right[k] + v * up[k] for k in range(3))
        z = float(depth[py, px])
        point = tuple(eye[k] + z * ray[k] for k in range(3))
        return point, z * math.sqrt(sum(r * r for r in ray))

    def axis_distance(self, point) -> float:
        """How far `point` lies from the agent's central vertical axis (the distance reach is measured by)."""
        return math.hypot(point[0] - self.agent.x, point[1] - self.agent.y)
