"""The convex path: an LP (or convex QP) solved with cvxpy and Clarabel; statuses mapped here.

A design problem is convex when the balance equalities, the sign constraints and the
objective are affine in the design variables that are free in a call (masses and spring
rates at a fixed geometry: a variable that moves a point makes M·d bilinear). Then the
design is one LP: it is solved to its global optimum, with no initial guess.

:class:`ConvexBackend` takes the same standard form as the IPOPT backend (CasADi SX
``{x, p, f, g}``) plus the indices of the variables that enter linearly, and honours the
same call: ``solve(z0, p, bounds)``. Variables outside that set must be fixed in the call
(``lbz == ubz``): that is how the certificate of a general design fixes its geometry. The
cvxpy problem is built with parameters (DPP) on the first call of a constraint pattern and
re-used afterwards, so a study pays for the canonicalisation once. cvxpy's default QP
solver is OSQP; this backend always names ``solver="CLARABEL"``.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .base import Bounds, SolverOutput, Status

#: cvxpy problem statuses and what they mean for a design.
STATUS_MAP: Mapping[str, Status] = {
    "optimal": Status.OPTIMAL,
    "optimal_inaccurate": Status.OPTIMAL,  # the dense verification has the last word
    "infeasible": Status.INFEASIBLE,
    "infeasible_inaccurate": Status.INFEASIBLE,
}

#: Clarabel settings: tighter than its defaults (1e-8), as the designs are checked to 1e-8.
CLARABEL_DEFAULTS: Mapping[str, Any] = {
    "tol_gap_abs": 1e-11,
    "tol_gap_rel": 1e-11,
    "tol_feas": 1e-11,
    "max_iter": 200,
}


def map_status(status: str) -> Status:
    """The project's status for a cvxpy problem status (anything unlisted is a failure)."""
    return STATUS_MAP.get(status, Status.FAILED)


def affine_variables(nlp: Mapping[str, Any], candidates: Sequence[int]) -> bool:
    """Whether g and f are affine (f at most quadratic with a constant Hessian) in z[candidates]."""
    import casadi as ca

    z = nlp["x"]
    idx = list(candidates)
    if not idx:
        return False
    zl = ca.vertcat(*[z[i] for i in idx])
    g, f = nlp["g"], nlp["f"]
    if g.numel() and ca.depends_on(ca.jacobian(g, zl), zl):
        return False
    grad = ca.gradient(f, zl)
    return not ca.depends_on(ca.jacobian(grad, zl), z) and not ca.depends_on(ca.jacobian(grad, zl), nlp["p"])


