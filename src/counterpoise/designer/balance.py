"""The compressed balance equalities at a design: their evaluation, the balance test and
every polish of a solver's point (a part of :class:`~counterpoise.designer.designer.Designer`).

Each polish (:meth:`Balance.polish` with :meth:`Balance.snap` and :meth:`Balance.finish`,
:meth:`Balance.refine`, :meth:`Balance.polish_settings`) is one call of
:func:`counterpoise.solvers.gauss_newton.gauss_newton` with its own free variables and rules.
What it evaluates (the equalities, their Jacobian and the sign constraints; each setting's
residuals on seeded configurations) is built on first use and kept.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..formulation.conditions import BalanceConditions
from ..formulation.constraints import ConstraintRows
from ..formulation.formulation import Formulation
from ..model.problem import BOUND_TOLERANCE, Problem
from ..numeric import NumericFunction
from ..solvers.base import Bounds
from ..solvers.gauss_newton import Evaluate, Evaluation, gauss_newton

#: The compressed balance equalities (each coordinate's rows scaled to order one) hold when
#: every one is at most this (see :meth:`Balance.balances`).
BALANCE_TOLERANCE = 1e-9
#: Gauss-Newton on the balance equalities stops once every one is at most this (exact to rounding).
EXACT_BALANCE = 1e-15
#: A variable tried on a bound (:meth:`Balance.polish`) may raise the objective by this
#: much (relative, at least absolute on objectives below 1): rounding, not a worse design.
OBJECTIVE_ROUNDING = 1e-12
#: evaluations of the balance equalities kept for the same point asked again (:meth:`Balance.residual_jacobian`)
REMEMBERED_EVALUATIONS = 4
#: configurations per coordinate on which a setting's adjustments are polished (infeasible problems)
POLISH_CONFIGURATIONS = 8
#: Balance equalities below this are rounding noise: each coordinate's rows are scaled by its
#: largest sampled residual (formulation.conditions), so the equalities are of order one and
#: a few thousand ulps of them is noise, not a worse balance (used when polishing onto bounds).
ROUNDING_FLOOR = 1e-12
#: Variables this close to a bound (× span) are tried on it, one at a time, and kept there
#: when that is no worse (see :meth:`Balance.polish`); within BOUND_TOLERANCE × span they
#: are put on it as long as the balance holds.
SNAP_BAND = 1e-5


def admissible(signs: np.ndarray) -> bool:
    """The sign constraints (and constraint margins) hold: every one ≥ 0."""
    return bool(signs.size == 0 or signs.min() >= 0)


def nlp_bounds(formulation: Formulation, rows: ConstraintRows | None, n_equalities: int, overrides: Any = None, constraints: bool = True) -> Bounds:
    """Variable bounds (with per-call ``overrides``, SI: a slot or a variable name ->
    (lower, upper)) and the bounds of [``n_equalities`` equalities; signs ≥ 0; the design
    constraints' rows (unless ``constraints`` is False)]."""
    lbz, ubz = formulation.design.bounds(overrides)
    n_in = int(formulation.nonnegative.numel())
    kept = rows if constraints and rows is not None else None
    return Bounds(
        lbz,
        ubz,
        np.concatenate([np.zeros(n_equalities + n_in), kept.lbg if kept is not None else []]),
        np.concatenate([np.zeros(n_equalities), np.full(n_in, np.inf), kept.ubg if kept is not None else []]),
    )


class Balance:
    """The balance equalities of a designer's formulation (and the signs and constraint
    margins that must stay ≥ 0) at a design: evaluated, tested and polished."""

    def __init__(self, problem: Problem, formulation: Formulation, conditions: BalanceConditions, rows: ConstraintRows | None) -> None:
        self.problem = problem
        self.formulation = formulation
        self.conditions = conditions
        self.rows = rows
        self._residual_jacobian: NumericFunction | None = None
        self._settings: dict[str, tuple[Any, np.ndarray]] | None = None

    def balances(self, z: np.ndarray, p: np.ndarray, tolerance: float = BALANCE_TOLERANCE) -> bool:
        """Whether the compressed balance equalities hold at ``z`` (scaled as in the NLP)."""
        g = np.array(self.residual_jacobian()(z, p)[0]).reshape(-1)
        return bool(g.size == 0 or np.abs(g).max() <= tolerance)

    # -- helpers -------------------------------------------------------------------

    def residual_jacobian(self) -> NumericFunction:
        """(z, p) -> (balance equalities, their Jacobian, sign constraints) as arrays: a CasADi
        function evaluated through its buffers (:class:`~counterpoise.numeric.NumericFunction`), built once.
        The latest few evaluations are kept: a polish asks again for the point its
        Gauss-Newton steps ended at (:meth:`snap`, then :meth:`finish`)."""
        import casadi as ca

        if self._residual_jacobian is None:
            f = self.formulation
            eq = self.conditions.equalities
            signs = ca.vertcat(f.nonnegative, self.rows.margins()) if self.rows is not None else f.nonnegative
            self._residual_jacobian = NumericFunction(ca.Function("gJ", [f.z, f.p], [eq, ca.jacobian(eq, f.z), signs]), remember=REMEMBERED_EVALUATIONS)
        return self._residual_jacobian

    def evaluation(self, p: np.ndarray) -> Evaluate:
        """The balance equalities at ``p`` for :func:`~counterpoise.solvers.gauss_newton.gauss_newton`:
        (g, ∂g/∂z, whether the sign constraints hold)."""
        gj = self.residual_jacobian()

        def evaluate(z: np.ndarray) -> Evaluation:
            g, jac, signs = gj(z, p)  # new arrays on every call
            return g.reshape(-1), jac, admissible(signs)

        return evaluate

    def polish(self, z: np.ndarray, p: np.ndarray, bounds: Bounds, iterations: int = 8) -> np.ndarray:
        """Put variables that the solver left a hair inside a bound exactly on it.

        An interior-point solution sits ~1e-9 inside its active bounds. Each variable within
        :data:`~counterpoise.model.problem.BOUND_TOLERANCE` × span of a bound (the rule the
        reports use) is moved onto it and the balance equalities are re-solved for the
        other variables (Gauss-Newton). The polished point is kept only if it balances at
        least as well and respects the sign constraints; otherwise the solver's point stands.

        When the variables' scales differ widely, IPOPT can stop farther inside an active
        bound (1.1e-7 of the span for a lever whose counter-mass may reach 50 t). So each
        variable within :data:`SNAP_BAND` × span is then tried on its bound, one at a time,
        and kept there only if the objective does not get worse: a design exactly on the
        bound and no worse is the better report.
        """
        lo, hi = bounds.lbz, bounds.ubz
        band = BOUND_TOLERANCE * (hi - lo)
        at_lo = (z - lo <= band) & (hi > lo)
        z = self.snap(z, p, bounds, at_lo, (hi - z <= band) & (hi > lo) & ~at_lo, iterations, None)
        span = hi - lo
        near = SNAP_BAND * span
        with np.errstate(divide="ignore", invalid="ignore"):  # a fixed variable (span 0) is not tried
            share = np.minimum(z - lo, hi - z) / span  # each variable's distance to its nearer bound, per span
            tried = (hi > lo) & (lo < z) & (z < hi) & (share * span <= near)
        for _, i in sorted((float(share[i]), int(i)) for i in np.flatnonzero(tried)):
            on_lo, on_hi = (z == lo) & (hi > lo), (z == hi) & (hi > lo)
            if z[i] - lo[i] <= hi[i] - z[i]:
                on_lo[i] = True
            else:
                on_hi[i] = True
            f0 = float(self.formulation.report_values(z, p)[0][0, 0])
            z = self.snap(z, p, bounds, on_lo, on_hi, iterations, f0 + OBJECTIVE_ROUNDING * max(1.0, abs(f0)))
        return self.finish(z, p, bounds, iterations)

    def finish(self, z: np.ndarray, p: np.ndarray, bounds: Bounds, iterations: int = 8) -> np.ndarray:
        """Gauss-Newton steps on the balance equalities, moving only the variables inside
        their bounds, while each step at least halves the largest equality.

        The equalities are scaled by the largest residual sampled over the whole variable
        box; when a bound is far larger than what the design uses (a stiffness allowed up to
        1e7 N/m that ends at 0.15 N/m), IPOPT's stop (``|g| ~ 1e-16`` in those units) can still be
        1e-8 of the design's own gravity torque, which the dense check sees. Rounding stops
        the steps; a step that breaks a sign constraint is not taken."""
        lo, hi = bounds.lbz, bounds.ubz
        free = (z > lo) & (z < hi)
        if not free.any():
            return z
        return gauss_newton(self.evaluation(p), z, lo, hi, free=free, iterations=iterations, decrease=0.5).z

    def snap(
        self, z: np.ndarray, p: np.ndarray, bounds: Bounds, at_lo: np.ndarray, at_hi: np.ndarray, iterations: int, objective_limit: float | None
    ) -> np.ndarray:
        """``z`` with the variables ``at_lo``/``at_hi`` on those bounds and the others
        re-solved (see :meth:`polish`); or ``z`` itself if that balances worse, breaks a sign
        constraint or makes the objective exceed ``objective_limit``."""
        lo, hi = bounds.lbz, bounds.ubz
        active = at_lo | at_hi
        candidate = np.where(at_lo, lo, np.where(at_hi, hi, z))
        if not active.any() or np.array_equal(candidate, z):
            return z
        gj = self.residual_jacobian()
        candidate = gauss_newton(self.evaluation(p), candidate, lo, hi, free=~active, iterations=iterations, tolerance=EXACT_BALANCE, decrease=None).z
        g_new, _, signs = (np.array(v).reshape(-1) for v in gj(candidate, p))
        g_old = np.array(gj(z, p)[0]).reshape(-1)
        worst_new = np.abs(g_new).max(initial=0.0)
        worst_old = np.abs(g_old).max(initial=0.0)
        if not (worst_new <= max(worst_old, ROUNDING_FLOOR) and admissible(signs)):
            return z
        if objective_limit is not None and not float(self.formulation.report_values(candidate, p)[0][0, 0]) <= objective_limit:
            return z
        return candidate

    def polish_settings(self, z: np.ndarray, p: np.ndarray, b: Bounds, iterations: int = 20) -> np.ndarray:
        """The closest design of an infeasible problem, with the adjustments of each setting
        (a working mode, a payload sample) re-solved for that setting's own balance.

        A least-squares closest design trades every scenario against the others, so a
        scenario that its own adjustments could balance is left a little off. Here the
        shared variables stay; for each setting, Gauss-Newton steps on the residuals of its
        scenarios (on seeded configurations, :data:`POLISH_CONFIGURATIONS` per coordinate)
        move only its adjustments, within their bounds. Kept when that setting's residual
        drops and the sign constraints hold; the dense check then says which scenarios are met.
        """
        gj = self.residual_jacobian()
        for function, columns in self._setting_residuals().values():

            def evaluate(candidate: np.ndarray, function: Any = function) -> Evaluation:
                r, jac = (np.array(v) for v in function(candidate, p))
                return r, jac, admissible(np.array(gj(candidate, p)[2]))

            z = gauss_newton(evaluate, z, b.lbz, b.ubz, free=columns, iterations=iterations).z
        return z

    def _setting_residuals(self) -> dict[str, tuple[Any, np.ndarray]]:
        """Per setting with adjustments: a CasADi function (z, p) -> (residuals of its scenarios
        on seeded configurations, their Jacobian), and the indices of its adjustment slots."""
        import casadi as ca

        if self._settings is not None:
            return self._settings
        f = self.formulation
        problem = self.problem
        rng = np.random.default_rng(problem.settings.seed + 3)
        out: dict[str, tuple[Any, np.ndarray]] = {}
        for setting in dict.fromkeys(problem.setting(s.name) for s in problem.scenarios):
            columns = np.array([i for i, slot in enumerate(f.design.slots) if slot.scenario == setting], dtype=int)
            if columns.size == 0:
                continue
            rows = []
            for block in f.blocks:
                if problem.setting(block.scenario) != setting:
                    continue
                coords = [problem.coordinate[n] for n in block.coordinates]
                lo = np.array([c.lower for c in coords])
                hi = np.array([c.upper for c in coords])
                for q in lo + (hi - lo) * rng.random((POLISH_CONFIGURATIONS * len(coords), len(coords))):
                    rows.append(block.residual(q, f.z, f.p))
            r = ca.vertcat(*rows)
            out[setting] = (ca.Function("setting_residual", [f.z, f.p], [r, ca.jacobian(r, f.z)]), columns)
        self._settings = out
        return out

    def refine(self, z: np.ndarray, p: np.ndarray, b: Bounds, iterations: int = 8) -> np.ndarray:
        """Gauss-Newton steps on the balance equalities from ``z``, within the bounds.

        Least squares on ``½|g|²`` stops near ``|g| ~ 1e-8`` (squaring loses half the digits), just
        short of :meth:`balances`; a few Newton steps on g itself finish the job when a
        balanced design is that near. Kept only while ``|g|`` decreases and signs stay ≥ 0.
        """
        # a fixed variable (lower = upper: a part's rate in a part search) does not move: in
        # the minimum-norm step it would take a share that the bounds then cut away, and the
        # steps would stall short of balance (issue 32)
        return gauss_newton(self.evaluation(p), z, b.lbz, b.ubz, free=b.ubz > b.lbz, iterations=iterations, tolerance=EXACT_BALANCE).z
