"""The balance residual as an affine function of the design and of every deviation.

For a fixed geometry the residual ∂V/∂q of each (subsystem, scenario) block, at one
configuration q, is affine in the linear design variables z (masses, stiffnesses) and in
each deviation δ_i (:mod:`.perturb`), with bilinear terms z·δ (a deviation of a spring's
rate scales with its stiffness):

    r(q; z, δ) = a(q) + A(q) z + Σ_i δ_i/h_i · (b_i(q) + B_i(q) z)

where h_i is the half width of deviation i, so b_i + B_i z is the change of the residual at
δ_i = +h_i. The coefficients are read exactly (not by finite differences of a nonlinear
function) from the CasADi residual at z_ref, z_ref + e_j, δ = h_i e_i and both, because the
residual is affine in each. The worst case over the tolerance box is then

    |r(q; z, 0)| + Σ_i |b_i(q) + B_i(q) z|      (box: each δ_i at the sign that adds)
    |r(q; z, 0)| + ‖(b_i(q) + B_i(q) z)_i‖₂     (ellipsoid Σ (δ_i/h_i)² ≤ 1)

plus, for toleranced initial tensions, Σ ΔF0 |∂d/∂q| (the cable's force along its length).

**Products of deviations of one element.** A body whose mass and centre of mass are both
toleranced has m(1 + δ_m)(c + δ_c): the residual has the term δ_m δ_c; a spring with a rate
and a point tolerance (or both ends) has δ_k δ_a, δ_a δ_b, δ_k δ_a δ_b. The residual is still
*multi-affine* (affine in each deviation, the others fixed: a squared end shift ½ k |δ|² does
not depend on the configuration), and the deviations of different elements never multiply.
So the deviations are grouped by element; a group of several is evaluated at each of its 2ⁿ
vertices (its change F_g(v) from r₀, exact), and since the groups are independent the worst
case over the box is, exactly,

    max( r + Σ_g max_v F_g(v),  −r − Σ_g min_v F_g(v) )

(for a group of one, max = |s_i| = −min: the formula above). The extreme of a multi-affine
function over a box lies at a vertex. Over the ellipsoid the products are bounded: the
first-order part ‖s‖₂ plus, per group, the largest |F_g(v) − Σ_i v_i s_i| over its box's
vertices (which contain the ellipsoid): a bound, labelled so.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import itertools

import numpy as np

from ..formulation.formulation import Formulation
from ..model.problem import Problem
from .perturb import Deviation, nonaffine

#: configurations per (subsystem, scenario) block in the robust LP
LP_CONFIGURATIONS = 1024
#: random machines evaluated together by :meth:`Decomposition.sampled` (memory: rows × this)
SAMPLED_CHUNK = 32


@dataclass
class Rows:
    """Stacked rows (one per block, configuration and coordinate) of the decomposition."""

    r0: np.ndarray  # (M,) residual at z_ref, δ = 0
    A: np.ndarray  # (M, n_free) change per unit step of each free slot
    S0: np.ndarray  # (M, n_dev) change at δ_i = +h_i, at z_ref
    SB: np.ndarray  # (M, n_dev, n_free) change of S per unit step of each free slot
    tension: np.ndarray  # (M,) Σ ΔF0 |∂d/∂q| (N·m or N)
    reference: np.ndarray  # (M,) the largest gravity torque (force) of the row's kind
    kinds: np.ndarray  # (n_dev,) the tolerance kind of each deviation ("rate", "mass", ...)
    block: np.ndarray  # (M,) index of the row's block
    q: list[np.ndarray]  # configurations of each block
    #: elements with several deviations (their products are not first order): each group's
    #: change at every vertex of its own box, exact
    groups: tuple["Group", ...] = ()
    #: (M,) True for a row of a revolute coordinate (its reference is a torque), else a force
    revolute: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    def reference_of(self, revolute: np.ndarray) -> np.ndarray:
        """The reference of rows of these kinds (revolute or not), as this set's rows have it."""
        out = np.ones(revolute.shape, dtype=float)
        for k in (True, False):
            mine = self.reference[self.revolute == k]
            if mine.size:
                out[revolute == k] = mine[0]
        return out

    def residual(self, dz: np.ndarray) -> np.ndarray:
        return self.r0 + self.A @ dz

    def sensitivities(self, dz: np.ndarray) -> np.ndarray:
        return self.S0 + self.SB @ dz if self.SB.shape[2] else self.S0

    @property
    def grouped(self) -> np.ndarray:
        """(n_dev,) True for the deviations that belong to a group of several."""
        out = np.zeros(self.S0.shape[1], dtype=bool)
        for g in self.groups:
            out[list(g.members)] = True
        return out

    def at(self, signs: Sequence[float], dz: np.ndarray | None = None) -> np.ndarray:
        """The residual at the corner ``signs`` (each ±1 or 0) of the box, exactly (products
        within a group included), at the step ``dz`` (None: z_ref)."""
        step = np.zeros(self.A.shape[1]) if dz is None else dz
        s = np.asarray(signs, dtype=float)
        single = ~self.grouped
        out = self.residual(step) + self.sensitivities(step)[:, single] @ s[single]
        for g in self.groups:
            out = out + g.restricted(g.values(step), [bool(s[i]) for i in g.members])[:, g.vertex([s[i] for i in g.members if s[i]])]
        return out


