"""What a solve returns before verification: the design, its objective, the solver's word.

:func:`build_solution` is the one place a :class:`Solution` is made from a solver's point
(the designer and the minimax designer both call it).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import SolverError
from ..formulation.formulation import Formulation
from ..formulation.layout import Gravity3, Slot
from ..model.problem import Problem
from ..solvers.base import SolverOutput, Status


@dataclass
class Solution:
    """A design (SI values per slot) and how it was obtained."""

    problem: Problem
    status: Status
    message: str
    values: dict[Slot, float]
    objective: float
    added_mass: float
    added_inertia: float
    iterations: int
    solve_time: float  # wall seconds spent in solver calls (not in building solvers)
    solver: str
    solver_status: str
    conditions: int
    condition_summary: str
    #: per scenario name: gravity vector and base-parameter values the design was solved for
    scenario_parameters: dict[str, tuple[Gravity3, dict[str, float]]] = field(default_factory=dict)
    #: minimax designs (directly attached springs): the worst residual ratio on the NLP's samples
    sampled_ratio: float | None = None
    #: objective minus the LP optimum at this design's geometry (kg; 0 on the convex path,
    #: NaN when there is no LP to compare with): see :mod:`.convex`
    certificate_gap: float = float("nan")
    #: multi-start: (starts that reached the best objective, starts run); (1, 1) for one solve
    starts: tuple[int, int] = (1, 1)
    #: an outer design method's own verdict (status, message), which goes beyond the dense
    #: check (a payload schedule, the limits of catalogue parts); None: judge the verification
    verdict: tuple[Status, str] | None = None
    #: the dense verification, when a design method already ran it (None: not yet)
    verification: Any = None
    #: payload-range designs: the :class:`counterpoise.payload.PayloadDesign`
    payload: Any = None
    #: designs with spring slots: the :class:`counterpoise.selection.PartsReport`
    parts: Any = None
    #: every design constraint at this design, per scenario
    #: (:class:`counterpoise.formulation.constraints.ConstraintValue`)
    constraints: tuple[Any, ...] = ()
    #: designs with [robust]: the :class:`counterpoise.robust.RobustReport`
    robust: Any = None
    #: infeasible balance: what the reported closest design is (the smallest worst residual
    #: on sampled configurations, or least squares on the compressed conditions); None otherwise
    closest: str | None = None

    def variable_values(self, scenario: str) -> dict[str, float]:
        """Value of every variable as seen by ``scenario``."""
        setting = self.problem.setting(scenario)
        return {slot.variable: v for slot, v in self.values.items() if slot.scenario is None or slot.scenario == setting}


def build_solution(
    formulation: Formulation,
    z: np.ndarray,
    parameters: np.ndarray,
    lbz: np.ndarray,
    ubz: np.ndarray,
    out: SolverOutput,
    message: str,
    conditions: int,
    condition_summary: str,
    sampled_ratio: float | None = None,
) -> Solution:
    """The :class:`Solution` at the scaled point ``z`` (clipped to [lbz, ubz]) with ``parameters``."""
    f = formulation
    z = np.clip(z, lbz, ubz)
    x = f.design.to_x(z)
    if not np.all(np.isfinite(x)):
        raise SolverError(f"{f.problem.name}: the solver returned non-finite values")
    objective, mass, inertia = (float(v[0, 0]) for v in f.report_values(z, parameters))
    return Solution(
        problem=f.problem,
        status=out.status,
        message=message,
        values=f.design.values(x),
        objective=objective,
        added_mass=mass,
        added_inertia=inertia,
        iterations=out.iterations,
        solve_time=out.solve_time,
        solver=out.solver,
        solver_status=out.solver_status,
        conditions=conditions,
        condition_summary=condition_summary,
        scenario_parameters=f.parameters.scenario_values(parameters),
        sampled_ratio=sampled_ratio,
    )
