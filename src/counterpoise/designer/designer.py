"""The designer: a problem's formulation, its exact balance conditions and a solver backend,
built once and solved many times.

``Designer(problem).solve()`` returns a :class:`Solution` (not yet verified). Parameters
(gravity and every literal parameter of every scenario) are the NLP's parameter vector,
so ``solve(parameters=...)`` re-solves a study point without rebuilding, and variable
bounds may be changed per call. CasADi objects do not pickle: a designer pickles as its
description (the problem and the solver options) and rebuilds itself in the worker.
``counterpoise solve`` keeps the state of each designer it builds on disk (its CasADi
objects written in one CasADi pickle context, :mod:`counterpoise.io.cache`), and a later
solve of the same content takes it from there instead of building (``_restore``).
When the problem is an LP (fixed geometry) it is solved by Clarabel, and an IPOPT design
gets a certificate gap (:mod:`.convex`). Every polish of a solver's point (:meth:`Designer.finish`,
``_snap``, :meth:`Designer.refine`, :meth:`Designer.polish_settings`) is one call of
:func:`counterpoise.solvers.gauss_newton.gauss_newton` with its own free variables and rules.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any, TypeGuard

import numpy as np

from ..formulation.conditions import BalanceConditions
from ..formulation.formulation import Formulation
from ..formulation.layout import Slot
from ..formulation.manifold import Geometries, for_geometry
from ..model.problem import BOUND_TOLERANCE, Problem
from ..solvers.base import Bounds, SolverOutput, Status
from ..solvers.gauss_newton import Evaluate, Evaluation, gauss_newton, worst
from ..solvers.ipopt import IPOPT_DEFAULTS, IpoptBackend
from ..numeric import NumericFunction
from ..threads import limit_blas_threads
from . import convex
from ..formulation.constraints import MAX_ROUNDS, ConstraintRows, Extra, build_rows, evaluate, merge, violations
from .constrained import (
    BALANCEABLE_BUT_INFEASIBLE,
    INVALID_NUMBER,
    attach_constraints,
    between_samples,
    conflict_message,
    name_conflict,
    name_invalid_numbers,
    rows_multipliers,
    unmet_at,
)
from .options import BoundsOverride, SolveOptions
from .solution import Solution, build_solution

if TYPE_CHECKING:
    from ..io.cache import BuiltEntry
    from .minimax import MinimaxDesigner

#: The compressed balance equalities (each coordinate's rows scaled to order one) hold when
#: every one is at most this (see :meth:`Designer.balances`).
BALANCE_TOLERANCE = 1e-9
#: Gauss-Newton on the balance equalities stops once every one is at most this (exact to rounding).
EXACT_BALANCE = 1e-15
#: A variable tried on a bound (:meth:`Designer.polish`) may raise the objective by this
#: much (relative, at least absolute on objectives below 1): rounding, not a worse design.
OBJECTIVE_ROUNDING = 1e-12
#: Singular values below this share of the largest count as zero (rank of the conditions).
RANK_TOLERANCE = 1e-8
#: IPOPT tolerances of the least-squares closest-design solve (½|g|² needs the tight ones).
CLOSEST_TOL = 1e-14
CLOSEST_ACCEPTABLE_TOL = 1e-12

#: evaluations of the balance equalities kept for the same point asked again (:meth:`Designer.residual_jacobian`)
REMEMBERED_EVALUATIONS = 4

#: configurations per coordinate on which a setting's adjustments are polished (infeasible problems)
POLISH_CONFIGURATIONS = 8

#: Balance equalities below this are rounding noise: each coordinate's rows are scaled by its
#: largest sampled residual (formulation.conditions), so the equalities are of order one and
#: a few thousand ulps of them is noise, not a worse balance (used when polishing onto bounds).
ROUNDING_FLOOR = 1e-12


#: A variable put on its bound in the minimax closest design may raise the worst sampled
#: residual ratio by this much (absolute): rounding, not a worse design.
MINIMAX_ROUNDING = 1e-12
#: ``Solution.closest`` of a solve with ``certify=False`` (a probe of a part search or a
#: schedule): the least-squares closest design, which :meth:`Designer.certify` upgrades
LEAST_SQUARES_CLOSEST = "least squares on the compressed balance conditions"
#: ``Solution.closest`` when the minimax design failed or was no closer (see
#: :meth:`Designer.closest_minimax`)
LEAST_SQUARES_NO_CLOSER = LEAST_SQUARES_CLOSEST + "; the minimax design was no closer"

#: Seeded random starts of the closest-design search after the given ones (see
#: :meth:`Designer.closest_design_multistart`); only an infeasible-looking solve pays for them.
CLOSEST_RANDOM_STARTS = 4
#: Variables this close to a bound (× span) are tried on it, one at a time, and kept there
#: when that is no worse (see :meth:`Designer.polish`); within BOUND_TOLERANCE × span they
#: are put on it as long as the balance holds.
SNAP_BAND = 1e-5


class Designer:
    """Builds the solver for a problem once; :meth:`solve` may be called many times."""

    def __init__(self, problem: Problem, ipopt_options: Mapping[str, Any] | None = None, backend: str = "auto", extra: Extra | None = None) -> None:
        """``backend``: ``auto`` (the convex path when the problem is an LP/QP, else IPOPT),
        ``ipopt`` or ``clarabel`` (an error when the problem is not convex). ``extra``:
        configurations added to the sampled rows of workspace extremes (verification rounds).
        Under ``counterpoise solve`` the state built from the same content by an earlier
        solve is taken from the disk when it is kept there (:meth:`_restore`)."""
        import casadi as ca

        limit_blas_threads()
        kept = _kept_entry(problem, ipopt_options, backend, extra, self) if type(self) is Designer else None
        if kept is not None and self._restore(kept, problem):
            return
        self.problem = problem
        self._ipopt_options = dict(ipopt_options or {})
        self.formulation = f = Formulation(problem)
        self.parameters = f.parameters.values()
        self.conditions = BalanceConditions(f, self.parameters, problem.settings.seed)
        self.n_equalities = self.conditions.count
        self.options = {**IPOPT_DEFAULTS, "max_iter": problem.settings.max_iterations, **self._ipopt_options}
        #: design constraints and force limits as rows after the sign constraints (None: none)
        self.rows: ConstraintRows | None = build_rows(f, extra) if problem.constraints else None
        self._extra = dict(extra or {})
        nlp: dict[str, Any] = {"x": f.z, "p": f.p, "f": f.objective, "g": ca.vertcat(self.conditions.equalities, f.nonnegative, *self._row_g())}  # CasADi SX (no stubs)
        self.backend = IpoptBackend(nlp, self.options, "design")
        self.backend_choice = backend
        self.nlp = nlp
        #: the LP/QP backend when every variable enters linearly (see :mod:`.convex`)
        self.convex = convex.convex_backend(self, backend)
        #: a nonlinear constraint that moved an LP problem to the NLP (the names; empty: none)
        self.nonlinear_constraints = convex.nonlinear_constraints(self) if self.convex is None and self.rows is not None and backend == "auto" else ()
        self._refined: Designer | None = None  # with the configurations of verification rounds
        self._round = 0
        #: the LP over the linear variables at a fixed geometry (built on first use)
        self.certificate = convex.Certificate(self)
        self._feasibility: IpoptBackend | None = None
        self._residual_jacobian: NumericFunction | None = None
        self._settings: dict[str, tuple[Any, np.ndarray]] | None = None
        self._minimax: MinimaxDesigner | None = None  # the epigraph NLP of the closest design (built on first use)
        #: designers of this problem rebuilt for other loop geometries (:func:`for_geometry`)
        self.geometries = Geometries()
        if kept is not None:  # just built and not yet used: kept for a later counterpoise solve
            kept.keep(dict(self.__dict__))

    # -- kept on disk by counterpoise solve (counterpoise.io.cache) -----------------------
    def _restore(self, kept: BuiltEntry, problem: Problem) -> bool:
        """Take the state of a designer built from the same content, kept on disk by an
        earlier ``counterpoise solve`` (:class:`counterpoise.io.cache.BuiltEntry`); False when
        there is none. Its CasADi expressions and functions are unpickled in one CasADi
        context (shared symbols stay shared), so they are the ones built: the same
        designs, bit for bit."""

        def valid(found: object) -> TypeGuard[dict[str, Any]]:  # the state of a designer of this problem (put back in its place)
            return isinstance(found, dict) and found.get("problem") is problem

        state = kept.fetch(valid)
        if state is None:
            return False
        self.__dict__.update(state)
        return True

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickle as a description; the worker rebuilds the CasADi objects."""
        return (Designer, (self.problem, self._ipopt_options, self.backend_choice))

    # -- one call ------------------------------------------------------------------
    def bounds(self, n_equalities: int, overrides: BoundsOverride | None = None, constraints: bool = True) -> Bounds:
        """Variable bounds (with per-call ``overrides``, SI) and [equalities; signs ≥ 0;
        constraint rows (unless ``constraints`` is False)]."""
        lbz, ubz = self.formulation.design.bounds(overrides)
        n_in = int(self.formulation.nonnegative.numel())
        rows = self.rows if constraints and self.rows is not None else None
        return Bounds(
            lbz,
            ubz,
            np.concatenate([np.zeros(n_equalities + n_in), rows.lbg if rows is not None else []]),
            np.concatenate([np.zeros(n_equalities), np.full(n_in, np.inf), rows.ubg if rows is not None else []]),
        )

    def _row_g(self) -> list[Any]:
        return [self.rows.g] if self.rows is not None else []

    def solve(
        self,
        initial: Mapping[Slot, float] | None = None,
        parameters: Mapping[str, float] | None = None,
        bounds: BoundsOverride | None = None,
        certify: bool = True,
    ) -> Solution:
        """Solve with the built solver.

        ``initial`` overrides initial values (SI) of design-vector slots; ``parameters``
        overrides base parameters (SI) in every scenario; ``bounds`` maps a slot or a
        variable name to (lower, upper) in SI for this call only. Nothing is rebuilt, except
        for ``parameters`` that change a closed loop's geometry: the manifold equalities hold
        on one geometry, so a designer of those values is built (and kept) for them. The
        compression was computed at the file's values; the dense verification of the
        result says whether it still holds (a parameter that was 0 at build time may have
        hidden a condition).

        ``certify``: compute the solution's certificate gap (an LP, see :mod:`.convex`) and,
        for an infeasible problem, the minimax closest design (:meth:`closest_minimax`);
        callers that solve many times and report one design (part searches, schedules,
        multi-start) pass False (their probes get the least-squares closest design) and
        :meth:`certify` the one they report.
        """
        return self.solve_with(SolveOptions(parameters, bounds, initial, certify))

    def solve_with(self, options: SolveOptions) -> Solution:
        """:meth:`solve` with its options in one :class:`~.options.SolveOptions`."""
        parameters, bounds = options.parameters, options.bounds
        other = for_geometry(self, parameters, lambda problem: Designer(problem, self._ipopt_options, self.backend_choice), self.geometries)
        if other is not self:  # closed loops: a new geometry needs its own manifold equalities
            return other.solve_with(options)
        if self._refined is not None:  # a verification round added configurations
            return self._refined.solve_with(options)
        d = self.formulation.design
        p = self.formulation.parameters.values(parameters) if parameters else self.parameters
        b = self.bounds(self.n_equalities, bounds)
        z0 = np.clip(d.to_z(d.vector(options.initial or {})), b.lbz, b.ubz)
        solution = self._solve(z0, p, b, bounds, options.certify)
        # rounds only for a design whose solver held its sampled rows (one the dense check
        # then failed between them): re-solving a failed or conflicting one with more rows
        # cannot help (a max_force of 1e-300 N took 5 elastic solves of 500 iterations)
        add = violations(self.problem, solution.constraints) if solution.status is Status.OPTIMAL or between_samples(solution) else {}
        if add and self._round < MAX_ROUNDS:
            # a workspace extreme beyond its bound between the sampled configurations: add
            # the dense check's worst configurations to the rows and solve again from here
            extra = merge(self._extra, add)
            refined = Designer(self.problem, self._ipopt_options, self.backend_choice, extra)
            refined._round = self._round + 1
            self._refined = refined
            return refined.solve_with(replace(options, initial=dict(solution.values)))
        if options.certify:
            solution = replace(solution, stats=replace(solution.stats, certificate_gap=self._certificate_gap(solution, p, b)))
        return solution

    def certify(self, solution: Solution, parameters: Mapping[str, float] | None = None, bounds: BoundsOverride | None = None) -> Solution:
        """``solution`` (solved with these ``parameters`` and ``bounds``) with its certificate
        gap and, for an infeasible design, its minimax closest design: a new value."""
        other = for_geometry(self, parameters, lambda problem: Designer(problem, self._ipopt_options, self.backend_choice), self.geometries)
        if other is not self:
            return other.certify(solution, parameters, bounds)
        if self._refined is not None:
            return self._refined.certify(solution, parameters, bounds)
        p = self.formulation.parameters.values(parameters) if parameters else self.parameters
        b = self.bounds(self.n_equalities, bounds)
        if solution.status is Status.INFEASIBLE and solution.closest == LEAST_SQUARES_CLOSEST:
            solution = self._upgrade_closest(solution, p, b)
        return replace(solution, stats=replace(solution.stats, certificate_gap=self._certificate_gap(solution, p, b)))

    def _upgrade_closest(self, solution: Solution, p: np.ndarray, b: Bounds) -> Solution:
        """``solution`` (a solve made with ``certify=False``) with its least-squares closest
        design replaced by the minimax one (:meth:`closest_minimax`): the design reported."""
        d = self.formulation.design
        z, kind, seconds = self.closest_minimax(d.to_z(d.vector(solution.values)), p, b)
        if kind != LEAST_SQUARES_NO_CLOSER:
            z = self.polish_settings(z, p, b)
        stats = solution.stats
        out = SolverOutput(z, solution.status, stats.solver_status, stats.iterations, stats.solve_time + seconds, stats.solver)
        new = self._solution(z, p, b, out, solution.message, kind)
        return replace(
            solution,
            status=new.status,
            message=new.message,
            values=new.values,
            objective=new.objective,
            added_mass=new.added_mass,
            added_inertia=new.added_inertia,
            stats=replace(stats, solve_time=new.stats.solve_time),
            scenario_parameters=new.scenario_parameters,
            verdicts=new.verdicts,
            constraints=new.constraints,
            closest=new.closest,
        )

    def closest_reported(self, z: np.ndarray, p: np.ndarray, b: Bounds, minimax: bool) -> tuple[np.ndarray, str, float]:
        """(closest design, what it is, seconds): minimax, or least squares when not ``minimax``."""
        if minimax:
            return self.closest_minimax(z, p, b)
        return z, LEAST_SQUARES_CLOSEST, 0.0

    def _certificate_gap(self, solution: Solution, p: np.ndarray, b: Bounds) -> float:
        d = self.formulation.design
        return self.certificate.gap(d.to_z(d.vector(solution.values)), p, b, solution.stats.solver, solution.objective)

    def _solve(self, z0: np.ndarray, p: np.ndarray, b: Bounds, bounds: BoundsOverride | None, minimax: bool = True) -> Solution:
        """``minimax``: report the minimax closest design of an infeasible problem (else the
        least-squares one, upgraded by :meth:`certify`)."""
        d = self.formulation.design
        if self.convex is not None:
            z, out, message, kind = convex.solve_convex(self, z0, p, b, bounds, minimax)
            return self._solution(z, p, b, out, message, kind)
        if self.n_equalities > len(d):
            return self._overdetermined(z0, p, b, bounds, minimax)
        out = self.backend.solve(z0, p, b)
        z, message = out.z, f"{out.solver.upper()}: {out.solver_status}"
        closest_kind: str | None = None
        if out.status is Status.OPTIMAL:
            z, message = self.polish(z, p, b), "balanced design found"
        elif out.status is Status.INFEASIBLE:
            # IPOPT's infeasibility verdict is local (its restoration phase got stuck). The
            # least-squares closest design settles it: when that balances, restart from it.
            closest = self.closest_design_multistart([z, z0], p, b, bounds)
            elapsed = out.solve_time + closest.solve_time
            if self.balances(closest.z, p):
                out = self.backend.solve(closest.z, p, b)
                elapsed += out.solve_time
                z, message = out.z, f"{out.solver.upper()}: {out.solver_status}"
                if out.status is Status.OPTIMAL:
                    z, message = self.polish(z, p, b), "balanced design found (restarted from a balanced point)"
                elif out.status is Status.INFEASIBLE and (within := self._within_rounding(closest.z, p, b)) is not None:
                    # the balanced design lies beyond a bound by rounding (issue 32: a catalogue
                    # part's rate 1e-11 outside the balanceable window)
                    elapsed += within[1].solve_time
                    out = within[1]
                    z, message = within[0], f"balanced design found (a variable held on a bound that the exact balance passes by less than {BOUND_TOLERANCE:g} of its span)"
                elif out.status is Status.INFEASIBLE:
                    code = BALANCEABLE_BUT_INFEASIBLE if self.rows is not None else out.solver_status
                    out = SolverOutput(closest.z, Status.FAILED, code, out.iterations, out.solve_time, out.solver)
                    z, message = closest.z, "IPOPT declared a balanceable problem infeasible; the closest design is reported"
            else:
                z, closest_kind, seconds = self.closest_reported(closest.z, p, b, minimax)
                z = self.polish_settings(z, p, b)
                elapsed += seconds
            out = _with_time(out, elapsed)
        if out.solver_status == INVALID_NUMBER:
            named = name_invalid_numbers(self, [z, z0], p)
            if named:
                message = f"{message}: {named}"
        return self._solution(z, p, b, out, message, closest_kind)

    def _within_rounding(self, z: np.ndarray, p: np.ndarray, b: Bounds) -> tuple[np.ndarray, SolverOutput] | None:
        """A balanced design IPOPT calls infeasible from a balanced start ``z``: solved once
        more with every variable's bounds widened by :data:`BOUND_TOLERANCE` × its span (the
        rule that puts a value "on" a bound), the result put back within the bounds and
        polished. Returned (design, solver output) when that balances; None otherwise, or
        with design constraints (their conflicts are the elastic problem's to name).

        Why: the balance may need a variable a rounding amount beyond its bound (a catalogue
        part's rate within 1e-11 of its balanceable window's end: the lever 3e-12 m past its
        upper bound). IPOPT, held to 1e-12 on the balance with that variable pinned, declares
        it infeasible; within the stated tolerance it is a fit."""
        if self.rows is not None:
            return None
        span = np.where(np.isfinite(b.ubz - b.lbz), b.ubz - b.lbz, 0.0)
        widened = Bounds(b.lbz - BOUND_TOLERANCE * span, b.ubz + BOUND_TOLERANCE * span, b.lbg, b.ubg)
        out = self.backend.solve(z, p, widened)
        if out.status is not Status.OPTIMAL:
            return None
        candidate = self.polish(np.clip(out.z, b.lbz, b.ubz), p, b)
        if not self.balances(candidate, p) or not _admissible(np.array(self.residual_jacobian()(candidate, p)[2]).reshape(-1)):
            return None
        return candidate, out

    def balances(self, z: np.ndarray, p: np.ndarray, tolerance: float = BALANCE_TOLERANCE) -> bool:
        """Whether the compressed balance equalities hold at ``z`` (scaled as in the NLP)."""
        g = np.array(self.residual_jacobian()(z, p)[0]).reshape(-1)
        return bool(g.size == 0 or np.abs(g).max() <= tolerance)

    # -- helpers -------------------------------------------------------------------
    def residual_jacobian(self) -> NumericFunction:
        """(z, p) -> (balance equalities, their Jacobian, sign constraints) as arrays: a CasADi
        function evaluated through its buffers (:class:`~counterpoise.numeric.NumericFunction`), built once.
        The latest few evaluations are kept: a polish asks again for the point its
        Gauss-Newton steps ended at (:meth:`_snap`, then :meth:`finish`)."""
        import casadi as ca

        if self._residual_jacobian is None:
            f = self.formulation
            eq = self.conditions.equalities
            signs = ca.vertcat(f.nonnegative, self.rows.margins()) if self.rows is not None else f.nonnegative
            self._residual_jacobian = NumericFunction(ca.Function("gJ", [f.z, f.p], [eq, ca.jacobian(eq, f.z), signs]), remember=REMEMBERED_EVALUATIONS)
        return self._residual_jacobian

    def _balance_evaluation(self, p: np.ndarray) -> Evaluate:
        """The balance equalities at ``p`` for :func:`~counterpoise.solvers.gauss_newton.gauss_newton`:
        (g, ∂g/∂z, whether the sign constraints hold)."""
        gj = self.residual_jacobian()

        def evaluate(z: np.ndarray) -> Evaluation:
            g, jac, signs = gj(z, p)  # new arrays on every call
            return g.reshape(-1), jac, _admissible(signs)

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
        z = self._snap(z, p, bounds, at_lo, (hi - z <= band) & (hi > lo) & ~at_lo, iterations, None)
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
            z = self._snap(z, p, bounds, on_lo, on_hi, iterations, f0 + OBJECTIVE_ROUNDING * max(1.0, abs(f0)))
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
        return gauss_newton(self._balance_evaluation(p), z, lo, hi, free=free, iterations=iterations, decrease=0.5).z

    def _snap(
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
        candidate = gauss_newton(self._balance_evaluation(p), candidate, lo, hi, free=~active, iterations=iterations, tolerance=EXACT_BALANCE, decrease=None).z
        g_new, _, signs = (np.array(v).reshape(-1) for v in gj(candidate, p))
        g_old = np.array(gj(z, p)[0]).reshape(-1)
        worst_new = np.abs(g_new).max(initial=0.0)
        worst_old = np.abs(g_old).max(initial=0.0)
        if not (worst_new <= max(worst_old, ROUNDING_FLOOR) and _admissible(signs)):
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
                return r, jac, _admissible(np.array(gj(candidate, p)[2]))

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

    def closest_design(self, z0: np.ndarray, p: np.ndarray, bounds: BoundsOverride | None = None) -> SolverOutput:
        """The design within the bounds that comes closest to balance (least squares)."""
        import casadi as ca

        f = self.formulation
        if self._feasibility is None:
            nlp = {"x": f.z, "p": f.p, "f": 0.5 * ca.sumsqr(self.conditions.equalities), "g": f.nonnegative}
            self._feasibility = IpoptBackend(nlp, {**self.options, "tol": CLOSEST_TOL, "acceptable_tol": CLOSEST_ACCEPTABLE_TOL}, "closest")
        b = self.bounds(0, bounds, constraints=False)
        out = self._feasibility.solve(np.clip(z0, b.lbz, b.ubz), p, b)
        z = self.refine(out.z, p, b)
        return SolverOutput(z, out.status, out.solver_status, out.iterations, out.solve_time, out.solver)

    def closest_design_multistart(
        self, starts: list[np.ndarray], p: np.ndarray, b: Bounds, bounds: BoundsOverride | None = None
    ) -> SolverOutput:
        """:meth:`closest_design` from each of ``starts``, then from :data:`CLOSEST_RANDOM_STARTS`
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
            out = self.closest_design(z0, p, bounds)
            elapsed += out.solve_time
            g = np.array(self.residual_jacobian()(out.z, p)[0]).reshape(-1)
            tried.append((float(np.abs(g).max(initial=0.0)), i, out))
            if self.balances(out.z, p):
                break
        return _with_time(min(tried)[2], elapsed)

    def closest_minimax(self, z: np.ndarray, p: np.ndarray, b: Bounds) -> tuple[np.ndarray, str, float]:
        """The closest design reported for a balance that cannot be met: the one with the
        smallest worst residual ratio, the figure the report gives.

        Least squares on the compressed conditions (``z``, from :meth:`closest_design`) is not
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
        signs = np.array(self.residual_jacobian()(candidate, p)[2]).reshape(-1)[: int(self.formulation.nonnegative.numel())]
        if out.status is Status.OPTIMAL and _admissible(signs) and reached < least_squares:
            return candidate, f"minimax: the smallest worst residual on {m.n_samples} sampled configurations", out.solve_time
        return z, LEAST_SQUARES_NO_CLOSER, out.solve_time

    def refine(self, z: np.ndarray, p: np.ndarray, b: Bounds, iterations: int = 8) -> np.ndarray:
        """Gauss-Newton steps on the balance equalities from ``z``, within the bounds.

        Least squares on ``½|g|²`` stops near ``|g| ~ 1e-8`` (squaring loses half the digits), just
        short of :meth:`balances`; a few Newton steps on g itself finish the job when a
        balanced design is that near. Kept only while ``|g|`` decreases and signs stay ≥ 0.
        """
        # a fixed variable (lower = upper: a part's rate in a part search) does not move: in
        # the minimum-norm step it would take a share that the bounds then cut away, and the
        # steps would stall short of balance (issue 32)
        return gauss_newton(self._balance_evaluation(p), z, b.lbz, b.ubz, free=b.ubz > b.lbz, iterations=iterations, tolerance=EXACT_BALANCE).z

    def _overdetermined(self, z0: np.ndarray, p: np.ndarray, b: Bounds, bounds: BoundsOverride | None, minimax: bool = True) -> Solution:
        """More independent conditions than variables: balance only at special designs.

        Find the closest design; if it balances, the conditions are locally redundant:
        keep as many as the rank of their Jacobian there and optimise on that manifold
        (the reduction depends on the point, so this solver is built per call; its build
        time is not counted in ``solve_time``).
        """
        import casadi as ca

        f = self.formulation
        closest = self.closest_design_multistart([z0], p, b, bounds)
        g, jac, _ = (np.array(v) for v in self.residual_jacobian()(closest.z, p))
        if not self.balances(closest.z, p):
            message = "more independent balance conditions than design variables, and no design within the bounds meets them"
            z, kind, seconds = self.closest_reported(closest.z, p, b, minimax)
            z = self.polish_settings(z, p, b)
            out = SolverOutput(z, Status.INFEASIBLE, "overdetermined", closest.iterations, closest.solve_time + seconds, closest.solver)
            return self._solution(z, p, b, out, message, kind)
        u, s, _ = np.linalg.svd(jac, full_matrices=False)
        r = int(np.sum(s > RANK_TOLERANCE * s[0])) if s.size and s[0] > 0 else 0
        reduced = ca.mtimes(ca.DM(u[:, :r].T), self.conditions.equalities)
        nlp = {"x": f.z, "p": f.p, "f": f.objective, "g": ca.vertcat(reduced, f.nonnegative, *self._row_g())}
        backend = IpoptBackend(nlp, self.options, "design_reduced")
        rb = self.bounds(r, bounds)
        out = backend.solve(closest.z, p, rb)
        out = _with_time(out, out.solve_time + closest.solve_time)
        z, message = out.z, f"{out.solver.upper()}: {out.solver_status}"
        if out.status is Status.OPTIMAL:
            z, message = self.polish(z, p, rb), "balanced design found (conditions reduced at a balanced design)"
        elif out.status is Status.INFEASIBLE:
            out = SolverOutput(out.z, Status.FAILED, out.solver_status, out.iterations, out.solve_time, out.solver)
        return self._solution(z, p, b, out, message)

    def _solution(self, z: np.ndarray, parameters: np.ndarray, b: Bounds, out: SolverOutput, message: str, closest: str | None = None) -> Solution:
        """``closest``: what the reported closest design of an infeasible problem is (see
        :meth:`closest_minimax`); None for a design that balances."""
        solution = build_solution(self.formulation, z, parameters, b.lbz, b.ubz, out, message, self.n_equalities, self.conditions.summary())
        if closest is not None:  # a new Solution's closest is None
            solution = replace(solution, closest=closest)
        if self.rows is None:
            return solution
        if self.nonlinear_constraints:
            solution = replace(
                solution,
                message=solution.message
                + f"; the nonlinear constraint{'s' if len(self.nonlinear_constraints) > 1 else ''} {', '.join(self.nonlinear_constraints)} "
                "made this LP problem an NLP (IPOPT)",
            )
        if solution.status is Status.INFEASIBLE or out.solver_status == BALANCEABLE_BUT_INFEASIBLE:
            conflict = name_conflict(self, z, parameters, b)
            if conflict is not None:
                # balanced, yet infeasible: the constraints' verdict, on the design it describes
                # (the elastic one: balanced, the named constraints relaxed by the stated amounts)
                elastic = SolverOutput(conflict.z, Status.INFEASIBLE, out.solver_status, out.iterations, out.solve_time, out.solver)
                solution = build_solution(self.formulation, conflict.z, parameters, b.lbz, b.ubz, elastic, conflict.message, self.n_equalities, self.conditions.summary())
                values = tuple(replace(v, relaxed=conflict.relaxed.get((v.name, v.scenario), 0.0)) for v in evaluate(self.problem, solution, self.rows, None))
                message = conflict_message(self.problem, conflict, values)
                return replace(solution, message=message, constraints=values).judged(Status.INFEASIBLE, message, "constraints")
        solution = attach_constraints(solution, self.rows, rows_multipliers(out, self.rows))
        if (out.solver_status == BALANCEABLE_BUT_INFEASIBLE or solution.status is Status.FAILED) and not between_samples(solution):
            # the elastic problem did not settle it, or the solver failed: name the limits the
            # design reported misses
            unmet = unmet_at(self.problem, solution.constraints)
            if unmet:
                solution = replace(solution, message=f"{solution.message}; it misses {unmet}")
        return solution


def _admissible(signs: np.ndarray) -> bool:
    """The sign constraints (and constraint margins) hold: every one ≥ 0."""
    return bool(signs.size == 0 or signs.min() >= 0)


def _with_time(out: SolverOutput, seconds: float) -> SolverOutput:
    return SolverOutput(out.z, out.status, out.solver_status, out.iterations, seconds, out.solver)


# -- a designer kept on disk by counterpoise solve ---------------------------------------

#: the kind of :mod:`counterpoise.io.cache`'s built entries that hold designers
KEPT_KIND = "designer"


def _kept_entry(problem: Problem, ipopt_options: Mapping[str, Any] | None, backend: str, extra: Extra | None, designer: Designer) -> BuiltEntry | None:
    """The disk entry of a designer (key: the problem's content, the options, the CasADi
    version), or None when designers are not kept in this process (anything but the
    console script's ``solve``) or this one is not (a verification round's, with ``extra``)."""
    if extra:
        return None
    import casadi as ca

    from ..io.cache import built_entry
    from ..model.digest import digest

    version = str(getattr(ca, "__version__", ""))  # also in the entry's key by its installed version (io.cache.BUILT_LIBRARIES)
    return built_entry(
        KEPT_KIND, problem, digest(dict(ipopt_options or {})), backend, version, shared={"problem": problem, "designer": designer}, reducers=_KEPT_REDUCERS, casadi=True
    )


def _reduce_numeric(f: NumericFunction) -> tuple[Any, ...]:
    return (NumericFunction, (f.function, f.remember))


#: how a kept designer's parts that hold per-thread buffers pickle: rebuilt from their
#: function and settings (their buffers and remembered evaluations are not kept)
_KEPT_REDUCERS: dict[type, Callable[[Any], tuple[Any, ...]]] = {NumericFunction: _reduce_numeric}