@dataclass
class Group:
    """The deviations of one element (a body's mass and centre of mass, a spring's rate and
    points): its change from r₀ at every vertex of its box, vertices in
    ``itertools.product((-1, 1), repeat=n)`` order (the first member the slowest)."""

    members: tuple[int, ...]
    F: np.ndarray  # (M, 2ⁿ) change at each vertex, at z_ref
    FB: np.ndarray  # (M, 2ⁿ, n_free) change of F per unit step of each free slot

    def values(self, dz: np.ndarray) -> np.ndarray:
        return self.F + self.FB @ dz if self.FB.shape[2] else self.F

    def restricted(self, values: np.ndarray, keep: Sequence[bool]) -> np.ndarray:
        """``values`` (M, 2ⁿ) with the members not kept at 0: the mean over their two signs
        (the change is affine in each of them); (M, 2^kept)."""
        n = len(self.members)
        cube = values.reshape((values.shape[0],) + (2,) * n)
        drop = tuple(1 + k for k in range(n) if not keep[k])
        if drop:
            cube = cube.mean(axis=drop)
        return cube.reshape(values.shape[0], -1)

    @staticmethod
    def vertex(signs: Sequence[float]) -> int:
        """The index of the vertex with these signs (±1) among its group's vertices."""
        index = 0
        for s in signs:
            index = 2 * index + (1 if s > 0 else 0)
        return index

    def linear(self, values: np.ndarray) -> np.ndarray:
        """The first-order coefficients (M, n): c_i = mean_v v_i F(v) (the change at δ_i = +h)."""
        signs = np.array(list(itertools.product((-1.0, 1.0), repeat=len(self.members))))
        return values @ signs / len(signs)


