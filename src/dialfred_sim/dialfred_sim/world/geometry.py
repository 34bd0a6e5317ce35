"""Plain data that describes the shape of an object type, independent of pybullet.

Conventions (object frame): the origin is the centre of the object's footprint at its bottom, +z is
up, +x is the object's front (the side an agent faces when using it: a fridge door, a drawer front,
the seat of a sofa), +y is the object's left. Lengths are metres, angles radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal, Optional

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Part:
    """One primitive of a composed shape.

    shape: 'box' (half_extents = hx, hy, hz), 'cylinder' (half_extents = r, r, half length; its axis
    is the part's local z), or 'sphere' (half_extents = r, r, r).
    colour: 'main' paints the part with the instance's colour variant; 'dark' and 'light' are the
    main colour shaded; any other value is a palette name (see palette.PALETTE) and stays fixed.
    moving: True if the part belongs to the single articulated link (door, lid or drawer).
    """

    shape: Literal['box', 'cylinder', 'sphere']
    half_extents: Vec3
    pos: Vec3
    rpy: Vec3 = (0.0, 0.0, 0.0)
    colour: str = 'main'
    moving: bool = False


@dataclass(frozen=True)
class Articulation:
    """The one joint of an openable object: its moving parts turn or slide about it.

    kind: 'revolute' (hinged door or lid, open_value in radians) or 'prismatic' (drawer,
    open_value in metres). axis is the joint axis and origin a point on it, in the object frame.
    At joint value 0 the object is closed.
    """

    kind: Literal['revolute', 'prismatic']
    axis: Vec3
    origin: Vec3
    open_value: float


@dataclass(frozen=True)
class Surface:
    """A rectangle on which things can be placed (a table top, a shelf, a fridge's inside).

    center: centre of the rectangle in the object frame, z being the height of the support.
    half_size: half extents along the object's x and y. clearance: free height above it.
    inside: True if the surface is enclosed by the object (a cabinet shelf, a sink basin, a pot).
    """

    center: Vec3
    half_size: tuple[float, float]
    clearance: float
    inside: bool = False


@dataclass(frozen=True)
class ShapeSpec:
    """Everything needed to build an object type: parts, optional joint, placement surfaces.

    size: the extents (x, y, z) of the closed object.
    """

    parts: tuple[Part, ...]
    size: Vec3
    articulation: Optional[Articulation] = None
    surfaces: tuple[Surface, ...] = ()


def _rpy_matrix(rpy: Vec3):
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return ((cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
            (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
            (-sp, cp * sr, cp * cr))


def fit_spec(spec: ShapeSpec, size: Vec3) -> ShapeSpec:
    """`spec` stretched so that its extents become `size` (x, y, z).

    Used to fit furniture into a room (a counter's cabinets share the counter's depth and height).
    Boxes stretch exactly; cylinders and spheres keep round sections (mean of the stretched axes).
    """
    s = (size[0] / spec.size[0], size[1] / spec.size[1], size[2] / spec.size[2])

    def scale_part(part: Part) -> Part:
        m = _rpy_matrix(part.rpy)
        # Scale along the part's own axes: |R^T| s.
        local = tuple(sum(abs(m[i][j]) * s[i] for i in range(3)) for j in range(3))
        hx, hy, hz = part.half_extents
        if part.shape == 'box':
            half = (hx * local[0], hy * local[1], hz * local[2])
        elif part.shape == 'cylinder':
            r = hx * (local[0] + local[1]) / 2
            half = (r, r, hz * local[2])
        else:
            r = hx * sum(local) / 3
            half = (r, r, r)
        pos = (part.pos[0] * s[0], part.pos[1] * s[1], part.pos[2] * s[2])
        return replace(part, half_extents=half, pos=pos)

    surfaces = tuple(
        replace(surf, center=(surf.center[0] * s[0], surf.center[1] * s[1], surf.center[2] * s[2]),
                half_size=(surf.half_size[0] * s[0], surf.half_size[1] * s[1]),
                clearance=surf.clearance * s[2])
        for surf in spec.surfaces)
    art = spec.articulation
    if art is not None:
        origin = (art.origin[0] * s[0], art.origin[1] * s[1], art.origin[2] * s[2])
        value = art.open_value * (s[0] if art.kind == 'prismatic' else 1.0)
        art = replace(art, origin=origin, open_value=value)
    return ShapeSpec(parts=tuple(scale_part(p) for p in spec.parts), size=tuple(size),
                     articulation=art, surfaces=surfaces)
