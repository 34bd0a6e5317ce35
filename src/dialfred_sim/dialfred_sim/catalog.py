"""The object catalog: every AI2-THOR/ALFRED object type the world knows, with its affordances.

Built from `data/object_types.csv` (compiled from ALFRED, DialFRED and AI2-THOR sources; see that
folder's provenance in the project docs). ALFRED's own rules are preferred over raw THOR flags where
they differ (cleanable/heatable/coolable, what a receptacle accepts), as the data README advises.
"""

from __future__ import annotations

import csv
import functools
from dataclasses import dataclass, replace
from importlib import resources
from typing import Optional

from .palette import COLOUR_NAMES

ROOM_TYPES: tuple[str, ...] = ('kitchen', 'living_room', 'bedroom', 'bathroom')

_N_COLOUR_VARIANTS = 4  # a scene can hold same-class objects of up to this many colours


@dataclass(frozen=True)
class ObjectType:
    """One object type: its name, words, size, look and affordances."""

    name: str
    noun: str
    nouns: tuple[str, ...]              # phrases people use for it, most common first
    pickupable: bool
    receptacle: bool
    openable: bool
    toggleable: bool
    sliceable: bool
    cleanable: bool
    heatable: bool
    coolable: bool
    movable_receptacle: bool
    materials: tuple[str, ...]
    room_types: tuple[str, ...]
    scene_counts: dict                  # room type -> number of ALFRED scenes (of 30) holding it
    typical_receptacles: tuple[str, ...]  # where it may be put (ALFRED's allow-lists)
    accepts: tuple[str, ...]            # for receptacles: what may be put in/on it
    dims: Optional[tuple[float, float, float]]  # approx_size_m as in the CSV
    colours: tuple[str, ...]            # colour variants (palette names), most common first
    preposition: str                    # 'in' or 'on' (for receptacles)
    sliced_type: Optional[str]          # 'AppleSliced' for Apple
    parent_type: Optional[str]          # 'Apple' for AppleSliced
    task_roles: dict                    # ALFRED role -> number of demos
    in_dialfred: bool                   # one of DialFRED's interaction targets

    @property
    def material(self) -> str:
        """The salient material named in appearance answers (the first listed)."""
        return self.materials[0] if self.materials else 'plastic'


def _flag(value: str) -> bool:
    return value.strip() == '1'


def _list(value: str) -> tuple[str, ...]:
    return tuple(v for v in (s.strip() for s in value.split(';')) if v)


def _shares(value: str) -> list[tuple[str, float]]:
    out = []
    for item in _list(value):
        key, _, num = item.partition('=')
        out.append((key.strip(), float(num) if num else 0.0))
    return out


def _dims(value: str) -> Optional[tuple[float, float, float]]:
    if not value.strip():
        return None
    a, b, c = (float(v) for v in value.split('x'))
    return (a, b, c)


def _colour_variants(name: str, observed: list[str]) -> tuple[str, ...]:
    """The observed DialFRED colours first, then others drawn from the palette by a fixed rule."""
    colours = [c for c in observed if c in COLOUR_NAMES]
    # Deterministic filler independent of Python's hash seed.
    start = sum(ord(ch) for ch in name) % len(COLOUR_NAMES)
    i = 0
    while len(colours) < _N_COLOUR_VARIANTS:
        candidate = COLOUR_NAMES[(start + 7 * i) % len(COLOUR_NAMES)]
        if candidate not in colours:
            colours.append(candidate)
        i += 1
    return tuple(colours)


def _row_to_type(row: dict) -> ObjectType:
    name = row['type']
    nouns = [n for n, _ in sorted(_shares(row['noun_variants_alfred']), key=lambda kv: -kv[1])]
    noun = row['noun'].strip() or name.lower()
    if noun not in nouns:
        nouns.insert(0, noun)
    scene_counts = {k: int(v) for k, v in _shares(row['scene_counts'])}
    parent = name[:-len('Sliced')] if name.endswith('Sliced') else None
    return ObjectType(
        name=name,
        noun=noun,
        nouns=tuple(nouns),
        pickupable=_flag(row['pickupable']),
        receptacle=_flag(row['receptacle']),
        openable=_flag(row['openable']),
        toggleable=_flag(row['toggleable']),
        sliceable=_flag(row['sliceable']),
        cleanable=_flag(row['cleanable']),
        heatable=_flag(row['heatable']),
        coolable=_flag(row['coolable']),
        movable_receptacle=_flag(row['alfred_movable_receptacle']),
        materials=_list(row['materials']),
        room_types=_list(row['room_types']),
        scene_counts=scene_counts,
        typical_receptacles=_list(row['typical_receptacles']),
        accepts=_list(row['alfred_accepts']),
        dims=_dims(row['approx_size_m']),
        colours=_colour_variants(name, [c for c, _ in _shares(row['colours_dialfred'])]),
        preposition=row['preposition'].strip() or 'on',
        sliced_type=None,
        parent_type=parent,
        task_roles={k: int(v) for k, v in _shares(row['alfred_task_roles'])},
        in_dialfred=_flag(row['in_dialfred_objects_actions']),
    )


@functools.lru_cache(maxsize=1)
def load_catalog() -> dict[str, ObjectType]:
    """All object types by name, read once from the packaged CSV."""
    text = resources.files('dialfred_sim').joinpath('data/object_types.csv').read_text()
    types = {row['type']: _row_to_type(row) for row in csv.DictReader(text.splitlines())}
    # Link whole objects to their slices; slices inherit the parent's look.
    for name, t in list(types.items()):
        if t.parent_type and t.parent_type in types:
            parent = types[t.parent_type]
            types[parent.name] = replace(parent, sliced_type=name)
            types[name] = replace(t, colours=parent.colours, materials=parent.materials or t.materials)
    # Sliceable in this world means: it has a sliced form (an Egg cracks in THOR; not modelled here).
    for name, t in list(types.items()):
        if t.sliceable and not types[name].sliced_type:
            types[name] = replace(types[name], sliceable=False)
    return types


def object_type(name: str) -> ObjectType:
    """The type called `name`; KeyError with the known names' count if unknown."""
    catalog = load_catalog()
    try:
        return catalog[name]
    except KeyError:
        raise KeyError(f'unknown object type {name!r} ({len(catalog)} types known)') from None
