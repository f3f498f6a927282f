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


#: coordinate-ascent sweeps over the tilt angles at most (each sweep sets every free angle to
#: its exact best given the others; they stop once no row gains more than TILT_ASCENT_TOLERANCE)
TILT_ASCENT_SWEEPS = 50
#: a sweep that raises no row's |f| by more than this share of its value ends the ascent
TILT_ASCENT_TOLERANCE = 1e-15
#: points of the search grid over the free tilts at most (its ends included: every vertex of
#: the box is on it); per tilt the largest count whose power stays within it, at least 2
TILT_SEARCH_POINTS = 32
#: a row whose |f| cannot exceed this share of the size of its terms (|c| + |w| |g|, the
#: largest over the rows) is rounding noise: it keeps its grid value and is not climbed
TILT_ROUNDING = 1e-12


def _basis(theta: np.ndarray) -> np.ndarray:
    """(1, sin θ, 1 − cos θ) of angles θ from a range's centre, (..., 3)."""
    theta = np.asarray(theta, dtype=float)
    return np.stack([np.ones_like(theta), np.sin(theta), 1 - np.cos(theta)], axis=-1)


def _kron(matrices: list[np.ndarray]) -> np.ndarray:
    out = np.ones((1, 1))
    for m in matrices:
        out = np.kron(out, m)
    return out


def _along(coefficients: np.ndarray, theta: np.ndarray, i: int) -> np.ndarray:
    """Per row, f along free tilt i with the others at ``theta``: the coefficients (R, 3, ..., 3)
    contracted with every other tilt's e(θ), (R, 3) in the basis (1, sin θᵢ, 1 − cos θᵢ)."""
    m = coefficients.ndim - 1
    letters = "abcdefghijklmnopqstuvwxyz"[:m]
    operands: list[np.ndarray] = [coefficients]
    scripts = ["r" + letters]
    for j in range(m):
        if j != i:
            operands.append(_basis(theta[:, j]))
            scripts.append("r" + letters[j])
    return np.einsum(",".join(scripts) + "->r" + letters[i], *operands)


