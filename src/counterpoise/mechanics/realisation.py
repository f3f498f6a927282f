"""How a spring of the model is built: the geometry of its realisation (all SI).

Two mounts exist (``[springs.<name>] mount``):

* **pulley** (the zero-free-length spring). The pulley sits at the spring's ``from`` point
  (its radius neglected); a cable runs from the pulley to the ``to`` point, distance
  d = |from − to|, and behind the pulley on to the spring's moving end. The spring body lies
  behind the pulley, its fixed end anchored so that its length is L = d + L0 − F0/k; it then
  pulls F = k·d. The cable's length C (from the spring's end over the pulley to the link
  point) is constant; the spring's end reaches the pulley when d = C, so the shortest cable
  that serves the whole workspace is C = d_max. The fixed end then sits C + L0 − F0/k behind
  the pulley, along the cable's run.
* **direct**: the spring between its ends through a cable of length c: L = d − c,
  F = F0 + k (L − L0).

A designed spring whose free length and initial tension are not known yet (free stiffness,
no catalogue part) has only its rate: its force k·d is known, its own length is not (NaN).

:func:`realise` is the one place these figures are computed, :func:`realise_spring` the
one place a model spring is evaluated for it (ends, pulley, rate, a direct mount's data);
the build sheet (:mod:`counterpoise.report.build`) and a drawing may both use them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..model.elements import ZeroFreeLengthSpring
    from .energy import Mechanics

Point3 = tuple[float, float, float]

PULLEY = "pulley"
DIRECT = "direct"
NAN = float("nan")


@dataclass(frozen=True)
class Realisation:
    """One spring as built (SI: m, N, N/m); lengths of the spring body NaN when unknown."""

    mount: str  # PULLEY or DIRECT
    rate: float
    free_length: float
    initial_tension: float
    distance_home: float  # |from − to| at home
    distance_min: float  # over the workspace
    distance_max: float
    cable: float  # pulley: from the spring's end over the pulley to the link point; direct: the given cable
    length_home: float  # of the spring body
    length_min: float
    length_max: float
    force_home: float
    force_min: float
    force_max: float
    #: pulley: distance from the pulley to the spring's fixed end along the cable's run
    #: behind it (C + L0 − F0/k); direct: NaN
    anchor_distance: float
    #: world positions of the ``from`` and ``to`` points at the configuration evaluated
    #: (:func:`realise_spring`; empty from :func:`realise` alone)
    ends: tuple[Point3, ...] = ()

    @property
    def pulley(self) -> Point3 | None:
        """A pulley mount's pulley (world, at the ``from`` point); None for a direct mount."""
        return self.ends[0] if self.mount == PULLEY and self.ends else None

    @property
    def cable_behind_home(self) -> float:
        """Pulley: the cable between the pulley and the spring's end at home (C − d)."""
        return self.cable - self.distance_home if self.mount == PULLEY else NAN


def realise(
    rate: float,
    distance_home: float,
    distance_min: float,
    distance_max: float,
    free_length: float = NAN,
    initial_tension: float = NAN,
    cable: float | None = None,
) -> Realisation:
    """The realisation of a spring of ``rate`` k whose ends are ``distance_*`` apart.

    ``cable`` None: a pulley mount (the cable is then d_max, see the module docstring);
    a number: a direct mount through that cable. Home is a configuration of the workspace:
    the extremes are widened to hold it (a sample of configurations may miss it).
    """
    k, l0, f0 = rate, free_length, initial_tension
    distance_min, distance_max = min(distance_min, distance_home), max(distance_max, distance_home)
    if cable is None:
        offset = l0 - f0 / k if k > 0 else NAN  # L = d + L0 − F0/k
        lengths = (distance_home + offset, distance_min + offset, distance_max + offset)
        forces = (k * distance_home, k * distance_min, k * distance_max)
        return Realisation(PULLEY, k, l0, f0, distance_home, distance_min, distance_max, distance_max, *lengths, *forces, distance_max + offset)
    lengths = (distance_home - cable, distance_min - cable, distance_max - cable)
    force_home, force_min, force_max = (f0 + k * (length - l0) for length in lengths)
    return Realisation(DIRECT, k, l0, f0, distance_home, distance_min, distance_max, cable, *lengths, force_home, force_min, force_max, NAN)


def realise_spring(
    mech: "Mechanics",
    spring: "ZeroFreeLengthSpring",
    distances: tuple[float, float] | None = None,
    free_length: float = NAN,
    initial_tension: float = NAN,
) -> Realisation:
    """The realisation of ``spring`` at the configuration of ``mech`` (its home, for a build
    sheet): the rate and ends evaluated there, ``distances`` the (least, largest) distance
    of its ends over the workspace (None: this configuration's only). ``free_length`` and
    ``initial_tension``: a pulley mount's part (NaN: not chosen yet); a direct mount takes
    its own from the model."""
    rate = float(mech.value(spring.stiffness))
    ends = tuple(tuple(float(c) for c in mech.position(p)) for p in spring.ends)
    d = math.dist(ends[0], ends[1])
    lo, hi = distances if distances is not None else (d, d)
    cable = None
    if spring.direct is not None:
        free_length = float(mech.value(spring.direct.free_length))
        initial_tension = float(mech.value(spring.direct.initial_tension))
        cable = float(mech.value(spring.direct.cable))
    return replace(realise(rate, d, lo, hi, free_length, initial_tension, cable), ends=ends)  # type: ignore[arg-type]  # a point is three floats


def finite(value: float) -> float | None:
    """``value``, or None when it is NaN (an unknown figure: an empty cell)."""
    return None if math.isnan(value) else value
