"""Render every object type's composed shape and write a labelled contact sheet.

    python scripts/render_gallery.py                      # writes docs/images/object_gallery.png
    python scripts/render_gallery.py --out /tmp/g.png --types Fridge Mug --size 256
    python scripts/render_gallery.py --bench              # prints build/render timings as JSON

Each tile is one type built on a gray floor, seen from a 3/4 front view with the tiny renderer
(shadow=0). Openable types get a second tile, opened. Needs pybullet, numpy and pillow.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from dialfred_sim.world.bullet import bullet_client, pybullet
from dialfred_sim.world import palette
from dialfred_sim.world.bodies import ShapeCache, build_body, set_articulation, triangle_count
from dialfred_sim.world.shapes import TYPES_WITH_SHAPES, shape_for

ROOT = Path(__file__).resolve().parents[1]
CATALOG = ROOT / 'src' / 'dialfred_sim' / 'dialfred_sim' / 'data' / 'object_types.csv'
FOV = 50.0
LABEL_H = 14


def new_client() -> bullet_client.BulletClient:
    """A DIRECT client; pybullet's banner goes to stderr so stdout stays clean JSON."""
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        return bullet_client.BulletClient(connection_mode=pybullet.DIRECT)
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def load_catalog() -> dict[str, dict[str, str]]:
    with open(CATALOG, newline='') as f:
        return {row['type']: row for row in csv.DictReader(f)}


def parse_dims(text: str):
    return tuple(float(v) for v in text.split('x')) if text else None


def gallery_colour(catalog: dict[str, dict[str, str]], name: str) -> str:
    """The type's most frequent DialFRED colour, skipping black (it hides the shape); slices take
    their whole fruit's colour."""
    if name.endswith('Sliced'):
        name = name[:-len('Sliced')]
    row = catalog.get(name, {})
    names = [kv.split('=')[0] for kv in row.get('colours_dialfred', '').split(';') if '=' in kv]
    names = [n for n in names if n in palette.PALETTE and n != 'black']
    return names[0] if names else 'tan'


def camera(client: bullet_client.BulletClient, size, zoom: float = 1.0, shift=(0.0, 0.0, 0.0), azimuth: float = 35.0,
           elevation: float = 25.0):
    """View and projection matrices framing a box of extents `size` standing at `shift`."""
    target = [shift[0], shift[1], shift[2] + size[2] / 2]
    radius = 0.5 * math.sqrt(sum(s * s for s in size))
    dist = 1.05 * zoom * radius / math.sin(math.radians(FOV / 2))
    az, el = math.radians(azimuth), math.radians(elevation)
    eye = [target[0] + dist * math.cos(el) * math.cos(az), target[1] + dist * math.cos(el) * math.sin(az),
           target[2] + dist * math.sin(el)]
    view = client.computeViewMatrix(eye, target, [0, 0, 1])
    proj = client.computeProjectionMatrixFOV(FOV, 1.0, max(dist - 2 * radius, 0.01), dist + 2 * radius + 1)
    return view, proj


def render(client: bullet_client.BulletClient, px: int, view, proj) -> np.ndarray:
    """An RGB frame from the tiny renderer without shadows."""
    rgba = client.getCameraImage(px, px, view, proj, renderer=pybullet.ER_TINY_RENDERER, shadow=0)[2]
    return np.asarray(rgba, dtype=np.uint8).reshape(px, px, 4)[:, :, :3]


def add_floor(client: bullet_client.BulletClient) -> int:
    vis = client.createVisualShape(pybullet.GEOM_BOX, halfExtents=[6, 6, 0.005],
                                   rgbaColor=[0.55, 0.55, 0.55, 1])
    return client.createMultiBody(0, -1, vis, [0, 0, -0.005])


def tiles(types: list[str], px: int) -> list[tuple[str, np.ndarray]]:
    catalog = load_catalog()
    client = new_client()
    cache = ShapeCache(client)
    add_floor(client)
    out = []
    for name in types:
        row = catalog.get(name, {})
        spec = shape_for(name, parse_dims(row.get('approx_size_m', '')))
        body = build_body(client, spec, gallery_colour(catalog, name), (0, 0, 0), 0.0, cache)
        view, proj = camera(client, spec.size)
        out.append((name, render(client, px, view, proj)))
        if spec.articulation is not None:
            set_articulation(client, body, spec, 1.0)
            art = spec.articulation
            if art.kind == 'prismatic':  # frame the slid-out part too
                move = [a * art.open_value for a in art.axis]
                size = [spec.size[i] + abs(move[i]) for i in range(3)]
                view, proj = camera(client, size, shift=(move[0] / 2, move[1] / 2, min(move[2], 0.0)))
            else:  # room for the swung door or lid
                view, proj = camera(client, spec.size, zoom=1.4)
            out.append((name + ' (open)', render(client, px, view, proj)))
        client.removeBody(body)
    client.disconnect()
    return out