class ConvexBackend:
    """LP/QP over the variables ``linear`` of a standard-form NLP, solved by Clarabel."""

    name = "clarabel"

    def __init__(self, nlp: Mapping[str, Any], linear: Sequence[int], options: Mapping[str, Any] | None = None) -> None:
        import casadi as ca

        z, p = nlp["x"], nlp["p"]
        self.n = int(z.numel())
        self.linear = np.array(sorted(linear), dtype=int)
        zl = ca.vertcat(*[z[int(i)] for i in self.linear])
        g = nlp["g"] if nlp["g"].numel() else ca.SX(0, 1)
        grad = ca.gradient(nlp["f"], zl)
        hess = ca.jacobian(grad, zl)
        # everything the LP needs, evaluated at one point with the other variables fixed
        self._data = ca.Function("lp_data", [z, p], [nlp["f"], grad, g, ca.jacobian(g, zl) if g.numel() else ca.SX(0, zl.numel())])
        h = np.array(ca.Function("lp_hess", [z, p], [hess])(np.zeros(self.n), np.zeros(int(p.numel()))), dtype=float)
        self.hessian = 0.5 * (h + h.T)
        if np.abs(self.hessian).max(initial=0.0) > 0 and np.linalg.eigvalsh(self.hessian).min() < -1e-12 * max(1.0, np.abs(self.hessian).max()):
            raise ValueError("the objective is not convex in the linear variables")
        self.options = {**CLARABEL_DEFAULTS, **(options or {})}
        self._problems: dict[tuple[Any, ...], tuple[Any, ...]] = {}

    # -- building --------------------------------------------------------------------
    def _problem(self, eq: np.ndarray, ge: np.ndarray, le: np.ndarray) -> tuple[Any, ...]:
        """The parametrised cvxpy problem for one pattern of equality/inequality rows."""
        key = (eq.tobytes(), ge.tobytes(), le.tobytes())
        if key in self._problems:
            return self._problems[key]
        import cvxpy as cp

        m = len(self.linear)
        y = cp.Variable(m)
        c = cp.Parameter(m)
        lo, hi = cp.Parameter(m), cp.Parameter(m)
        cons = [y >= lo, y <= hi]
        params: dict[str, Any] = {"c": c, "lo": lo, "hi": hi}
        if eq.any():
            a_eq, b_eq = cp.Parameter((int(eq.sum()), m)), cp.Parameter(int(eq.sum()))
            cons.append(a_eq @ y == b_eq)
            params.update(a_eq=a_eq, b_eq=b_eq)
        n_in = int(ge.sum() + le.sum())
        if n_in:
            a_in, b_in = cp.Parameter((n_in, m)), cp.Parameter(n_in)
            cons.append(a_in @ y >= b_in)
            params.update(a_in=a_in, b_in=b_in)
        objective = c @ y
        if np.abs(self.hessian).max(initial=0.0) > 0:
            objective = objective + 0.5 * cp.quad_form(y, cp.psd_wrap(self.hessian))
        problem = cp.Problem(cp.Minimize(objective), cons)
        self._problems[key] = (problem, y, params)
        return self._problems[key]

    # -- one call --------------------------------------------------------------------
    def solve(self, z0: np.ndarray, p: np.ndarray, bounds: Bounds) -> SolverOutput:
        import cvxpy as cp

        t0 = time.perf_counter()
        lbz, ubz = np.asarray(bounds.lbz, dtype=float), np.asarray(bounds.ubz, dtype=float)
        fixed = np.ones(self.n, dtype=bool)
        fixed[self.linear] = False
        if np.any(lbz[fixed] != ubz[fixed]):
            raise ValueError("variables outside the linear set must be fixed (lower == upper) in a convex call")
        zref = np.clip(np.asarray(z0, dtype=float).reshape(-1), lbz, ubz)
        zref[fixed] = lbz[fixed]
        f0, grad, g0, jac = (np.array(v, dtype=float) for v in self._data(zref, p))
        grad = grad.reshape(-1)
        g0 = g0.reshape(-1)
        jac = jac.reshape(g0.size, len(self.linear))
        y0 = zref[self.linear]
        const = g0 - jac @ y0  # g(y) = const + jac @ y exactly (g is affine in y)
        lbg, ubg = np.asarray(bounds.lbg, dtype=float), np.asarray(bounds.ubg, dtype=float)
        eq = np.isfinite(lbg) & (lbg == ubg)
        ge = np.isfinite(lbg) & ~eq
        le = np.isfinite(ubg) & ~eq
        problem, y, params = self._problem(eq, ge, le)
        # linear term of f around y0: f(y) = f0 + grad·(y - y0) + ½ (y - y0)ᵀ H (y - y0)
        params["c"].value = grad - self.hessian @ y0
        params["lo"].value, params["hi"].value = lbz[self.linear], ubz[self.linear]
        if "a_eq" in params:
            params["a_eq"].value, params["b_eq"].value = jac[eq], lbg[eq] - const[eq]
        if "a_in" in params:
            params["a_in"].value = np.vstack([jac[ge], -jac[le]])
            params["b_in"].value = np.concatenate([lbg[ge] - const[ge], const[le] - ubg[le]])
        try:
            problem.solve(solver="CLARABEL", **self.options)
            code = str(problem.status)
        except cp.error.SolverError as exc:
            code = f"solver_error: {exc}"
        z = zref.copy()
        if y.value is not None and np.all(np.isfinite(y.value)):
            z[self.linear] = np.clip(np.asarray(y.value, dtype=float), lbz[self.linear], ubz[self.linear])
        stats = problem.solver_stats
        iterations = int(getattr(stats, "num_iters", 0) or 0) if stats is not None else 0
        return SolverOutput(
            z=z,
            status=map_status(code),
            solver_status=code,
            iterations=iterations,
            solve_time=time.perf_counter() - t0,
            solver=self.name,
        )
