"""Composed box/cylinder/sphere shapes for every ALFRED object type.

`shape_for(type_name, dims)` returns a ShapeSpec in the object frame of geometry.py (origin at the
bottom centre of the footprint, +x front, +y left, +z up). `dims` are the catalogue's approx_size_m
numbers as given: for pickupables the oriented box edges sorted largest first, for fixed objects
(length, width, height) of the axis-aligned box; each type's layout in registry.py says which edge
goes where (the long side of furniture runs along y, its front facing +x). The numbers scale the
shape; proportions that the catalogue gets wrong for our purpose are fixed by the builder (a
CounterTop's 0.02 m is its slab only, so the counter gets a base and a 0.9 m height). After
building, every shape is recentred so its closed bounding box sits on the origin; ShapeSpec.size is
that box.

Colours: 'main' is the instance's colour variant and is given to the largest visible part; 'dark'
and 'light' shade it; palette names stay fixed (silver blades, black handles).

Receptacles get Surfaces; `inside=True` where the object encloses them. For a prismatic articulation
(Drawer) the inside surfaces ride on the moving drawer: see `surface_offset`. Hanging holders
(TowelHolder, HandTowelHolder, ToiletPaperHanger) get a thin surface on their bar, ring or spindle;
what hangs there needs a pose of its own.

Modules: primitives (primitive helpers, `_finish`, `part_bounds`, `surface_offset`, hinges), one
module of builders per family (food, kitchenware, utensils, household, openables, furniture,
fixtures, decor), and registry (type name -> builder, layout and default extents; `shape_for`).
"""

from .primitives import _rot, part_bounds, surface_offset  # noqa: F401  (_rot: tests use shapes._rot)
from .registry import TYPES_WITH_SHAPES, shape_for

__all__ = ['TYPES_WITH_SHAPES', 'part_bounds', 'shape_for', 'surface_offset']
