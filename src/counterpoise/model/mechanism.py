"""Mechanism model: coordinates, subsystems, frames, points and bodies.

These are the typed, frozen objects the loader produces; nothing downstream sees the raw
TOML. Geometry is 3-D throughout (planar mechanisms simply rotate about ``z``). All
numbers are SI; expressions are kept as trees (:mod:`counterpoise.expr`) so that the same
model evaluates on floats, numpy arrays and CasADi symbols.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

from .expr import Expr, names
from .units import DisplayUnit

GROUND = "ground"
Vector = tuple[Expr, Expr, Expr]


@dataclass(frozen=True)
class Coordinate:
    """A generalized coordinate (joint angle or slider position) and its range."""

    name: str
    subsystem: str
    lower: float
    upper: float
    home: float  # reference configuration for report quantities (default: mid-range)
    unit: DisplayUnit
    description: str = ""
    #: solved from the subsystem's loop closures (counterpoise.model.loops); its range is
    #: its home (it has none of its own) and its home picks the assembly branch
    dependent: bool = False


@dataclass(frozen=True)
class Subsystem:
    """An independently moving part (a leg of a parallel manipulator, a serial arm).

    Balance is required for each subsystem over the whole box of its coordinate ranges.
    """

    name: str
    coordinates: tuple[str, ...]
    description: str = ""


@dataclass(frozen=True)
class Rotation:
    """Rotation by ``angle`` about ``axis`` (a unit vector in the current frame)."""

    axis: Vector
    angle: Expr

    @property
    def expressions(self) -> tuple[Expr, ...]:
        """Every expression the transform depends on (the angle, then the axis)."""
        return (self.angle, *self.axis)


@dataclass(frozen=True)
class Translation:
    """A shift by ``vector`` (expressions, SI lengths)."""

    vector: Vector

    @property
    def expressions(self) -> tuple[Expr, ...]:
        """Every expression the transform depends on (the vector)."""
        return tuple(self.vector)


Transform = Union[Rotation, Translation]


@dataclass(frozen=True)
class Frame:
    """A frame placed in its parent by a chain of elementary transforms.

    pose(frame) = pose(parent) · T_1 · T_2 · … (each transform acts in the frame built so far).
    ``subsystem`` is the subsystem whose coordinates move it (None: fixed to ground).
    ``orientation``: the frame whose axes it keeps (``orientation = "<frame>"`` in a file);
    the loader has already appended the rotations that undo the parent chain's and redo
    that frame's, so the transforms alone give the pose. ``link``: the robot link it is.
    """

    name: str
    parent: str | None
    transforms: tuple[Transform, ...]
    subsystem: str | None
    description: str = ""
    keys: tuple[str, ...] = ()  # file key of each transform (a DH row gives four), for messages
    orientation: str | None = None
    link: bool = False  # a link of a [robot] model

    def names(self) -> frozenset[str]:
        """Every name (coordinate, variable, parameter) its own transforms use (not its parent's)."""
        return frozenset().union(*(names(tree) for t in self.transforms for tree in t.expressions))

    def key(self, index: int) -> str:
        """The file key of transform ``index``."""
        return self.keys[index] if index < len(self.keys) else f"frames.{self.name}.transforms.{index}"


@dataclass(frozen=True)
class Point:
    """A point fixed in a frame."""

    frame: str
    position: Vector


@dataclass(frozen=True)
class Body:
    """A given mass of the mechanism (link, payload share) lumped at its centre of mass."""

    name: str
    mass: Expr
    com: Point
    subsystem: str | None
    description: str = ""
