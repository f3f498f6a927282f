"""The minimax designer, for springs attached directly (free length, initial tension).

A real spring attached without a pulley pulls with F0 + k·(d − c − L0): its energy is not
a trigonometric polynomial of the joint angles, exact balance is generally impossible and
rank-compressed conditions do not exist (:mod:`counterpoise.formulation.assumptions`).
The design then minimises the worst residual ratio over sampled configurations, in
epigraph form:

    minimise t   subject to   −t ≤ r_j(q_s; z) / T ≤ t   for every sampled q_s and coordinate j,
                              L0 ≤ d(q_s) − c ≤ L_max     for every directly attached spring,

with T the largest unbalanced gravity torque over the samples (the verification's
reference). A subsystem with closed loops is sampled on its configuration manifold
(:func:`counterpoise.mechanics.closure.manifold_configurations`, at the scenario's
parameter values): r_j and the gravity torque are then the generalized forces along the
independent coordinates, r_i = ∂V/∂q_i + (dq_d/dq_i)ᵀ ∂V/∂q_d, as in the dense check of
:mod:`counterpoise.verify.manifold`, and the spring lengths are those of the assembled
configurations. The design is then checked on the dense verification sample like any other:
the residual ratio reported is the dense one; t is the design's :class:`MinimaxDesign` extra
(``solution.extra(MinimaxDesign).sampled_ratio``), which also marks it a minimax design.
Built once; :meth:`solve` takes parameters and bounds per call, like :class:`Designer`
(and, like it, builds another for parameters that change a closed loop's geometry).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..formulation.formulation import Formulation
from ..formulation.layout import Slot
from ..formulation.manifold import Geometries, for_geometry
from ..mechanics import Mechanics, casadi_functions
from ..mechanics.kinematics import dot, sub
from ..mechanics.sampling import configurations
from ..model.problem import Problem
from ..solvers.base import Bounds, SolverOutput, Status
from ..solvers.ipopt import IPOPT_DEFAULTS, IpoptBackend
from ..threads import limit_blas_threads
from ..formulation.constraints import MAX_ROUNDS, ConstraintRows, Extra, build_rows, describe, merge, violations
from .constrained import attach_constraints, rows_multipliers
from .options import SolveOptions
from .solution import Solution, build_solution

@dataclass(frozen=True)
class MinimaxDesign:
    """The extra of a minimax design (:meth:`MinimaxDesigner.solve`): its worst residual
    ratio ``t`` on the NLP's sampled configurations, and how many there were. Its presence
    marks the design as a minimax one: judged by the minimax rule
    (:func:`counterpoise.verify.judge.judge_minimax`), not by exact balance."""

    sampled_ratio: float
    samples: int


def minimax_of(solution: Solution) -> MinimaxDesign | None:
    """The minimax extra of ``solution``; None for a design of exact balance conditions."""
    return solution.extra(MinimaxDesign)


#: sampled configurations per (subsystem, scenario): SAMPLES_PER_COORDINATE × n_q (+ corners)
SAMPLES_PER_COORDINATE = 96
#: start of the epigraph variable t (a worst residual ratio; any value above the optimum)
INITIAL_RATIO = 10.0


def has_direct_springs(problem: Problem) -> bool:
    """Some spring is attached directly (its part's free length and initial tension count)."""
    return any(s.direct is not None for s in problem.springs)


def needs_minimax(problem: Problem) -> bool:
    """Some spring's energy is not ½ k |a − b|² (attached directly, or behind a pulley of
    radius > 0 without a pin): no exact balance conditions, the minimax designer designs it."""
    return any(not s.exact for s in problem.springs)


def _why(problem: Problem) -> str:
    """Why a problem has no exact balance: its real springs, by kind."""
    kinds = []
    if has_direct_springs(problem):
        kinds.append("directly attached springs")
    if any(s.direct is None and not s.exact for s in problem.springs):
        kinds.append("cables over pulleys of radius > 0")
    return " and ".join(kinds) or "real springs"


def _along(values: Any, tangent: tuple[np.ndarray, np.ndarray, np.ndarray] | None) -> Any:
    """Generalized forces (n_q, N) projected along the manifold: (n_i, N); as is without loops.

    ``values`` is a numpy array or a CasADi matrix; row j of the result is
    values[ind_j] + Σ_d tangent[:, d, j] · values[dep_d] (dq_d/dq_i of each sample).
    """
    if tangent is None:
        return values
    import casadi as ca

    ind, dep, t = tangent
    numeric = isinstance(values, np.ndarray)
    out = []
    for j, i in enumerate(ind):
        row = values[int(i), :]
        for d, k in enumerate(dep):
            w = t[:, d, j][None, :]
            row = row + (w * values[int(k), :] if numeric else ca.times(ca.DM(w), values[int(k), :]))
        out.append(row)
    return np.vstack(out) if numeric else ca.vertcat(*out)


def _independent(block: Any, tangent: tuple[np.ndarray, np.ndarray, np.ndarray] | None) -> list[str]:
    """The coordinates whose residuals :func:`_along` returns."""
    return list(block.coordinates) if tangent is None else [block.coordinates[int(i)] for i in tangent[0]]


class MinimaxDesigner:
    """Smallest worst-case residual ratio on sampled configurations (see the module docstring)."""

    def __init__(
        self,
        problem: Problem,
        ipopt_options: Mapping[str, Any] | None = None,
        extra: Extra | None = None,
        *,
        coordinates: Collection[str] | None = None,
        springs: Collection[str] | None = None,
    ) -> None:
        """``extra``: configurations added to the sampled rows of workspace extremes (see
        :mod:`counterpoise.formulation.constraints`; verification rounds).
        ``coordinates``, ``springs`` (None: all): only the residual rows of these
        coordinates and the length rows of these springs enter the NLP (the part search of
        a group of slots that do not interact with the rest, :mod:`counterpoise.selection.groups`);
        the reference torque is the whole problem's either way, so ratios compare."""
        import casadi as ca

        limit_blas_threads()
        self.problem = problem
        self._ipopt_options = dict(ipopt_options or {})
        self._only = (None if coordinates is None else frozenset(coordinates), None if springs is None else frozenset(springs))
        self._restricted: dict[tuple[frozenset[str], frozenset[str]], MinimaxDesigner] = {}
        #: designers of this problem rebuilt for other loop geometries (:func:`for_geometry`)
        self.geometries: Geometries[MinimaxDesigner] = Geometries()
        self.formulation = f = Formulation(problem)
        self.parameters = f.parameters.values()
        rng = np.random.default_rng(problem.settings.seed + 5)
        z0 = f.design.to_z(f.design.initial)
        t = ca.SX.sym("t")
        rows: list[Any] = []  # CasADi SX expressions (casadi ships no type information)
        torque = {True: 0.0, False: 0.0}
        samples: dict[tuple[str, str], np.ndarray] = {}
        tangents: dict[tuple[str, str], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        for block in f.blocks:
            n_q = len(block.coordinates)
            key = (block.subsystem, block.scenario)
            if problem.subsystem_loops(block.subsystem):  # closed loops: on the configuration manifold
                coords = problem.subsystem_coordinates(block.subsystem)
                ind = np.array([i for i, c in enumerate(coords) if not c.dependent], dtype=int)
                dep = np.array([i for i, c in enumerate(coords) if c.dependent], dtype=int)
                _, base = f.parameters.scenario_values(self.parameters)[block.scenario]
                from ..mechanics.closure import manifold_configurations  # closed loops only (~3 ms to import)

                points = manifold_configurations(problem, block.subsystem, SAMPLES_PER_COORDINATE * len(ind), rng, base)
                q = points.q
                tangents[key] = (ind, dep, points.tangent)
            else:
                q = configurations(problem, block.subsystem, SAMPLES_PER_COORDINATE * n_q, rng)
            samples[key] = q
            values = _along(np.array(block.gravity_torque.map(q.shape[0])(q.T, z0, self.parameters)), tangents.get(key))
            for j, name in enumerate(_independent(block, tangents.get(key))):
                revolute = problem.coordinate[name].unit.dimension == ""
                torque[revolute] = max(torque[revolute], float(np.abs(values[j]).max(initial=0.0)))
        ratios = []
        for block in f.blocks:
            key = (block.subsystem, block.scenario)
            q = samples[key]
            residual = _along(block.residual.map(q.shape[0])(ca.DM(q.T), f.z, f.p), tangents.get(key))  # (n_i, N)
            for j, name in enumerate(_independent(block, tangents.get(key))):
                if self._only[0] is not None and name not in self._only[0]:
                    continue
                revolute = problem.coordinate[name].unit.dimension == ""
                scale = torque[revolute] or 1.0
                r = residual[j, :].T / scale
                rows += [t - r, t + r]  # both ≥ 0
                ratios.append(r)
        self.reference = torque
        #: sampled configurations (every subsystem and scenario)
        self.n_samples = int(sum(q.shape[0] for q in samples.values()))
        self._ratios = ca.vertcat(*ratios)
        self._ratio_function: Any = None
        # spring lengths within [L0, L_max] on the samples
        functions = casadi_functions()
        for c, scenario in enumerate(problem.scenarios):
            gravity, base = f.parameters.split(f.p, c)
            variables = f.design.symbols(f.x, scenario.name)
            for spring in problem.springs:
                m = spring.direct
                if m is None or spring.subsystem is None or (self._only[1] is not None and spring.name not in self._only[1]):
                    continue
                coords_sym = ca.SX.sym("q", len(problem.subsystem_coordinates(spring.subsystem)))
                names = [k.name for k in problem.subsystem_coordinates(spring.subsystem)]
                mech = Mechanics(problem, base, variables, {n: coords_sym[i] for i, n in enumerate(names)}, gravity, functions)
                d = sub(mech.position(spring.ends[0]), mech.position(spring.ends[1]))
                length = ca.sqrt(dot(d, d)) - mech.value(m.cable)
                checks = [length - mech.value(m.free_length) - spring.slack_margin]
                if m.max_length is not None:
                    checks.append(mech.value(m.max_length) - length)
                fun = ca.Function("spring_length", [coords_sym, f.z, f.p], [ca.vertcat(*checks)])
                q = samples[(spring.subsystem, scenario.name)]
                values = fun.map(q.shape[0])(ca.DM(q.T), f.z, f.p)
                for i in range(values.shape[0]):
                    rows.append(values[i, :].T / max(float(np.max(np.abs(f.design.upper), initial=0.0)), 1e-3))
        self.n_rows = int(sum(r.numel() for r in rows))
        #: design constraints and force limits, last in g
        self.rows: ConstraintRows | None = build_rows(f, extra) if problem.constraints else None
        self._extra = dict(extra or {})
        self._refined: MinimaxDesigner | None = None
        self._round = 0
        g = ca.vertcat(*rows, f.nonnegative, *([self.rows.g] if self.rows is not None else []))
        self.n_signs = int(f.nonnegative.numel())
        self.z = ca.vertcat(f.z, t)
        self.options = {**IPOPT_DEFAULTS, "max_iter": max(problem.settings.max_iterations, 1000), "tol": 1e-9, **dict(ipopt_options or {})}
        self.backend = IpoptBackend({"x": self.z, "p": f.p, "f": t, "g": g}, self.options, "minimax")

    def restricted(self, coordinates: Collection[str], springs: Collection[str]) -> MinimaxDesigner:
        """The designer of only these coordinates' residuals and springs' lengths (built once)."""
        key = (frozenset(coordinates), frozenset(springs))
        if key not in self._restricted:
            self._restricted[key] = MinimaxDesigner(self.problem, self._ipopt_options, coordinates=key[0], springs=key[1])
        return self._restricted[key]

    def solve(
        self,
        initial: Mapping[Slot, float] | None = None,
        parameters: Mapping[str, float] | None = None,
        bounds: Mapping[Slot | str, tuple[float, float]] | None = None,
    ) -> Solution:
        """The smallest worst residual ratio with these initial values, base parameters and
        bounds (SI, for this call; see :class:`~.options.SolveOptions`)."""
        return self.solve_with(SolveOptions(parameters, bounds, initial))

    def solve_with(self, options: SolveOptions) -> Solution:
        """:meth:`solve` with its options in one :class:`~.options.SolveOptions` (``certify`` changes nothing here)."""
        parameters, bounds = options.parameters, options.bounds
        other = for_geometry(self, parameters, lambda problem: MinimaxDesigner(problem, self._ipopt_options, coordinates=self._only[0], springs=self._only[1]), self.geometries)
        if other is not self:  # closed loops: a new geometry is sampled on its own manifold
            return other.solve_with(options)
        if self._refined is not None:  # a verification round added configurations
            return self._refined.solve_with(options)
        f = self.formulation
        d = f.design
        p = f.parameters.values(parameters) if parameters else self.parameters
        lbz, ubz = d.bounds(bounds)
        z0 = np.clip(d.to_z(d.vector(options.initial or {})), lbz, ubz)
        rows = self.rows
        out = self.backend.solve(np.concatenate([z0, [INITIAL_RATIO]]), p, self._bounds(lbz, ubz, True))
        t = float(out.z[-1])
        ok = out.status is Status.OPTIMAL
        message = (
            f"smallest worst-case residual ratio on the sampled configurations: {t:.6g} ({_why(self.problem)}: exact balance is generally impossible)"
            if ok
            else f"minimax design: {out.solver.upper()} {out.solver_status}"
        )
        design_out = SolverOutput(out.z[:-1], out.status, out.solver_status, out.iterations, out.solve_time, out.solver)
        summary = "epigraph rows on sampled configurations"
        solution = build_solution(f, out.z[:-1], p, lbz, ubz, design_out, message, self.n_rows, summary).with_extra(MinimaxDesign(t, self.n_samples))
        if rows is None:
            return solution
        solution = attach_constraints(solution, rows, rows_multipliers(out, rows))
        if not ok:
            unmet = [v for v in solution.constraints if v.active == "violated"]
            if unmet:
                # the worst residual ratio is free (t), so only the constraints can make this infeasible
                text = "; ".join(describe(self.problem, v) for v in unmet[:3])
                if out.status is Status.INFEASIBLE:
                    solution = solution.judged(Status.INFEASIBLE, f"infeasible: the constraints cannot all hold: at the solver's last point {text}", "minimax")
                else:
                    solution = replace(solution, message=f"{solution.message}; at the solver's last point the constraints are not met: {text}")
        add = violations(self.problem, solution.constraints)
        if add and self._round < MAX_ROUNDS:
            extra = merge(self._extra, add)
            refined = MinimaxDesigner(self.problem, self._ipopt_options, extra, coordinates=self._only[0], springs=self._only[1])
            refined._round = self._round + 1
            self._refined = refined
            return refined.solve_with(replace(options, initial=dict(solution.values)))
        return solution

    def _bounds(self, lbz: np.ndarray, ubz: np.ndarray, constraints: bool) -> Bounds:
        """Bounds of (z, t) and of [epigraph and spring-length rows ≥ 0; signs ≥ 0; constraint
        rows (free when ``constraints`` is False)]."""
        rows = self.rows
        n = self.n_rows + self.n_signs
        m = rows.lbg.size if rows is not None else 0
        return Bounds(
            np.concatenate([lbz, [0.0]]),
            np.concatenate([ubz, [np.inf]]),
            np.concatenate([np.zeros(n), (rows.lbg if constraints else np.full(m, -np.inf)) if rows is not None else []]),
            np.concatenate([np.full(n, np.inf), (rows.ubg if constraints else np.full(m, np.inf)) if rows is not None else []]),
        )

    def ratios(self, z: np.ndarray, p: np.ndarray) -> np.ndarray:
        """The residual ratios r_j(q_s; z) / T on every sampled configuration (scaled ``z``)."""
        import casadi as ca

        if self._ratio_function is None:
            f = self.formulation
            self._ratio_function = ca.Function("ratios", [f.z, f.p], [self._ratios])
        return np.array(self._ratio_function(z, p)).reshape(-1)

    def smallest_worst_ratio(self, z0: np.ndarray, p: np.ndarray, lbz: np.ndarray, ubz: np.ndarray) -> tuple[SolverOutput, float]:
        """The design within [lbz, ubz] (scaled) with the smallest worst residual ratio on the
        samples, from ``z0``, design constraints left out: the closest design of a balance
        problem that cannot be met (see :meth:`counterpoise.designer.closest.Closest.minimax`).
        Returns the solver's output (without t) and t."""
        z0 = np.clip(z0, lbz, ubz)
        t0 = max(INITIAL_RATIO, 2.0 * float(np.abs(self.ratios(z0, p)).max(initial=0.0)))
        out = self.backend.solve(np.concatenate([z0, [t0]]), p, self._bounds(lbz, ubz, False))
        design = SolverOutput(out.z[:-1], out.status, out.solver_status, out.iterations, out.solve_time, out.solver)
        return design, float(out.z[-1])
