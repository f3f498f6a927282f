"""What a solve returns before verification: the design, its objective, the solver's word.

:func:`build_solution` is the one place a :class:`Solution` is made from a solver's point
(the designer and the minimax designer both call it).

A :class:`Solution` is immutable (``frozen``): a layer that adds to a design (constraint
values, a certificate gap, the best of several starts, a payload schedule, catalogue parts,
a robust report) returns a new value made with :func:`dataclasses.replace` and never
changes the one it was given, like cvxpy's reductions, whose ``invert`` maps the inner
solution to a new outer one. A layer whose own verdict goes beyond the dense check says
so with :meth:`Solution.judged`, which appends a :class:`Verdict` naming the layer: the
stack :attr:`Solution.verdicts` keeps what every layer said, innermost first, and
:func:`counterpoise.verify.judge.judge` takes the outermost as it stands.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from ..errors import SolverError
from ..formulation.formulation import Formulation
from ..formulation.layout import Gravity3, Slot
from ..model.problem import Problem
from ..solvers.base import SolverOutput, Status

if TYPE_CHECKING:
    from ..formulation.constraints import ConstraintValue
    from ..payload.design import PayloadDesign
    from ..robust.method import RobustReport
    from ..selection.parts import PartsReport
    from ..verify.checks import Verification

#: who gives a design its verdict (:attr:`Verdict.source`): the dense check (the rule for
#: every design no layer judged), or a layer
VERDICT_SOURCES = ("check", "constraints", "minimax", "robust", "payload", "parts", "realisation")

#: the type of an extra (:meth:`Solution.extra`)
E = TypeVar("E")


@dataclass(frozen=True)
class Verdict:
    """A design's status and the one line a user reads, and who said it.

    ``source`` (one of :data:`VERDICT_SOURCES`): ``check`` when the dense check judged the
    design (:func:`counterpoise.verify.judge.judge`), else the layer whose own word goes
    beyond it: the design constraints (balanced, yet infeasible with them), the minimax
    designer (its constraints cannot hold; or its dense ratio reported as is), the robust
    counterpart or its tuning, a payload range's schedule, the catalogue parts' limits."""

    status: Status
    message: str
    source: str

    def __post_init__(self) -> None:
        if self.source not in VERDICT_SOURCES:
            raise ValueError(f"verdict source {self.source!r}: expected one of {', '.join(VERDICT_SOURCES)}")


@dataclass(frozen=True)
class Solution:
    """A design (SI values per slot) and how it was obtained; immutable (see the module
    docstring): a layer returns a new one with :func:`dataclasses.replace` or :meth:`judged`."""

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
    #: the layers' own verdicts, innermost first (:meth:`judged`); empty: the design is
    #: judged by its dense check (:func:`counterpoise.verify.judge.judge`)
    verdicts: tuple[Verdict, ...] = ()
    #: the dense verification, when a design method already ran it (None: not yet)
    verification: Verification | None = None
    #: payload-range designs: the schedule, samples and range (:mod:`counterpoise.payload`)
    payload: PayloadDesign | None = None
    #: designs with spring slots: the chosen catalogue parts (:mod:`counterpoise.selection`)
    parts: PartsReport | None = None
    #: every design constraint at this design, per scenario
    constraints: tuple[ConstraintValue, ...] = ()
    #: designs with [robust]: tolerance bands, counterpart and tuning (:mod:`counterpoise.robust`)
    robust: RobustReport | None = None
    #: infeasible balance: what the reported closest design is (the smallest worst residual
    #: on sampled configurations, or least squares on the compressed conditions); None otherwise
    closest: str | None = None
    #: typed results of outer layers, one per type, reachable by type (:meth:`extra`)
    extras: tuple[object, ...] = ()

    def extra(self, kind: type[E]) -> E | None:
        """The outer layer's result of type ``kind`` attached to this design, or None."""
        return next((e for e in self.extras if isinstance(e, kind)), None)

    def with_extra(self, value: object) -> Solution:
        """A new solution with ``value`` among its extras (replacing one of the same type)."""
        return replace(self, extras=(*(e for e in self.extras if type(e) is not type(value)), value))

    @property
    def verdict(self) -> Verdict | None:
        """The outermost layer's own verdict (None: judge the dense check)."""
        return self.verdicts[-1] if self.verdicts else None

    def judged(self, status: Status, message: str, source: str) -> Solution:
        """A new solution with the verdict of layer ``source`` on top; this one is left as it is."""
        return replace(self, verdicts=(*self.verdicts, Verdict(status, message, source)))

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
