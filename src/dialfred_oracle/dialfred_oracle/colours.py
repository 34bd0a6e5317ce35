"""Colour names from rendered pixels: what colour word a person would give an object's image.

The simulator paints every object with one of the 20 palette colours
(`dialfred_sim.palette.PALETTE`) and renders it with pybullet's tiny renderer, which multiplies
a surface's colour by `0.6 ambient + 0.35 max(0, n.l) + 0.05 specular` and truncates to integers
(no textures, no shadows here).
A rendered palette colour is therefore the palette RGB scaled by a factor in [SHADE_MIN, SHADE_MAX].
Measured by rendering a sphere and a box of every palette colour from several viewpoints under the
world's light (`dialfred_sim.world.shading.measure_shade_range`, re-run by tests/oracle/test_answers.py):
every rendered channel lies at floor(c * s) for s in [0.593, 0.993]. This module reads pixels only: it draws
nothing and needs no simulator.

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

from dialfred_sim.palette import COLOUR_NAMES, PALETTE

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
