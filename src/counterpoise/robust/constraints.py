"""Design constraints and force limits at every corner of the tolerance box.

A robust design must meet everything a nominal one must (docs/robust.md, "Constraints at
every corner"): each ``[constraints.<name>]`` and each ``max_force`` holds for every built
balancer the tolerances allow, not only for the nominal one. The constraint rows of the
perturbed problem (:func:`counterpoise.formulation.constraints.build_rows`: home quantities
exactly, workspace extremes on sampled configurations) depend on the deviation parameters
where the tolerance changes the constrained quantity (a rate scales a spring's force, a mass
a total mass; a counter-mass's own mass is untoleranced unless named). Each constraint's
rows are written at every corner of the deviations its rows depend on (read off the CasADi
expression's sparsity, not sampled), so that

- the LP/SOCP path holds ``lbg ≤ g(z, p_c) ≤ ubg`` for every corner c (rows affine in the
  free slots: exact coefficients, as for the residual);
- the minimax NLP holds the same rows as CasADi expressions.

At a corner the rows are exact; between the corners a constraint multi-affine in the
deviations (a rate or a mass times geometry) takes its extremes at corners, and so does one
convex in them on its bounded side (a spring's length under a point tolerance, bounded
above). After each solve the constraints are evaluated at every corner on the dense sample
(the values design.csv shows: each constraint's worst corner), and configurations where a
workspace extreme goes beyond its bound are added to the rows for another round, as the
designer does (:data:`~counterpoise.formulation.constraints.MAX_ROUNDS`).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..formulation.constraints import ConstraintRows, ConstraintValue, Extra, build_rows, evaluate, scale
from .affine import Decomposition
from .perturb import corner_text

if TYPE_CHECKING:
    from ..designer.solution import Solution

#: corners of the deviations one set of constraints depends on, enumerated at most
MAX_CONSTRAINT_CORNERS = 1024


@dataclass(frozen=True)
class LinearRows:
    """Constraint rows affine in the free slots: ``lower ≤ g0 + G dz ≤ upper`` (scaled),
    ``group`` the index of each row's constraint (in :attr:`CornerConstraints.names`)."""

    G: np.ndarray
    g0: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    group: np.ndarray


