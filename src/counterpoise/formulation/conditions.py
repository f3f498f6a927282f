"""Exact balance equalities g(z, p) = 0 that stand for "∂V/∂q = 0 for every q".

Each (subsystem, scenario) block's residual, sampled on configurations, is compressed to
its rank (:mod:`.compression`); the stack of all blocks is compressed once more, so that
identical legs or scenarios do not repeat conditions. This relies on the residual lying in
a fixed finite-dimensional function space (:mod:`.assumptions` checks that it does).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .formulation import Block, Formulation

# .assumptions, .compression and .manifold's conditions are imported where the equalities are
# built: a designer kept by ``counterpoise solve`` (counterpoise.io.cache) is read back without them


class BalanceConditions:
    """Exact, rank-compressed balance equalities g(z, p) = 0 for a formulation."""

    def __init__(self, formulation: Formulation, parameters: np.ndarray, seed: int) -> None:
        import casadi as ca

        from .assumptions import check_exact_conditions
        from .compression import NOISE_TOLERANCE, adaptive_compression, coordinate_weights, largest_value, sample_residuals
        from .manifold import manifold_conditions

        check_exact_conditions(formulation.problem)
        self.formulation = formulation
        rng = np.random.default_rng(seed)
        f = formulation
        stacked = []
        #: (subsystem, scenario, number of independent conditions) of every block
        self.ranks: list[tuple[str, str, int]] = []
        for block in f.blocks:
            if f.problem.subsystem_loops(block.subsystem):  # closed loops: conditions on the manifold
                rank, rows = manifold_conditions(f, block, parameters, rng, self._random_designs)
                self.ranks.append((block.subsystem, block.scenario, rank))
                if rows is not None:
                    stacked.append(rows)
                continue
            coords = [f.problem.coordinate[n] for n in block.coordinates]
            lo = np.array([c.lower for c in coords])
            hi = np.array([c.upper for c in coords])
            n_q = len(coords)

            def sample(n_conf: int, n_design: int, block: Block = block) -> tuple[np.ndarray, Any, float]:
                q = lo + (hi - lo) * rng.random((n_conf, n_q))
                z = self._random_designs(n_design, rng)
                values = sample_residuals(block.residual, q, z, parameters)
                weights = coordinate_weights(values, n_q, NOISE_TOLERANCE * largest_value(block.magnitude, q, z, parameters))
                with np.errstate(over="ignore", invalid="ignore"):  # huge bounds: compress() reports the overflow
                    return values * np.tile(weights, n_conf)[:, None], (q, weights), 0.0

            # at least as many designs as a residual affine in the design variables needs (2·rank + 8), so that
            # a long chain is sampled once rather than twice
            start_designs = max(32, 2 * (len(f.design) + 1) + 8)
            comp, (q, weights) = adaptive_compression(sample, start_configurations=16 + 8 * n_q, start_designs=start_designs)
            self.ranks.append((block.subsystem, block.scenario, comp.rank))
            if comp.rank:
                residual_at = {i: block.residual(q[i], f.z, f.p) for i in sorted({int(r) // n_q for r in comp.rows})}
                rows = [residual_at[int(r) // n_q][int(r) % n_q] * float(weights[int(r) % n_q]) for r in comp.rows]
                stacked.append(ca.mtimes(ca.DM(comp.matrix), ca.vertcat(*rows)))
        per_block = ca.vertcat(*stacked) if stacked else ca.SX(0, 1)
        # Across blocks: identical legs, or scenarios that repeat a condition, collapse here.
        self.equalities = self._compress_stack(per_block, parameters, rng)

    def _compress_stack(self, stacked: Any, parameters: np.ndarray, rng: np.random.Generator) -> Any:
        import casadi as ca

        from .compression import numerical_rank

        f = self.formulation
        if stacked.numel() == 0:
            return stacked
        fun = ca.Function("stack", [f.z, f.p], [stacked])
        n_design = 2 * stacked.numel() + 8
        z = self._random_designs(n_design, rng)
        values = np.array(fun.map(n_design)(z.T, np.tile(parameters[:, None], (1, n_design))))
        u, s, _ = np.linalg.svd(values, full_matrices=False)
        rank = numerical_rank(s)
        if rank == stacked.numel():
            return stacked
        return ca.mtimes(ca.DM(u[:, :rank].T), stacked)

    def _random_designs(self, n: int, rng: np.random.Generator) -> np.ndarray:  # noqa: D401
        """``n`` scaled designs drawn uniformly in the bounds: (n, number of slots)."""
        d = self.formulation.design
        return d.to_z(d.lower + (d.upper - d.lower) * rng.random((n, len(d))))

    @property
    def count(self) -> int:
        return int(self.equalities.numel())

    def summary(self) -> str:
        """'leg/nominal 3' per block, and whether repeats were removed."""
        parts = ", ".join(f"{sub}/{sc} {r}" for sub, sc, r in self.ranks)
        total = sum(r for *_, r in self.ranks)
        return parts + (f"; {total} before removing repeats across blocks" if total != self.count else "")
