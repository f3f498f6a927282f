"""The mixed-integer program of a superstructure (cvxpy, solved by HiGHS).

Candidates (docs/synthesis.md#formulation):

- a spring of class (A, B) with one end on a grid point of its region and the other
  *anywhere* in its (convex) region: variables the rate k and U = k u, where the free end
  is o + D u with u in the unit box; its 16 weights (:mod:`.structure`) are linear in
  (k, U) and 0 ≤ U ≤ k keeps the end in its region (the perspective of the box). Both
  ends on holes: the rate alone. Both orientations are candidates;
- a counter-mass at a site: the mass M and U = M u, the mass anywhere in its region (one
  candidate), or on one of its holes (one candidate per hole).

Binaries: z per candidate (k ≤ k_max z, k ≥ k_min z), and at most one candidate per
class, whose sum y_c says whether the class is used. The balance rows
(:mod:`.conditions`) are equalities on Σ weights; the cost Σ cost_c y_c is minimised, then
the added mass Σ M. Every variable is scaled to [0, 1] and every row to a largest
coefficient of 1 before HiGHS sees them.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..model.synthesis import SynthesisSpec
from .conditions import Conditions
from .structure import MASS, SPRING, ElementClass, region_arrays

#: a solution is exact when its polished residual is below this share of the largest
#: coefficient of the mechanism (each row scaled to its largest entry first)
EXACT_RESIDUAL = 1e-10
#: bounds are met to this share of the variable's scale after polishing
BOUND_SLACK = 1e-9
#: HiGHS's feasibility tolerances (primal and integrality)
FEASIBILITY = 1e-9


@contextmanager
def quiet_stdout() -> Iterator[None]:
    """HiGHS prints its banner on the process's standard output (file descriptor 1) each
    time a solver object is made, whatever its options: send it to /dev/null meanwhile."""
    import os
    import sys

    try:
        sys.stdout.flush()
        saved = os.dup(1)
    except (OSError, ValueError, AttributeError):  # no real descriptor (a captured stream)
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


@dataclass(frozen=True)
class Candidate:
    """One way to add an element of class ``cls``: ``free`` is the index of the free end
    (0: the first frame's, 1: the second's; -1: none, every point fixed), ``points`` the
    fixed ends (a spring's a and b, None for the free one; a counter-mass's hole)."""

    index: int
    cls: int
    free: int
    points: tuple[np.ndarray | None, ...]
    magnitude: int  # k or M in x
    free_vars: tuple[tuple[int, ...], ...]  # per setting: the indices of U in x
    region: int = -1  # which of the class's regions is free


@dataclass
class Solved:
    """A HiGHS answer: status ('optimal', 'infeasible', 'time_limit', ...), the columns'
    values (scaled), the objective and the proven bound, seconds."""

    status: str
    x: np.ndarray | None = None
    value: float = math.nan
    bound: float = math.nan
    seconds: float = 0.0


@dataclass
class LinearMip:
    """min objective·v subject to a_eq v = b_eq, a_ub v ≤ b_ub, lower ≤ v ≤ upper, v
    integer where ``integer``; ``classes``: the column of each candidate's binary (or each
    class's, in a relaxation), for cuts. Solved by HiGHS through cvxpy (:meth:`solve`)."""

    n: int
    integer: np.ndarray
    a_eq: Any  # a scipy.sparse matrix (its stubs' generic classes do not follow our slicing and stacking)
    b_eq: np.ndarray
    a_ub: Any  # as a_eq
    b_ub: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    objectives: dict[str, np.ndarray]
    binaries: np.ndarray

    def solve(
        self,
        objective: str,
        rows: Sequence[tuple[np.ndarray, float]] = (),
        fixed: dict[int, tuple[float, float]] | None = None,
        time_limit: float = 120.0,
        log_file: str | None = None,
    ) -> Solved:
        """Minimise objective ``objective`` with the extra rows ``(a, b)`` (a·v ≤ b) and the
        columns ``fixed`` to (lower, upper)."""
        import cvxpy as cp
        import scipy.sparse as sp

        lower, upper = self.lower.copy(), self.upper.copy()
        for col, (lo, hi) in (fixed or {}).items():
            lower[col], upper[col] = lo, hi
        ints = np.flatnonzero(self.integer)
        conts = np.flatnonzero(~self.integer)
        xc = cp.Variable(len(conts))
        xi = cp.Variable(len(ints), integer=True)

        def split(a: Any) -> Any:  # a sparse matrix times the two cvxpy variables: a cvxpy expression
            a = sp.csc_matrix(a)
            return a[:, conts] @ xc + a[:, ints] @ xi

        a_ub, b_ub = self.a_ub, self.b_ub
        if rows:
            a_ub = sp.vstack([a_ub, sp.csr_matrix(np.array([r for r, _ in rows]))])
            b_ub = np.r_[b_ub, [b for _, b in rows]]
        constraints = [xc >= lower[conts], xc <= upper[conts], xi >= lower[ints], xi <= upper[ints], split(a_ub) <= b_ub]
        if len(self.b_eq):
            constraints.append(split(self.a_eq) == self.b_eq)
        c = self.objectives[objective]
        problem = cp.Problem(cp.Minimize(c[conts] @ xc + c[ints] @ xi), constraints)
        options: dict[str, object] = {
            "mip_rel_gap": 1e-9,
            "mip_abs_gap": 1e-9,
            "primal_feasibility_tolerance": FEASIBILITY,
            "mip_feasibility_tolerance": FEASIBILITY,
            "time_limit": float(time_limit),
            "random_seed": 0,
            "threads": 1,
        }
        if log_file is not None:  # the log (read by a progress thread), not the console
            options.update({"output_flag": True, "log_to_console": False, "log_file": log_file})
        else:
            options["output_flag"] = False
        started = time.perf_counter()
        try:
            with quiet_stdout():
                problem.solve(solver=cp.HIGHS, **options)
        except cp.error.SolverError:
            return Solved("failed", seconds=time.perf_counter() - started)
        seconds = time.perf_counter() - started
        extra = problem.solver_stats.extra_stats if problem.solver_stats is not None else None
        info = extra.get("info") if isinstance(extra, dict) else extra
        bound = float(getattr(info, "mip_dual_bound", math.nan)) if info is not None else math.nan
        status = problem.status
        if status in ("infeasible", "infeasible_inaccurate"):
            return Solved("infeasible", seconds=seconds, bound=bound)
        if xc.value is None or (len(ints) and xi.value is None):
            return Solved("time_limit" if status == "user_limit" else str(status), seconds=seconds, bound=bound)
        v = np.zeros(self.n)
        v[conts] = np.asarray(xc.value, dtype=float)
        if len(ints):
            v[ints] = np.round(np.asarray(xi.value, dtype=float))
        name = "optimal" if status == "optimal" else ("time_limit" if status in ("user_limit", "optimal_inaccurate") else str(status))
        return Solved(name, v, float(problem.value), bound, seconds)


