"""The relaxation: every attachment point anywhere in its region, not only on the grid
(docs/synthesis.md#bound).

A spring of class (A, B) with its ends a = o_A + D_A u and b = o_B + D_B v (u, v in unit
boxes; a list of holes is replaced by the box around it) has the weights
(k, k a, −k b, −k a bᵀ): linear in k, U = k u, V = k v and X = k u vᵀ. The products X
are relaxed by their McCormick envelopes, written for the perspective (U, V ≤ k):

    X ≥ 0,   X ≥ U + V − k,   X ≤ U,   X ≤ V      (elementwise, U_i with V_j),

which every real spring (and every sum of springs) satisfies. A counter-mass's weights
(M, M s) are linear already. With one binary y_c per class (k ≤ k_max y_c) and the
balance rows of :mod:`.conditions`, the least cost Σ cost_c y_c is a lower bound of the
cost of every exact design whose points lie anywhere in their regions: when it equals the
grid's optimum, the minimum is proven independent of the grid. The same program is the
master of the search (:mod:`.search`): the classes it chooses are tried on the grid.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..model.synthesis import HOLES, Region, SynthesisSpec
from .conditions import Conditions
from .milp import LinearMip, Solved, quiet_stdout
from .structure import SPRING, ElementClass, region_arrays


def _box(region: Region) -> tuple[np.ndarray, np.ndarray]:
    """(origin, axes) of a region, a list of holes as the box around it."""
    if region.kind != HOLES:
        return region_arrays(region)
    holes = np.array(region.holes, dtype=float)
    lo, hi = holes.min(axis=0), holes.max(axis=0)
    axes = np.array([[hi[i] - lo[i] if j == i else 0.0 for j in range(3)] for i in range(3) if hi[i] > lo[i]]).reshape(-1, 3).T
    return lo, axes


class Relaxation:
    """The relaxation as a :class:`LinearMip`: continuous columns (scaled to [0, 1]), then
    one binary per class (``mip.binaries``)."""

    def __init__(self, spec: SynthesisSpec, classes: Sequence[ElementClass], cond: Conditions) -> None:
        import scipy.sparse as sp

        self.spec, self.classes, self.cond = spec, tuple(classes), cond
        n_set = len(cond.settings)
        copies = n_set if spec.adjust else 1
        rows_of = [cond.setting_rows(s) for s in range(n_set)]
        self.n = 0
        ub_rows: list[tuple[dict[int, float], float]] = []  # sparse rows: {col: coef}, rhs
        weight_maps: list[tuple[int, int, dict[int, np.ndarray]]] = []  # (class, copy, col -> weight column)
        self.magnitude: dict[int, int] = {}
        kmax, mmax = spec.max_rate, spec.max_mass

        def new(count: int) -> list[int]:
            start = self.n
            self.n += count
            return list(range(start, start + count))

        for c in self.classes:
            if c.kind == SPRING:
                (oa, da), (ob, db) = _box(c.regions[0]), _box(c.regions[1])
                ma, mb = da.shape[1], db.shape[1]
                (k,) = new(1)
                self.magnitude[c.index] = k
                for s in range(copies):
                    u, v = new(ma), new(mb)
                    x = np.array(new(ma * mb), dtype=int).reshape(ma, mb)
                    cols: dict[int, np.ndarray] = {}
                    w = np.zeros(16)
                    w[0], w[1:4], w[4:7], w[7:] = 1.0, oa, -ob, -np.outer(oa, ob).ravel()
                    cols[k] = kmax * w
                    for i, col in enumerate(u):
                        w = np.zeros(16)
                        w[1:4] = da[:, i]
                        w[7:] = -np.outer(da[:, i], ob).ravel()
                        cols[col] = kmax * w
                        ub_rows.append(({col: 1.0, k: -1.0}, 0.0))
                    for j, col in enumerate(v):
                        w = np.zeros(16)
                        w[4:7] = -db[:, j]
                        w[7:] = -np.outer(oa, db[:, j]).ravel()
                        cols[col] = kmax * w
                        ub_rows.append(({col: 1.0, k: -1.0}, 0.0))
                    for i in range(ma):
                        for j in range(mb):
                            col = int(x[i, j])
                            w = np.zeros(16)
                            w[7:] = -np.outer(da[:, i], db[:, j]).ravel()
                            cols[col] = kmax * w
                            ub_rows += [({col: 1.0, u[i]: -1.0}, 0.0), ({col: 1.0, v[j]: -1.0}, 0.0), ({u[i]: 1.0, v[j]: 1.0, k: -1.0, col: -1.0}, 0.0)]
                    weight_maps.append((c.index, s, cols))
            else:
                origin, axes = _box(c.regions[0])
                m = axes.shape[1]
                (mass,) = new(1)
                self.magnitude[c.index] = mass
                for s in range(copies):
                    u = new(m)
                    cols = {mass: mmax * np.r_[1.0, origin]}
                    for i, col in enumerate(u):
                        cols[col] = mmax * np.r_[0.0, axes[:, i]]
                        ub_rows.append(({col: 1.0, mass: -1.0}, 0.0))
                    weight_maps.append((c.index, s, cols))
        n_cont = self.n
        self.binary = {c.index: n_cont + c.index for c in self.classes}
        self.n += len(self.classes)
        lo_rate = spec.min_rate / kmax if kmax else 0.0
        lo_mass = spec.min_mass / mmax if mmax else 0.0
        for c in self.classes:  # k ≤ y, k ≥ low y
            low = lo_rate if c.kind == SPRING else lo_mass
            ub_rows += [({self.magnitude[c.index]: 1.0, self.binary[c.index]: -1.0}, 0.0), ({self.magnitude[c.index]: -1.0, self.binary[c.index]: low}, 0.0)]
        g = np.zeros((cond.rows, self.n))
        for cls, s, cols in weight_maps:
            e = cond.matrix[cls]
            for setting in range(n_set):
                if copies == 1 or setting == s:
                    r = rows_of[setting]
                    if len(r):
                        for col, w in cols.items():
                            g[r, col] += e[r] @ w
        size = np.maximum(np.abs(g).max(axis=1) if self.n else 0.0, np.abs(cond.fixed))
        size[size == 0] = 1.0
        self.row_scale = size
        data: list[float] = []
        ri: list[int] = []
        ci: list[int] = []
        for i, (row, _) in enumerate(ub_rows):
            for col, coef in row.items():
                data.append(coef)
                ri.append(i)
                ci.append(col)
        a_ub = sp.csr_matrix((data, (ri, ci)), shape=(len(ub_rows), self.n))
        cost = np.zeros(self.n)
        mass_obj = np.zeros(self.n)
        for c in self.classes:
            cost[self.binary[c.index]] = c.cost
            if c.kind != SPRING:
                mass_obj[self.magnitude[c.index]] = mmax
        self.g = g / size[:, None]
        self.e = cond.fixed / size
        self.mip = LinearMip(
            self.n,
            np.r_[np.zeros(n_cont, dtype=bool), np.ones(len(self.classes), dtype=bool)],
            sp.csr_matrix(self.g),
            -self.e,
            a_ub,
            np.array([b for _, b in ub_rows]),
            np.zeros(self.n),
            np.ones(self.n),
            {"cost": cost, "mass": mass_obj},
            np.array([self.binary[c.index] for c in self.classes], dtype=int),
        )

    def chosen(self, solved: Solved) -> frozenset[int]:
        """The classes a solution uses."""
        if solved.x is None:
            return frozenset()
        return frozenset(c.index for c in self.classes if solved.x[self.binary[c.index]] > 0.5)

    def least_residual(self, time_limit: float) -> tuple[tuple[int, float], ...]:
        """The rows the relaxation cannot balance, with every class allowed: (row, residual
        in J) of its least Σ |residual|, largest first; empty when it balances."""
        import cvxpy as cp
        import scipy.sparse as sp

        v = cp.Variable(self.n)
        t = cp.Variable(self.cond.rows, nonneg=True)
        residual = sp.csr_matrix(self.g) @ v + self.e
        problem = cp.Problem(cp.Minimize(cp.sum(t)), [v >= 0, v <= 1, self.mip.a_ub @ v <= self.mip.b_ub, residual <= t, -residual <= t])
        try:
            with quiet_stdout():
                problem.solve(solver=cp.HIGHS, output_flag=False, time_limit=float(time_limit), threads=1)
        except cp.error.SolverError:
            return ()
        if v.value is None:
            return ()
        values = (self.g @ np.asarray(v.value) + self.e) * self.row_scale
        scale = float(np.abs(self.cond.fixed).max()) if self.cond.rows else 1.0
        order = np.argsort(-np.abs(values))
        return tuple((int(i), float(values[i])) for i in order if abs(values[i]) > 1e-7 * scale)
