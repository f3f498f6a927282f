"""Solve, verify and evaluate a problem: the result a report is written from."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import expr as ex
from .mechanics import NUMPY_FUNCTIONS, Mechanics
from .nlp import Designer, Solution, Status
from .problem import Problem
from .verify import Verification, verify


@dataclass(frozen=True)
class QuantityValue:
    """A report quantity in one scenario (``scenario`` None: the same in every scenario)."""

    name: str
    scenario: str | None
    value: float  # SI


@dataclass(frozen=True)
class DesignResult:
    problem: Problem
    status: Status
    message: str
    solution: Solution
    verification: Verification
    quantities: tuple[QuantityValue, ...]

    @property
    def optimal(self) -> bool:
        return self.status is Status.OPTIMAL


def design(problem: Problem, designer: Designer | None = None) -> DesignResult:
    """Solve ``problem`` (with a prebuilt ``designer`` if given), verify it, evaluate reports."""
    designer = designer or Designer(problem)
    solution = designer.solve()
    verification = verify(solution)
    status, message = _judge(solution, verification)
    return DesignResult(problem, status, message, solution, verification, evaluate_quantities(solution))


def _judge(solution: Solution, verification: Verification) -> tuple[Status, str]:
    if solution.status is Status.OPTIMAL:
        if verification.balanced:
            return Status.OPTIMAL, solution.message
        unmet = verification.unmet()
        if not unmet:
            return Status.FAILED, "verification failed: the residual could not be evaluated (NaN)"
        worst = unmet[0]
        return Status.FAILED, (
            f"verification failed: subsystem '{worst.subsystem}', coordinate '{worst.coordinate}'"
            f"{_scenario_text(solution, worst.scenario)} keeps a residual of {worst.max_residual:.3g} "
            f"(ratio {verification.residual_ratio:.2g} > {verification.tolerance:.0e})"
        )
    if solution.status is Status.INFEASIBLE:
        return Status.INFEASIBLE, _unmet_message(solution, verification)
    return Status.FAILED, solution.message


def _scenario_text(solution: Solution, scenario: str) -> str:
    return f" in scenario '{scenario}'" if len(solution.problem.scenarios) > 1 else ""


def _unmet_message(solution: Solution, verification: Verification) -> str:
    problem = solution.problem
    parts = []
    total = verification.max_gravity_torque
    for c in verification.unmet()[:3]:
        share = f" ({100 * c.max_residual / total:.3g} % of the unbalanced gravity torque)" if total > 0 else ""
        parts.append(
            f"subsystem '{c.subsystem}', coordinate '{c.coordinate}'{_scenario_text(solution, c.scenario)}: "
            f"residual up to {c.max_residual:.3g}{share}"
        )
    at_bounds = []
    for slot, value in solution.values.items():
        v = problem.variable[slot.variable]
        side = active_bound(value, v.lower, v.upper)
        if side:
            at_bounds.append(f"{slot.variable} at its {side} bound")
    text = "balance cannot be met within the bounds: " + ("; ".join(parts) or solution.message)
    if at_bounds:
        text += "; at the closest design " + ", ".join(at_bounds)
    return text


def active_bound(value: float, lower: float, upper: float, rel: float = 1e-6) -> str:
    """'lower', 'upper' or '': whether ``value`` is within ``rel`` × max(range, |bounds|) of a bound."""
    span = max(upper - lower, abs(upper), abs(lower), 1e-300)
    if upper > lower:
        if value - lower <= rel * span:
            return "lower"
        if upper - value <= rel * span:
            return "upper"
    return ""


def evaluate_quantities(solution: Solution) -> tuple[QuantityValue, ...]:
    """Every report quantity, per scenario; one row when all scenarios agree."""
    problem = solution.problem
    per_scenario: dict[str, dict[str, float]] = {}
    for scenario in problem.scenarios:
        gravity, base = solution.scenario_parameters[scenario.name]
        home = {c.name: c.home for c in problem.coordinates}
        mech = Mechanics(problem, base, solution.variable_values(scenario.name), home, gravity, NUMPY_FUNCTIONS)
        functions = dict(NUMPY_FUNCTIONS)
        functions["total_mass"] = ex.NameArgs(mech.total_mass)
        functions["com_distance"] = ex.NameArgs(mech.com_distance)
        env = dict(mech.env)
        values = {}
        for q in problem.report:
            # a quantity that cannot be evaluated at this design (0/0, a centre of mass of
            # nothing) is reported as NaN rather than losing the whole report
            with np.errstate(all="ignore"):
                try:
                    value = float(ex.evaluate(q.expr, env, functions))
                except (ArithmeticError, ValueError):
                    value = float("nan")
            env[q.name] = values[q.name] = value
        per_scenario[scenario.name] = values
    out = []
    for q in problem.report:
        vals = {s: per_scenario[s][q.name] for s in per_scenario}
        first = next(iter(vals.values()))
        same = all(math.isclose(v, first, rel_tol=1e-12, abs_tol=1e-300) or (math.isnan(v) and math.isnan(first)) for v in vals.values())
        if same:
            out.append(QuantityValue(q.name, None, first))
        else:
            out.extend(QuantityValue(q.name, s, v) for s, v in vals.items())
    return tuple(out)
