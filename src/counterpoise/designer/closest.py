"""The closest design of a balance that cannot be met (a part of
:class:`~counterpoise.designer.designer.Designer`): least squares on the compressed balance
conditions, from several starts (:meth:`Closest.least_squares_multistart`), and the design
reported, the one with the smallest worst residual ratio on sampled configurations
(:meth:`Closest.minimax`). Each NLP is built on first use: only a problem that looks
infeasible pays for it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from ..formulation.conditions import BalanceConditions
from ..formulation.formulation import Formulation
from ..model.problem import BOUND_TOLERANCE, Problem
from ..solvers.base import Bounds, SolverOutput, Status
from ..solvers.gauss_newton import worst
from ..solvers.ipopt import IpoptBackend
from .balance import Balance, admissible, nlp_bounds
from .options import BoundsOverride

if TYPE_CHECKING:
    from .minimax import MinimaxDesigner

#: IPOPT tolerances of the least-squares closest-design solve (½|g|² needs the tight ones).
CLOSEST_TOL = 1e-14
CLOSEST_ACCEPTABLE_TOL = 1e-12
#: A variable put on its bound in the minimax closest design may raise the worst sampled
#: residual ratio by this much (absolute): rounding, not a worse design.
MINIMAX_ROUNDING = 1e-12
#: ``Solution.closest`` of a solve with ``certify=False`` (a probe of a part search or a
#: schedule): the least-squares closest design, which :meth:`Designer.certify` upgrades
LEAST_SQUARES_CLOSEST = "least squares on the compressed balance conditions"
#: ``Solution.closest`` when the minimax design failed or was no closer (see :meth:`Closest.minimax`)
LEAST_SQUARES_NO_CLOSER = LEAST_SQUARES_CLOSEST + "; the minimax design was no closer"
#: Seeded random starts of the closest-design search after the given ones (see
#: :meth:`Closest.least_squares_multistart`); only an infeasible-looking solve pays for them.
CLOSEST_RANDOM_STARTS = 4


def with_time(out: SolverOutput, seconds: float) -> SolverOutput:
    """``out`` with ``seconds`` as its solve time."""
    return SolverOutput(out.z, out.status, out.solver_status, out.iterations, seconds, out.solver)


class Closest:
    """The closest designs of a designer's problem (see the module docstring)."""

    def __init__(
        self, problem: Problem, formulation: Formulation, conditions: BalanceConditions, balance: Balance, options: Mapping[str, Any], ipopt_options: Mapping[str, Any]
    ) -> None:
        self.problem = problem
        self.formulation = formulation
        self.conditions = conditions
        self.balance = balance
        #: the designer's IPOPT options (its NLP's), and those it was given (the minimax designer's)
        self.options = dict(options)
        self._ipopt_options = dict(ipopt_options)
        self._feasibility: IpoptBackend | None = None  # ½|g|² subject to the signs (built on first use)
        self._minimax: MinimaxDesigner | None = None  # the epigraph NLP of the closest design (built on first use)

    def least_squares(self, z0: np.ndarray, p: np.ndarray, bounds: BoundsOverride | None = None) -> SolverOutput:
        """The design within the bounds that comes closest to balance (least squares)."""
        import casadi as ca

        f = self.formulation
        if self._feasibility is None:
            nlp = {"x": f.z, "p": f.p, "f": 0.5 * ca.sumsqr(self.conditions.equalities), "g": f.nonnegative}
            self._feasibility = IpoptBackend(nlp, {**self.options, "tol": CLOSEST_TOL, "acceptable_tol": CLOSEST_ACCEPTABLE_TOL}, "closest")
        b = nlp_bounds(f, None, 0, bounds, constraints=False)
        out = self._feasibility.solve(np.clip(z0, b.lbz, b.ubz), p, b)
        z = self.balance.refine(out.z, p, b)
        return SolverOutput(z, out.status, out.solver_status, out.iterations, out.solve_time, out.solver)

    def least_squares_multistart(
        self, starts: list[np.ndarray], p: np.ndarray, b: Bounds, bounds: BoundsOverride | None = None
    ) -> SolverOutput:
        """:meth:`least_squares` from each of ``starts``, then from :data:`CLOSEST_RANDOM_STARTS`
        seeded random designs in the box, until one balances; else the one closest to balance.

        Least squares on bilinear conditions (a mass times its offset) has local minima: a
        counter-mass at its lower bound with its offset on the wrong side is one, where the
        offset no longer matters and more mass only makes it worse. Other starts escape it.
        """
        rng = np.random.default_rng(self.problem.settings.seed)
        randoms = [b.lbz + (b.ubz - b.lbz) * rng.random(len(b.lbz)) for _ in range(CLOSEST_RANDOM_STARTS)]
        tried: list[tuple[float, int, SolverOutput]] = []
        elapsed = 0.0
        for i, z0 in enumerate([*starts, *randoms]):
            out = self.least_squares(z0, p, bounds)
            elapsed += out.solve_time
            g = np.array(self.balance.residual_jacobian()(out.z, p)[0]).reshape(-1)
            tried.append((float(np.abs(g).max(initial=0.0)), i, out))
            if self.balance.balances(out.z, p):
                break
        return with_time(min(tried)[2], elapsed)

    def minimax(self, z: np.ndarray, p: np.ndarray, b: Bounds) -> tuple[np.ndarray, str, float]:
        """The closest design reported for a balance that cannot be met: the one with the
        smallest worst residual ratio, the figure the report gives.

        Least squares on the compressed conditions (``z``, from :meth:`least_squares`) is not
        that design: it weighs the scaled conditions, not the residual ratio the dense check
        reports (issue 24: on an infeasible four-bar, a worst residual of 11.9 % where 9.39 %
        can be reached; tests/test_closest.py has such a four-bar and a closed-form case). So the epigraph NLP of :class:`~counterpoise.designer.minimax.MinimaxDesigner`
        (``min t s.t. |r_j(q_s; z)| ≤ t·T`` on sampled configurations, T the largest unbalanced
        gravity force of the coordinate's kind; built on first use) is solved from ``z``
        within the bounds, design constraints left out as in the least-squares design.
        Variables within BOUND_TOLERANCE × span of a bound are put on it when that does not
        raise the worst sampled ratio (beyond rounding). The minimax design is kept when IPOPT
        converged, the sign constraints hold and its worst sampled ratio is below the
        least-squares one; else ``z`` stands.

        Returns (design, what it is: the text of ``Solution.closest``, solve seconds).
        """
        from .minimax import MinimaxDesigner

        if self._minimax is None:
            self._minimax = MinimaxDesigner(self.problem, self._ipopt_options)
        m = self._minimax
        lo, hi = b.lbz, b.ubz
        least_squares = worst(m.ratios(z, p))
        out, _ = m.smallest_worst_ratio(z, p, lo, hi)
        candidate = np.clip(out.z, lo, hi)
        reached = worst(m.ratios(candidate, p))
        band = BOUND_TOLERANCE * (hi - lo)
        snapped = np.where((candidate - lo <= band) & (hi > lo), lo, np.where((hi - candidate <= band) & (hi > lo), hi, candidate))
        if not np.array_equal(snapped, candidate) and worst(m.ratios(snapped, p)) <= reached + MINIMAX_ROUNDING:
            candidate, reached = snapped, worst(m.ratios(snapped, p))
        signs = np.array(self.balance.residual_jacobian()(candidate, p)[2]).reshape(-1)[: int(self.formulation.nonnegative.numel())]
        if out.status is Status.OPTIMAL and admissible(signs) and reached < least_squares:
            return candidate, f"minimax: the smallest worst residual on {m.n_samples} sampled configurations", out.solve_time
        return z, LEAST_SQUARES_NO_CLOSER, out.solve_time

    def reported(self, z: np.ndarray, p: np.ndarray, b: Bounds, minimax: bool) -> tuple[np.ndarray, str, float]:
        """(closest design, what it is, seconds): minimax, or least squares when not ``minimax``."""
        if minimax:
            return self.minimax(z, p, b)
        return z, LEAST_SQUARES_CLOSEST, 0.0
