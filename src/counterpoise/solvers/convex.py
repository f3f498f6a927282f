"""The convex path: an LP (or convex QP) handed to Clarabel as matrices; statuses mapped here.

A design problem is convex when the balance equalities, the sign constraints and the
objective are affine in the design variables that are free in a call (masses and spring
rates at a fixed geometry: a variable that moves a point makes M·d bilinear). Then the
design is one LP: it is solved to its global optimum, with no initial guess.

:class:`ConvexBackend` takes the same standard form as the IPOPT backend (CasADi SX
``{x, p, f, g}``) plus the indices of the variables that enter linearly, and honours the
same call: ``solve(z0, p, bounds)``. Variables outside that set must be fixed in the call
(``lbz == ubz``): that is how the certificate of a general design fixes its geometry.

The structure of this LP never varies: one vector of variables y, the constraints
``lbg ≤ g(y) ≤ ubg`` and ``lbz ≤ y ≤ ubz`` with g affine, the objective ``c·y + ½ yᵀHy``
with H constant. Its coefficients come from CasADi (one ``ca.Function`` built once, giving
g, its Jacobian and the objective's gradient, evaluated per call with that call's
parameters p and fixed variables, since p may enter the coefficients too), and Clarabel
gets them as matrices in its standard form ``A y + s = b, s ∈ {0}ᵐ × ℝ₊ⁿ`` through its
own Python API. A modelling layer (cvxpy) would add nothing here and cost 0.5–1 s of
import per process.

Clarabel's Python API reads a sparse matrix through the attributes of a SciPy CSC matrix
(``data``, ``indices``, ``indptr``, ``shape``, ``nnz``, ``has_canonical_format``).
:class:`CscMatrix` provides exactly these from numpy arrays, so the solve path does not
import ``scipy.sparse`` (≈ 0.14 s); should a Clarabel release refuse it, the matrices are
passed as ``scipy.sparse.csc_matrix`` instead (``tests/test_speed.py`` pins both).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..numeric import NumericFunction
from .base import Bounds, SolverOutput, Status

#: Clarabel's statuses (``str(solution.status)``) and what they mean for a design; the
#: near-statuses count as their full ones, the dense verification has the last word.
STATUS_MAP: Mapping[str, Status] = {
    "Solved": Status.OPTIMAL,
    "AlmostSolved": Status.OPTIMAL,
    "PrimalInfeasible": Status.INFEASIBLE,
    "AlmostPrimalInfeasible": Status.INFEASIBLE,
}

#: Clarabel settings: tighter than its defaults (1e-8), as the designs are checked to 1e-8.
CLARABEL_DEFAULTS: Mapping[str, Any] = {
    "tol_gap_abs": 1e-11,
    "tol_gap_rel": 1e-11,
    "tol_feas": 1e-11,
    "max_iter": 200,
}

#: the objective counts as non-convex when H's smallest eigenvalue is below this, relative
NONCONVEX_TOLERANCE = 1e-12

#: ``solver_status`` of a call whose data hold NaN or inf (the solver is not called)
INVALID_DATA = "invalid_data"


def map_status(status: str) -> Status:
    """The project's status for a Clarabel status name (anything unlisted is a failure)."""
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


@dataclass(frozen=True)
class CscMatrix:
    """A compressed-sparse-column matrix with the attributes Clarabel reads (SciPy's names)."""

    data: np.ndarray
    indices: np.ndarray
    indptr: np.ndarray
    shape: tuple[int, int]
    has_canonical_format: bool = field(default=True, init=False)  # sorted rows, no duplicates

    @property
    def nnz(self) -> int:
        return int(self.data.size)

    @classmethod
    def from_dense(cls, dense: np.ndarray) -> CscMatrix:
        """The nonzeros of a dense 2-D array, column by column, rows ascending."""
        dense = np.asarray(dense, dtype=float)
        cols, rows = np.nonzero(dense.T)  # row-major over the transpose: by column, then row
        indptr = np.zeros(dense.shape[1] + 1, dtype=np.int64)
        np.cumsum(np.bincount(cols, minlength=dense.shape[1]), out=indptr[1:])
        return cls(dense[rows, cols], rows.astype(np.int64), indptr, (int(dense.shape[0]), int(dense.shape[1])))

    def to_scipy(self) -> Any:
        from scipy.sparse import csc_matrix

        return csc_matrix((self.data, self.indices, self.indptr), shape=self.shape)


