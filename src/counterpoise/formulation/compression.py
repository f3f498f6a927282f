"""Balance conditions: from "zero residual everywhere" to a few exact equalities.

For zero-free-length springs and rigid bodies, V(q) is a trigonometric polynomial in the
joint angles (a polynomial in slider positions), so the residual r(q; x) = ∂V/∂q of a
subsystem lies, for every design x, in one fixed finite-dimensional function space. On N
sampled configurations the stacked residual R(x) ∈ R^(N·n_q) therefore stays in a fixed
subspace; its dimension is the number of independent balance conditions.

:func:`compress` finds that subspace from R at random designs (SVD), picks as many sampled
rows as its rank (greedy pivoting), and returns a small matrix T such that
c(x) = T · R_S(x) are the coordinates of R(x) in an orthonormal basis: c(x) = 0 exactly
when R(x) = 0. Handing IPOPT c instead of the raw sampled equalities keeps the NLP square
or under-determined (raw equalities outnumber the design variables and IPOPT stops with
Not_Enough_Degrees_Of_Freedom). Whether the samples were enough is checked independently,
and densely, by :mod:`counterpoise.verify`.

The rank tolerance is relative to the largest singular value, so the rows handed in must
be of comparable size: :mod:`.conditions` scales each coordinate's rows by its largest
sampled residual first (a 24-link chain's base joint carries residuals ten orders of
magnitude above its tip's, whose conditions would otherwise fall under the tolerance).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import SolverError

#: Singular values below RANK_TOLERANCE × the largest are treated as zero.
RANK_TOLERANCE = 1e-10
#: ... and so are those whose RMS entry is below NOISE_TOLERANCE × the largest energy term
#: (Σ |energy of each element| over the samples): a residual that is zero in exact
#: arithmetic (a spring whose length cannot change, an axis exactly perpendicular to
#: gravity) still carries rounding noise of about 1e-16 of the terms that cancel, and
#: that noise must not count as a condition.
NOISE_TOLERANCE = 1e-12


@dataclass(frozen=True)
class Compression:
    """c(x) = matrix @ R(x)[rows] spans the same conditions as R(x) = 0."""

    rows: np.ndarray  # indices of the sampled residual entries kept
    matrix: np.ndarray  # (rank × rank)
    singular_values: np.ndarray

    @property
    def rank(self) -> int:
        return len(self.rows)


def numerical_rank(singular_values: np.ndarray, tolerance: float | None = None, floor: float = 0.0) -> int:
    """Number of singular values above ``tolerance`` (default RANK_TOLERANCE) × the largest
    and above the absolute ``floor``."""
    tol = RANK_TOLERANCE if tolerance is None else tolerance
    if singular_values.size == 0 or singular_values[0] == 0:
        return 0
    return int(np.sum((singular_values > tol * singular_values[0]) & (singular_values > floor)))


def pivot_rows(basis: np.ndarray) -> np.ndarray:
    """Greedy choice of ``rank`` well-conditioned rows of an orthonormal ``basis`` (QR with pivoting on basisᵀ)."""
    work = basis.copy()
    n, r = work.shape
    chosen: list[int] = []
    for _ in range(r):
        norms = np.einsum("ij,ij->i", work, work)
        norms[chosen] = -1.0
        i = int(np.argmax(norms))
        chosen.append(i)
        v = work[i] / np.sqrt(norms[i])
        work -= np.outer(work @ v, v)
    return np.array(chosen, dtype=int)


def noise_floor(samples: np.ndarray, energy_scale: float) -> float:
    """Singular value of a matrix shaped like ``samples`` whose entries are all
    NOISE_TOLERANCE × ``energy_scale``: directions below it are rounding noise."""
    return NOISE_TOLERANCE * energy_scale * float(np.sqrt(samples.size))


def compress(samples: np.ndarray, tolerance: float | None = None, energy_scale: float = 0.0) -> Compression:
    """Compress conditions from ``samples`` (rows: residual entries, columns: random designs).

    ``energy_scale``: the largest energy term of the samples (see :data:`NOISE_TOLERANCE`).
    """
    if samples.size == 0:
        return Compression(np.zeros(0, dtype=int), np.zeros((0, 0)), np.zeros(0))
    if not np.isfinite(samples).all():  # the loader checks the box, but only on samples
        raise SolverError(
            "the balance residual is not a finite number at some designs within the bounds "
            "(a bound too large to compute with, or expressions such as sqrt or log of a variable)"
        )
    u, s, _ = np.linalg.svd(samples, full_matrices=False)
    r = numerical_rank(s, tolerance, noise_floor(samples, energy_scale))
    basis = u[:, :r]
    rows = pivot_rows(basis) if r else np.zeros(0, dtype=int)
    matrix = np.linalg.inv(basis[rows, :]) if r else np.zeros((0, 0))
    return Compression(rows, matrix, s)


def adaptive_compression(
    evaluate: Callable[[int, int], tuple[np.ndarray, Any, float]],
    start_configurations: int,
    start_designs: int,
    max_rounds: int = 6,
) -> tuple[Compression, Any]:
    """Sample until the rank is well below both the number of rows and of designs.

    ``evaluate(n_configurations, n_designs)`` returns the sampled residual matrix, whatever
    the caller needs to rebuild those rows (the configurations) and the largest energy
    term of the samples (for the noise floor, see :data:`NOISE_TOLERANCE`). The rank is
    accepted once rows ≥ 2·rank + 8 and designs ≥ 2·rank + 8: more samples could not
    plausibly reveal new conditions (the dense verification checks this independently).
    """
    n_conf, n_design = start_configurations, start_designs
    for _ in range(max_rounds):
        samples, context, energy_scale = evaluate(n_conf, n_design)
        comp = compress(samples, energy_scale=energy_scale)
        need = 2 * comp.rank + 8
        if samples.shape[0] >= need and samples.shape[1] >= need:
            break
        if samples.shape[0] < need:
            n_conf *= 2
        if samples.shape[1] < need:
            n_design *= 2
    return comp, context


# -- sampling the residual (shared by :mod:`.conditions` and :mod:`.manifold`) ----------------


def coordinate_weights(values: np.ndarray, n_q: int, noise: float = 0.0) -> np.ndarray:
    """One weight per coordinate: 1 / its largest sampled |residual|, and 0 when that is not
    above ``noise`` (rounding noise of the energy terms, see
    :data:`NOISE_TOLERANCE`: a residual that is zero in exact arithmetic, such
    as a spring whose length cannot change or an axis parallel to gravity, carries no condition).

    Scaling each coordinate's rows changes no zero set (r = 0 exactly when w·r = 0) but
    puts every coordinate on the same footing before the SVD: in a long chain the inner
    joints carry residuals ten orders of magnitude larger than the outer ones, and a rank
    tolerance relative to the largest singular value would drop the outer conditions.
    """
    largest = np.abs(values).reshape(-1, n_q, values.shape[1]).max(axis=(0, 2)) if values.size else np.zeros(n_q)
    loaded = largest > noise
    return np.where(loaded, 1.0 / np.where(loaded, largest, 1.0), 0.0)


def sample_residuals(residual: Any, q: np.ndarray, z: np.ndarray, parameters: np.ndarray) -> np.ndarray:
    """Residual entries at every (configuration, design) pair: (N·n_q) × K."""
    n_conf, n_q = q.shape
    n_design = z.shape[0]
    mapped = residual.map(n_conf * n_design)
    qq = np.tile(q.T, (1, n_design))
    zz = np.repeat(z.T, n_conf, axis=1)
    pp = np.tile(parameters[:, None], (1, n_conf * n_design))
    out = np.array(mapped(qq, zz, pp))  # n_q × (K·N), column k*N + i
    return out.reshape(n_q, n_design, n_conf).transpose(2, 0, 1).reshape(n_conf * n_q, n_design)


def largest_value(function: Any, q: np.ndarray, z: np.ndarray, parameters: np.ndarray) -> float:
    """Largest |value| of a scalar function of (q, z, p) over every (configuration, design) pair."""
    n_conf, n_design = q.shape[0], z.shape[0]
    mapped = function.map(n_conf * n_design)
    out = np.array(mapped(np.tile(q.T, (1, n_design)), np.repeat(z.T, n_conf, axis=1), np.tile(parameters[:, None], (1, n_conf * n_design))))
    return float(np.abs(out).max(initial=0.0))
