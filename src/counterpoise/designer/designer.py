"""The designer: a problem's formulation, its exact balance conditions and a solver backend,
built once and solved many times.

``Designer(problem).solve()`` returns a :class:`Solution` (not yet verified). Parameters
(gravity and every literal parameter of every scenario) are the NLP's parameter vector,
so ``solve(parameters=...)`` re-solves a study point without rebuilding, and variable
bounds may be changed per call. CasADi objects do not pickle: a designer pickles as its
description (the problem and the solver options) and rebuilds itself in the worker.
``counterpoise solve`` keeps the state of each designer it builds on disk (its CasADi
objects written in one CasADi pickle context, :class:`counterpoise.io.cache.BuiltEntry`),
and a later solve of the same content takes it from there instead of building.

The designer does one job, the NLP: it builds it and solves it (IPOPT, restarted from a
balanced point when IPOPT's infeasibility is local; an overdetermined problem reduced at a
balanced design; design constraints in rounds) and makes the :class:`Solution`. The rest is
in its parts, each built with it:

- :class:`~.balance.Balance` (:attr:`Designer.balance`): the balance equalities at a design,
  the balance test and every polish of a solver's point;
- :class:`~.closest.Closest` (:attr:`Designer.closest`): the closest design of a balance that
  cannot be met (least squares from several starts; the minimax design reported);
- :mod:`.convex`: the LP path (Clarabel) and the certificate gap of an IPOPT design;
- :mod:`.constrained`: the design constraints' values and conflicts at a design.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any, TypeGuard

import numpy as np

from ..formulation.conditions import BalanceConditions
from ..formulation.constraints import MAX_ROUNDS, ConstraintRows, Extra, build_rows, evaluate, merge, violations
from ..formulation.formulation import Formulation
from ..formulation.layout import Slot
from ..formulation.manifold import Geometries, for_geometry
from ..model.problem import BOUND_TOLERANCE, Problem
from ..numeric import NumericFunction
from ..solvers.base import Bounds, SolverOutput, Status
from ..solvers.ipopt import IPOPT_DEFAULTS, IpoptBackend
from ..threads import limit_blas_threads
from . import convex
from .balance import Balance, admissible, nlp_bounds
from .closest import LEAST_SQUARES_CLOSEST, LEAST_SQUARES_NO_CLOSER, Closest, with_time
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
    from ..solvers.convex import ConvexBackend

#: Singular values below this share of the largest count as zero (rank of the conditions).
RANK_TOLERANCE = 1e-8


#: IPOPT's failures that are local to its path, not a verdict on the problem: like an
#: infeasibility verdict, they are settled from the least-squares closest design
#: (restarted from it when it balances). A time limit or an invalid number is not restarted.
RESTARTED_FAILURES = frozenset({"Error_In_Step_Computation", "Search_Direction_Becomes_Too_Small", "Maximum_Iterations_Exceeded"})
#: a certificate gap (kg) within this share of the objective (at least of 1 kg) is rounding
CERTIFIED_GAP = 1e-9


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
        #: the balance equalities at a design: evaluated, tested, polished
        self.balance = Balance(problem, f, self.conditions, self.rows)
        #: the closest design of a balance that cannot be met (its NLPs built on first use)
        self.closest = Closest(problem, f, self.conditions, self.balance, self.options, self._ipopt_options)
        #: designers of this problem rebuilt for other loop geometries (:func:`for_geometry`)
        self.geometries: Geometries[Designer] = Geometries()
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
        return nlp_bounds(self.formulation, self.rows, n_equalities, overrides, constraints)

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
        for an infeasible problem, the minimax closest design (:meth:`.closest.Closest.minimax`);
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
            gap = self._certificate_gap(solution, p, b)
            solution = self._certified(replace(solution, stats=replace(solution.stats, certificate_gap=gap)), p, gap)
        return solution

    def _certified(self, solution: Solution, p: np.ndarray, gap: float) -> Solution:
        """A design IPOPT stopped on a local breakdown (:data:`RESTARTED_FAILURES`, even
        after the restart) that balances and that its certificate LP cannot better at its
        geometry (gap within :data:`CERTIFIED_GAP`) is reported optimal, saying so: the
        breakdown is the degenerate optimum's (a counter-mass at 0 leaves its lever free),
        not a failure to find it."""
        status = solution.stats.solver_status
        if solution.status is not Status.FAILED or status not in RESTARTED_FAILURES or not np.isfinite(gap):
            return solution
        if gap > CERTIFIED_GAP * max(1.0, abs(solution.objective)):
            return solution
        d = self.formulation.design
        if not self.balance.balances(d.to_z(d.vector(solution.values)), p):
            return solution
        message = f"balanced design found (IPOPT stopped on {status}; its certificate LP finds no lighter design at this geometry: gap {gap:.3g} kg)"
        return replace(solution, status=Status.OPTIMAL, message=message)

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
        design replaced by the minimax one (:meth:`.closest.Closest.minimax`): the design reported."""
        d = self.formulation.design
        z, kind, seconds = self.closest.minimax(d.to_z(d.vector(solution.values)), p, b)
        if kind != LEAST_SQUARES_NO_CLOSER:
            z = self.balance.polish_settings(z, p, b)
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

    def _certificate_gap(self, solution: Solution, p: np.ndarray, b: Bounds) -> float:
        d = self.formulation.design
        return self.certificate.gap(d.to_z(d.vector(solution.values)), p, b, solution.stats.solver, solution.objective)

    def _solve(self, z0: np.ndarray, p: np.ndarray, b: Bounds, bounds: BoundsOverride | None, minimax: bool = True) -> Solution:
        """``minimax``: report the minimax closest design of an infeasible problem (else the
        least-squares one, upgraded by :meth:`certify`)."""
        d = self.formulation.design
        if self.convex is not None:
            return self._solve_convex(self.convex, z0, p, b, bounds, minimax)
        if self.n_equalities > len(d):
            return self._overdetermined(z0, p, b, bounds, minimax)
        out = self.backend.solve(z0, p, b)
        z, message = out.z, f"{out.solver.upper()}: {out.solver_status}"
        closest_kind: str | None = None
        if out.status is Status.OPTIMAL:
            z, message = self.balance.polish(z, p, b), "balanced design found"
        elif out.status is Status.INFEASIBLE or out.solver_status in RESTARTED_FAILURES:
            # IPOPT's infeasibility verdict is local (its restoration phase got stuck), and so
            # is a numerical breakdown (a counter-mass going to 0 leaves its lever free: a
            # singular step). The least-squares closest design settles it: when that
            # balances, restart from it.
            closest = self.closest.least_squares_multistart([z, z0], p, b, bounds)
            elapsed = out.solve_time + closest.solve_time
            if self.balance.balances(closest.z, p):
                out = self.backend.solve(closest.z, p, b)
                elapsed += out.solve_time
                z, message = out.z, f"{out.solver.upper()}: {out.solver_status}"
                if out.status is Status.OPTIMAL:
                    z, message = self.balance.polish(z, p, b), "balanced design found (restarted from a balanced point)"
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
                z, closest_kind, seconds = self.closest.reported(closest.z, p, b, minimax)
                z = self.balance.polish_settings(z, p, b)
                elapsed += seconds
            out = with_time(out, elapsed)
        if out.solver_status == INVALID_NUMBER:
            named = name_invalid_numbers(self, [z, z0], p)
            if named:
                message = f"{message}: {named}"
        return self._solution(z, p, b, out, message, closest_kind)

    def _solve_convex(self, backend: ConvexBackend, z0: np.ndarray, p: np.ndarray, b: Bounds, bounds: BoundsOverride | None, minimax: bool) -> Solution:
        """The LP path (:mod:`.convex`): the LP's optimum (variables on a bound put exactly on
        it), or the closest design."""
        out = backend.solve(z0, p, b)
        if out.status is Status.OPTIMAL:
            # An interior-point LP solution meets the equalities to ~1e-8 relative: put bound
            # variables on their bounds, then Newton steps on the (linear) equalities for the
            # others finish to rounding (a 24-link chain's masses span ten orders of magnitude).
            z = self.balance.polish(out.z, p, b)
            on_bound = (z <= b.lbz) | (z >= b.ubz)
            fixed = Bounds(np.where(on_bound, z, b.lbz), np.where(on_bound, z, b.ubz), b.lbg, b.ubg)
            z = self.balance.refine(z, p, fixed)
            return self._solution(z, p, b, out, "balanced design found (LP, Clarabel)")
        if out.status is Status.INFEASIBLE:
            closest = self.closest.least_squares(z0, p, bounds)
            z, kind, seconds = self.closest.reported(closest.z, p, b, minimax)
            z = self.balance.polish_settings(z, p, b)
            out = SolverOutput(z, Status.INFEASIBLE, out.solver_status, out.iterations, out.solve_time + closest.solve_time + seconds, out.solver)
            return self._solution(z, p, b, out, "CLARABEL: infeasible", kind)
        return self._solution(out.z, p, b, out, f"CLARABEL: {out.solver_status}")

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
        candidate = self.balance.polish(np.clip(out.z, b.lbz, b.ubz), p, b)
        if not self.balance.balances(candidate, p) or not admissible(np.array(self.balance.residual_jacobian()(candidate, p)[2]).reshape(-1)):
            return None
        return candidate, out

    def _overdetermined(self, z0: np.ndarray, p: np.ndarray, b: Bounds, bounds: BoundsOverride | None, minimax: bool = True) -> Solution:
        """More independent conditions than variables: balance only at special designs.

        Find the closest design; if it balances, the conditions are locally redundant:
        keep as many as the rank of their Jacobian there and optimise on that manifold
        (the reduction depends on the point, so this solver is built per call; its build
        time is not counted in ``solve_time``).
        """
        import casadi as ca

        f = self.formulation
        closest = self.closest.least_squares_multistart([z0], p, b, bounds)
        g, jac, _ = (np.array(v) for v in self.balance.residual_jacobian()(closest.z, p))
        if not self.balance.balances(closest.z, p):
            message = "more independent balance conditions than design variables, and no design within the bounds meets them"
            z, kind, seconds = self.closest.reported(closest.z, p, b, minimax)
            z = self.balance.polish_settings(z, p, b)
            out = SolverOutput(z, Status.INFEASIBLE, "overdetermined", closest.iterations, closest.solve_time + seconds, closest.solver)
            return self._solution(z, p, b, out, message, kind)
        u, s, _ = np.linalg.svd(jac, full_matrices=False)
        r = int(np.sum(s > RANK_TOLERANCE * s[0])) if s.size and s[0] > 0 else 0
        reduced = ca.mtimes(ca.DM(u[:, :r].T), self.conditions.equalities)
        nlp = {"x": f.z, "p": f.p, "f": f.objective, "g": ca.vertcat(reduced, f.nonnegative, *self._row_g())}
        backend = IpoptBackend(nlp, self.options, "design_reduced")
        rb = self.bounds(r, bounds)
        out = backend.solve(closest.z, p, rb)
        out = with_time(out, out.solve_time + closest.solve_time)
        z, message = out.z, f"{out.solver.upper()}: {out.solver_status}"
        if out.status is Status.OPTIMAL:
            z, message = self.balance.polish(z, p, rb), "balanced design found (conditions reduced at a balanced design)"
        elif out.status is Status.INFEASIBLE:
            out = SolverOutput(out.z, Status.FAILED, out.solver_status, out.iterations, out.solve_time, out.solver)
        return self._solution(z, p, b, out, message)

    def _solution(self, z: np.ndarray, parameters: np.ndarray, b: Bounds, out: SolverOutput, message: str, closest: str | None = None) -> Solution:
        """``closest``: what the reported closest design of an infeasible problem is (see
        :meth:`.closest.Closest.minimax`); None for a design that balances."""
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