@dataclass(frozen=True)
class ConeProgram:
    """``min ½ yᵀPy + qᵀy  s.t.  A y + s = b``, s in ``n_zero`` zero cones then ``n_nonneg`` ≥ 0."""

    P: np.ndarray  # dense, symmetric
    q: np.ndarray
    A: np.ndarray  # dense
    b: np.ndarray
    n_zero: int
    n_nonneg: int

    def finite(self) -> bool:
        return bool(np.isfinite(self.P).all() and np.isfinite(self.q).all() and np.isfinite(self.A).all() and np.isfinite(self.b).all())


#: the upper triangles of the objective matrices as Clarabel reads them, and Clarabel's
#: settings, by content: a backend's Hessian and options do not change between its calls
#: (at most _KEPT_SIZE each, then emptied)
_KEPT_SIZE = 8
_upper_kept: dict[tuple[tuple[int, ...], bytes], CscMatrix] = {}
_settings_kept: dict[tuple[tuple[str, Any], ...], Any] = {}


def _upper(P: np.ndarray) -> CscMatrix:
    key = (P.shape, np.ascontiguousarray(P, dtype=float).tobytes())
    found = _upper_kept.get(key)
    if found is None:
        found = CscMatrix.from_dense(np.triu(P))
        if len(_upper_kept) >= _KEPT_SIZE:
            _upper_kept.clear()  # a few at most (clear: safe when threads share the dict)
        _upper_kept[key] = found
    return found


def _settings(options: Mapping[str, Any]) -> Any:
    """Clarabel's settings with ``options`` (a solver copies them when it is made)."""
    import clarabel

    try:
        key: tuple[tuple[str, Any], ...] | None = tuple(options.items())
        found = _settings_kept.get(key)  # type: ignore[arg-type]  # None is not looked up
    except TypeError:  # an option value that cannot be a key
        key, found = None, None
    if found is None:
        found = clarabel.DefaultSettings()
        found.verbose = False
        for name, value in options.items():
            setattr(found, name, value)
        if key is not None:
            if len(_settings_kept) >= _KEPT_SIZE:
                _settings_kept.clear()
            _settings_kept[key] = found
    return found


def solve_cone_program(lp: ConeProgram, options: Mapping[str, Any], duals: list[np.ndarray] | None = None) -> tuple[np.ndarray | None, str, int]:
    """Solve with Clarabel: (y or None, Clarabel's status name, iterations). ``duals``: a
    list that receives Clarabel's dual vector z (KKT: P y + q + Aᵀz = 0)."""
    import clarabel

    settings = _settings(options)
    cones = []
    if lp.n_zero:
        cones.append(clarabel.ZeroConeT(lp.n_zero))
    if lp.n_nonneg:
        cones.append(clarabel.NonnegativeConeT(lp.n_nonneg))
    P, A = _upper(lp.P), CscMatrix.from_dense(lp.A)
    try:
        solver = clarabel.DefaultSolver(P, lp.q, A, lp.b, cones, settings)
    except (TypeError, AttributeError):  # a Clarabel that insists on SciPy's own matrices
        solver = clarabel.DefaultSolver(P.to_scipy(), lp.q, A.to_scipy(), lp.b, cones, settings)
    solution = solver.solve()
    x = np.asarray(solution.x, dtype=float)
    y = x if x.size == lp.q.size and np.isfinite(x).all() else None
    if duals is not None:
        duals.append(np.asarray(solution.z, dtype=float))
    return y, str(solution.status), int(solution.iterations)


