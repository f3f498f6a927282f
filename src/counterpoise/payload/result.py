"""What the payload layer found of a design: its :class:`PayloadDesign` (an extra of the
:class:`~counterpoise.designer.solution.Solution`, ``solution.extra(PayloadDesign)``): the
range, the samples, the schedule.

The record and what it answers from its own data; the schedule's solver is imported only
for annotations.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

from ..designer.checks import Verification
from ..designer.solution import Solution
from ..errors import SolverError
from ..formulation.layout import Slot
from ..model.payload import Payload
from ..model.problem import Problem
from ..solvers.base import Status
from .scenarios import Sampled, is_pinned, modes, sampled_problem, setting_name

if TYPE_CHECKING:
    from .schedule import AdjustmentSolver, Schedule
    from .widest import WidestRange


@dataclass(frozen=True)
class PayloadDesign:
    """The outcome of a payload-range design (``problem`` is the sampled problem solved)."""

    problem: Problem
    payload: Payload
    status: Status
    message: str
    solution: Solution
    verification: Verification
    samples: tuple[float, ...]
    schedule: Schedule | None
    checked: tuple[float, float]  # the payload range the schedule covers (kg)
    widest: WidestRange | None
    #: the schedule's solver for this design (adjustments at any payload; not compared)
    adjuster: "AdjustmentSolver | None" = field(default=None, compare=False, repr=False)

    def pinned(self, slot: Slot) -> bool:
        """Whether a design slot is an adjustment fixed to its nominal (not an active bound)."""
        setting_mass = {setting_name(self.payload, m): m for m in self.samples}
        return is_pinned(self.problem, slot, setting_mass)

    def shared(self) -> dict[str, float]:
        """The design's shared (non-adjustable) variables, SI."""
        return {slot.variable: v for slot, v in self.solution.values.items() if slot.scenario is None}

    def _scheduled(self) -> Sampled:
        if self.adjuster is None or self.schedule is None:
            raise SolverError(f"{self.problem.name}: the payload design has no schedule (its samples were not balanced)")
        masses = [s.payload for s in self.schedule.rows + self.schedule.between if s.feasible]
        return sampled_problem(self.adjuster.source, masses or self.samples)

    def schedule_solution(self) -> Solution:
        """The design on every feasible payload of its schedule (grid and between), one
        scenario per working mode and payload, each with that payload's adjustments: what
        a check that must hold at every payload (a part's limits) is run on.

        When no payload of the schedule is feasible (a design that balances none: the
        closest design of a range it cannot balance), there are no scheduled adjustments to
        put in: the design itself, on its samples, is returned (issue 32: ``KeyError: 0.0``,
        the samples' masses looked up among the feasible payloads)."""
        by_mass = {s.payload: s for s in self.schedule.rows + self.schedule.between if s.feasible} if self.schedule is not None else {}
        if not by_mass:
            return self.solution
        sampled = self._scheduled()
        n_modes = len(modes(self.adjuster.source)) or 1  # type: ignore[union-attr]  # a design with a schedule has its adjuster
        first = list(self.solution.scenario_parameters.values())[:n_modes]
        values: dict[Slot, float] = {slot: v for slot, v in self.solution.values.items() if slot.scenario is None}
        scenario_parameters = {}
        for i, scenario in enumerate(sampled.problem.scenarios):
            mass = sampled.setting_mass[scenario.setting or ""]
            gravity, base = first[i % n_modes]
            scenario_parameters[scenario.name] = (gravity, {**base, self.payload.name: mass})
            row = by_mass.get(mass)
            if row is None:  # no feasible schedule row: the design's own samples (their settings)
                continue
            for name, v in row.values.items():
                values[Slot(name, scenario.setting)] = v
        return replace(self.solution, problem=sampled.problem, values=values, scenario_parameters=scenario_parameters)

    def mass_of(self, scenario: str) -> float | None:
        """The payload mass of a scenario of :meth:`schedule_solution` or of the design."""
        for sampled in (self._scheduled(), sampled_problem(self.adjuster.source, self.samples)):  # type: ignore[union-attr]  # a design with a schedule has its adjuster
            if any(s.name == scenario for s in sampled.problem.scenarios):
                return sampled.setting_mass[sampled.problem.setting(scenario) or ""]
        return None
