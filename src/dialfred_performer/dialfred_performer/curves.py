"""Training curves as a PNG drawn with Pillow (matplotlib is not a dependency), from metrics.jsonl.

Three panels over optimiser updates: loss, action accuracy, pointer accuracy; training (windows of
`log_every` updates) as a line, validation (each epoch) as a line with dots.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from PIL import Image, ImageDraw, ImageFont

PANELS = (('loss', 'loss'), ('action_accuracy', 'action accuracy'), ('pointer_accuracy', 'pointer accuracy'))
COLOURS = {'train': (31, 119, 180), 'val': (255, 127, 14)}
W, H, MARGIN = 360, 260, (48, 28, 14, 34)      # panel size; left, top, right, bottom margins


def read_metrics(path: Path) -> list[dict]:
    path = Path(path)
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()] if path.exists() else []


def _ticks(lo: float, hi: float, n: int = 4) -> list[float]:
    if hi <= lo:
        return [lo]
    step = 10 ** math.floor(math.log10((hi - lo) / n))
    for m in (1, 2, 5, 10):
        if (hi - lo) / (step * m) <= n:
            step *= m
            break
    first = math.ceil(lo / step) * step
    return [first + k * step for k in range(int((hi - first) / step) + 1)]


def _axes(draw: ImageDraw.ImageDraw, x0: int, title: str, points: list, y_range, font):
    """A panel's title, frame, grid lines and ticks; returns its data -> pixel mapping (None without points)."""
    left, top, right, bottom = x0 + MARGIN[0], MARGIN[1], x0 + W - MARGIN[2], H - MARGIN[3]
    draw.text((x0 + W // 2 - len(title) * 3, 8), title, fill='black', font=font)
    draw.rectangle((left, top, right, bottom), outline=(160, 160, 160))
    if not points:
        return None
    x_lo, x_hi = 0, max(max(p[0] for p in points), 1)
    y_lo, y_hi = y_range

    def at(x: float, y: float) -> tuple[float, float]:
        return (left + (x - x_lo) / (x_hi - x_lo) * (right - left),
                bottom - (min(max(y, y_lo), y_hi) - y_lo) / (y_hi - y_lo) * (bottom - top))

    for y in _ticks(y_lo, y_hi):
        _, py = at(x_lo, y)
        draw.line((left, py, right, py), fill=(230, 230, 230))
        draw.text((x0 + 4, py - 6), f'{y:.3g}', fill='black', font=font)
    for x in _ticks(x_lo, x_hi):
        px, _ = at(x, y_lo)
        draw.text((px - 8, bottom + 4), f'{x:g}', fill='black', font=font)
    return at


def _panel(draw: ImageDraw.ImageDraw, x0: int, key: str, title: str, rows: list[dict], font) -> None:
    series = {kind: [(r['update'], r[key]) for r in rows if r['kind'] == kind and r.get(key) is not None]
              for kind in COLOURS}
    points = [p for s in series.values() for p in s]
    y_range = (0.0, 1.0) if 'accuracy' in key else (0.0, max([p[1] for p in points] + [0.0]) * 1.05 or 1.0)
    at = _axes(draw, x0, title, points, y_range, font)
    if at is None:
        return
    for kind, s in series.items():
        pts = [at(x, y) for x, y in sorted(s)]
        if len(pts) > 1:
            draw.line(pts, fill=COLOURS[kind], width=2)
        if kind == 'val' or len(pts) == 1:
            for px, py in pts:
                draw.ellipse((px - 3, py - 3, px + 3, py + 3), fill=COLOURS[kind])


def draw_curves(metrics_path: Path, out_path: Path) -> Path:
    """Write the curves of `metrics_path` (metrics.jsonl) to `out_path` (PNG, written atomically)."""
    rows = read_metrics(metrics_path)
    image = Image.new('RGB', (W * len(PANELS), H + 20), 'white')
    draw = ImageDraw.Draw(image)
    font = ImageFont.load_default()
    for k, (key, title) in enumerate(PANELS):
        _panel(draw, k * W, key, title, rows, font)
    for k, (kind, colour) in enumerate(COLOURS.items()):
        x = 12 + k * 110
        draw.line((x, H + 8, x + 24, H + 8), fill=colour, width=3)
        draw.text((x + 30, H + 2), {'train': 'training', 'val': 'validation'}[kind], fill='black', font=font)
    draw.text((W * len(PANELS) - 120, H + 2), 'x: optimiser updates', fill='black', font=font)
    out_path = Path(out_path)
    tmp = out_path.with_name(out_path.name + '.tmp.png')
    image.save(tmp)
    tmp.replace(out_path)
    return out_path


def draw_series(rows: list[dict], panels, out_path: Path, x_key: str = 'update', x_label: str = '') -> Path:
    """A row of line panels from `rows` (dicts with `x_key`): each panel is (title, ((key, label,
    colour), ...), y range or None for 0 (or the lowest value) to the highest); a legend per panel."""
    font = ImageFont.load_default()
    image = Image.new('RGB', (W * len(panels), H + 20 + 14 * max(len(p[1]) for p in panels)), 'white')
    draw = ImageDraw.Draw(image)
    for k, (title, lines, y_range) in enumerate(panels):
        x0 = k * W
        series = [[(r[x_key], r[key]) for r in rows if r.get(key) is not None] for key, _, _ in lines]
        points = [p for s in series for p in s]
        for j, (_, label, colour) in enumerate(lines):
            y = H + 8 + 14 * j
            draw.line((x0 + 12, y, x0 + 36, y), fill=colour, width=3)
            draw.text((x0 + 42, y - 6), label, fill='black', font=font)
        ys = [p[1] for p in points] or [0.0]
        y_lo, y_hi = y_range or (min(0.0, min(ys)), max(ys) * 1.05 if max(ys) > 0 else 1.0)
        at = _axes(draw, x0, title, points, (y_lo, y_hi if y_hi > y_lo else y_lo + 1.0), font)
        if at is None:
            continue
        for s, (_, _, colour) in zip(series, lines):
            pts = [at(x, y) for x, y in sorted(s)]
            if len(pts) > 1:
                draw.line(pts, fill=colour, width=2)
            else:
                for px, py in pts:
                    draw.ellipse((px - 3, py - 3, px + 3, py + 3), fill=colour)
    if x_label:
        draw.text((W * len(panels) - 160, H + 2), x_label, fill='black', font=font)
    out_path = Path(out_path)
    tmp = out_path.with_name(out_path.name + '.tmp.png')
    image.save(tmp)
    tmp.replace(out_path)
    return out_path