@dataclass(frozen=True)
class Element:
    """A chosen element: its class, rate or mass (SI), and points per setting (a spring's
    two ends in their frames; a counter-mass's position)."""

    cls: int
    magnitude: float
    points: tuple[tuple[np.ndarray, ...], ...]  # per setting
    free: int = -1  # the end the grid left free (adjusted per payload with ``adjust``); -1 none


@dataclass(frozen=True)
class Design:
    """An exact design of the superstructure on its grid: its elements, cost and added mass."""

    classes: frozenset[int]
    elements: tuple[Element, ...]
    cost: float
    added_mass: float
    residual: float  # the polished residual (relative)


@dataclass
class Program:
    """The scaled mixed-integer program of one superstructure (see the module)."""

    spec: SynthesisSpec
    classes: tuple[ElementClass, ...]
    cond: Conditions
    candidates: list[Candidate] = field(default_factory=list)
    n_x: int = 0
    scale: np.ndarray = field(default_factory=lambda: np.zeros(0))
    common: int = -1  # the shared rate's index in x (same_rate)

    def __post_init__(self) -> None:
        self._build()

    # -- candidates and the linear maps --------------------------------------------------
    def _new(self, count: int, scale: float) -> list[int]:
        start = self.n_x
        self.n_x += count
        self._scales += [scale] * count
        return list(range(start, start + count))

    def _build(self) -> None:
        spec, cond = self.spec, self.cond
        self._scales: list[float] = []
        n_set = len(cond.settings)
        copies = n_set if spec.adjust else 1
        # per candidate: (setting -> (cols, T (features x cols)))
        self._maps: list[list[tuple[list[int], np.ndarray]]] = []
        for c in self.classes:
            if c.kind == SPRING:
                ra, rb = c.regions
                ends = []
                if rb.convex:
                    ends += [(1, a) for a in (ra.grid() if ra.convex else ra.holes)]
                if ra.convex:
                    ends += [(0, b) for b in (rb.grid() if rb.convex else rb.holes)]
                if not ra.convex and not rb.convex:
                    ends = [(-1, (a, b)) for a in ra.holes for b in rb.holes]  # type: ignore[misc]  # a pair of holes
                for free, fixed in ends:
                    self._spring(c, free, fixed, copies, n_set)
            else:
                (region,) = c.regions
                if region.convex:
                    self._mass(c, None, copies, n_set)
                else:
                    for hole in region.holes:
                        self._mass(c, np.array(hole, dtype=float), copies, n_set)
        if spec.same_rate and any(c.kind == SPRING for c in self.classes):
            self.common = self._new(1, spec.max_rate)[0]
        self.scale = np.array(self._scales)
        self._assemble()

    def _spring(self, c: ElementClass, free: int, fixed: object, copies: int, n_set: int) -> None:
        k = self._new(1, self.spec.max_rate)[0]
        if free == -1:
            a, b = (np.array(p, dtype=float) for p in fixed)  # type: ignore[attr-defined]  # a pair of holes
            tk = np.concatenate([[1.0], a, -b, -np.outer(a, b).ravel()])
            maps = [([k], tk[:, None])] * n_set
            self.candidates.append(Candidate(len(self.candidates), c.index, -1, (a, b), k, ((),) * n_set))
            self._maps.append(maps)
            return
        point = np.array(fixed, dtype=float)
        origin, axes = region_arrays(c.regions[free])
        m = axes.shape[1]
        per_copy = [self._new(m, self.spec.max_rate) for _ in range(copies)]
        if free == 0:  # A free: a = origin + axes u; b fixed
            b = point
            tk = np.concatenate([[1.0], origin, -b, -np.outer(origin, b).ravel()])
            tu = np.zeros((16, m))
            tu[1:4] = axes
            tu[7:16] = -np.einsum("il,j->ijl", axes, b).reshape(9, m)
            points: tuple[np.ndarray | None, ...] = (None, b)
        else:  # B free: b = origin + axes v; a fixed
            a = point
            tk = np.concatenate([[1.0], a, -origin, -np.outer(a, origin).ravel()])
            tu = np.zeros((16, m))
            tu[4:7] = -axes
            tu[7:16] = -np.einsum("i,jl->ijl", a, axes).reshape(9, m)
            points = (a, None)
        maps = []
        free_vars = []
        for s in range(n_set):
            cols = per_copy[s if copies > 1 else 0]
            maps.append(([k, *cols], np.column_stack([tk, tu])))
            free_vars.append(tuple(cols))
        self.candidates.append(Candidate(len(self.candidates), c.index, free, points, k, tuple(free_vars), free))
        self._maps.append(maps)

    def _mass(self, c: ElementClass, hole: np.ndarray | None, copies: int, n_set: int) -> None:
        mag = self._new(1, self.spec.max_mass)[0]
        if hole is not None:
            tm = np.concatenate([[1.0], hole])
            self.candidates.append(Candidate(len(self.candidates), c.index, -1, (hole,), mag, ((),) * n_set))
            self._maps.append([([mag], tm[:, None])] * n_set)
            return
        origin, axes = region_arrays(c.regions[0])
        m = axes.shape[1]
        per_copy = [self._new(m, self.spec.max_mass) for _ in range(copies)]
        tm = np.concatenate([[1.0], origin])
        tu = np.vstack([np.zeros((1, m)), axes])
        maps, free_vars = [], []
        for s in range(n_set):
            cols = per_copy[s if copies > 1 else 0]
            maps.append(([mag, *cols], np.column_stack([tm, tu])))
            free_vars.append(tuple(cols))
        self.candidates.append(Candidate(len(self.candidates), c.index, 0, (None,), mag, tuple(free_vars), 0))
        self._maps.append(maps)

    def _assemble(self) -> None:
        """G (rows × x, unscaled), the row scaling, and the scaled program's matrices."""
        cond = self.cond
        rows = cond.rows
        g = np.zeros((rows, self.n_x))
        setting_rows = [cond.setting_rows(s) for s in range(len(cond.settings))]
        for cand, maps in zip(self.candidates, self._maps):
            e = cond.matrix[cand.cls]
            for s, (cols, t) in enumerate(maps):
                r = setting_rows[s]
                if len(r):
                    g[np.ix_(r, np.array(cols, dtype=int))] += e[r] @ t
        self.g = g
        scaled = g * self.scale
        size = np.maximum(np.abs(scaled).max(axis=1) if self.n_x else 0.0, np.abs(cond.fixed))
        size[size == 0] = 1.0
        self.row_scale = size
        self.g_scaled = scaled / size[:, None]
        self.e_scaled = cond.fixed / size
        self.class_of = np.array([c.cls for c in self.candidates], dtype=int)
        self.is_mass = np.array([self.classes[c.cls].kind == MASS for c in self.candidates], dtype=bool)
        self.costs = np.array([c.cost for c in self.classes])

    # -- the program as matrices ---------------------------------------------------------
    def mip(self) -> "LinearMip":
        """The scaled program: columns x (n_x, in [0, 1]) then z (one binary per candidate)."""
        import scipy.sparse as sp

        n, nz = self.n_x, len(self.candidates)
        lo_rate = self.spec.min_rate / self.spec.max_rate if self.spec.max_rate else 0.0
        lo_mass = self.spec.min_mass / self.spec.max_mass if self.spec.max_mass else 0.0
        mags = np.array([c.magnitude for c in self.candidates], dtype=int)
        eye = np.arange(nz)
        rows: list[sp.spmatrix] = []
        rhs: list[np.ndarray] = []
        # k ≤ z (scaled), k ≥ low z
        rows.append(sp.hstack([sp.csr_matrix((np.ones(nz), (eye, mags)), shape=(nz, n)), -sp.identity(nz)]))
        rhs.append(np.zeros(nz))
        lows = np.where(self.is_mass, lo_mass, lo_rate)
        rows.append(sp.hstack([sp.csr_matrix((-np.ones(nz), (eye, mags)), shape=(nz, n)), sp.diags(lows)]))
        rhs.append(np.zeros(nz))
        # at most one candidate per class
        nc = len(self.classes)
        rows.append(sp.hstack([sp.csr_matrix((nc, n)), sp.csr_matrix((np.ones(nz), (self.class_of, eye)), shape=(nc, nz))]))
        rhs.append(np.ones(nc))
        # a free end stays in its region: U ≤ k
        pairs = sorted({(col, c.magnitude) for c in self.candidates for cols in c.free_vars for col in cols})
        if pairs:
            m = len(pairs)
            r = np.arange(m)
            cols_u = np.array([p[0] for p in pairs])
            cols_k = np.array([p[1] for p in pairs])
            rows.append(sp.hstack([sp.csr_matrix((np.r_[np.ones(m), -np.ones(m)], (np.r_[r, r], np.r_[cols_u, cols_k])), shape=(m, n)), sp.csr_matrix((m, nz))]))
            rhs.append(np.zeros(m))
        if self.common >= 0:  # the same rate for every chosen spring: |k_j − K| ≤ 1 − z_j
            springs = np.flatnonzero(~self.is_mass)
            s = len(springs)
            r = np.arange(s)
            for sign in (1.0, -1.0):
                a = sp.csr_matrix((np.r_[sign * np.ones(s), -sign * np.ones(s)], (np.r_[r, r], np.r_[mags[springs], np.full(s, self.common)])), shape=(s, n))
                rows.append(sp.hstack([a, sp.csr_matrix((np.ones(s), (r, springs)), shape=(s, nz))]))
                rhs.append(np.ones(s))
        lower = np.zeros(n + nz)
        if self.common >= 0:
            lower[self.common] = lo_rate
        mass = np.zeros(n + nz)
        mass[mags[self.is_mass]] = self.spec.max_mass
        cost = np.r_[np.zeros(n), self.costs[self.class_of]]
        # the total scaled rate: after the least added mass, the least rates (a springs-only
        # design is otherwise any point of its feasible set)
        rates = np.zeros(n + nz)
        rates[mags[~self.is_mass]] = 1.0
        return LinearMip(
            n + nz,
            np.r_[np.zeros(n, dtype=bool), np.ones(nz, dtype=bool)],
            sp.hstack([sp.csr_matrix(self.g_scaled), sp.csr_matrix((self.cond.rows, nz))]).tocsr(),
            -self.e_scaled,
            sp.vstack(rows).tocsr(),
            np.concatenate(rhs),
            lower,
            np.ones(n + nz),
            {"cost": cost, "mass": mass, "rates": rates},
            n + np.arange(nz),
        )

    # -- a solution as a design ----------------------------------------------------------
    def design(self, solved: Solved) -> Design | None:
        """The design of a solution, polished to exact arithmetic on its chosen candidates
        (a least-squares correction of the scaled x on the balance rows, which are linear in
        x); None when it is not exact (the solver's tolerance, not the mechanics, balanced it)."""
        if solved.x is None:
            return None
        z = solved.x[self.n_x :]
        chosen = [c for c in self.candidates if z[c.index] > 0.5]
        cols = sorted({c.magnitude for c in chosen} | {v for c in chosen for vs in c.free_vars for v in vs})
        x = np.zeros(self.n_x)
        x[cols] = solved.x[cols]
        if self.common >= 0:  # one rate: the chosen springs' rates move together
            springs = [c.magnitude for c in chosen if self.classes[c.cls].kind == SPRING]
            if springs:
                x[springs] = float(np.mean(x[springs]))
            basis = np.zeros((self.n_x, 0))
            free = [col for col in cols if col not in springs]
            basis = np.zeros((self.n_x, len(free) + (1 if springs else 0)))
            for i, col in enumerate(free):
                basis[col, i] = 1.0
            if springs:
                basis[springs, -1] = 1.0
        else:
            basis = np.zeros((self.n_x, len(cols)))
            basis[cols, np.arange(len(cols))] = 1.0
        a = self.g_scaled @ basis
        for _ in range(3):
            r = self.g_scaled @ x + self.e_scaled
            x -= basis @ np.linalg.lstsq(a, r, rcond=None)[0]
            x = self._clipped(x, chosen)
        residual = float(np.abs(self.g_scaled @ x + self.e_scaled).max()) if self.cond.rows else 0.0
        if residual > EXACT_RESIDUAL:
            return None
        si = x * self.scale
        elements = []
        for c in chosen:
            mag = si[c.magnitude]
            cls = self.classes[c.cls]
            per_setting = []
            for vs in c.free_vars:
                if c.free < 0:
                    per_setting.append(tuple(np.array(p, dtype=float) for p in c.points if p is not None))
                    continue
                origin, axes = region_arrays(cls.regions[c.free])
                u = si[list(vs)] / mag if mag > 0 else np.zeros(len(vs))
                free_point = origin + axes @ np.clip(u, 0.0, 1.0)
                pts = [free_point if p is None else p for p in c.points]
                per_setting.append(tuple(pts))
            elements.append(Element(c.cls, float(mag), tuple(per_setting), c.free))
        classes = frozenset(c.cls for c in chosen)
        cost = float(sum(self.classes[i].cost for i in classes))
        added = float(sum(e.magnitude for e in elements if self.classes[e.cls].kind == MASS))
        return Design(classes, tuple(elements), cost, added, residual)

    def _clipped(self, x: np.ndarray, chosen: list[Candidate]) -> np.ndarray:
        out = x.copy()
        for c in chosen:
            out[c.magnitude] = min(max(out[c.magnitude], 0.0), 1.0)
            for vs in c.free_vars:
                for v in vs:
                    out[v] = min(max(out[v], 0.0), out[c.magnitude])
        return out
