"""Dense, independent check that a design is balanced.

For every (subsystem, scenario) the residual ∂V/∂q is evaluated on ``verify_samples``
random configurations plus every corner of the coordinate box (:mod:`.residuals`), and
set against the forces gravity puts on the unbalanced mechanism (:mod:`.checks`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .checks import PRISMATIC, REVOLUTE, CoordinateCheck, Verification
from .residuals import configurations, energy_scale, residuals

if TYPE_CHECKING:
    from ..designer.solution import Solution


def verify(solution: "Solution", samples: int | None = None, seed: int | None = None) -> Verification:
    """Check ``solution`` on random configurations plus corners, per (subsystem, scenario)."""
    problem = solution.problem
    settings = problem.settings
    rng = np.random.default_rng(settings.seed + 1 if seed is None else seed)
    n = settings.verify_samples if samples is None else samples
    checks = []
    for scenario in problem.scenarios:
        variables = solution.variable_values(scenario.name)
        gravity, base = solution.scenario_parameters[scenario.name]
        for sub in problem.subsystems:
            q = configurations(problem, sub.name, n, rng)
            r, t = residuals(problem, sub.name, q, variables, base, gravity)
            scale = energy_scale(problem, sub.name, q, variables, base, gravity)
            for j, name in enumerate(sub.coordinates):
                column = np.abs(r[:, j])
                worst = int(np.nanargmax(column)) if not np.isnan(column).all() else 0
                kind = REVOLUTE if problem.coordinate[name].unit.dimension == "" else PRISMATIC
                checks.append(
                    CoordinateCheck(
                        subsystem=sub.name,
                        scenario=scenario.name,
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
    return Verification(tuple(checks), settings.verify_tolerance)
