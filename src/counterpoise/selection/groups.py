"""Independent slot groups. Zero-free-length slots (:func:`slot_groups`): the connected
components of the column matroid of the balance conditions' Jacobian (at random points),
joined by sign constraints and non-additive objective terms. Directly attached slots
(:func:`direct_groups`): the connected components of which slot's parameters and which
design variables enter which residual row and spring length of the minimax design. Slots
in different groups are searched separately."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..designer.designer import Designer
from ..formulation.layout import Slot
from ..model import expr as ex
from ..model.elements import ZeroFreeLengthSpring
from ..model.problem import Problem
from ..verify.residuals import frame_names

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


def slot_groups(
    designer: Designer,
    names: list[str],
    base_values: Any,
    seed: int,
    parameters: Mapping[str, float] | None = None,
    bounds: Mapping[Slot | str, tuple[float, float]] | None = None,
) -> list[tuple[str, ...]]:
    """Slots whose conditions share variables, as tuples of slot names; ``parameters`` and
    ``bounds`` (SI): the call's, as in :meth:`Designer.solve` (the random points lie in these bounds)."""
    import casadi as ca

    d = designer
    f = d.formulation
    n = len(f.design)
    parts = _Components(n)
    rng = np.random.default_rng(seed)
    lo, hi = f.design.lower, f.design.upper
    if bounds:
        lbz, ubz = f.design.bounds(bounds)
        lo, hi = lbz * f.design.scale, ubz * f.design.scale
    p = f.parameters.values(parameters) if parameters else d.parameters
    points = [f.design.to_z(f.design.vector(base_values))] + [f.design.to_z(lo + (hi - lo) * rng.random(n)) for _ in range(RANDOM_POINTS)]
    gj = d.balance.residual_jacobian()
    for z in points:
        _, jac, _ = (np.array(v) for v in gj(z, p))
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


# -- directly attached slots ---------------------------------------------------------------

#: an entry of a residual row's scaled Jacobian below this fraction of the block's largest is zero
#: (a dependence that cancels, such as a parallelogram's R(θ1) R(θ2 − θ1), leaves rounding only)
ROW_TOLERANCE = 1e-8
#: random (configuration, design, part) points at which the residual rows' Jacobian is taken
ROW_POINTS = 3


@dataclass(frozen=True)
class DirectGroup:
    """Directly attached slots that interact, with the residual rows and spring lengths that
    involve them: the minimax design of these alone (:meth:`MinimaxDesigner.restricted`) is
    independent of every other group's parts and geometry."""

    slots: tuple[str, ...]
    coordinates: frozenset[str]  # the coordinates whose residual rows involve the group
    springs: frozenset[str]  # the directly attached springs whose lengths involve the group
    variables: frozenset[str]  # the design variables the group's rows involve


def _variables_of(problem: Problem, spring: ZeroFreeLengthSpring, frames: Mapping[str, frozenset[str]]) -> set[str]:
    names = set(ex.names(spring.stiffness)) if spring.stiffness is not None else set()
    for point in spring.ends:
        names |= set().union(*(ex.names(t) for t in point.position)) | set(frames[point.frame])
    if spring.direct is not None:
        names |= ex.names(spring.direct.cable) | ex.names(spring.direct.free_length)
        if spring.direct.max_length is not None:
            names |= ex.names(spring.direct.max_length)
    return names & set(problem.variable)


