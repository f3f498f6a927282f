"""Independent slot groups: the connected components of the column matroid of the balance
conditions' Jacobian (at random points), joined by sign constraints and non-additive
objective terms. Slots in different groups are searched separately."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..designer.designer import Designer
from ..formulation.layout import Slot

#: singular values below this fraction of the largest count as zero (rank of the Jacobian)
RANK_TOLERANCE = 1e-9
#: entries of a reduced null-space row below this fraction of its largest are zero
SUPPORT_TOLERANCE = 1e-8
#: pivots below this fraction of the matrix's largest entry are skipped in the echelon form
PIVOT_TOLERANCE = 1e-10
#: random points of the design box at which the Jacobian is taken (besides the relaxed optimum)
RANDOM_POINTS = 2


class _Components:
    """Union-find over column indices."""

    def __init__(self, n: int) -> None:
        self.parent = list(range(n))

    def find(self, i: int) -> int:
        while self.parent[i] != i:
            self.parent[i] = self.parent[self.parent[i]]
            i = self.parent[i]
        return i

    def union(self, i: int, j: int) -> None:
        self.parent[self.find(i)] = self.find(j)


def reduced_echelon(a: np.ndarray) -> np.ndarray:
    """Reduced row echelon form of ``a`` (rows: a basis of a space), zero rows dropped.

    With ``a`` a basis of a null space, each row's support is a fundamental circuit of the
    column matroid (columns are not permuted: a row's entries keep their column index).
    """
    m = np.array(a, dtype=float)
    rows, cols = m.shape
    scale = max(float(np.abs(m).max(initial=0.0)), 1e-300)
    r = 0
    for c in range(cols):
        if r >= rows:
            break
        k = r + int(np.argmax(np.abs(m[r:, c])))
        if abs(m[k, c]) < PIVOT_TOLERANCE * scale:
            continue
        m[[r, k]] = m[[k, r]]
        m[r] /= m[r, c]
        for i in range(rows):
            if i != r:
                m[i] -= m[i, c] * m[r]
        r += 1
    return m[:r]


def slot_groups(designer: Designer, names: list[str], base_values: Any, seed: int) -> list[tuple[str, ...]]:
    """Slots whose conditions share variables, as tuples of slot names."""
    import casadi as ca

    d = designer
    f = d.formulation
    n = len(f.design)
    parts = _Components(n)
    rng = np.random.default_rng(seed)
    lo, hi = f.design.lower, f.design.upper
    points = [f.design.to_z(f.design.vector(base_values))] + [f.design.to_z(lo + (hi - lo) * rng.random(n)) for _ in range(RANDOM_POINTS)]
    gj = d.residual_jacobian()
    for z in points:
        _, jac, _ = (np.array(v) for v in gj(z, d.parameters))
        if jac.size == 0:
            continue
        jac = jac / max(np.abs(jac).max(), 1e-300)
        _, s, vt = np.linalg.svd(jac, full_matrices=True)
        rank = int(np.sum(s > RANK_TOLERANCE * (s[0] if s.size else 1)))
        null = vt[rank:].T  # columns: the null space of the Jacobian
        if null.size:  # columns in one matroid component share a circuit
            for row in reduced_echelon(null.T):
                support = np.flatnonzero(np.abs(row) > SUPPORT_TOLERANCE * max(np.abs(row).max(), 1e-300))
                for a, b in zip(support[:-1], support[1:]):
                    parts.union(int(a), int(b))
    # sign constraints couple the variables they mention
    nonneg = f.nonnegative
    if nonneg.numel():
        sparsity = ca.jacobian(nonneg, f.z).sparsity()
        rows: dict[int, list[int]] = {}
        for r_, c_ in zip(*sparsity.get_triplet()):
            rows.setdefault(r_, []).append(c_)
        for cols in rows.values():
            for a, b in zip(cols[:-1], cols[1:]):
                parts.union(a, b)
    # a non-additive objective term (M·d²) couples its variables too
    hessian = ca.hessian(f.objective, f.z)[0].sparsity()
    for r_, c_ in zip(*hessian.get_triplet()):
        parts.union(r_, c_)
    slot_index = {nm: f.design.index[Slot(nm, None)] for nm in names}
    groups: dict[int, list[str]] = {}
    for nm in names:
        groups.setdefault(parts.find(slot_index[nm]), []).append(nm)
    return [tuple(g) for g in groups.values()]
