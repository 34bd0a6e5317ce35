"""The records of a live world: an object instance and its state, the ground truth read from it, and
the agent's pose on the grid (plain dataclasses; `scene.World` holds and changes them)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

from .camera import START_HORIZON
from ..catalog import ObjectType
from .geometry import ShapeSpec
from .rooms import GRID

COLD, ROOM, HOT = 'cold', 'room', 'hot'     # an object's temperature


@dataclass
class WorldObject:
    """One object instance and its state (fixtures and small objects alike)."""

    object_id: str
    otype: ObjectType
    colour: str
    spec: ShapeSpec
    body: int
    position: tuple[float, float, float]
    yaw: float
    fixture: bool                                # part of the floor plan, never moves
    parent: Optional[str] = None                 # receptacle it is in/on
    surface: int = 0                             # index of the parent's surface it rests on
    local: tuple[float, float, float] = (0.0, 0.0, 0.0)   # position in the parent's frame
    local_yaw: float = 0.0
    contents: list[str] = field(default_factory=list)
    controls: Optional[str] = None
    is_open: bool = False
    is_on: bool = False
    is_dirty: bool = False
    is_sliced: bool = False
    temperature: str = ROOM
    held: bool = False
    sliced_from: Optional[str] = None            # a slice remembers the object it was cut from

    @property
    def type_name(self) -> str:
        return self.otype.name


@dataclass(frozen=True)
class ObjectState:
    """Ground truth about one object, as the oracle and the task checker read it."""

    object_id: str
    type_name: str
    noun: str
    position: tuple[float, float, float]
    parent: Optional[str]
    parent_type: Optional[str]
    colour: str
    material: str
    pickupable: bool
    receptacle: bool
    is_open: bool
    is_on: bool
    is_dirty: bool
    is_sliced: bool
    temperature: str
    held: bool
    contents: tuple[str, ...]


@dataclass
class AgentPose:
    """The agent on the 0.25 m grid: point (i, j), yaw in {0, 90, 180, 270}, camera pitch."""

    i: int
    j: int
    rotation: int = 0
    horizon: float = START_HORIZON

    @property
    def x(self) -> float:
        return self.i * GRID

    @property
    def y(self) -> float:
        return self.j * GRID

    def forward_cell(self) -> tuple[int, int]:
        di, dj = {0: (1, 0), 90: (0, 1), 180: (-1, 0), 270: (0, -1)}[self.rotation % 360]
        return self.i + di, self.j + dj
