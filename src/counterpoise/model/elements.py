"""Balancing elements a design may add: counter-masses and zero-free-length springs."""

from __future__ import annotations

import math
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


#: the default clearance (m) between a pulley and the link point (beyond the pulley's and
#: the pin's radii), and between the spring's end and the pulley at the largest extension
PULLEY_CLEARANCE = 0.003
#: the default extension (m) a spring keeps beyond its free length everywhere in the workspace
SLACK_MARGIN = 0.003
#: the least wrap (rad) of a cable on a pulley or pin of radius > 0, and the least gap to a full turn
MIN_WRAP = math.radians(5.0)


@dataclass(frozen=True)
class Pulley:
    """The pulley of a zero-free-length spring (``[springs.<name>] pulley = {...}``,
    docs/build.md#pulleys): at the spring's ``from`` point, turning about ``axis`` (in the
    ``from`` frame), radius ``radius`` (0: a point, an eyelet or a small pulley whose radius
    is neglected).

    The cable comes from the spring, which lies behind the pulley along ``lead`` (a
    direction in the ``from`` frame; None: towards the link point at home), wraps over the
    pulley in the sense ``sense`` about the axis (+1 counter-clockwise, −1 clockwise) and
    leaves it on a tangent to the link point (``to``). With ``pin``, the cable's end is
    instead wrapped onto a pin of the same radius at ``to`` (an open belt): its straight run
    is then exactly as long as the distance between the axes, and when the pin's frame keeps
    the pulley frame's orientation the cable length is that distance plus a constant, a
    zero-free-length spring at any radius. Otherwise a radius > 0 makes the cable length a
    tangent plus a wrapped arc, and the spring pulls k·(ℓ − ℓ*) with ℓ* the design variable
    ``zero_length`` (where the anchor is set; :mod:`counterpoise.mechanics.cable`).
    """

    radius: float = 0.0
    clearance: float = PULLEY_CLEARANCE
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    sense: int = 1
    pin: bool = False
    lead: tuple[float, float, float] | None = None
    #: a pin's fixing direction (where the cable's end is fixed on it) in the ``to`` frame;
    #: None: chosen so that the cable wraps half a turn on the pin at home
    fixing: tuple[float, float, float] | None = None
    #: radius > 0 without a pin: the variable ℓ* (m), the cable length at which the pull is zero
    zero_length: str | None = None

    @property
    def exact(self) -> bool:
        """The spring pulls k·d exactly: a point pulley, or a pin of the same radius."""
        return self.radius == 0.0 or self.pin


@dataclass(frozen=True)
class BuiltSpring:
    """A spring as built (the as-built model, :mod:`counterpoise.verify.asbuilt`): rate,
    initial tension and free length of the part that is made, and ``offset`` such that its
    extension is x = path + offset (path: the cable's length from the pulley's entry
    point to the link point, or the distance between the ends for a point pulley or a direct
    mount). It pulls F0 + k·x while x ≥ 0; below, its coils close and the cable goes slack
    (no force). Expressions: numbers, or parameters that take a value per scenario."""

    rate: Expr
    initial_tension: Expr
    free_length: Expr
    offset: Expr


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
    #: a pulley mount's pulley (None for a direct mount)
    pulley: Pulley | None = Pulley()
    #: the extension (m) the spring keeps beyond its free length everywhere in the workspace
    slack_margin: float = SLACK_MARGIN
    #: the as-built model: the real spring with slack (None: the design model)
    built: BuiltSpring | None = None

    @property
    def exact(self) -> bool:
        """Its energy is ½ k |a − b|² (a trigonometric polynomial for rigid bodies): a pulley
        mount that pulls k·d, in the design model."""
        return self.direct is None and self.built is None and (self.pulley is None or self.pulley.exact)
