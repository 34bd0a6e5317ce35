"""The tiny renderer's shading of the palette: how far a rendered colour strays from its palette RGB.

The oracle names colours from pixels (dialfred_oracle.colours), assuming each rendered channel is the palette
value scaled by a shade in its [SHADE_MIN, SHADE_MAX]; `measure_shade_range` measures that range here, where
the world's bodies and light are.
"""

from __future__ import annotations

import numpy as np

from ..palette import COLOUR_NAMES, PALETTE, rgba
from .bodies import ShapeCache
from .bullet import bullet_client, pybullet
from .camera import LIGHT_DIRECTION


def measure_shade_range(size: int = 64) -> tuple[float, float]:
    """Render a sphere and a box of every palette colour under the world's light from several
    viewpoints in a private pybullet client; return the (min, max) ratio of rendered to palette
    channel values (channels below 100 are skipped: integer truncation dominates there)."""
    client = bullet_client.BulletClient(connection_mode=pybullet.DIRECT)
    try:
        cache = ShapeCache(client)
        proj = client.computeProjectionMatrixFOV(60, 1, 0.02, 5)
        eyes = [(0.5, 0.0, 0.3), (0.0, 0.5, 0.3), (-0.5, 0.0, 0.3), (0.0, -0.5, 0.3), (0.35, 0.35, -0.2),
                (0.01, 0.0, 0.6)]
        lo, hi = np.inf, -np.inf
        for name in COLOUR_NAMES:
            base = np.array(PALETTE[name], dtype=np.float64)
            bodies = [client.createMultiBody(0, -1, cache.visual('sphere', (0.1, 0.1, 0.1), rgba(name)), [0, 0, 0]),
                      client.createMultiBody(0, -1, cache.visual('box', (0.08, 0.08, 0.08), rgba(name)),
                                             [0, 0, 0], client.getQuaternionFromEuler((0.3, 0.2, 0.7)))]
            for body in bodies:
                others = [b for b in bodies if b != body]
                for b in others:
                    client.resetBasePositionAndOrientation(b, (0, 0, -10), (0, 0, 0, 1))
                client.resetBasePositionAndOrientation(body, (0, 0, 0), client.getQuaternionFromEuler((0.3, 0.2, 0.7)))
                for eye in eyes:
                    view = client.computeViewMatrix(eye, (0, 0, 0), (0, 0, 1))
                    _, _, px, _, seg = client.getCameraImage(size, size, view, proj, renderer=client.ER_TINY_RENDERER,
                                                             shadow=0, lightDirection=LIGHT_DIRECTION)
                    px = np.asarray(px, np.uint8).reshape(size, size, 4)[:, :, :3]
                    seg = np.asarray(seg).reshape(size, size)
                    p = px[seg == body].astype(np.float64)
                    ok = base >= 100
                    if len(p) and ok.any():
                        ratio = p[:, ok] / base[ok]
                        lo, hi = min(lo, float(ratio.min())), max(hi, float(ratio.max()))
            for b in bodies:
                client.removeBody(b)
        return lo, hi
    finally:
        client.disconnect()
