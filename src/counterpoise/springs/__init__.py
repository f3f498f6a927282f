"""Designed springs: a real helical extension spring for every free-stiffness spring.

- :mod:`.materials`: the material table and the standard wire series (``counterpoise/data``);
- :mod:`.physics`: the formulas of an extension spring with machine hooks (Shigley ch. 10);
- :mod:`.design`: :func:`design` (the lightest spring for a rate and a force range, or the
  reasons there is none), :func:`redesign_at` (the same wound spring against a new
  requirement), :func:`smallest_initial_tension` (what a spring behind a pulley needs of
  its shortest distance), :func:`largest_force` (the force limit of a designed spring) and
  :func:`force_limit` (the same for a spring's design options from the problem file);
- :mod:`.workspace`: after a solve, each free-stiffness spring's requirement over the
  verified workspace and its design, and :func:`.workspace.mechanism_size` (the default
  envelope's scale) (imported on demand: it needs the mechanics).

This package imports only numpy and its data at import time, so any layer may use
:func:`largest_force`. See docs/springs.md.
"""

from __future__ import annotations

from .design import (
    MIN_SAFETY_FACTOR,
    RATE_ROUNDING,
    RATE_TOLERANCE,
    SLACK_MARGIN,
    Envelope,
    Requirement,
    SpringDesign,
    design,
    force_limit,
    largest_force,
    redesign_at,
    smallest_initial_tension,
)
from .materials import DEFAULT_MATERIAL, Material, material, materials, wire_diameters, wire_series

__all__ = [
    "DEFAULT_MATERIAL",
    "MIN_SAFETY_FACTOR",
    "RATE_ROUNDING",
    "RATE_TOLERANCE",
    "SLACK_MARGIN",
    "Envelope",
    "Material",
    "Requirement",
    "SpringDesign",
    "design",
    "force_limit",
    "largest_force",
    "redesign_at",
    "smallest_initial_tension",
    "material",
    "materials",
    "wire_diameters",
    "wire_series",
]
