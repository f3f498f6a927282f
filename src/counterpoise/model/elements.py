"""Balancing elements a design may add: counter-masses and zero-free-length springs."""

from __future__ import annotations

from dataclasses import dataclass

from .expr import Expr
from .mechanism import Point


@dataclass(frozen=True)
class CounterMass:
    """An added point mass on a link.

    Its added inertia is ``mass * d**2`` with ``d`` its distance from the axis of the joint
    it rides on. ``joint`` locates that joint's rotation as (frame name, index of the
    rotation in the frame's transforms); the loader picks the innermost coordinate-driven
    rotation of the frame chain unless the file names the joint's coordinate. ``None``
    means no rotation moves it (added inertia 0).
    """

    name: str
    mass: Expr
    position: Point
    joint: tuple[str, int] | None
    subsystem: str | None
    description: str = ""


@dataclass(frozen=True)
class DirectMount:
    """A real spring attached directly (no pulley), through a cable of length ``cable``.

    With d the distance between the ends and x = d − cable − free_length its extension,
    it pulls with F = initial_tension + k·x (energy F0·x + ½ k x²), in tension only, while
    free_length ≤ d − cable ≤ max_length (None: no upper limit).
    """

    free_length: Expr
    initial_tension: Expr
    cable: Expr
    max_length: Expr | None = None


@dataclass(frozen=True)
class SpringDesignOptions:
    """How a free-stiffness spring is designed as a helical extension spring after the
    solve (:mod:`counterpoise.springs`; docs/springs.md). Lengths in m; an envelope limit
    left None takes its default from the mechanism's size (max_length, max_outer_diameter)
    or is no limit (max_body_length)."""

    material: str = "music_wire"
    max_outer_diameter: float | None = None  # None: the default of the mechanism's size (springs.workspace)
    max_body_length: float | None = None
    max_length: float | None = None  # the largest working length, hooks included (pulley mount)
    rate_tolerance: float = 0.10  # ± share of the rate written into the spring's spec
    #: on every allowable stress at the largest working force of the rate's upper tolerance
    #: (springs.design.MIN_SAFETY_FACTOR)
    min_safety_factor: float = 1.2
    #: behind a pulley: F0 ≤ k (d_min − slack_margin), m (springs.design.SLACK_MARGIN)
    slack_margin: float = 0.003


@dataclass(frozen=True)
class ZeroFreeLengthSpring:
    """A spring of zero free length between two points: energy ½ k |a − b|².

    Realised in practice by a spring behind a string over a pulley. ``slot`` names the
    catalogue slot the spring takes its part from (its stiffness is then the slot's rate
    symbol), or is None for a spring whose stiffness the file gives.
    """

    name: str
    stiffness: Expr
    ends: tuple[Point, Point]
    subsystem: str | None
    description: str = ""
    slot: str | None = None
    direct: DirectMount | None = None  # None: zero free length (behind a string over a pulley)
    #: free-stiffness springs (no slot): how their helical spring is designed after the solve
    design: SpringDesignOptions = SpringDesignOptions()
