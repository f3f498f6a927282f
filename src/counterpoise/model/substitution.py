"""Mass moment substitution: a body replaced, for gravity, by point masses at chosen points.

Gravity sees a body only through its mass m and first moment m c. Point masses μ_j at
points s_j of the body (given in the body's frame) stand for it when

    Σ_j μ_j = m,        Σ_j μ_j s_j = m c                         (A μ = b, 4 equations)

(docs/derivations.md, identity I3). :func:`substitution_matrix` solves this once for the
geometry: μ = P b with P the pseudo-inverse of A, which is the exact solution when A is
square and invertible, the least-norm one when the points leave freedom, and wrong when b
is outside the range of A (the centre of mass is off the line of two points, off the plane
of three): :func:`substitution_gap` measures that. The μ_j are then handed to the
neighbouring bodies that hold those points (the legs of a parallel mechanism share its
platform this way).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .expr import Expr
from .mechanism import Point


@dataclass(frozen=True)
class SubstitutedMass:
    """μ_j: a point mass (an expression of the body's mass and centre of mass) at ``point``."""

    name: str
    mass: Expr
    point: Point  # in the receiving frame
    at: tuple[float, float, float]  # the same point in the substituted body's frame, SI


@dataclass(frozen=True)
class Substitution:
    """A body replaced by point masses (``[substitutions.<body>]``)."""

    body: str
    frame: str  # the substituted body's frame
    masses: tuple[SubstitutedMass, ...]
    description: str = ""


def _scaled_system(points: np.ndarray) -> tuple[np.ndarray, float]:
    """A (4 × n) with the position rows divided by a length L (conditioning), and L."""
    length = float(np.abs(points).max(initial=0.0)) or 1.0
    a = np.vstack([np.ones(len(points)), (points / length).T])
    return a, length


def substitution_matrix(points: np.ndarray) -> np.ndarray:
    """P (n × 4) with μ = P [m, m c_x, m c_y, m c_z] for points ``points`` (n × 3, SI)."""
    a, length = _scaled_system(np.asarray(points, dtype=float))
    p = np.linalg.pinv(a, rcond=1e-12)
    return p @ np.diag([1.0, 1.0 / length, 1.0 / length, 1.0 / length])


def substitution_gap(points: np.ndarray, com: np.ndarray) -> float:
    """How far (relative) the centre of mass ``com`` is from being substitutable: 0 when
    A μ = [1, c] has an exact solution; the residual of the least-squares one otherwise."""
    a, length = _scaled_system(np.asarray(points, dtype=float))
    b = np.concatenate([[1.0], np.asarray(com, dtype=float) / length])
    mu = np.linalg.pinv(a, rcond=1e-12) @ b
    return float(np.linalg.norm(a @ mu - b) / np.linalg.norm(b))
