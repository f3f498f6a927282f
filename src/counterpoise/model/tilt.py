"""A tilting base: gravity's direction over continuous ranges of base tilts.

A holder on a tilting operating table, an exoskeleton whose wearer leans, a mobile arm on a
slope: the mechanism's base turns, and gravity, seen from the base, turns the other way.
``[gravity] tilt`` gives the tilts (an axis of the base and a range of angles each); the
balance must then hold for every coordinate in its range *and* every tilt in its range.
How that stays exact with finitely many conditions: :func:`tilt_nodes`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: the largest tilt range about one axis (a full turn)
FULL_TURN = 2 * math.pi
#: the most balance scenarios a problem may have once its tilts are expanded (its scenarios
#: times 3ⁿ tilt nodes for n tilt ranges, :func:`tilt_nodes`): building the balance
#: conditions grows faster than linearly with them (27 scenarios of a two-link arm: ~30 s,
#: 81: ~2 min; docs/tilt.md), and 3ⁿ explodes (10 axes: 59,049). A file beyond it is
#: an input error saying how many it asks for and what brings it down.
MAX_SCENARIOS = 81


@dataclass(frozen=True)
class Tilt:
    """A continuous range of base tilts about one axis of the base.

    A tilt φ about ``axis`` turns the base (and everything fixed to it) by φ about that axis,
    right-hand rule; in the base's coordinates gravity turns by −φ. Several tilts compose
    in the order given: the base is turned by R₁(φ₁) R₂(φ₂) ..., so gravity in base
    coordinates is (R₁(φ₁) R₂(φ₂) ...)ᵀ g.
    """

    axis: tuple[float, float, float]  # unit vector, base coordinates
    lower: float  # rad
    upper: float  # rad
    description: str = ""


def tilted_directions(direction: tuple[float, float, float], tilts: tuple[Tilt, ...], angles: np.ndarray) -> np.ndarray:
    """Gravity's directions in base coordinates, (n, 3), for the base tilted by each row of
    ``angles`` (n, one column per tilt; see :class:`Tilt`): v ← R(axisₖ, φₖ)ᵀ v for k = 1, 2, ...,
    since gᵀ(R₁ R₂ ...) = (... R₂ᵀ R₁ᵀ g)ᵀ; Rᵀ by Rodrigues' formula with −φ."""
    angles = np.atleast_2d(np.asarray(angles, dtype=float))
    v = np.tile(np.asarray(direction, dtype=float), (angles.shape[0], 1))
    for k, tilt in enumerate(tilts):
        axis = np.asarray(tilt.axis, dtype=float)
        c, s = np.cos(angles[:, k])[:, None], np.sin(angles[:, k])[:, None]
        v = v * c - np.cross(axis, v) * s + axis * (v @ axis)[:, None] * (1 - c)
    return v


def tilted(direction: tuple[float, float, float], tilts: tuple[Tilt, ...], angles: tuple[float, ...]) -> tuple[float, float, float]:
    """Gravity's direction in base coordinates when the base is tilted by ``angles`` (see :class:`Tilt`)."""
    x, y, z = (float(c) for c in tilted_directions(direction, tilts, np.array([angles]))[0])
    return (x, y, z)


def tilt_nodes(tilt: Tilt) -> tuple[float, ...]:
    """The tilt angles a design is balanced at: three distinct angles of the range (its ends
    and middle; a full turn: three angles 120° apart), one for a single angle.

    Why three are enough: gravity enters the potential energy linearly, g·p, and a tilt φ
    enters g through one rotation, i.e. through cos φ and sin φ only. So the residual is a
    trigonometric polynomial of degree 1 in each tilt angle, a·cos φ + b·sin φ + c, and
    three distinct angles (mod 360°) determine it: zero at three, zero at every tilt. With
    several tilts, the product of the nodes (3ⁿ) does the same for the tensor product.
    """
    if tilt.upper == tilt.lower:
        return (tilt.lower,)
    if tilt.upper - tilt.lower >= FULL_TURN - 1e-12:
        return tuple(tilt.lower + k * FULL_TURN / 3 for k in range(3))
    return (tilt.lower, 0.5 * (tilt.lower + tilt.upper), tilt.upper)


def angle_name(angle: float) -> str:
    """'p15', 'm7p5', '0': a tilt angle in degrees as part of an identifier."""
    text = f"{math.degrees(angle):.6g}".replace("-", "m").replace(".", "p").replace("+", "")
    return text if text.startswith("m") or text == "0" else f"p{text}"


def tilt_text(tilts: tuple[Tilt, ...], angles: tuple[float, ...]) -> str:
    """'base tilted 15° about [1, 0, 0], -15° about [0, 1, 0]'."""
    parts = [f"{math.degrees(a):.6g}° about [{', '.join(f'{c:.6g}' for c in t.axis)}]" for t, a in zip(tilts, angles)]
    return "base tilted " + ", ".join(parts)


