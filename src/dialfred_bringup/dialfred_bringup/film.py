"""Episodes as pictures (ROS-free): a GIF of captioned frames and a contact sheet of a few episodes.

Used by the launcher's jobs (`dialogue --gif`, `demo`); frames are HxWx3 uint8 RGB arrays.
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Optional, Sequence

import numpy as np


def save_captioned_gif(film, path: Path, width: int = 320, seconds_per_frame: float = 1.0,
                       durations_ms: Optional[Sequence[int]] = None) -> None:
    """A GIF of (RGB frame, caption lines) pairs: each frame scaled to `width` with its lines under it.
    `durations_ms`: how long each frame stays up; default: frames with more than two lines (an answer
    to read) twice `seconds_per_frame`, the others (actions) 0.6 of it."""
    from PIL import Image, ImageDraw, ImageFont  # lazy: PIL, which the rest of this module does without
    font = ImageFont.load_default(size=12)
    line_h, chars = 15, width // 6
    wrapped = [[w for line in lines for w in textwrap.wrap(line, chars)] for _, lines in film]
    panel = line_h * max(len(w) for w in wrapped) + 8
    if durations_ms is None:
        durations_ms = [int(1000 * seconds_per_frame * (2.0 if len(lines) > 2 else 0.6)) for _, lines in film]
    images = []
    for (frame, _), lines in zip(film, wrapped):
        h = round(frame.shape[0] * width / frame.shape[1])
        img = Image.new('RGB', (width, h + panel), (255, 255, 255))
        img.paste(Image.fromarray(frame).resize((width, h), Image.BILINEAR), (0, 0))
        draw = ImageDraw.Draw(img)
        for k, line in enumerate(lines):
            draw.text((4, h + 4 + k * line_h), line, fill=(20, 20, 20), font=font)
        images.append(img.convert('P', palette=Image.ADAPTIVE, colors=128))
    path.parent.mkdir(parents=True, exist_ok=True)
    images[0].save(path, save_all=True, append_images=images[1:], duration=list(durations_ms), loop=0,
                   optimize=True)


def save_contact_sheet(rows, path: Path, per_row: int = 8, size: int = 128) -> None:
    """One PNG with a row per episode: its label (a line of text) over `per_row` of its frames, evenly
    spaced from the first to the last. `rows`: (label, [frames]) pairs."""
    from PIL import Image, ImageDraw, ImageFont  # lazy: PIL, which the rest of this module does without
    font = ImageFont.load_default(size=12)
    label_h = 18
    sheet = Image.new('RGB', (per_row * size, len(rows) * (label_h + size)), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for r, (label, frames) in enumerate(rows):
        top = r * (label_h + size)
        draw.text((4, top + 3), textwrap.shorten(label, per_row * size // 6), fill=(20, 20, 20), font=font)
        picks = sorted(set(np.linspace(0, len(frames) - 1, min(per_row, len(frames))).round().astype(int)))
        for c, k in enumerate(picks):
            tile = Image.fromarray(frames[k]).resize((size, size), Image.BILINEAR)
            sheet.paste(tile, (c * size, top + label_h))
    path.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(path)
