"""The fixed palette of colour names used for object colour variants and by the oracle.

DialFRED's appearance answers use one colour word out of about twenty. Every object instance in
the world is painted with one of these named colours, so the colour an answer should name is known
exactly (the oracle later recovers it from rendered pixels).
"""

from __future__ import annotations

# sRGB values, 0-255. Chosen to be far apart from each other under the tiny renderer's lighting.
PALETTE: dict[str, tuple[int, int, int]] = {
    'black': (20, 20, 20),
    'gray': (128, 128, 128),
    'white': (240, 240, 240),
    'red': (220, 30, 30),
    'maroon': (128, 0, 0),
    'brown': (139, 69, 19),
    'tan': (210, 180, 140),
    'beige': (245, 245, 200),
    'khaki': (195, 176, 96),
    'olive': (110, 110, 0),
    'green': (20, 160, 40),
    'teal': (0, 128, 128),
    'blue': (30, 80, 230),
    'navy': (0, 0, 110),
    'purple': (128, 0, 160),
    'pink': (255, 150, 190),
    'orange': (255, 140, 0),
    'gold': (212, 175, 55),
    'silver': (190, 195, 205),
    'yellow': (240, 230, 30),
}

COLOUR_NAMES: tuple[str, ...] = tuple(PALETTE)


def rgba(name: str, alpha: float = 1.0) -> list[float]:
    """Palette colour `name` as a pybullet rgbaColor (floats in [0, 1])."""
    r, g, b = PALETTE[name]
    return [r / 255.0, g / 255.0, b / 255.0, alpha]
