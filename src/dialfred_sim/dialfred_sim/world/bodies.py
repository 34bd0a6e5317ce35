"""Turn a ShapeSpec into a static pybullet multibody (visual shapes only).

Layout of a built body: the base carries no visual; every rigid part is a link on a fixed joint to
the base, placed at the part's pose, so one visual shape id can be shared by every part (in every
body) with the same geometry and colour. If the spec has an articulation, one extra link sits on the
revolute/prismatic joint at `articulation.origin`, and each moving part is a fixed-joint child of it.
Joint indices are therefore: rigid parts 0..n-1 in spec order, then the articulated joint (n), then
the moving parts. All masses are 0 and there are no collision shapes.

Cylinders and spheres are low-polygon meshes built here rather than pybullet's own primitives, which
the tiny renderer tessellates finely (a 12-sided cylinder costs about 60% of pybullet's cylinder).
"""

from __future__ import annotations

import functools
import math
from typing import Any, Sequence

from .bullet import pybullet

from .. import palette
from .geometry import Part, ShapeSpec, Vec3

_DARK = 0.55   # 'dark' = main * _DARK
_LIGHT = 0.5   # 'light' = main + (1 - main) * _LIGHT


def part_rgba(name: str, main_colour: str) -> tuple[float, float, float, float]:
    """The rgba a part coloured `name` gets on an instance whose colour variant is `main_colour`."""
    if name in ('main', 'dark', 'light'):
        r, g, b, a = palette.rgba(main_colour)
        if name == 'dark':
            return (r * _DARK, g * _DARK, b * _DARK, a)
        if name == 'light':
            return (r + (1 - r) * _LIGHT, g + (1 - g) * _LIGHT, b + (1 - b) * _LIGHT, a)
        return (r, g, b, a)
    return tuple(palette.rgba(name))  # type: ignore[return-value]


def cylinder_segments(radius: float) -> int:
    """Sides of the polygon that stands for a cylinder of this radius."""
    return 8 if radius < 0.02 else 12 if radius < 0.1 else 16


def sphere_segments(radius: float) -> tuple[int, int]:
    """(longitudes, latitudes) of the low-polygon sphere of this radius."""
    return (6, 4) if radius < 0.02 else (10, 6)


def triangle_count(spec: ShapeSpec) -> int:
    """Triangles the renderer draws for one body of this spec (its cost grows with this number)."""
    total = 0
    for part in spec.parts:
        if part.shape == 'box':
            total += 12
        elif part.shape == 'cylinder':
            total += 4 * cylinder_segments(part.half_extents[0]) - 4
        else:
            lon, lat = sphere_segments(part.half_extents[0])
            total += 2 * lon * (lat - 1)
    return total


# pybullet 3.2.7's createVisualShape never releases the vertex, index and normal lists it is given
# (their reference counts stay raised), so each mesh is built once per process and the very same
# lists are passed to every client.
@functools.lru_cache(maxsize=None)
def _cylinder_mesh(r: float, half_len: float) -> tuple[list, list, list]:
    n = cylinder_segments(r)
    verts, normals, idx = [], [], []
    for k in range(n):
        a = 2 * math.pi * k / n
        c, s = math.cos(a), math.sin(a)
        verts += [[r * c, r * s, -half_len], [r * c, r * s, half_len]]
        normals += [[c, s, 0.0], [c, s, 0.0]]
    for k in range(n):
        a0, b0, a1, b1 = 2 * k, 2 * k + 1, 2 * ((k + 1) % n), 2 * ((k + 1) % n) + 1
        idx += [a0, a1, b1, a0, b1, b0]
    for z, sign in ((-half_len, -1.0), (half_len, 1.0)):
        first = len(verts)
        for k in range(n):
            a = 2 * math.pi * k / n
            verts.append([r * math.cos(a), r * math.sin(a), z])
            normals.append([0.0, 0.0, sign])
        for k in range(1, n - 1):
            tri = [first, first + k, first + k + 1]
            idx += tri if sign > 0 else [tri[0], tri[2], tri[1]]
    return verts, idx, normals


@functools.lru_cache(maxsize=None)
def _sphere_mesh(r: float) -> tuple[list, list, list]:
    lon, lat = sphere_segments(r)
    verts, normals, idx = [], [], []
    for i in range(lat + 1):
        theta = math.pi * i / lat
        for k in range(lon):
            phi = 2 * math.pi * k / lon
            n = [math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)]
            verts.append([r * x for x in n])
            normals.append(n)
    for i in range(lat):
        for k in range(lon):
            a, b = i * lon + k, i * lon + (k + 1) % lon
            c, d = a + lon, b + lon
            if i > 0:
                idx += [a, c, b]
            if i < lat - 1:
                idx += [b, c, d]
    return verts, idx, normals


