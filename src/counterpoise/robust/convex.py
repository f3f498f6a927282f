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
from dataclasses import dataclass, field

import numpy as np

from ..errors import SolverError
from .affine import Rows
from .constraints import LinearRows


@dataclass(frozen=True)
class RobustLP:
    status: str  # cvxpy's status
    dz: np.ndarray  # the step of the free slots from z_ref (scaled)
    ratio: float  # the worst-case ratio on the LP's rows
    seconds: float
    solver: str
    #: the elastic problem: each constraint's slack (scaled, in the order of the rows' groups)
    slack: np.ndarray = field(default_factory=lambda: np.zeros(0))


def solve_robust(
    rows: Rows,
    objective: tuple[np.ndarray, float],
    signs: tuple[np.ndarray, np.ndarray],
    bounds: tuple[np.ndarray, np.ndarray],
    mode: str,
    weight: float,
    limit: float,
    shape: str,
    design_rows: LinearRows | None = None,
    elastic: bool = False,
) -> RobustLP:
    """``objective`` (c, c0): c·dz + c0 (kg); ``signs`` (G, g0): G dz + g0 ≥ 0; ``bounds``: on dz;
    ``design_rows``: the design constraints at every tolerance corner (:mod:`.constraints`).

    ``elastic``: each constraint may be missed by a slack s ≥ 0 (its scaled units); minimise
    Σ s instead of the objective: the constraints with s > 0 are those that cannot hold
    together with the balance requirement (``limit``) and the bounds."""
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
    slack = None
    if design_rows is not None and design_rows.g0.size:
        c = design_rows
        g = c.G @ dz + c.g0 if n else cp.Constant(c.g0)
        if elastic:
            slack = cp.Variable(int(c.group.max()) + 1, nonneg=True)
            g_lo, g_hi = g + slack[c.group], g - slack[c.group]
        else:
            g_lo = g_hi = g
        lo, hi = np.isfinite(c.lower), np.isfinite(c.upper)
        if lo.any():
            constraints.append(g_lo[np.flatnonzero(lo)] >= c.lower[lo])
        if hi.any():
            constraints.append(g_hi[np.flatnonzero(hi)] <= c.upper[hi])
    rho = cp.Variable()
    if mode == "minimise":
        constraints.append(worst <= rho)
        cost = cost + weight * rho
    elif mode == "limit":
        constraints.append(worst <= limit)
    else:
        raise ValueError(f"unknown robust mode {mode!r}")
    problem = cp.Problem(cp.Minimize(cp.sum(slack) if slack is not None else cost), constraints)
    try:
        problem.solve(solver=cp.CLARABEL)
    except cp.error.SolverError as exc:
        raise SolverError(f"robust counterpart: Clarabel failed ({exc})") from None
    seconds = time.perf_counter() - start
    if dz.value is None:
        return RobustLP(problem.status, np.zeros(n), float("nan"), seconds, "clarabel")
    value = np.asarray(dz.value, dtype=float).reshape(-1)
    ratio = float(np.max(np.asarray(worst.value if hasattr(worst, "value") else worst)))
    missed = np.asarray(slack.value, dtype=float).reshape(-1) if slack is not None and slack.value is not None else np.zeros(0)
    return RobustLP(problem.status, value, ratio, seconds, "clarabel", missed)