def direct_groups(problem: Problem, designer: Any, parts: Callable[[dict[str, int]], dict[str, float]], seed: int) -> list[DirectGroup]:
    """The directly attached slots of ``problem`` split into groups that do not interact.

    Decided from the structure of the minimax designer's rows: each residual row (one
    coordinate, every scenario) joins the slots whose parameters (rate, free length,
    initial tension, longest length) and the design variables that enter it, read off its
    Jacobian with respect to (z, p) at random configurations, designs and parts (an entry
    that is zero to rounding, relative to the block's largest, does not count); each spring's length
    rows join its slot with its variables; sign constraints join their variables. A
    subsystem with closed loops counts as one row (its residuals are projected on the
    manifold). ``parts(rows)``: the parameters of the parts ``rows`` (slot -> catalogue row).
    Slots in different connected components are independent: in the minimax design, the
    worst ratio is the largest of the groups' and each group's depends on its own parts
    and variables only.
    """
    import casadi as ca

    f = designer.formulation
    n_z = len(f.design)
    slots = [s.name for s in problem.slots]
    entity = {("slot", s): n_z + i for i, s in enumerate(slots)}
    coords = [c.name for c in problem.coordinates]
    entity.update({("coordinate", c): n_z + len(slots) + i for i, c in enumerate(coords)})
    springs = [s.name for s in problem.springs if s.direct is not None]
    entity.update({("spring", s): n_z + len(slots) + len(coords) + i for i, s in enumerate(springs)})
    union = _Components(n_z + len(slots) + len(coords) + len(springs))
    # the p entries of each slot's parameters, in every scenario
    names = f.parameters.base_names
    columns: list[int] = []
    owner: list[int] = []
    for c in range(len(problem.scenarios)):
        for slot in slots:
            for key in (slot, f"{slot}:free_length", f"{slot}:initial_tension", f"{slot}:max_length"):
                if key in names:
                    columns.append(c * f.parameters.stride + 3 + names.index(key))
                    owner.append(entity[("slot", slot)])
    rng = np.random.default_rng(seed)
    lo, hi = f.design.lower, f.design.upper
    p_cols = ca.vertcat(*[f.p[i] for i in columns]) if columns else ca.SX(0, 1)
    for block in f.blocks:
        loops = bool(problem.subsystem_loops(block.subsystem))
        if loops:
            for a, b in zip(block.coordinates[:-1], block.coordinates[1:]):
                union.union(entity[("coordinate", a)], entity[("coordinate", b)])
        q = ca.SX.sym("q", len(block.coordinates))
        r = block.residual(q, f.z, f.p)
        jac = ca.Function("row_jacobian", [q, f.z, f.p], [ca.jacobian(r, ca.vertcat(f.z, p_cols))])
        ranges = [problem.coordinate[c] for c in block.coordinates]
        points = []
        for _ in range(ROW_POINTS):
            qv = np.array([c.home if c.dependent else c.lower + (c.upper - c.lower) * rng.random() for c in ranges])
            z = f.design.to_z(lo + (hi - lo) * rng.random(n_z))
            rows = {s.name: int(rng.integers(len(s.catalogue))) for s in problem.slots}
            p = f.parameters.values(parts(rows))
            scale = np.concatenate([np.ones(n_z), np.maximum(np.abs(p[columns]), 1e-12)]) if columns else np.ones(n_z)
            points.append(np.abs(np.array(jac(qv, z, p))) * scale[None, :])
        # relative to the block's largest entry: a row that vanishes (a turntable's about the
        # vertical) has rounding entries only, which must not count relative to themselves
        top = max((float(j.max(initial=0.0)) for j in points), default=0.0)
        if top <= 0:
            continue
        for j in points:
            for i, name in enumerate(block.coordinates):
                for col in np.flatnonzero(j[i] > ROW_TOLERANCE * top):
                    union.union(entity[("coordinate", name)], int(col) if col < n_z else owner[int(col) - n_z])
    frames = frame_names(problem)
    index: dict[str, list[int]] = {}
    for i, s in enumerate(f.design.slots):
        index.setdefault(s.variable, []).append(i)
    for s in problem.springs:
        if s.direct is None:
            continue
        me = entity[("spring", s.name)]
        if s.slot is not None:
            union.union(me, entity[("slot", s.slot)])
        for v in _variables_of(problem, s, frames):
            for i in index[v]:
                union.union(me, i)
    nonneg = f.nonnegative
    if nonneg.numel():
        sparsity = ca.jacobian(nonneg, f.z).sparsity()
        by_row: dict[int, list[int]] = {}
        for r_, c_ in zip(*sparsity.get_triplet()):
            by_row.setdefault(r_, []).append(c_)
        for cols in by_row.values():
            for a, b in zip(cols[:-1], cols[1:]):
                union.union(a, b)
    out: dict[int, list[str]] = {}
    for slot in slots:
        out.setdefault(union.find(entity[("slot", slot)]), []).append(slot)
    groups = []
    for root, members in out.items():
        groups.append(
            DirectGroup(
                tuple(members),
                frozenset(c for c in coords if union.find(entity[("coordinate", c)]) == root),
                frozenset(s for s in springs if union.find(entity[("spring", s)]) == root),
                frozenset(f.design.slots[i].variable for i in range(n_z) if union.find(i) == root),
            )
        )
    return groups
