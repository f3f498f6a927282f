"""The robust counterpart at a fixed geometry, written with cvxpy and solved by Clarabel.

Variables: the free (linear) design slots z; the worst-case residual of every sampled row
is |a + A z| + Σ_i |b_i + B_i z| (box) or |a + A z| + ‖b + B z‖₂ (ellipsoid), plus the
initial-tension term, divided by the row's reference torque (:mod:`.affine`). An LP for
the box, an SOCP for the ellipsoid:

- ``minimise``: objective(z) + weight · ρ, with every row's worst-case ratio ≤ ρ;
- ``limit``:    objective(z), with every row's worst-case ratio ≤ limit.

cvxpy is imported here only, so that a problem without ``[robust]`` never loads it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import SolverError
from .affine import Rows


@dataclass(frozen=True)
class RobustLP:
    status: str  # cvxpy's status
    dz: np.ndarray  # the step of the free slots from z_ref (scaled)
    ratio: float  # the worst-case ratio on the LP's rows
    seconds: float
    solver: str


def solve_robust(
    rows: Rows,
    objective: tuple[np.ndarray, float],
    signs: tuple[np.ndarray, np.ndarray],
    bounds: tuple[np.ndarray, np.ndarray],
    mode: str,
    weight: float,
    limit: float,
    shape: str,
) -> RobustLP:
    """``objective`` (c, c0): c·dz + c0 (kg); ``signs`` (G, g0): G dz + g0 ≥ 0; ``bounds``: on dz."""
    import cvxpy as cp

    start = time.perf_counter()
    n = rows.A.shape[1]
    dz = cp.Variable(n)
    scale = 1.0 / rows.reference
    r = cp.multiply(scale, rows.r0 + rows.A @ dz)
    n_dev = rows.S0.shape[1]
    constraints = [dz >= bounds[0], dz <= bounds[1]]
    if signs[0].size:
        constraints.append(signs[0] @ dz + signs[1] >= 0)
    spread = 0
    if n_dev:
        # (M·n_dev) rows: each deviation's change, scaled like the residual
        S0 = (rows.S0 * scale[:, None]).reshape(-1)
        SB = (rows.SB * scale[:, None, None]).reshape(-1, n)
        s = S0 + SB @ dz if n else cp.Constant(S0)
        m = rows.r0.size
        if shape == "box":
            u = cp.Variable(m * n_dev)
            constraints += [u >= s, u >= -s]
            spread = cp.reshape(u, (m, n_dev), order="C") @ np.ones(n_dev)
        else:
            spread = cp.norm(cp.reshape(s, (m, n_dev), order="C"), 2, axis=1)
    e = cp.Variable(rows.r0.size)
    constraints += [e >= r, e >= -r]
    worst = e + spread + rows.tension * scale
    cost = objective[0] @ dz + objective[1] if n else cp.Constant(objective[1])
    if mode == "minimise":
        rho = cp.Variable()
        constraints.append(worst <= rho)
        problem = cp.Problem(cp.Minimize(cost + weight * rho), constraints)
    elif mode == "limit":
        constraints.append(worst <= limit)
        problem = cp.Problem(cp.Minimize(cost), constraints)
    else:
        raise ValueError(f"unknown robust mode {mode!r}")
    try:
        problem.solve(solver=cp.CLARABEL)
    except cp.error.SolverError as exc:
        raise SolverError(f"robust counterpart: Clarabel failed ({exc})") from None
    seconds = time.perf_counter() - start
    if dz.value is None:
        return RobustLP(problem.status, np.zeros(n), float("nan"), seconds, "clarabel")
    value = np.asarray(dz.value, dtype=float).reshape(-1)
    ratio = float(np.max(np.asarray(worst.value if hasattr(worst, "value") else worst)))
    return RobustLP(problem.status, value, ratio, seconds, "clarabel")