def contact_sheet(items: list[tuple[str, np.ndarray]], px: int, cols: int) -> Image.Image:
    rows = math.ceil(len(items) / cols)
    sheet = Image.new('RGB', (cols * px, rows * (px + LABEL_H)), 'white')
    draw = ImageDraw.Draw(sheet)
    for i, (label, rgb) in enumerate(items):
        x, y = (i % cols) * px, (i // cols) * (px + LABEL_H)
        sheet.paste(Image.fromarray(rgb), (x, y))
        draw.text((x + 2, y + px + 1), label, fill='black')
    return sheet


def bench(repeats: int = 20) -> dict:
    """Build/render timings: a room of 15 furniture pieces and 30 small objects vs plain boxes."""
    catalog = load_catalog()
    furniture = ['Fridge', 'CounterTop', 'CounterTop', 'Cabinet', 'Cabinet', 'Drawer', 'Microwave',
                 'DiningTable', 'Chair', 'Chair', 'Shelf', 'GarbageCan', 'SinkBasin', 'StoveBurner',
                 'CoffeeMachine']
    small = ['Apple', 'Tomato', 'Potato', 'Lettuce', 'Bread', 'Egg', 'Mug', 'Cup', 'Bowl', 'Plate',
             'Pot', 'Pan', 'Knife', 'ButterKnife', 'Fork', 'Spoon', 'Spatula', 'Ladle', 'WineBottle',
             'Glassbottle', 'SoapBottle', 'SaltShaker', 'PepperShaker', 'DishSponge', 'Kettle',
             'Vase', 'CellPhone', 'Book', 'CreditCard', 'KeyChain']
    specs = [shape_for(n, parse_dims(catalog[n]['approx_size_m'])) for n in furniture + small]
    rng = np.random.default_rng(0)
    poses = []
    for k in range(len(specs)):
        if k < len(furniture):  # furniture around the walls of a 5 m x 4.4 m room, facing inwards
            a = 2 * math.pi * k / len(furniture)
            poses.append(((2.5 * math.cos(a), 2.2 * math.sin(a), 0.0), a + math.pi))
        else:  # small objects scattered on the floor in front of it
            a, r = rng.uniform(0, 2 * math.pi), rng.uniform(1.1, 1.8)
            poses.append(((r * math.cos(a), r * math.sin(a), 0.0), rng.uniform(-3, 3)))
    client = new_client()
    result: dict = {'objects': len(specs),
                    'triangles_composed': sum(triangle_count(s) for s in specs),
                    'triangles_boxes': 12 * len(specs)}

    def scene(composed: bool) -> float:
        client.resetSimulation()
        cache = ShapeCache(client)
        add_floor(client)
        t0 = time.perf_counter()
        for spec, (pos, yaw) in zip(specs, poses):
            if composed:
                build_body(client, spec, 'red', pos, yaw, cache)
            else:
                vis = cache.visual('box', tuple(s / 2 for s in spec.size), palette.rgba('red'))
                client.createMultiBody(0, -1, vis, [pos[0], pos[1], pos[2] + spec.size[2] / 2],
                                       client.getQuaternionFromEuler([0, 0, yaw]))
        return time.perf_counter() - t0

    # an agent's eye in the middle of the room, looking at the walls in 8 directions
    views = [client.computeViewMatrix([0.4 * math.cos(a), 0.4 * math.sin(a), 1.5],
                                      [2.4 * math.cos(a), 2.4 * math.sin(a), 0.4], [0, 0, 1])
             for a in np.linspace(0, 2 * math.pi, 8, endpoint=False)]
    proj = client.computeProjectionMatrixFOV(60, 1.0, 0.05, 20)
    for composed in (True, False):
        key = 'composed' if composed else 'boxes'
        result[f'scene_build_s_{key}'] = round(scene(composed), 4)
        for px in (128, 300):
            t0 = time.perf_counter()
            for i in range(repeats):
                client.getCameraImage(px, px, views[i % len(views)], proj,
                                      renderer=pybullet.ER_TINY_RENDERER, shadow=0)
            result[f'render_ms_{px}_{key}'] = round(1000 * (time.perf_counter() - t0) / repeats, 2)
    # one typical body of each kind, with a fresh cache and with a warm one
    for name in ('Mug', 'Cabinet', 'Fridge'):
        spec = shape_for(name, parse_dims(catalog[name]['approx_size_m']))
        client.resetSimulation()
        cache = ShapeCache(client)
        t0 = time.perf_counter()
        build_body(client, spec, 'red', (0, 0, 0), 0.0, cache)
        cold = time.perf_counter() - t0
        t0 = time.perf_counter()
        for _ in range(repeats):
            build_body(client, spec, 'red', (0, 0, 0), 0.0, cache)
        warm = (time.perf_counter() - t0) / repeats
        result[f'build_ms_{name}'] = {'cold_cache': round(1000 * cold, 3), 'warm_cache': round(1000 * warm, 3)}
    client.disconnect()
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--out', default=str(ROOT / 'docs' / 'images' / 'object_gallery.png'))
    parser.add_argument('--types', nargs='*', help='only these types (default: all)')
    parser.add_argument('--size', type=int, default=128, help='tile size in pixels')
    parser.add_argument('--cols', type=int, default=13)
    parser.add_argument('--bench', action='store_true', help='print timings as JSON instead')
    args = parser.parse_args()
    if args.bench:
        print(json.dumps(bench(), indent=2))
        return
    items = tiles(args.types or list(TYPES_WITH_SHAPES), args.size)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    contact_sheet(items, args.size, min(args.cols, len(items))).save(out)
    print(f'wrote {out} ({len(items)} tiles)')


if __name__ == '__main__':
    main()