class ShapeCache:
    """Visual shape ids of one client, keyed by (geometry, rgba); valid until resetSimulation (which
    the world never calls: shapes are shared by every room built on the client)."""

    def __init__(self, client: Any):
        self.client = client
        self._ids: dict[tuple, int] = {}
        # createMultiBody's link arguments per (spec, colour): they depend on nothing else, and
        # working them out part by part took about 40% of a body's build
        self._links: dict[tuple, dict] = {}

    def links(self, spec: ShapeSpec, colour: str) -> dict:
        """The link keyword arguments of createMultiBody for a body of `spec` in `colour` (computed
        once per client; the same lists are passed to every body of that kind)."""
        key = (spec, colour)
        links = self._links.get(key)
        if links is None:
            links = self._links[key] = link_arguments(spec, colour, self)
        return links

    def visual(self, shape: str, half_extents: Vec3, rgba: Sequence[float]) -> int:
        """Id of a visual shape centred on its frame (cylinder axis along local z)."""
        he = tuple(round(float(h), 5) for h in half_extents)
        key = (shape, he, tuple(round(float(c), 4) for c in rgba))
        vid = self._ids.get(key)
        if vid is None:
            colour = list(key[2])
            if shape == 'box':
                vid = self.client.createVisualShape(pybullet.GEOM_BOX, halfExtents=list(he),
                                                    rgbaColor=colour)
            else:
                verts, idx, normals = (_cylinder_mesh(he[0], he[2]) if shape == 'cylinder'
                                       else _sphere_mesh(he[0]))
                vid = self.client.createVisualShape(pybullet.GEOM_MESH, vertices=verts,
                                                    indices=idx, normals=normals,
                                                    rgbaColor=colour)
            if vid < 0:
                raise RuntimeError(f'pybullet refused visual shape {key}')
            self._ids[key] = vid
        return vid

    def clear(self) -> None:
        """Forget every id (call after client.resetSimulation())."""
        self._ids.clear()
        self._links.clear()


def _quat(rpy: Sequence[float]) -> list[float]:
    """(x, y, z, w) of R = Rz(yaw) Ry(pitch) Rx(roll), as pybullet.getQuaternionFromEuler."""
    cr, sr = math.cos(rpy[0] / 2), math.sin(rpy[0] / 2)
    cp, sp = math.cos(rpy[1] / 2), math.sin(rpy[1] / 2)
    cy, sy = math.cos(rpy[2] / 2), math.sin(rpy[2] / 2)
    return [sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy]


def link_arguments(spec: ShapeSpec, colour: str, cache: ShapeCache) -> dict:
    """createMultiBody's link keyword arguments for `spec` painted with palette colour `colour`: every
    rigid part a fixed link of the base, then (if the spec has moving parts) the articulated joint and
    the moving parts fixed to it (see the module's docstring)."""
    rigid = [p for p in spec.parts if not p.moving]
    moving = [p for p in spec.parts if p.moving]
    visuals, positions, orientations, parents, joint_types, axes = [], [], [], [], [], []

    def add(part: Part, parent: int, offset: Vec3 = (0.0, 0.0, 0.0)) -> None:
        visuals.append(cache.visual(part.shape, part.half_extents, part_rgba(part.colour, colour)))
        positions.append([part.pos[i] - offset[i] for i in range(3)])
        orientations.append(_quat(part.rpy))
        parents.append(parent)
        joint_types.append(pybullet.JOINT_FIXED)
        axes.append([0.0, 0.0, 1.0])

    for part in rigid:
        add(part, 0)
    art = spec.articulation
    if moving:
        if art is None:
            raise ValueError('moving parts without an articulation')
        visuals.append(-1)
        positions.append(list(art.origin))
        orientations.append([0.0, 0.0, 0.0, 1.0])
        parents.append(0)
        joint_types.append(pybullet.JOINT_REVOLUTE if art.kind == 'revolute'
                           else pybullet.JOINT_PRISMATIC)
        axes.append(list(art.axis))
        hinge = len(visuals)  # parent index of the moving parts (link index + 1)
        for part in moving:
            add(part, hinge, art.origin)
    n = len(visuals)
    return dict(linkMasses=[0] * n, linkCollisionShapeIndices=[-1] * n, linkVisualShapeIndices=visuals,
                linkPositions=positions, linkOrientations=orientations,
                linkInertialFramePositions=[[0.0, 0.0, 0.0]] * n,
                linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * n,
                linkParentIndices=parents, linkJointTypes=joint_types, linkJointAxis=axes)


def build_body(client: Any, spec: ShapeSpec, colour: str, position: Sequence[float], yaw: float,
               cache: ShapeCache | None = None) -> int:
    """Create the static, visual-only multibody of `spec` painted with palette colour `colour`.

    position: world position of the object-frame origin (bottom centre); yaw: turn about +z.
    Returns the body's unique id. The body is built closed (joint value 0).
    """
    cache = cache if cache is not None else ShapeCache(client)
    return client.createMultiBody(
        baseMass=0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
        basePosition=list(position), baseOrientation=_quat((0.0, 0.0, yaw)), **cache.links(spec, colour))


def articulation_joint(spec: ShapeSpec) -> int | None:
    """Index of the revolute/prismatic joint in bodies built from `spec` (None if it has none)."""
    if spec.articulation is None or not any(p.moving for p in spec.parts):
        return None
    return sum(1 for p in spec.parts if not p.moving)


def set_articulation(client: Any, body: int, spec: ShapeSpec, fraction: float) -> None:
    """Open the body's door/lid/drawer to `fraction` (0 closed .. 1 fully open)."""
    joint = articulation_joint(spec)
    if joint is None:
        raise ValueError('this shape has no articulation')
    fraction = min(max(float(fraction), 0.0), 1.0)
    client.resetJointState(body, joint, fraction * spec.articulation.open_value)