@dataclass(frozen=True)
class _Layout:
    """The rows of the cone program of one set of bounds (they depend on the bounds only).

    Row k of ``A`` is ``signs[k]`` × row ``rows[k]`` of [∂g/∂y; I]; entry k of ``b`` is
    ``signs[k]`` × (entry ``bounds[k]`` of [lbg, ubg, lo, hi] − entry ``rows[k]`` of
    [const, 0]): a sign flip and a subtraction of 0 are exact, so these are the figures of
    the blocks written out (``lbg − const`` on equalities, ``const − lbg`` on lbg ≤ g rows,
    ``−lo`` on lower bounds, ...)."""

    fixed: np.ndarray  # variables outside the linear set
    rows: np.ndarray
    bounds: np.ndarray
    signs: np.ndarray
    n_zero: int
    masks: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]  # eq, fix, ge, le (multipliers)


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
        self._data = NumericFunction(ca.Function("lp_data", [z, p], [nlp["f"], grad, g, ca.jacobian(g, zl) if g.numel() else ca.SX(0, zl.numel())]))
        h = np.array(ca.Function("lp_hess", [z, p], [hess])(np.zeros(self.n), np.zeros(int(p.numel()))), dtype=float)
        self.hessian = 0.5 * (h + h.T)
        scale = np.abs(self.hessian).max(initial=0.0)
        if scale > 0 and np.linalg.eigvalsh(self.hessian).min() < -NONCONVEX_TOLERANCE * max(1.0, scale):
            raise ValueError("the objective is not convex in the linear variables")
        self.options = {**CLARABEL_DEFAULTS, **(options or {})}
        self._layouts: dict[bytes, _Layout] = {}
        self._eye, self._zeros = np.eye(len(self.linear)), np.zeros(len(self.linear))

    def _layout(self, lbz: np.ndarray, ubz: np.ndarray, lbg: np.ndarray, ubg: np.ndarray) -> _Layout:
        """The rows of the cone program for these bounds (kept for up to _KEPT_SIZE sets of bounds, then forgotten all at once)."""
        key = b"".join(np.ascontiguousarray(v).tobytes() for v in (lbz, ubz, lbg, ubg)) + bytes(str((lbz.size, lbg.size)), "ascii")
        found = self._layouts.get(key)
        if found is not None:
            return found
        fixed = np.ones(self.n, dtype=bool)
        fixed[self.linear] = False
        if np.any(lbz[fixed] != ubz[fixed]):
            raise ValueError("variables outside the linear set must be fixed (lower == upper) in a convex call")
        lo, hi = lbz[self.linear], ubz[self.linear]
        n_g, m = lbg.size, len(self.linear)
        # equalities: g rows with lbg == ubg, variables with lo == hi
        eq, fix = np.isfinite(lbg) & (lbg == ubg), np.isfinite(lo) & (lo == hi)
        # inequalities as A y ≤ b: lbg ≤ g, g ≤ ubg, lo ≤ y, y ≤ hi (finite sides only)
        ge, le = np.isfinite(lbg) & ~eq, np.isfinite(ubg) & ~eq
        below, above = np.isfinite(lo) & ~fix, np.isfinite(hi) & ~fix
        g_rows, y_rows = np.arange(n_g), n_g + np.arange(m)
        # (rows of [∂g/∂y; I], entries of [lbg, ubg, lo, hi], sign) block by block
        blocks = [
            (g_rows[eq], g_rows[eq], 1.0),
            (y_rows[fix], 2 * n_g + np.flatnonzero(fix), 1.0),
            (g_rows[ge], g_rows[ge], -1.0),
            (g_rows[le], n_g + g_rows[le], 1.0),
            (y_rows[below], 2 * n_g + np.flatnonzero(below), -1.0),
            (y_rows[above], 2 * n_g + m + np.flatnonzero(above), 1.0),
        ]
        found = _Layout(
            fixed,
            np.concatenate([r for r, _, _ in blocks]).astype(np.intp),
            np.concatenate([e for _, e, _ in blocks]).astype(np.intp),
            np.concatenate([np.full(r.size, sign) for r, _, sign in blocks]),
            int(eq.sum() + fix.sum()),
            (eq, fix, ge, le),
        )
        if len(self._layouts) >= _KEPT_SIZE:
            self._layouts.clear()
        self._layouts[key] = found
        return found

    def program(self, z0: np.ndarray, p: np.ndarray, bounds: Bounds) -> tuple[ConeProgram, np.ndarray]:
        """The cone program of one call, and the reference point (the fixed variables set)."""
        lbz, ubz = np.asarray(bounds.lbz, dtype=float), np.asarray(bounds.ubz, dtype=float)
        lbg, ubg = np.asarray(bounds.lbg, dtype=float), np.asarray(bounds.ubg, dtype=float)
        layout = self._layout(lbz, ubz, lbg, ubg)
        fixed = layout.fixed
        zref = np.clip(np.asarray(z0, dtype=float).reshape(-1), lbz, ubz)
        zref[fixed] = lbz[fixed]
        _, grad, g0, jac = (np.array(v, dtype=float) for v in self._data(zref, p))
        m = len(self.linear)
        grad, g0 = grad.reshape(-1), g0.reshape(-1)
        jac = jac.reshape(g0.size, m)
        y0 = zref[self.linear]
        const = g0 - jac @ y0  # g(y) = const + jac @ y exactly (g is affine in y)
        signs = layout.signs
        A = np.concatenate([jac, self._eye])[layout.rows] * signs[:, None]
        b = signs * (np.concatenate([lbg, ubg, lbz[self.linear], ubz[self.linear]])[layout.bounds] - np.concatenate([const, self._zeros])[layout.rows])
        # f(y) = f0 + grad·(y - y0) + ½ (y - y0)ᵀ H (y - y0): linear term grad - H y0
        program = ConeProgram(self.hessian, grad - self.hessian @ y0, A, b, layout.n_zero, int(b.size - layout.n_zero))
        self._rows = layout.masks
        return program, zref

    def multipliers(self, z: np.ndarray) -> np.ndarray | None:
        """The g rows' multipliers in CasADi's sign (∇f + Jᵀλ = 0) from Clarabel's duals ``z``
        of the last :meth:`program`: λ = z on equalities and g ≤ ubg rows, −z on lbg ≤ g rows."""
        eq, fix, ge, le = self._rows
        counts = [int(eq.sum()), int(fix.sum()), int(ge.sum()), int(le.sum())]
        if z.size < sum(counts):
            return None
        lam = np.zeros(eq.size)
        at = 0
        lam[eq] = z[at : at + counts[0]]
        at += counts[0] + counts[1]
        lam[ge] -= z[at : at + counts[2]]
        at += counts[2]
        lam[le] += z[at : at + counts[3]]
        return lam

    def solve(self, z0: np.ndarray, p: np.ndarray, bounds: Bounds) -> SolverOutput:
        t0 = time.perf_counter()
        program, z = self.program(z0, p, bounds)
        duals: list[np.ndarray] = []
        if program.finite():
            y, code, iterations = solve_cone_program(program, self.options, duals)
        else:
            y, code, iterations = None, f"{INVALID_DATA}: NaN or inf in the problem's coefficients", 0
        if y is not None:
            lo, hi = np.asarray(bounds.lbz, dtype=float)[self.linear], np.asarray(bounds.ubz, dtype=float)[self.linear]
            z[self.linear] = np.minimum(np.maximum(y, lo), hi)  # numpy's clip, without its wrapper
        return SolverOutput(
            z=z,
            status=map_status(code),
            solver_status=code,
            iterations=iterations,
            solve_time=time.perf_counter() - t0,
            solver=self.name,
            multipliers=self.multipliers(duals[0]) if duals else None,
        )
