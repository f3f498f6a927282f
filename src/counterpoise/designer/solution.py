"""What a solve returns before verification: the design, its objective, the solver's word.

:func:`build_solution` is the one place a :class:`Solution` is made from a solver's point
(the designer, the minimax designer and the robust layer call it).

A :class:`Solution` holds what every design has: the problem, status and message, the
values, objective, added mass and inertia, the :class:`SolverStats` (kept apart), the
verdicts, the verification, the design constraints' values and, for a balance that cannot
be met, what the reported closest design is. What a layer adds of its own (a payload
schedule, catalogue parts, a robust report, the realisation limits, a minimax design's
sampled ratio) is an *extra*: a value of the layer's own type, reached by that type
(``solution.extra(PayloadDesign)``; :meth:`Solution.with_extra`), so the core result names
no outer layer (compare cvxpy's ``Solution`` with its solver statistics kept apart, and its
reductions' ``invert``).

A :class:`Solution` is immutable (``frozen``): a layer that adds to a design returns a new
value made with :func:`dataclasses.replace` or :meth:`Solution.with_extra` and never changes
the one it was given. A layer whose own verdict goes beyond the dense check says so with
:meth:`Solution.judged`, which appends a :class:`Verdict` naming the layer: the stack
:attr:`Solution.verdicts` keeps what every layer said, innermost first, and
:func:`counterpoise.verify.judge.judge` takes the outermost as it stands.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TypeVar

import numpy as np

from ..errors import SolverError
from ..formulation.constraints import ConstraintValue
from ..formulation.formulation import Formulation
from ..formulation.layout import Gravity3, Slot
from ..model.problem import Problem
from .. import registry
from ..solvers.base import SolverOutput, Status
from .checks import Verification

#: who gives a design its verdict (:attr:`Verdict.source`) besides the registered layers:
#: the dense check (the rule for every design no layer judged), the design constraints and
#: the minimax rule of the core designer
CORE_SOURCES = ("check", "constraints", "minimax")


def verdict_sources() -> tuple[str, ...]:
    """Every valid :attr:`Verdict.source`: the core's, then each registered layer's name
    (:data:`counterpoise.registry.REGISTRY`)."""
    return (*CORE_SOURCES, *registry.names())


#: the verdict sources of the layers registered when this module was imported (:func:`verdict_sources`)
VERDICT_SOURCES = verdict_sources()

#: the type of an extra (:meth:`Solution.extra`)
E = TypeVar("E")


@dataclass(frozen=True)
class Verdict:
    """A design's status and the one line a user reads, and who said it.

    ``source`` (one of :func:`verdict_sources`): ``check`` when the dense check judged the
    design (:func:`counterpoise.verify.judge.judge`), else the layer whose own word goes
    beyond it: the design constraints (balanced, yet infeasible with them), the minimax
    designer (its constraints cannot hold; or its dense ratio reported as is), the robust
    counterpart or its tuning, a payload range's schedule, the catalogue parts' limits."""

    status: Status
    message: str
    source: str

    def __post_init__(self) -> None:
        sources = verdict_sources()
        if self.source not in sources:
            raise ValueError(f"verdict source {self.source!r}: expected one of {', '.join(sources)}")


@dataclass(frozen=True)
class SolverStats:
    """How a design was obtained: the solver's own figures, kept apart from the design."""

    iterations: int = 0
    solve_time: float = 0.0  # wall seconds spent in solver calls (not in building solvers)
    solver: str = ""
    solver_status: str = ""
    #: the balance conditions (or minimax rows) the solver was given, and their summary
    conditions: int = 0
    condition_summary: str = ""
    #: objective minus the LP optimum at this design's geometry (kg; 0 on the convex path,
    #: NaN when there is no LP to compare with): see :mod:`.convex`
    certificate_gap: float = float("nan")
    #: multi-start: (starts that reached the best objective, starts run); (1, 1) for one solve
    starts: tuple[int, int] = (1, 1)


@dataclass(frozen=True)
class Solution:
    """A design (SI values per slot) and how it was obtained; immutable (see the module
    docstring): a layer returns a new one with :func:`dataclasses.replace`,
    :meth:`with_extra` or :meth:`judged`."""

    problem: Problem
    status: Status
    message: str
    values: dict[Slot, float]
    objective: float
    added_mass: float
    added_inertia: float
    stats: SolverStats = field(default_factory=SolverStats)
    #: per scenario name: gravity vector and base-parameter values the design was solved for
    scenario_parameters: dict[str, tuple[Gravity3, dict[str, float]]] = field(default_factory=dict)
    #: the layers' own verdicts, innermost first (:meth:`judged`); empty: the design is
    #: judged by its dense check (:func:`counterpoise.verify.judge.judge`)
    verdicts: tuple[Verdict, ...] = ()
    #: the dense verification, when a design method already ran it (None: not yet)
    verification: Verification | None = None
    #: every design constraint at this design, per scenario
    constraints: tuple[ConstraintValue, ...] = ()
    #: infeasible balance: what the reported closest design is (the smallest worst residual
    #: on sampled configurations, or least squares on the compressed conditions); None otherwise
    closest: str | None = None
    #: what outer layers added, one value per type, reached by its type (:meth:`extra`)
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

    def settled(self, verdict: Verdict) -> Solution:
        """The design as finally judged (what :func:`counterpoise.pipeline.run` returns):
        ``verdict`` on top of the stack (unless it is the outermost already), and its status
        and message the design's own, so that a finished design has one status. A new
        value; this one is left as it is (a layer's solution keeps what its solver said)."""
        verdicts = self.verdicts if self.verdict is verdict else (*self.verdicts, verdict)
        return replace(self, status=verdict.status, message=verdict.message, verdicts=verdicts)

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
        stats=SolverStats(out.iterations, out.solve_time, out.solver, out.solver_status, conditions, condition_summary),
        scenario_parameters=f.parameters.scenario_values(parameters),
    )
