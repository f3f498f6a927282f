"""What a solve returns before verification: the design, its objective, the solver's word."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..formulation.layout import Gravity3, Slot
from ..model.problem import Problem
from ..solvers.base import Status


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

    def variable_values(self, scenario: str) -> dict[str, float]:
        """Value of every variable as seen by ``scenario``."""
        setting = self.problem.setting(scenario)
        return {slot.variable: v for slot, v in self.values.items() if slot.scenario is None or slot.scenario == setting}