def grid(lower: np.ndarray, upper: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """About ``count`` configurations: a full grid (endpoints included) for up to three
    coordinates, else the box's corners (up to 4096) and random points."""
    n_q = lower.size
    if n_q <= 3:
        m = max(3, int(round(count ** (1.0 / n_q))))
        m += 1 - m % 2  # odd: the middle of each range (where |cos| of a symmetric range peaks) is a node
        axes = [np.linspace(lo, hi, m) for lo, hi in zip(lower, upper)]
        return np.stack([g.reshape(-1) for g in np.meshgrid(*axes, indexing="ij")], axis=1)
    corners = np.array(np.meshgrid(*[[lo, hi] for lo, hi in zip(lower, upper)], indexing="ij")).reshape(n_q, -1).T
    corners = corners[: min(len(corners), 4096)]
    return np.vstack([corners, lower + (upper - lower) * rng.random((count, n_q))])


class Decomposition:
    """The affine decomposition of a perturbed problem's residual (built once)."""

    def __init__(self, perturbed: Problem, deviations: Sequence[Deviation], original: Problem) -> None:
        self.problem = perturbed
        self.original = original
        self.deviations = tuple(deviations)
        self.formulation = Formulation(perturbed)
        self._maps: dict[tuple[int, int, str], Any] = {}  # (block, configurations, function) -> mapped CasADi function
        self._tangents: dict[tuple[int, tuple[int, ...], bytes], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}  # closed loops: per (block, q)
        #: the elements with several deviations (their indices), whose products are evaluated exactly
        by_element: dict[tuple[str, str], list[int]] = {}
        for i, d in enumerate(self.deviations):
            element = "spring" if d.tolerance.kind in ("rate", "point", "initial_tension") else "body"
            by_element.setdefault((element, d.tolerance.item), []).append(i)
        # a deviation the residual is not affine in (a point of a directly attached spring) is
        # evaluated at both ends of its range, with its element's others: a group even alone
        curved = set(nonaffine(perturbed, self.deviations))
        self.nonaffine = tuple(i for i, d in enumerate(self.deviations) if d.label in curved)
        self.groups: tuple[tuple[int, ...], ...] = tuple(tuple(m) for m in by_element.values() if len(m) > 1 or set(m) & set(self.nonaffine))
        spec = original.robust
        pulley = {s.name for s in original.springs if s.direct is None}  # a direct spring's initial tension is a deviation parameter
        self.tensions = {t.item: t.amount for t in (spec.tolerances if spec else ()) if t.kind == "initial_tension" and t.amount > 0 and t.item in pulley}

    def configurations(self, count: int, seed: int) -> list[np.ndarray]:
        """About ``count`` configurations per block (:func:`grid`); a subsystem with closed
        loops: the grid over its independent coordinates, assembled on the configuration
        manifold (every coordinate of the subsystem, on the branch of home)."""
        rng = np.random.default_rng(seed)
        out = []
        for b, block in enumerate(self.formulation.blocks):
            c = self._closure(b)
            if c is not None:
                out.append(c.solve(grid(c.lower, c.upper, count, rng)).q)
                continue
            coords = [self.problem.coordinate[n] for n in block.coordinates]
            out.append(grid(np.array([c.lower for c in coords]), np.array([c.upper for c in coords]), count, rng))
        return out

    # -- closed loops: rows along the configuration manifold -------------------------
    def _closure(self, b: int) -> Any:
        """The closure (:class:`counterpoise.mechanics.closure.Closure`) of block ``b``'s
        subsystem at its scenario's geometry; None for an open chain. The deviations (rates,
        masses, centres of mass, spring ends) are not loop geometry: one manifold for all."""
        block = self.formulation.blocks[b]
        if not self.problem.subsystem_loops(block.subsystem):
            return None
        from ..mechanics.closure import closure, scenario_base  # closed loops only (~3 ms to import)

        return closure(self.problem, block.subsystem, scenario_base(self.problem, block.scenario))

    def names(self, b: int) -> list[str]:
        """The coordinates of block ``b``'s rows: its independent ones (all of an open chain)."""
        block = self.formulation.blocks[b]
        c = self._closure(b)
        return list(block.coordinates) if c is None else [block.coordinates[int(i)] for i in c.independent]

    def tangent(self, b: int, qb: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """(independent, dependent indices, dq_d/dq_i (N, n_d, n_i)) at the assembled
        configurations ``qb`` of block ``b``; None for an open chain."""
        c = self._closure(b)
        if c is None:
            return None
        key = (b, qb.shape, qb.tobytes())
        found = self._tangents.get(key)
        if found is None:
            _, jac = c.equations(np.asarray(qb, dtype=float))
            found = (np.asarray(c.independent, dtype=int), np.asarray(c.dependent, dtype=int), c.tangent(jac)[0])
            if len(self._tangents) >= 8:
                self._tangents.pop(next(iter(self._tangents)))
            self._tangents[key] = found
        return found

    def along(self, b: int, qb: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Generalized forces of block ``b`` at ``qb``, configuration-major (N · n,) or (N, n),
        along the manifold: r_i = g_i + (dq_d/dq_i)ᵀ g_d, (N · n_i,) or (N, n_i). The projection
        is linear and does not depend on the design or the deviations, so a residual affine
        (multi-affine) in them stays so. An open chain's are returned as is."""
        t = self.tangent(b, qb)
        if t is None:
            return values
        ind, dep, tangent = t
        flat = values.ndim == 1
        g = values.reshape(len(qb), -1)
        out = g[:, ind] + np.einsum("kdi,kd->ki", tangent, g[:, dep])
        return out.reshape(-1) if flat else out

    def along_symbolic(self, b: int, qb: np.ndarray, values: Any) -> Any:
        """The same for a CasADi matrix (n, N) of block ``b``'s residual at ``qb``: (n_i, N)."""
        t = self.tangent(b, qb)
        if t is None:
            return values
        import casadi as ca

        ind, dep, tangent = t
        out = []
        for j, i in enumerate(ind):
            row = values[int(i), :]
            for d, k in enumerate(dep):
                row = row + ca.times(ca.DM(tangent[:, d, j][None, :]), values[int(k), :])
            out.append(row)
        return ca.vertcat(*out)

    def sampled(self, q: list[np.ndarray], z: np.ndarray, p: np.ndarray, count: int, seed: int) -> np.ndarray:
        """The largest |residual| per row (as :meth:`rows` stacks them) over ``count`` random
        machines, every deviation uniformly within its range (seeded): (M,)."""
        signs = np.random.default_rng(seed).uniform(-1.0, 1.0, (count, len(self.deviations)))
        out = np.zeros(0)
        for start in range(0, count, SAMPLED_CHUNK):
            part = np.abs(self.residuals(q, z, p, signs[start : start + SAMPLED_CHUNK])).max(axis=1)
            out = part if not out.size else np.maximum(out, part)
        return out

    def residuals(self, q: list[np.ndarray], z: np.ndarray, p: np.ndarray, signs: np.ndarray) -> np.ndarray:
        """The residual (rows as :meth:`rows` stacks them) at each deviation vector of ``signs``
        (C, n_dev), each entry a multiple of its half width in [−1, 1]: (M, C). Evaluated, not
        composed from the affine decomposition: what the corners of a residual that is not
        affine in the deviations are taken from (a point of a directly attached spring)."""
        out = []
        for b in range(len(self.formulation.blocks)):
            qb = q[b]
            fn = self.mapped(b, len(qb))
            columns = [self.along(b, qb, np.array(fn(qb.T, z, self.p_at(p, row))).T.reshape(-1)) for row in np.atleast_2d(signs)]
            out.append(np.stack(columns, axis=1))
        return np.concatenate(out)

    def mapped(self, b: int, n: int, which: str = "residual") -> Any:
        """Block ``b``'s residual (or ``which`` function) mapped over ``n`` columns, built once."""
        key = (b, n, which)
        if key not in self._maps:
            self._maps[key] = getattr(self.formulation.blocks[b], which).map(n)
        return self._maps[key]

    def p_with(self, p: np.ndarray, deviation: int | None) -> np.ndarray:
        """``p`` with deviation ``deviation`` at +h in every scenario (None: unchanged)."""
        if deviation is None:
            return p
        signs = [0] * len(self.deviations)
        signs[deviation] = 1
        return self.p_at(p, signs)

    def parameter_index(self, deviation: int) -> list[int]:
        """The entries of the parameter vector that hold deviation ``deviation`` (one per scenario)."""
        layout = self.formulation.parameters
        i = layout.base_names.index(self.deviations[deviation].parameter)
        return [c * layout.stride + 3 + i for c in range(len(self.problem.scenarios))]

    def p_at(self, p: np.ndarray, signs: Sequence[float]) -> np.ndarray:
        """``p`` with every deviation i at ``signs[i]`` × its half width, in every scenario."""
        out = np.array(p, dtype=float, copy=True)
        for i, (d, s) in enumerate(zip(self.deviations, signs)):
            out[self.parameter_index(i)] = s * d.half_width
        return out

    def values_at(self, signs: Sequence[float]) -> dict[str, float]:
        """The deviation parameters' values (SI) at a corner: name -> ``signs[i]`` × half width."""
        return {d.parameter: float(s) * d.half_width for d, s in zip(self.deviations, signs)}

    def rows(self, q: list[np.ndarray], z_ref: np.ndarray, free: Sequence[int], p: np.ndarray, deviations: bool = True) -> Rows:
        """The rows at configurations ``q`` (one array per block), around ``z_ref``, for
        unit steps of the scaled slots ``free``; ``deviations`` False: without the changes
        of the deviations (S0, SB and the groups left empty: the residual, the reference and
        the initial tensions' term only)."""
        f = self.formulation
        n_dev, n_free = (len(self.deviations) if deviations else 0), len(free)
        groups = self.groups if deviations else ()
        blocks_r0, blocks_A, blocks_S0, blocks_SB, blocks_T, blocks_ref, ids, revolute = [], [], [], [], [], [], [], []
        designs = [z_ref] + [z_ref + np.eye(z_ref.size)[j] for j in free]
        blocks_groups: list[tuple[list[np.ndarray], list[np.ndarray]]] = [([], []) for _ in groups]
        for b, block in enumerate(f.blocks):
            qb = q[b]
            n = len(qb)
            fn = self.mapped(b, n)

            def value(z: np.ndarray, dev: int | None, fn: Any = fn, qb: np.ndarray = qb, at: np.ndarray | None = None, b: int = b) -> np.ndarray:
                pv = self.p_with(p, dev) if at is None else at
                return self.along(b, qb, np.array(fn(qb.T, z, pv)).T.reshape(-1))  # (n · n_q,), configuration-major; along the manifold

            base = [value(z, None) for z in designs]
            r0 = base[0]
            A = np.stack([v - r0 for v in base[1:]], axis=1) if n_free else np.zeros((r0.size, 0))
            S0 = np.zeros((r0.size, n_dev))
            SB = np.zeros((r0.size, n_dev, n_free))
            for i in range(n_dev):
                shifted = [value(z, i) for z in designs]
                S0[:, i] = shifted[0] - r0
                for j in range(n_free):
                    SB[:, i, j] = (shifted[j + 1] - base[j + 1]) - S0[:, i]
            for g, members in enumerate(groups):
                vertices = list(itertools.product((-1, 1), repeat=len(members)))
                F = np.zeros((r0.size, len(vertices)))
                FB = np.zeros((r0.size, len(vertices), n_free))
                for k, v in enumerate(vertices):
                    signs = np.zeros(len(self.deviations))
                    signs[list(members)] = v
                    at = self.p_at(p, signs.tolist())
                    shifted = [value(z, None, at=at) for z in designs]
                    F[:, k] = shifted[0] - r0
                    for j in range(n_free):
                        FB[:, k, j] = (shifted[j + 1] - base[j + 1]) - F[:, k]
                blocks_groups[g][0].append(F)
                blocks_groups[g][1].append(FB)
            torque = np.abs(self.along(b, qb, np.array(self.mapped(b, n, "gravity_torque")(qb.T, z_ref, p)).T.reshape(-1)))
            kinds = np.tile([self.problem.coordinate[c].unit.dimension == "" for c in self.names(b)], n)
            blocks_r0.append(r0)
            blocks_A.append(A)
            blocks_S0.append(S0)
            blocks_SB.append(SB)
            blocks_T.append(self._tension(b, qb, z_ref, p))
            blocks_ref.append(torque)
            ids.append(np.full(r0.size, b))
            revolute.append(kinds)
        torque = np.concatenate(blocks_ref)
        kind = np.concatenate(revolute)
        reference = np.empty_like(torque)
        for k in (True, False):
            mask = kind == k
            if mask.any():
                largest = float(torque[mask].max())
                reference[mask] = largest if largest > 0 else 1.0
        return Rows(
            np.concatenate(blocks_r0),
            np.concatenate(blocks_A),
            np.concatenate(blocks_S0),
            np.concatenate(blocks_SB),
            np.concatenate(blocks_T),
            reference,
            np.array([d.tolerance.kind for d in self.deviations][:n_dev]),
            np.concatenate(ids),
            list(q),
            tuple(Group(members, np.concatenate(F), np.concatenate(FB)) for members, (F, FB) in zip(groups, blocks_groups)),
            kind,
        )

    def _tension(self, b: int, qb: np.ndarray, z: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Σ ΔF0 |∂d/∂q_j| per configuration and coordinate (configuration-major; closed
        loops: the cable's lever arm along the manifold, projected before its absolute value)."""
        block = self.formulation.blocks[b]
        out = np.zeros((len(qb), len(self.names(b))))
        if not self.tensions:
            return out.reshape(-1)
        from ..selection.geometry import spring_length_gradients

        f = self.formulation
        gravity_base = f.parameters.scenario_values(p)[block.scenario]
        variables = f.design.symbols(f.design.to_x(z), block.scenario)
        geometry = spring_length_gradients(self.original, block.subsystem, qb, variables, gravity_base[1], gravity_base[0])
        for name, amount in self.tensions.items():
            if name not in geometry:
                continue
            length, grad = geometry[name]
            out += amount * np.abs(self.along(b, qb, np.asarray(grad))) / (2 * np.maximum(length, 1e-12))[:, None]
        return out.reshape(-1)


def worst(rows: Rows, dz: np.ndarray, shape: str = "box", kinds: Sequence[str] | None = None) -> np.ndarray:
    """Worst-case residual ratio per row at the step ``dz`` (deviations of ``kinds`` only;
    None: all, initial tensions included): exact over the box (the module docstring), a
    bound over the ellipsoid when an element has several deviations."""
    r = rows.residual(dz)
    s = rows.sensitivities(dz)
    chosen = np.isin(rows.kinds, list(kinds)) if kinds is not None and rows.kinds.size else np.ones(s.shape[1], dtype=bool)
    tension = rows.tension if kinds is None or "initial_tension" in kinds else 0.0
    if shape != "box":  # first order over the ellipsoid, plus a bound of each group's products
        spread = np.sqrt((s[:, chosen] ** 2).sum(axis=1))
        for g in rows.groups:
            keep = [bool(chosen[i]) for i in g.members]
            if sum(keep) > 1:
                values = g.restricted(g.values(dz), keep)
                linear = s[:, [i for i, k in zip(g.members, keep) if k]]
                signs = np.array(list(itertools.product((-1.0, 1.0), repeat=sum(keep))))
                spread = spread + np.abs(values - linear @ signs.T).max(axis=1)
        return (np.abs(r) + spread + tension) / rows.reference
    single = chosen & ~rows.grouped
    spread = np.abs(s[:, single]).sum(axis=1)
    high, low = r + spread, r - spread
    for g in rows.groups:
        keep = [bool(chosen[i]) for i in g.members]
        if any(keep):
            values = g.restricted(g.values(dz), keep)
            high = high + values.max(axis=1)
            low = low + values.min(axis=1)
    return (np.maximum(high, -low) + tension) / rows.reference


def has_products(rows: Rows, shape: str) -> bool:
    """Whether the worst case of ``rows`` over the shape is a bound rather than exact: an
    ellipsoid with an element of several deviations (over the box every product is exact)."""
    return shape != "box" and bool(rows.groups)


def worst_corner(rows: Rows) -> tuple[int, tuple[int, ...]]:
    """The row where the worst case over the box is largest (at no step) and the corner that
    gives it (a sign per deviation): each single deviation at the sign of its change on that
    side, each group at its worst vertex (the deviations of different elements add)."""
    k = int(np.argmax(worst(rows, np.zeros(rows.A.shape[1]))))
    r, s = float(rows.r0[k]), rows.S0[k]
    single = ~rows.grouped
    high = r + float(np.abs(s[single]).sum()) + sum(float(g.F[k].max()) for g in rows.groups)
    low = r - float(np.abs(s[single]).sum()) + sum(float(g.F[k].min()) for g in rows.groups)
    up = high >= -low  # the residual's largest positive value is the worst
    signs = [0] * s.size
    for j in np.flatnonzero(single):
        signs[int(j)] = (1 if s[j] >= 0 else -1) * (1 if up else -1)
    for g in rows.groups:
        vertex = list(itertools.product((-1, 1), repeat=len(g.members)))[int(np.argmax(g.F[k]) if up else np.argmin(g.F[k]))]
        for i, v in zip(g.members, vertex):
            signs[i] = v
    return k, tuple(signs)