def _best_along(lower: float, upper: float, alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row, the angle of [lower, upper] where |α cos θ + β sin θ + γ| is largest, and that
    value (signed): the ends of the range, or θ* = atan2(β, α) and θ* + π (where the
    derivative −α sin θ + β cos θ vanishes) when they lie in it (modulo 360°)."""
    star = np.arctan2(beta, alpha)
    candidates = [np.full_like(alpha, lower), np.full_like(alpha, upper)]
    for c in (star, star + math.pi):
        inside = lower + np.mod(c - lower, FULL_TURN)  # the same angle, at or above the lower end
        candidates.append(np.where(inside <= upper, inside, lower))
    angles = np.stack(candidates)
    values = alpha * np.cos(angles) + beta * np.sin(angles) + gamma
    best = np.argmax(np.where(np.isnan(values), -np.inf, np.abs(values)), axis=0)
    rows = np.arange(alpha.size)
    return angles[best, rows], values[best, rows]


def _climbed(coefficients: np.ndarray, on_grid: np.ndarray, half: list[float], per: int, floor: float) -> np.ndarray:
    """The rows that may hold the largest |f| over the box, given each row's largest |f| on
    the search grid (``per`` points per free tilt, ranges ± ``half``; ``coefficients`` (N, 3ᵐ)):
    those whose grid value plus the most f can rise between grid points reaches the largest
    grid value, and ``floor`` (rounding noise below it is not climbed).

    Along one angle f is A cos(θ − θ*) + γ; between two grid points δ apart its |f| exceeds
    the larger end's by at most A (1 − cos(δ/2)) (θ* is within δ/2 of one end). Snapping one
    angle after the other to the grid: |f(θ)| ≤ (grid maximum) + Σₖ Aₖ (1 − cos(δₖ/2)), Aₖ
    the largest amplitude along tilt k over the box: √(b₁² + b₂²), bⱼ = Σ over the
    coefficients with index j on axis k of |Dₐ| × the largest |e| of the others' indices."""
    m = len(half)
    largest = [np.array([1.0, math.sin(min(h, 0.5 * math.pi)), 1 - math.cos(min(h, math.pi))]) for h in half]
    size = np.abs(coefficients)
    rise = np.zeros(coefficients.shape[0])
    for k in range(m):
        weights = _kron([np.eye(3) if j == k else largest[j][:, None] for j in range(m)])  # (3ᵐ, 3): index j on axis k kept
        b = size @ weights
        rise += np.hypot(b[:, 1], b[:, 2]) * (1 - math.cos(half[k] / (per - 1)))  # δ/2 = (2h/(per − 1))/2
    with np.errstate(invalid="ignore"):
        top = max(float(np.nanmax(on_grid)) if np.isfinite(on_grid).any() else np.inf, floor)
        keep = ~(on_grid + rise < top)  # NaN or infinite: kept
    return np.flatnonzero(keep)


def tilt_extremes(
    acceleration: float, direction: tuple[float, float, float], tilts: tuple[Tilt, ...], constant: np.ndarray, slope: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The largest |fᵢ(φ)| = |cᵢ + wᵢ · g(φ)| over the tilt box, g(φ) gravity (``acceleration``
    times :func:`tilted_directions`), for rows i: ``constant`` c (N,), ``slope`` w (N, 3).
    Returns, per row, f at the tilt found (signed, (N,)) and that tilt ((N, n) angles).

    A quantity linear in gravity (a residual, a gravity torque) has this form, and in each
    tilt angle it is a trigonometric polynomial of degree 1 (a tilt enters gravity through one
    rotation): with θₖ = φₖ − (the range's centre), f = Σₐ Dₐ Πₖ eₐₖ(θₖ), e = (1, sin θ, 1 − cos θ),
    its 3ᵐ coefficients D (m free tilts) solved from its values on the nodes of
    :func:`tilt_nodes` (the docs' argument: those values determine f). Then:

    1. f on a grid over the free tilts that includes the ends of every range (so every vertex
       of the box; :data:`TILT_SEARCH_POINTS` points), each row's best grid point;
    2. the rows that can beat the best grid value anywhere between grid points
       (:func:`_climbed`, a bound) climb, from their best grid point and their best vertex, by
       coordinate ascent: each free angle in turn set to its exact best given the others —
       along one angle f is α cos θ + β sin θ + γ, whose largest |f| on the range is at an end
       or where the derivative vanishes (:func:`_best_along`, closed form) — until a sweep
       gains nothing. It ends where no single angle can raise |f|: a vertex, an edge's extreme
       or a face's (each free angle at an end of its range or stationary).

    With one tilt the largest over the rows is the exact maximum; with several, the largest
    of these coordinate-wise maxima. A row that does not climb keeps its grid value (a lower
    bound of its own maximum, below the largest)."""
    constant = np.asarray(constant, dtype=float).reshape(-1)
    slope = np.asarray(slope, dtype=float).reshape(-1, 3)
    n_rows, n = constant.size, len(tilts)
    free = [k for k, t in enumerate(tilts) if t.upper > t.lower]
    centres = np.array([0.5 * (t.lower + t.upper) for t in tilts])
    nodes = [np.array(tilt_nodes(t)) for t in tilts]
    grid = np.array(np.meshgrid(*nodes, indexing="ij")).reshape(n, -1).T  # the node grid, (n_nodes, n)
    gravities = acceleration * tilted_directions(direction, tilts, grid)
    with np.errstate(invalid="ignore", over="ignore"):
        at_nodes = constant[:, None] + slope @ gravities.T
    # values on the nodes -> coefficients of Πₖ (1, sin θₖ, 1 − cos θₖ) (a fixed tilt: its one value)
    to_coefficients = _kron([np.linalg.inv(_basis(nodes[k] - centres[k])).T if k in free else np.ones((1, 1)) for k in range(n)])
    coefficients = at_nodes @ to_coefficients  # (N, 3ᵐ)
    angles = np.tile(centres, (n_rows, 1))
    if not free or n_rows == 0:
        return coefficients.reshape(n_rows), angles
    m = len(free)
    per = max(2, int(math.floor(TILT_SEARCH_POINTS ** (1.0 / m) + 1e-9)))
    axes_theta = [np.linspace(tilts[k].lower, tilts[k].upper, per) - centres[k] for k in free]
    flat = coefficients @ _kron([_basis(t).T for t in axes_theta])  # f on the search grid, (N, perᵐ)
    with np.errstate(invalid="ignore"):
        magnitude = np.where(np.isnan(flat), -np.inf, np.abs(flat))
    on_grid = np.argmax(magnitude, axis=1)
    all_rows = np.arange(n_rows)
    best_value = flat[all_rows, on_grid]
    best_theta = np.column_stack([axes_theta[i][idx] for i, idx in enumerate(np.unravel_index(on_grid, (per,) * m))])
    with np.errstate(invalid="ignore"):
        terms = np.abs(constant) + abs(acceleration) * np.linalg.norm(slope, axis=1)
        floor = TILT_ROUNDING * float(np.nanmax(terms)) if np.isfinite(terms).any() else 0.0
    rows = _climbed(coefficients, magnitude[all_rows, on_grid], [(tilts[k].upper - tilts[k].lower) / 2 for k in free], per, floor)
    if rows.size:
        grid_index = on_grid[rows]
        corner_index = np.ravel_multi_index(np.array(np.meshgrid(*[[0, per - 1]] * m, indexing="ij")).reshape(m, -1), (per,) * m)
        corner = corner_index[np.argmax(magnitude[rows][:, corner_index], axis=1)]
        mine = coefficients[rows].reshape((rows.size,) + (3,) * m)
        for start in (grid_index, corner):
            theta = np.column_stack([axes_theta[i][idx] for i, idx in enumerate(np.unravel_index(start, (per,) * m))])
            current = flat[rows, start]
            for _ in range(TILT_ASCENT_SWEEPS):
                before = np.abs(current)
                for i, k in enumerate(free):
                    a0, a1, a2 = _along(mine, theta, i).T  # along angle i: D contracted with the others' e(θ)
                    # a0 + a1 sin θ + a2 (1 − cos θ) = −a2 cos θ + a1 sin θ + (a0 + a2)
                    t, f = _best_along(tilts[k].lower - centres[k], tilts[k].upper - centres[k], -a2, a1, a0 + a2)
                    better = np.abs(f) > np.abs(current)
                    theta[better, i] = t[better]
                    current = np.where(better, f, current)
                if not np.any(np.abs(current) > before * (1 + TILT_ASCENT_TOLERANCE)):
                    break
            take = ~(np.abs(best_value[rows]) >= np.abs(current))  # NaN: take
            best_value[rows[take]] = current[take]
            best_theta[rows[take]] = theta[take]
    for i, k in enumerate(free):
        angles[:, k] = centres[k] + best_theta[:, i]
    return best_value, angles


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


