"""A lower bound on the least worst residual of affine equations over a box.

For g(z) = J z + c and any weights y, Hölder's inequality gives for every z in the box
[l, u]: max_j |g_j(z)| ≥ y·g(z) / |y|₁ ≥ ( y·c + Σ_i min(w_i l_i, w_i u_i) ) / |y|₁ with
w = Jᵀy. With y the residual r of the box-constrained least-squares point, that point's
optimality gives y·g(z) ≥ |r|₂² over the box, so the bound is |r|₂² / |r|₁: never above the
least worst residual (the minimax one), and close to it when the least-squares residuals
are of similar size; not tight in general (the weights of the minimax LP's dual would make
it so). The least-squares point is found for a few variables by trying each of them at its
lower bound, at its upper bound or free (3^n small least-squares solves). Any weights give a
valid bound, so a pattern that is not the optimum's only gives a weaker one. Used by
:mod:`counterpoise.designer.unbalanceable`.
"""

from __future__ import annotations

import itertools

import numpy as np


def least_residual_bound(jacobian: np.ndarray, offset: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> float:
    """A lower bound on min over the box [lower, upper] of max_j |(J z + c)_j| (see the module
    docstring); 0.0 when none is found. Valid for every pattern tried, to rounding."""
    m, n = jacobian.shape
    best = 0.0
    for pattern in itertools.product((0, 1, 2), repeat=n):  # 0: at lower, 1: at upper, 2: free
        z = np.where(np.array(pattern) == 1, upper, lower).astype(float)
        free = [i for i, kind in enumerate(pattern) if kind == 2]
        if free:
            fixed = [i for i, kind in enumerate(pattern) if kind != 2]
            rhs = -(offset + jacobian[:, fixed] @ z[fixed])
            z[free] = np.linalg.lstsq(jacobian[:, free], rhs, rcond=None)[0]
            z = np.clip(z, lower, upper)
        y = jacobian @ z + offset
        norm = float(np.abs(y).sum())
        if norm == 0.0 or not np.isfinite(norm):
            continue
        w = jacobian.T @ y
        bound = (float(y @ offset) + float(np.minimum(w * lower, w * upper).sum())) / norm
        best = max(best, bound)
    return best
