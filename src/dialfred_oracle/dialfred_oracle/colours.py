"""Colour names from rendered pixels: what colour word a person would give an object's image.

The simulator paints every object with one of the 20 palette colours
(`dialfred_sim.world.palette.PALETTE`) and renders it with pybullet's tiny renderer, which multiplies
a surface's colour by `0.6 ambient + 0.35 max(0, n.l) + 0.05 specular` and truncates to integers
(no textures, no shadows here).
A rendered palette colour is therefore the palette RGB scaled by a factor in [SHADE_MIN, SHADE_MAX].
Measured by rendering a sphere and a box of every palette colour from several viewpoints under the
world's light (`measure_shade_range`, re-run by tests/oracle/test_answers.py): every rendered channel lies
at floor(c * s) for s in [0.593, 0.993].

`colour_name` labels each pixel with the nearest shaded palette colour in CIELAB and returns the
name most pixels agree on. The simulator's appearance samples (dialfred_sim.ground_truth) hold only
the parts painted in the object's colour variant; on whole masks, where fixed-colour details (a
knife's blade, a window's glass, a screen) and darker trims also vote, the main colour still wins
for most objects (measured over 33 rooms: 86-89% of in-view objects, against 100% with part masks).
"""

from __future__ import annotations

import functools
from typing import Optional

import numpy as np

from dialfred_sim.world.camera import LIGHT_DIRECTION
from dialfred_sim.world.palette import COLOUR_NAMES, PALETTE, rgba

SHADE_MIN, SHADE_MAX = 0.58, 1.0     # measured 0.593-0.993 (see module docstring), with a margin
_SHADE_STEPS = 43                    # about one shade per 0.01
MAX_LAB_DISTANCE = 12.0              # pixels farther than this from every shaded palette colour do not vote


def srgb_to_lab(rgb: np.ndarray) -> np.ndarray:
    """CIELAB (D65) of sRGB colours: (..., 3) values in 0-255 -> (..., 3) floats (L in 0-100)."""
    c = np.asarray(rgb, dtype=np.float64) / 255.0
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    m = np.array([[0.4124564, 0.3575761, 0.1804375],
                  [0.2126729, 0.7151522, 0.0721750],
                  [0.0193339, 0.1191920, 0.9503041]])
    xyz = linear @ m.T / np.array([0.95047, 1.0, 1.08883])
    eps, kappa = 216 / 24389, 24389 / 27
    f = np.where(xyz > eps, np.cbrt(xyz), (kappa * xyz + 16) / 116)
    return np.stack([116 * f[..., 1] - 16, 500 * (f[..., 0] - f[..., 1]), 200 * (f[..., 1] - f[..., 2])], axis=-1)


@functools.lru_cache(maxsize=1)
def reference_table() -> tuple[np.ndarray, np.ndarray]:
    """(Lab of every shaded palette colour (M, 3), index into COLOUR_NAMES of each (M,)).

    Each palette colour appears as the renderer would draw it at shades SHADE_MIN..SHADE_MAX."""
    shades = np.linspace(SHADE_MIN, SHADE_MAX, _SHADE_STEPS)
    rgb, label = [], []
    for k, name in enumerate(COLOUR_NAMES):
        base = np.array(PALETTE[name], dtype=np.float64)
        rgb.append(np.floor(base[None, :] * shades[:, None]))
        label += [k] * len(shades)
    return srgb_to_lab(np.concatenate(rgb)), np.array(label)


def pixel_labels(pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel, (index of the nearest palette colour, its Lab distance). pixels: (N, 3) RGB."""
    pixels = np.asarray(pixels).reshape(-1, 3)
    if pixels.dtype == np.uint8:
        # A flat-shaded object shows a few dozen distinct colours in hundreds of pixels: label each
        # distinct colour once (about 40x less work for the oracle's 400-pixel samples).
        codes = pixels.astype(np.int64) @ np.array([1 << 16, 1 << 8, 1])
        distinct, index = np.unique(codes, return_inverse=True)
        rgb = np.stack([distinct >> 16, (distinct >> 8) & 255, distinct & 255], axis=1)
        labels, dist = _nearest_shaded_colour(rgb)
        return labels[index.reshape(-1)], dist[index.reshape(-1)]
    return _nearest_shaded_colour(pixels)


def _nearest_shaded_colour(pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lab = srgb_to_lab(np.asarray(pixels, dtype=np.float64))
    refs, labels = reference_table()
    d2 = ((lab[:, None, :] - refs[None, :, :]) ** 2).sum(-1)
    nearest = d2.argmin(1)
    return labels[nearest], np.sqrt(d2[np.arange(len(lab)), nearest])


def colour_votes(pixels: np.ndarray) -> dict[str, int]:
    """How many pixels each palette colour explains, most first. Only pixels within
    MAX_LAB_DISTANCE of some shaded palette colour vote, unless none is: then all do."""
    pixels = np.asarray(pixels).reshape(-1, 3)
    if len(pixels) == 0:
        return {}
    labels, dist = pixel_labels(pixels)
    close = dist <= MAX_LAB_DISTANCE
    counts = np.bincount(labels[close] if close.any() else labels, minlength=len(COLOUR_NAMES))
    order = sorted((k for k in range(len(COLOUR_NAMES)) if counts[k]), key=lambda k: (-counts[k], k))
    return {COLOUR_NAMES[k]: int(counts[k]) for k in order}


def colour_name(pixels: np.ndarray) -> Optional[str]:
    """The palette colour name of an object from RGB samples of its rendered mask ((N, 3) uint8):
    the name that explains most pixels (ties: palette order). None for an empty sample."""
    votes = colour_votes(pixels)
    return next(iter(votes)) if votes else None


def measure_shade_range(size: int = 64) -> tuple[float, float]:
    """Render a sphere and a box of every palette colour under the world's light from several
    viewpoints in a private pybullet client; return the (min, max) ratio of rendered to palette
    channel values (channels below 100 are skipped: integer truncation dominates there)."""
    from dialfred_sim.world.bodies import ShapeCache  # lazy: pybullet, which the rest of this module does without
    # lazy: pybullet, which the rest of this module does without
    from dialfred_sim.world.bullet import bullet_client, pybullet

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
