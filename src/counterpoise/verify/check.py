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
from .manifold import ManifoldResiduals
from .residuals import SubsystemResiduals, configurations, energy_scale

#: Residual evaluators of the problems checked last (a study verifies one problem many times).
_CACHE_SIZE = 4
#: Configurations on which the energy scale of the noise floor is taken.
ENERGY_SCALE_SAMPLES = 256
#: The energy scale is skipped when every coordinate carries more than this share of the
#: largest gravity torque of its subsystem and every residual is below SCALE_RESIDUAL of it.
SCALE_LOAD_SPREAD = 1e-6
SCALE_RESIDUAL = 1e-9
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
                if problem.subsystem_loops(sub.name):  # closed loops: on the configuration manifold
                    found.append((scenario.name, sub.name, ManifoldResiduals(problem, sub.name, n, rng, scenario.name)))  # type: ignore[arg-type]
                    continue
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
        gravity, base = solution.scenario_parameters[scenario]
        r, t = evaluator.evaluate(variables, base, gravity)
        q = evaluator.q  # after evaluate: a manifold is solved again when the geometry changed
        # column by column: r and t are transposed views, and a column is contiguous
        columns = [np.abs(r[:, j]) for j in range(r.shape[1])]
        residual = np.array([c.max() for c in columns])  # NaN if any is NaN
        loads = np.array([np.abs(t[:, j]).max() for j in range(t.shape[1])])
        balancers = np.array([np.abs(r[:, j] - t[:, j]).max() for j in range(r.shape[1])])
        scale = _energy_scale_if_needed(problem, subsystem, q, residual, loads, variables, base, gravity)
        for j, name in enumerate(evaluator.names):
            column = columns[j]
            worst = int(np.nanargmax(column)) if not np.isnan(column).all() else 0
            kind = REVOLUTE if problem.coordinate[name].unit.dimension == "" else PRISMATIC
            checks.append(
                CoordinateCheck(
                    subsystem=subsystem,
                    scenario=scenario,
                    coordinate=name,
                    kind=kind,
                    max_residual=float(residual[j]),
                    max_gravity_torque=float(loads[j]),
                    max_balancer_force=float(balancers[j]),
                    energy_scale=scale,
                    configurations=int(q.shape[0]),
                    worst_configuration=tuple(float(v) for v in q[worst]),
                )
            )
    return Verification(tuple(checks), problem.settings.verify_tolerance)


def _energy_scale_if_needed(
    problem: Problem, subsystem: str, q: np.ndarray, residual: np.ndarray, loads: np.ndarray, variables: Any, base: Any, gravity: Any
) -> float:
    """The energy scale of the noise floor (:mod:`.checks`), or 0 when it cannot matter.

    It matters only where gravity's torque may itself be rounding noise: a coordinate that
    gravity loads far less than the others (or not at all), or a residual that is not far
    below the gravity torque (noise measured against noise, or a design that fails anyway).
    A well-loaded, balanced subsystem skips it (it costs a full energy evaluation).
    """
    top = float(loads.max(initial=0.0))
    if top > 0 and np.all(loads > SCALE_LOAD_SPREAD * top) and np.all(residual <= SCALE_RESIDUAL * top):
        return 0.0
    # the size of the terms whose rounding noise a residual that is zero in exact
    # arithmetic keeps (a few hundred configurations show it well enough)
    return energy_scale(problem, subsystem, q[:ENERGY_SCALE_SAMPLES], variables, base, gravity)