class CornerConstraints:
    """The constraint rows of a decomposition's perturbed problem at every corner."""

    def __init__(self, decomposition: Decomposition, extra: Extra | None = None) -> None:
        import casadi as ca

        self.decomposition = decomposition
        f = decomposition.formulation
        self.extra: dict[tuple[str, str], np.ndarray] = dict(extra or {})
        self.rows: ConstraintRows = build_rows(f, extra)
        self.function = ca.Function("corner_constraints", [f.z, f.p], [self.rows.g])
        self.names: list[str] = list(dict.fromkeys(g.constraint.name for g in self.rows.groups))
        n_dev = len(decomposition.deviations)
        # which deviations each constraint's rows depend on (structurally)
        jac = ca.jacobian(self.rows.g, f.p)
        pattern = np.array(ca.DM(jac.sparsity(), 1)) != 0 if self.rows.count else np.zeros((0, f.p.numel()), dtype=bool)
        self.depends: dict[str, tuple[int, ...]] = {}
        for name in self.names:
            mine = np.zeros(self.rows.count, dtype=bool)
            for g in self.rows.groups:
                if g.constraint.name == name:
                    mine[g.start : g.stop] = True
            used = [i for i in range(n_dev) if pattern[mine][:, decomposition.parameter_index(i)].any()]
            self.depends[name] = tuple(used)
        union = sorted({i for used in self.depends.values() for i in used})
        if 2 ** len(union) > MAX_CONSTRAINT_CORNERS:
            labels = ", ".join(decomposition.deviations[i].label for i in union)
            raise ValueError(f"the constraints depend on {len(union)} deviations ({labels}): {2 ** len(union)} corners is more than {MAX_CONSTRAINT_CORNERS}")
        #: every corner of the deviations any constraint depends on (signs per deviation; 0: nominal)
        self.corners: list[tuple[int, ...]] = []
        for signs in itertools.product((-1, 1), repeat=len(union)):
            full = [0] * n_dev
            for i, s in zip(union, signs):
                full[i] = s
            self.corners.append(tuple(full))
        self._nonlinear: dict[tuple[int, ...], tuple[str, ...]] = {}

    def nonlinear(self, free: Sequence[int]) -> tuple[str, ...]:
        """The constraints whose rows are nonlinear in the slots ``free`` (the others held):
        the LP path needs none."""
        import casadi as ca

        key = tuple(free)
        if key not in self._nonlinear:
            z = self.decomposition.formulation.z
            zf = ca.vertcat(*[z[i] for i in key]) if key else ca.SX(0, 1)
            self._nonlinear[key] = tuple(
                dict.fromkeys(g.constraint.name for g in self.rows.groups if key and ca.depends_on(ca.jacobian(self.rows.g[g.start : g.stop], zf), zf))
            )
        return self._nonlinear[key]

    def refined(self, add: Extra) -> "CornerConstraints":
        """The same with configurations ``add`` added to the sampled rows (a verification round)."""
        from ..formulation.constraints import merge

        return CornerConstraints(self.decomposition, merge(self.extra, add))

    def _relevant(self, name: str, corner: Sequence[int]) -> bool:
        """Whether ``corner`` is one of constraint ``name``'s own (its other deviations at +1:
        one representative of the corners that differ only where it does not depend)."""
        used = set(self.depends[name])
        return all(s == 1 for i, s in enumerate(corner) if i not in used and s != 0)

    def linear_rows(self, z_ref: np.ndarray, free: Sequence[int], p: np.ndarray) -> LinearRows:
        """The rows at every corner, affine in the free slots' step from ``z_ref`` (exact:
        the rows are affine in the free slots, :meth:`nonlinear` is empty)."""
        blocks_G, blocks_g, lo, hi, group = [], [], [], [], []
        index = {name: k for k, name in enumerate(self.names)}
        for corner in self.corners:
            pc = self.decomposition.p_at(p, corner)
            g0 = np.array(self.function(z_ref, pc)).reshape(-1)
            G = np.stack([np.array(self.function(z_ref + np.eye(z_ref.size)[j], pc)).reshape(-1) - g0 for j in free], axis=1) if len(free) else np.zeros((g0.size, 0))
            keep = np.zeros(g0.size, dtype=bool)
            for g in self.rows.groups:
                if self._relevant(g.constraint.name, corner):
                    keep[g.start : g.stop] = True
            ids = np.zeros(g0.size, dtype=int)
            for g in self.rows.groups:
                ids[g.start : g.stop] = index[g.constraint.name]
            blocks_G.append(G[keep])
            blocks_g.append(g0[keep])
            lo.append(self.rows.lbg[keep])
            hi.append(self.rows.ubg[keep])
            group.append(ids[keep])
        n = len(free)
        if not blocks_g:
            return LinearRows(np.zeros((0, n)), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, dtype=int))
        return LinearRows(np.vstack(blocks_G), np.concatenate(blocks_g), np.concatenate(lo), np.concatenate(hi), np.concatenate(group))

    def symbolic_rows(self) -> tuple[Any, np.ndarray, np.ndarray]:
        """(g, lbg, ubg): the rows at every corner as CasADi expressions of the formulation's
        z and p (the minimax NLP's)."""
        import casadi as ca

        f = self.decomposition.formulation
        parts, lo, hi = [], [], []
        zero = np.zeros(f.p.numel())
        for corner in self.corners:
            keep = np.zeros(self.rows.count, dtype=bool)
            for g in self.rows.groups:
                if self._relevant(g.constraint.name, corner):
                    keep[g.start : g.stop] = True
            if not keep.any():
                continue
            offset = ca.DM(self.decomposition.p_at(zero, corner))
            rows = self.function(f.z, f.p + offset)
            parts.append(rows[np.flatnonzero(keep).tolist()])
            lo.append(self.rows.lbg[keep])
            hi.append(self.rows.ubg[keep])
        rows_g = ca.vertcat(*parts) if parts else ca.SX(0, 1)
        return rows_g, np.concatenate(lo) if lo else np.zeros(0), np.concatenate(hi) if hi else np.zeros(0)

    def worst(self, design: "Solution", perturbed_problem: Any) -> tuple[ConstraintValue, ...]:
        """Every constraint at its worst corner of the design (dense extremes per corner): the
        value with the least margin to its bounds, its corner named in ``corner``."""
        deviations = self.decomposition.deviations
        best: dict[tuple[str, str], tuple[float, ConstraintValue]] = {}
        for corner in self.corners:
            values = self.decomposition.values_at(corner)
            params = {s: (g, {**base, **values}) for s, (g, base) in design.scenario_parameters.items()}
            at = replace(design, problem=perturbed_problem, scenario_parameters=params)
            for v in evaluate(perturbed_problem, at, self.rows, None):
                if not self._relevant(v.name, corner):
                    continue
                margin = _margin(v)
                key = (v.name, v.scenario)
                if key not in best or margin < best[key][0]:
                    named = tuple(s if i in self.depends[v.name] else 0 for i, s in enumerate(corner))
                    text = corner_text(deviations, named) if self.depends[v.name] else "any (no tolerance enters it)"
                    best[key] = (margin, replace(v, corner=text))
        return tuple(v for _, v in best.values())


def _margin(v: ConstraintValue) -> float:
    """How far inside its bounds a constraint value is, relative to its scale (< 0: beyond)."""
    if v.value != v.value:
        return -np.inf
    s = scale(v.constraint)
    room = [np.inf]
    if v.upper is not None:
        room.append((v.upper - v.value) / s)
    if v.lower is not None:
        room.append((v.value - v.lower) / s)
    return float(min(room))
