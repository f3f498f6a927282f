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
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..formulation.formulation import Formulation
from ..model.problem import Problem
from .perturb import Deviation

#: configurations per (subsystem, scenario) block in the robust LP
LP_CONFIGURATIONS = 1024


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

    def residual(self, dz: np.ndarray) -> np.ndarray:
        return self.r0 + self.A @ dz

    def sensitivities(self, dz: np.ndarray) -> np.ndarray:
        return self.S0 + self.SB @ dz if self.SB.shape[2] else self.S0


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
        spec = original.robust
        self.tensions = {t.item: t.amount for t in (spec.tolerances if spec else ()) if t.kind == "initial_tension" and t.amount > 0}

    def configurations(self, count: int, seed: int) -> list[np.ndarray]:
        rng = np.random.default_rng(seed)
        out = []
        for block in self.formulation.blocks:
            coords = [self.problem.coordinate[n] for n in block.coordinates]
            out.append(grid(np.array([c.lower for c in coords]), np.array([c.upper for c in coords]), count, rng))
        return out

    def _map(self, b: int, n: int, which: str = "residual") -> Any:
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

    def rows(self, q: list[np.ndarray], z_ref: np.ndarray, free: Sequence[int], p: np.ndarray) -> Rows:
        """The rows at configurations ``q`` (one array per block), around ``z_ref``, for
        unit steps of the scaled slots ``free``."""
        f = self.formulation
        n_dev, n_free = len(self.deviations), len(free)
        blocks_r0, blocks_A, blocks_S0, blocks_SB, blocks_T, blocks_ref, ids, revolute = [], [], [], [], [], [], [], []
        designs = [z_ref] + [z_ref + np.eye(z_ref.size)[j] for j in free]
        for b, block in enumerate(f.blocks):
            qb = q[b]
            n = len(qb)
            fn = self._map(b, n)

            def value(z: np.ndarray, dev: int | None, fn: Any = fn, qb: np.ndarray = qb) -> np.ndarray:
                return np.array(fn(qb.T, z, self.p_with(p, dev))).T.reshape(-1)  # (n · n_q,), configuration-major

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
            torque = np.abs(np.array(self._map(b, n, "gravity_torque")(qb.T, z_ref, p)).T.reshape(-1))
            kinds = np.tile([self.problem.coordinate[c].unit.dimension == "" for c in block.coordinates], n)
            blocks_r0.append(r0)
            blocks_A.append(A)
            blocks_S0.append(S0)
            blocks_SB.append(SB)
            blocks_T.append(self._tension(block, qb, z_ref, p))
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
            np.array([d.tolerance.kind for d in self.deviations]),
            np.concatenate(ids),
            list(q),
        )

    def _tension(self, block: Any, qb: np.ndarray, z: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Σ ΔF0 |∂d/∂q_j| per configuration and coordinate (configuration-major)."""
        out = np.zeros((len(qb), len(block.coordinates)))
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
            out += amount * np.abs(grad) / (2 * np.maximum(length, 1e-12))[:, None]
        return out.reshape(-1)


def worst(rows: Rows, dz: np.ndarray, shape: str = "box", kinds: Sequence[str] | None = None) -> np.ndarray:
    """Worst-case residual ratio per row at the step ``dz`` (deviations of ``kinds`` only;
    None: all, initial tensions included)."""
    r = np.abs(rows.residual(dz))
    s = rows.sensitivities(dz)
    if kinds is not None:
        s = s[:, np.isin(rows.kinds, list(kinds))] if rows.kinds.size else s
    spread = np.abs(s).sum(axis=1) if shape == "box" else np.sqrt((s**2).sum(axis=1))
    tension = rows.tension if kinds is None or "initial_tension" in kinds else 0.0
    return (r + spread + tension) / rows.reference
