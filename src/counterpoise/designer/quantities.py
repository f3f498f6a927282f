"""Report quantities of a design: the file's named expressions, evaluated per scenario."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..mechanics import NUMPY_FUNCTIONS, Mechanics
from ..model import expr as ex
from .solution import Solution


@dataclass(frozen=True)
class QuantityValue:
    """A report quantity in one scenario (``scenario`` None: the same in every scenario)."""

    name: str
    scenario: str | None
    value: float  # SI


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
