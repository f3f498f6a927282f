"""A payload range: a point mass whose value is only known to lie in a range.

A payload (a surgical tool, an instrument) is carried at a point of a frame. The problem
file gives its mass as a range ``[lower, upper]`` and a ``nominal`` value in it (default
the lower end). The loader turns it into an ordinary body whose mass is a literal
parameter named after the payload (its value is the nominal mass), so every layer below
sees a normal problem; :mod:`counterpoise.payload` makes one scenario per sampled mass.
"""

from __future__ import annotations

from dataclasses import dataclass

from .mechanism import Point
from .units import DisplayUnit

#: ``objective = "max_payload_range"``: find the widest payload range a design can balance.
MAX_PAYLOAD_RANGE = "max_payload_range"
#: the default goal: minimise added mass and inertia (the ``[objective]`` table).
MIN_ADDED = "min_added"


@dataclass(frozen=True)
class Payload:
    """A payload mass range at a point (SI); the body and parameter share its name."""

    name: str
    point: Point
    lower: float  # kg
    upper: float  # kg
    nominal: float  # kg, lower <= nominal <= upper
    unit: DisplayUnit  # display unit of the range
    subsystem: str | None
    description: str = ""

    def label(self, mass: float) -> str:
        """'31 g': a mass in the payload's display unit (scenario names, messages)."""
        return f"{self.unit.from_si(mass):.6g} {self.unit.label}"
