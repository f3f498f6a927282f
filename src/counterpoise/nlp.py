"""The design NLP: formulation (CasADi SX) kept apart from the solver that solves it.

:class:`Formulation` turns a :class:`Problem` into symbols: the design vector (one slot per
shared variable, one per scenario for adjustable ones), the parameter vector (gravity and
base parameters of every scenario), the objective, the sign constraints on masses and
stiffnesses, and one residual function per (subsystem, scenario) block.
:class:`BalanceConditions` compresses each block's sampled residual to its rank
(:mod:`counterpoise.balance`) and then the whole stack once more, so that identical legs
or scenarios do not repeat conditions. :class:`Designer` builds the IPOPT solver once and
solves; a problem's parameters enter as the NLP parameter vector, so one built solver
serves many parameter values (studies).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import numpy as np

from . import expr as ex
from .balance import adaptive_compression, numerical_rank
from .errors import SolverError
from .mechanics import Mechanics, casadi_functions
from .problem import Problem, Scenario


class Status(str, Enum):
    OPTIMAL = "optimal"
    INFEASIBLE = "infeasible"
    FAILED = "failed"


@dataclass(frozen=True)
class Slot:
    """One entry of the design vector: a variable, in one scenario if it is adjustable."""

    variable: str
    scenario: str | None  # None: shared by every scenario


@dataclass(frozen=True)
class Block:
    """Residual ∂V/∂q of one subsystem in one scenario, as a CasADi function r(q, x, p)."""

    subsystem: str
    scenario: str
    coordinates: tuple[str, ...]
    residual: Any  # casadi.Function (q, x, p) -> r
    gravity_torque: Any  # casadi.Function (q, x, p) -> ∂V/∂q of the bodies alone


class Formulation:
    """Symbols of the design problem; independent of sampling and of the solver."""

    def __init__(self, problem: Problem) -> None:
        import casadi as ca

        self.problem = problem
        self.slots = tuple(
            Slot(v.name, s.name) if v.adjustable else Slot(v.name, None)
            for v in problem.variables
            for s in (problem.scenarios if v.adjustable else problem.scenarios[:1])
        )
        self.slot_index = {slot: i for i, slot in enumerate(self.slots)}
        lower = np.array([problem.variable[s.variable].lower for s in self.slots], dtype=float)
        upper = np.array([problem.variable[s.variable].upper for s in self.slots], dtype=float)
        self.lower, self.upper = lower, upper
        self.initial = np.array([problem.variable[s.variable].initial for s in self.slots], dtype=float)
        #: design variables are scaled by their largest bound so that IPOPT sees O(1) numbers
        self.scale = np.maximum(np.maximum(np.abs(lower), np.abs(upper)), 1e-12)
        self.z = ca.SX.sym("z", len(self.slots))
        self.x = self.z * ca.DM(self.scale) if self.slots else self.z
        self.n_base = len(problem.base_parameters)
        self.p = ca.SX.sym("p", len(problem.scenarios) * (3 + self.n_base))
        self.functions = casadi_functions()

        self.blocks: list[Block] = []
        added_mass, added_inertia = [], []
        nonnegative: dict[str, Any] = {}  # keyed by the expression's text: one row per distinct constraint
        home = {k.name: k.home for k in problem.coordinates}
        for c, scenario in enumerate(problem.scenarios):
            variables, base, gravity = self.symbols(c, scenario)
            mech = Mechanics(problem, base, variables, home, gravity, self.functions)
            added_mass.append(mech.added_mass())
            added_inertia.append(mech.added_inertia())
            for expression in self.sign_constraints(mech):
                nonnegative.setdefault(str(expression), expression)
            for sub in problem.subsystems:
                q = ca.SX.sym("q", len(sub.coordinates))
                coords = {name: q[i] for i, name in enumerate(sub.coordinates)}
                mech_q = Mechanics(problem, base, variables, coords, gravity, self.functions)
                bodies, balancers = mech_q.energy_terms(sub.name)
                residual = ca.gradient(bodies + balancers, q)
                torque = ca.gradient(bodies, q)
                self.blocks.append(
                    Block(
                        sub.name,
                        scenario.name,
                        sub.coordinates,
                        ca.Function(f"r_{sub.name}_{scenario.name}", [q, self.z, self.p], [residual]),
                        ca.Function(f"t_{sub.name}_{scenario.name}", [q, self.z, self.p], [torque]),
                    )
                )
        n = len(problem.scenarios)
        self.added_mass = sum(added_mass) / n
        self.added_inertia = sum(added_inertia) / n
        w = problem.objective
        self.objective = w.mass_weight * self.added_mass + w.inertia_weight * self.added_inertia
        self.nonnegative = ca.vertcat(*nonnegative.values()) if nonnegative else ca.SX(0, 1)
        self.report_function = ca.Function("mass_report", [self.z, self.p], [self.objective, self.added_mass, self.added_inertia])

    def symbols(self, c: int, scenario: Scenario) -> tuple[dict[str, Any], dict[str, Any], list[Any]]:
        """Variables, base parameters and gravity of scenario number ``c`` as symbols."""
        variables = {}
        for v in self.problem.variables:
            slot = Slot(v.name, scenario.name if v.adjustable else None)
            variables[v.name] = self.x[self.slot_index[slot]]
        offset = c * (3 + self.n_base)
        gravity = [self.p[offset + i] for i in range(3)]
        base = {p.name: self.p[offset + 3 + i] for i, p in enumerate(self.problem.base_parameters)}
        return variables, base, gravity

    def sign_constraints(self, mech: Mechanics) -> list[Any]:
        """Masses and stiffnesses that depend on variables must stay ≥ 0 (≥ 0 rows of g)."""
        p = self.problem
        trees = [b.mass for b in p.bodies] + [c.mass for c in p.counter_masses] + [s.stiffness for s in p.springs]
        out = []
        for tree in trees:
            variables = ex.names(tree) & set(p.variable)
            if not variables:
                continue  # fixed: checked by the loader
            if isinstance(tree, ex.Name) and p.variable[tree.id].lower >= 0:
                continue  # a bare variable with a non-negative lower bound
            out.append(mech.value(tree))
        return out

    def parameter_values(self, overrides: Mapping[str, float] | None = None) -> np.ndarray:
        """The NLP parameter vector: per scenario, gravity then the base parameters (SI).

        ``overrides`` replaces base parameters (SI) in every scenario, e.g. for a study.
        """
        values: list[float] = []
        for scenario in self.problem.scenarios:
            values += list(scenario.gravity.vector)
            for p in self.problem.base_parameters:
                v = (overrides or {}).get(p.name, scenario.parameters.get(p.name, p.value))
                values.append(float(v))  # type: ignore[arg-type]
        return np.array(values, dtype=float)

    def scenario_parameters(self, parameters: np.ndarray, scenario: int) -> tuple[tuple[float, float, float], dict[str, float]]:
        """Gravity vector and base-parameter values of scenario number ``scenario`` in ``parameters``."""
        offset = scenario * (3 + self.n_base)
        gravity = tuple(float(v) for v in parameters[offset : offset + 3])
        base = {p.name: float(parameters[offset + 3 + i]) for i, p in enumerate(self.problem.base_parameters)}
        return gravity, base  # type: ignore[return-value]

    def to_z(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(x, dtype=float) / self.scale

    def to_x(self, z: np.ndarray) -> np.ndarray:
        return np.asarray(z, dtype=float).reshape(-1) * self.scale


class BalanceConditions:
    """Exact, rank-compressed balance equalities g(z, p) = 0 for a formulation."""

    def __init__(self, formulation: Formulation, parameters: np.ndarray, seed: int) -> None:
        import casadi as ca

        self.formulation = formulation
        rng = np.random.default_rng(seed)
        f = formulation
        stacked = []
        #: (subsystem, scenario, number of independent conditions) of every block
        self.ranks: list[tuple[str, str, int]] = []
        for block in f.blocks:
            coords = [f.problem.coordinate[n] for n in block.coordinates]
            lo = np.array([c.lower for c in coords])
            hi = np.array([c.upper for c in coords])
            n_q = len(coords)

            def sample(n_conf: int, n_design: int, block: Block = block) -> tuple[np.ndarray, Any]:
                q = lo + (hi - lo) * rng.random((n_conf, n_q))
                z = f.to_z(f.lower + (f.upper - f.lower) * rng.random((n_design, len(f.slots))))
                return _sample_residuals(block.residual, q, z, parameters), q

            comp, q = adaptive_compression(sample, start_configurations=16 + 8 * n_q, start_designs=32)
            torque = np.abs(_sample_residuals(block.gravity_torque, q, f.to_z(f.initial)[None, :], parameters)).max(initial=0.0)
            scale = torque if torque > 0 else max(float(np.abs(comp.singular_values).max(initial=0.0)), 1.0)
            self.ranks.append((block.subsystem, block.scenario, comp.rank))
            if comp.rank:
                residual_at = {i: block.residual(q[i], f.z, f.p) for i in sorted({int(r) // n_q for r in comp.rows})}
                rows = [residual_at[int(r) // n_q][int(r) % n_q] for r in comp.rows]
                stacked.append(ca.mtimes(ca.DM(comp.matrix), ca.vertcat(*rows)) / scale)
        per_block = ca.vertcat(*stacked) if stacked else ca.SX(0, 1)
        # Across blocks: identical legs, or scenarios that repeat a condition, collapse here.
        self.equalities = self._compress_stack(per_block, parameters, rng)

    def _compress_stack(self, stacked: Any, parameters: np.ndarray, rng: np.random.Generator) -> Any:
        import casadi as ca

        f = self.formulation
        if stacked.numel() == 0:
            return stacked
        fun = ca.Function("stack", [f.z, f.p], [stacked])
        n_design = 2 * stacked.numel() + 8
        z = f.to_z(f.lower + (f.upper - f.lower) * rng.random((n_design, len(f.slots))))
        values = np.array(fun.map(n_design)(z.T, np.tile(parameters[:, None], (1, n_design))))
        u, s, _ = np.linalg.svd(values, full_matrices=False)
        rank = numerical_rank(s)
        if rank == stacked.numel():
            return stacked
        return ca.mtimes(ca.DM(u[:, :rank].T), stacked)

    @property
    def count(self) -> int:
        return int(self.equalities.numel())

    def summary(self) -> str:
        """'leg/nominal 3' per block, and whether repeats were removed."""
        parts = ", ".join(f"{sub}/{sc} {r}" for sub, sc, r in self.ranks)
        total = sum(r for *_, r in self.ranks)
        return parts + (f"; {total} before removing repeats across blocks" if total != self.count else "")


def _sample_residuals(residual: Any, q: np.ndarray, z: np.ndarray, parameters: np.ndarray) -> np.ndarray:
    """Residual entries at every (configuration, design) pair: (N·n_q) × K."""
    n_conf, n_q = q.shape
    n_design = z.shape[0]
    mapped = residual.map(n_conf * n_design)
    qq = np.tile(q.T, (1, n_design))
    zz = np.repeat(z.T, n_conf, axis=1)
    pp = np.tile(parameters[:, None], (1, n_conf * n_design))
    out = np.array(mapped(qq, zz, pp))  # n_q × (K·N), column k*N + i
    return out.reshape(n_q, n_design, n_conf).transpose(2, 0, 1).reshape(n_conf * n_q, n_design)


@dataclass
class Solution:
    """What a solve returns, before verification. Values are SI."""

    problem: Problem
    status: Status
    message: str
    values: dict[Slot, float]
    objective: float
    added_mass: float
    added_inertia: float
    iterations: int
    solve_time: float
    solver: str
    solver_status: str
    conditions: int
    condition_summary: str
    #: per scenario name: gravity vector and base-parameter values the design was solved for
    scenario_parameters: dict[str, tuple[tuple[float, float, float], dict[str, float]]] = field(default_factory=dict)

    def variable_values(self, scenario: str) -> dict[str, float]:
        """Value of every variable as seen by ``scenario``."""
        out = {}
        for slot, v in self.values.items():
            if slot.scenario is None or slot.scenario == scenario:
                out[slot.variable] = v
        return out


IPOPT_DEFAULTS: Mapping[str, Any] = {
    "print_level": 0,
    "sb": "yes",
    "tol": 1e-10,
    "constr_viol_tol": 1e-12,
    "acceptable_tol": 1e-8,
    "bound_relax_factor": 0.0,
    "honor_original_bounds": "yes",
    "mu_strategy": "adaptive",
}

_INFEASIBLE = {"Infeasible_Problem_Detected", "Restoration_Failed", "Not_Enough_Degrees_Of_Freedom"}


class Designer:
    """Builds the IPOPT solver for a problem once; :meth:`solve` may be called many times."""

    def __init__(self, problem: Problem, ipopt_options: Mapping[str, Any] | None = None) -> None:
        import casadi as ca

        self.problem = problem
        self.formulation = Formulation(problem)
        self.parameters = self.formulation.parameter_values()
        self.conditions = BalanceConditions(self.formulation, self.parameters, problem.settings.seed)
        f = self.formulation
        self.n_equalities = self.conditions.count
        self.options = {**IPOPT_DEFAULTS, "max_iter": problem.settings.max_iterations, **(ipopt_options or {})}
        nlp = {"x": f.z, "p": f.p, "f": f.objective, "g": ca.vertcat(self.conditions.equalities, f.nonnegative)}
        self.solver = ca.nlpsol("design", "ipopt", nlp, {"print_time": False, "ipopt": dict(self.options)})
        self._feasibility: Any = None
        self._residual_jacobian: Any = None

    def bounds(self, n_equalities: int) -> dict[str, np.ndarray]:
        """lbx/ubx of the scaled variables and lbg/ubg of [equalities; sign constraints]."""
        f = self.formulation
        n_in = int(f.nonnegative.numel())
        return {
            "lbx": f.lower / f.scale,
            "ubx": f.upper / f.scale,
            "lbg": np.zeros(n_equalities + n_in),
            "ubg": np.concatenate([np.zeros(n_equalities), np.full(n_in, np.inf)]),
        }

    def solve(self, initial: Mapping[Slot, float] | None = None, parameters: Mapping[str, float] | None = None) -> Solution:
        """Solve with the built solver.

        ``initial`` overrides initial values (SI) of design-vector slots; ``parameters``
        overrides base parameters (SI) in every scenario without rebuilding anything. The
        compression was computed at the file's values; the dense verification of the
        result says whether it still holds (a parameter that was 0 at build time may have
        hidden a condition).
        """
        f = self.formulation
        x0 = f.initial.copy()
        for slot, value in (initial or {}).items():
            x0[f.slot_index[slot]] = value
        p = f.parameter_values(parameters) if parameters else self.parameters
        if self.n_equalities > len(f.slots):
            return self._overdetermined(x0, p)
        t0 = time.perf_counter()
        out = self.solver(x0=f.to_z(x0), p=p, **self.bounds(self.n_equalities))
        elapsed = time.perf_counter() - t0
        stats = self.solver.stats()
        z = np.array(out["x"]).reshape(-1)
        ipopt_status = str(stats.get("return_status", "unknown"))
        if ipopt_status in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
            status, message = Status.OPTIMAL, "balanced design found"
            z = self.polish(z, p)
        elif ipopt_status in _INFEASIBLE:
            status, message = Status.INFEASIBLE, f"IPOPT: {ipopt_status}"
            z = self.closest_design(z, p)
        else:
            status, message = Status.FAILED, f"IPOPT: {ipopt_status}"
        return self._solution(z, p, status, message, int(stats.get("iter_count", 0)), elapsed, ipopt_status)

    def residual_jacobian(self) -> Any:
        """CasADi function (z, p) -> (balance equalities, their Jacobian, sign constraints), built once."""
        import casadi as ca

        if self._residual_jacobian is None:
            f = self.formulation
            eq = self.conditions.equalities
            self._residual_jacobian = ca.Function("gJ", [f.z, f.p], [eq, ca.jacobian(eq, f.z), f.nonnegative])
        return self._residual_jacobian

    def polish(self, z: np.ndarray, p: np.ndarray, rel: float = 1e-7, iterations: int = 8) -> np.ndarray:
        """Put variables that IPOPT left a hair inside a bound exactly on it.

        An interior-point solution sits ~1e-9 inside its active bounds. Each such variable is
        moved onto its bound and the balance equalities are re-solved for the other
        variables (Gauss-Newton). The polished point is kept only if it balances at least
        as well and respects the sign constraints; otherwise IPOPT's point stands.
        """
        f = self.formulation
        lo, hi = f.lower / f.scale, f.upper / f.scale
        span = np.maximum(hi - lo, 1e-300)
        at_lo = (z - lo) <= rel * span
        at_hi = (hi - z) <= rel * span
        active = (at_lo | at_hi) & (hi > lo)
        if not active.any():
            return z
        gj = self.residual_jacobian()
        candidate = np.where(at_lo, lo, np.where(at_hi, hi, z))
        free = ~active
        for _ in range(iterations):
            g, jac, _ = (np.array(v) for v in gj(candidate, p))
            g = g.reshape(-1)
            if not g.size or np.abs(g).max() <= 1e-15 or not free.any():
                break
            step, *_ = np.linalg.lstsq(jac[:, free], -g, rcond=None)
            candidate[free] = np.clip(candidate[free] + step, lo[free], hi[free])
        g_new, _, signs = (np.array(v).reshape(-1) for v in gj(candidate, p))
        g_old = np.array(gj(z, p)[0]).reshape(-1)
        worst_new = np.abs(g_new).max(initial=0.0)
        worst_old = np.abs(g_old).max(initial=0.0)
        if worst_new <= max(worst_old, 1e-14) and (signs.size == 0 or signs.min() >= 0):
            return candidate
        return z

    def closest_design(self, z0: np.ndarray, p: np.ndarray) -> np.ndarray:
        """The design within the bounds that comes closest to balance (least squares)."""
        import casadi as ca

        f = self.formulation
        if self._feasibility is None:
            nlp = {"x": f.z, "p": f.p, "f": 0.5 * ca.sumsqr(self.conditions.equalities), "g": f.nonnegative}
            opts = {**self.options, "tol": 1e-14, "acceptable_tol": 1e-12}
            self._feasibility = ca.nlpsol("closest", "ipopt", nlp, {"print_time": False, "ipopt": opts})
        out = self._feasibility(x0=np.clip(z0, f.lower / f.scale, f.upper / f.scale), p=p, **self.bounds(0))
        return np.array(out["x"]).reshape(-1)

    def _overdetermined(self, x0: np.ndarray, p: np.ndarray) -> Solution:
        """More independent conditions than variables: balance only at special designs.

        Find the closest design; if it balances, the conditions are locally redundant:
        keep as many as the rank of their Jacobian there and optimise on that manifold
        (the reduction depends on the point, so this solver is built per call).
        """
        import casadi as ca

        f = self.formulation
        t0 = time.perf_counter()
        z = self.closest_design(f.to_z(x0), p)
        g, jac, _ = (np.array(v) for v in self.residual_jacobian()(z, p))
        if np.abs(g).max() > 1e-9:
            message = "more independent balance conditions than design variables, and no design within the bounds meets them"
            return self._solution(z, p, Status.INFEASIBLE, message, 0, time.perf_counter() - t0, "overdetermined")
        u, s, _ = np.linalg.svd(jac, full_matrices=False)
        r = int(np.sum(s > 1e-8 * s[0])) if s.size and s[0] > 0 else 0
        reduced = ca.mtimes(ca.DM(u[:, :r].T), self.conditions.equalities)
        nlp = {"x": f.z, "p": f.p, "f": f.objective, "g": ca.vertcat(reduced, f.nonnegative)}
        solver = ca.nlpsol("design_reduced", "ipopt", nlp, {"print_time": False, "ipopt": dict(self.options)})
        out = solver(x0=z, p=p, **self.bounds(r))
        stats = solver.stats()
        ipopt_status = str(stats.get("return_status"))
        z = np.array(out["x"]).reshape(-1)
        if ipopt_status in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
            status, message = Status.OPTIMAL, "balanced design found (conditions reduced at a balanced design)"
            z = self.polish(z, p)
        else:
            status, message = Status.FAILED, f"IPOPT: {ipopt_status}"
        return self._solution(z, p, status, message, int(stats.get("iter_count", 0)), time.perf_counter() - t0, ipopt_status)

    def _solution(
        self, z: np.ndarray, parameters: np.ndarray, status: Status, message: str, iterations: int, elapsed: float, solver_status: str
    ) -> Solution:
        f = self.formulation
        z = np.clip(z, f.lower / f.scale, f.upper / f.scale)
        x = f.to_x(z)
        objective, mass, inertia = (float(v) for v in f.report_function(z, parameters))
        if not np.all(np.isfinite(x)):
            raise SolverError(f"{self.problem.name}: the solver returned non-finite values")
        return Solution(
            problem=self.problem,
            status=status,
            message=message,
            values={slot: float(v) for slot, v in zip(f.slots, x)},
            objective=objective,
            added_mass=mass,
            added_inertia=inertia,
            iterations=iterations,
            solve_time=elapsed,
            solver="ipopt",
            solver_status=solver_status,
            conditions=self.n_equalities,
            condition_summary=self.conditions.summary(),
            scenario_parameters={sc.name: f.scenario_parameters(parameters, i) for i, sc in enumerate(self.problem.scenarios)},
        )
