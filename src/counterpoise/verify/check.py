"""Dense, independent check that a design is balanced.

For every (subsystem, scenario) the residual ∂V/∂q is evaluated on ``verify_samples``
random configurations plus every corner of the coordinate box (:mod:`.residuals`), and
set against the forces gravity puts on the unbalanced mechanism (:mod:`.checks`).
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING, Any

import numpy as np

from ..model.problem import Problem
from .checks import PRISMATIC, REVOLUTE, CoordinateCheck, Verification
from .residuals import SubsystemResiduals, configurations, energy_scale

#: Residual evaluators of the problems checked last (a study verifies one problem many times).
_CACHE_SIZE = 4
#: Configurations on which the energy scale of the noise floor is taken.
ENERGY_SCALE_SAMPLES = 256
_cache: dict[int, tuple["weakref.ref[Problem]", dict[tuple[Any, ...], list[tuple[str, str, SubsystemResiduals]]]]] = {}

if TYPE_CHECKING:
    from ..designer.solution import Solution


def evaluators(solution: "Solution", samples: int | None = None, seed: int | None = None) -> list[tuple[str, str, SubsystemResiduals]]:
    """(scenario, subsystem, evaluator) of every pair, built once per problem, sample count
    and seed, and reused by later checks of the same problem (the configurations do not
    depend on parameter values; each evaluator rebuilds its arrays when the geometry does)."""
    problem = solution.problem
    settings = problem.settings
    seed = settings.seed + 1 if seed is None else seed
    n = settings.verify_samples if samples is None else samples
    entry = _cache.get(id(problem))
    if entry is None or entry[0]() is not problem:
        if len(_cache) >= _CACHE_SIZE:
            _cache.pop(next(iter(_cache)))
        entry = (weakref.ref(problem), {})
        _cache[id(problem)] = entry
    found = entry[1].get((n, seed))
    if found is None:
        rng = np.random.default_rng(seed)  # the draws follow (scenario, subsystem) order, as always
        found = []
        for scenario in problem.scenarios:
            for sub in problem.subsystems:
                q = configurations(problem, sub.name, n, rng)
                found.append((scenario.name, sub.name, SubsystemResiduals(problem, sub.name, q)))
        entry[1][(n, seed)] = found
    return found


def verify(solution: "Solution", samples: int | None = None, seed: int | None = None) -> Verification:
    """Check ``solution`` on random configurations plus corners, per (subsystem, scenario)."""
    problem = solution.problem
    checks = []
    for scenario, subsystem, evaluator in evaluators(solution, samples, seed):
        variables = solution.variable_values(scenario)
        q = evaluator.q
        gravity, base = solution.scenario_parameters[scenario]
        r, t = evaluator.evaluate(variables, base, gravity)
        # the size of the terms whose rounding noise a residual that is zero in exact
        # arithmetic keeps (a few hundred configurations show it well enough)
        scale = energy_scale(problem, subsystem, q[:ENERGY_SCALE_SAMPLES], variables, base, gravity)
        for j, name in enumerate(evaluator.names):
            column = np.abs(r[:, j])
            worst = int(np.nanargmax(column)) if not np.isnan(column).all() else 0
            kind = REVOLUTE if problem.coordinate[name].unit.dimension == "" else PRISMATIC
            checks.append(
                CoordinateCheck(
                    subsystem=subsystem,
                    scenario=scenario,
                    coordinate=name,
                    kind=kind,
                    max_residual=float(column.max()),  # NaN if any is NaN
                    max_gravity_torque=float(np.abs(t[:, j]).max()),
                    max_balancer_force=float(np.abs(r[:, j] - t[:, j]).max()),
                    energy_scale=scale,
                    configurations=int(q.shape[0]),
                    worst_configuration=tuple(float(v) for v in q[worst]),
                )
            )
    return Verification(tuple(checks), problem.settings.verify_tolerance)
