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

import itertools
import time
from dataclasses import dataclass, field
from typing import Any

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
    spread: Any = 0
    m = rows.r0.size
    single = ~rows.grouped if shape == "box" else np.ones(n_dev, dtype=bool)
    n_single = int(single.sum())
    if n_single:
        # (M·n_single) rows: each deviation's change, scaled like the residual
        S0 = (rows.S0[:, single] * scale[:, None]).reshape(-1)
        SB = (rows.SB[:, single] * scale[:, None, None]).reshape(-1, n)
        s = S0 + SB @ dz if n else cp.Constant(S0)
        if shape == "box":
            u = cp.Variable(m * n_single)
            constraints += [u >= s, u >= -s]
            spread = cp.reshape(u, (m, n_single), order="C") @ np.ones(n_single)
        else:
            spread = cp.norm(cp.reshape(s, (m, n_single), order="C"), 2, axis=1)
    # an element with several deviations (products): its largest and least change over its
    # vertices (box, exact), or the largest higher-order part (ellipsoid, a bound); affine.py
    high: Any = 0
    low: Any = 0
    for grp in rows.groups:
        n_v = grp.F.shape[1]
        F = (grp.F * scale[:, None]).reshape(-1)
        FB = (grp.FB * scale[:, None, None]).reshape(-1, n)
        if shape != "box":  # F − Σ v_i s_i, the part beyond first order
            vertices = np.array(list(itertools.product((-1.0, 1.0), repeat=len(grp.members))))
            F = F - ((rows.S0[:, list(grp.members)] * scale[:, None]) @ vertices.T).reshape(-1)
            FB = FB - np.einsum("mkj,vk->mvj", rows.SB[:, list(grp.members)] * scale[:, None, None], vertices).reshape(-1, n)
        f = F + FB @ dz if n else cp.Constant(F)
        top, bottom = cp.Variable(m), cp.Variable(m)
        constraints += [cp.reshape(f, (m, n_v), order="C") <= cp.reshape(top, (m, 1), order="C") @ np.ones((1, n_v))]
        constraints += [cp.reshape(f, (m, n_v), order="C") >= -cp.reshape(bottom, (m, 1), order="C") @ np.ones((1, n_v))]
        if shape == "box":
            high, low = high + top, low + bottom
        else:  # |higher-order part| ≤ max(top, bottom)
            bound = cp.Variable(m)
            constraints += [bound >= top, bound >= bottom]
            spread = spread + bound
    tension = rows.tension * scale
    if rows.groups and shape == "box":
        # max(r + Σ|s| + Σ max F_g, −r + Σ|s| + Σ (−min F_g)) + tension, exact over the box
        e = cp.Variable(m)
        constraints += [e >= r + high, e >= -r + low]
        worst = e + spread + tension
    else:
        e = cp.Variable(m)
        constraints += [e >= r, e >= -r]
        worst = e + spread + tension
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
