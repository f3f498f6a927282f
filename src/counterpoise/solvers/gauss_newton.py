"""One bounded Gauss-Newton iteration, shared by every polish of the designer.

The designer finishes solver points on its balance equalities g(z) = 0 in several places
(:meth:`~counterpoise.designer.balance.Balance.finish`, ``snap``, ``refine`` and
``polish_settings``); they differ only in which variables move, when a step is kept and
when to stop. :func:`gauss_newton` is that one loop:

- **step**: the minimum-norm least-squares solution of J[:, free] · Δ = −r
  (``numpy.linalg.lstsq``, SVD-based, so rank-revealing: singular values below ``rcond`` ×
  the largest are treated as zero and a redundant or rank-deficient system still gives a
  finite, smallest step);
- **bounds**: the new point is projected onto [lower, upper] (only the ``free`` variables move);
- **acceptance** (``decrease`` given): a step is kept only when the point is admissible (the
  ``evaluate`` callback says so, e.g. the sign constraints hold) and the worst residual
  max|r| drops, strictly, to at most ``decrease`` × its value before; the first rejected
  step ends the iteration and the last kept point is returned (a monotone safeguard).
  ``decrease=None`` keeps every step (plain Newton; the caller judges the end point);
- **stopping rules**, checked in this order: no free variable; the worst residual at most
  ``tolerance``; a rejected step; ``iterations`` steps taken.

No scipy: the plain solve path imports neither scipy nor cvxpy.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: (residual vector, its Jacobian over every variable, whether the point is admissible)
Evaluation = tuple[np.ndarray, np.ndarray, bool]
Evaluate = Callable[[np.ndarray], Evaluation]

#: why :func:`gauss_newton` stopped
NO_FREE_VARIABLE = "no free variable"
CONVERGED = "converged"
REJECTED = "rejected"
ITERATIONS = "iterations"


@dataclass(frozen=True)
class GaussNewtonResult:
    """The last kept point, its worst residual max|r|, the steps kept and why it stopped."""

    z: np.ndarray
    worst: float
    steps: int
    stop: str


def worst(r: np.ndarray) -> float:
    """max|r| (0 for an empty residual)."""
    return float(np.abs(np.asarray(r)).max(initial=0.0))


def gauss_newton(
    evaluate: Evaluate,
    z: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    free: np.ndarray | None = None,
    iterations: int = 8,
    tolerance: float = 0.0,
    decrease: float | None = 1.0,
    rcond: float | None = None,
) -> GaussNewtonResult:
    """Bounded Gauss-Newton on the residual of ``evaluate`` from ``z`` (see the module docstring).

    ``free``: a boolean mask or an index array of the variables that move (default: all);
    ``rcond``: numpy's cut-off of small singular values (None: machine precision × size).
    ``z`` is not modified.
    """
    if iterations < 0:
        raise ValueError("iterations must be at least 0")
    if decrease is not None and not 0.0 < decrease <= 1.0:
        raise ValueError("decrease must be in (0, 1]")
    best = np.array(z, dtype=float)
    mask = np.ones(best.size, dtype=bool) if free is None else _mask(free, best.size)
    lo, hi = np.asarray(lower, dtype=float)[mask], np.asarray(upper, dtype=float)[mask]
    if not mask.any():
        r, _, _ = evaluate(best)
        return GaussNewtonResult(best, worst(r), 0, NO_FREE_VARIABLE)
    r, jac, _ = evaluate(best)
    r = np.asarray(r, dtype=float).reshape(-1)
    best_worst = worst(r)
    steps, stop = 0, ITERATIONS
    for _ in range(iterations):
        if best_worst <= tolerance:
            stop = CONVERGED
            break
        step, *_ = np.linalg.lstsq(np.asarray(jac, dtype=float)[:, mask], -r, rcond=rcond)
        candidate = best.copy()
        candidate[mask] = np.minimum(np.maximum(candidate[mask] + step, lo), hi)  # numpy's clip, without its wrapper
        r_new, jac_new, admissible = evaluate(candidate)
        r_new = np.asarray(r_new, dtype=float).reshape(-1)
        new_worst = worst(r_new)
        if decrease is not None and not (admissible and new_worst < best_worst and new_worst <= decrease * best_worst):
            stop = REJECTED
            break
        best, best_worst, r, jac = candidate, new_worst, r_new, jac_new
        steps += 1
    else:
        if best_worst <= tolerance:
            stop = CONVERGED
    return GaussNewtonResult(best, best_worst, steps, stop)


def _mask(free: np.ndarray, n: int) -> np.ndarray:
    free = np.asarray(free)
    if free.dtype == bool:
        if free.shape != (n,):
            raise ValueError(f"free mask of shape {free.shape}, expected ({n},)")
        return free
    mask = np.zeros(n, dtype=bool)
    mask[free.astype(int)] = True
    return mask
