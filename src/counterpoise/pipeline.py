"""Solve, verify and evaluate a problem: the result a report is written from."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .designer.designer import Designer
from .designer.quantities import QuantityValue, evaluate_quantities
from .designer.solution import Solution
from .model.problem import Problem
from .solvers.base import Status
from .verify.check import verify
from .verify.checks import Verification
from .verify.judge import judge


@dataclass(frozen=True)
class DesignResult:
    problem: Problem
    status: Status
    message: str
    solution: Solution
    verification: Verification
    quantities: tuple[QuantityValue, ...]
    #: payload problems: the :class:`counterpoise.payload.PayloadDesign` (schedule, range)
    payload: Any = None

    @property
    def optimal(self) -> bool:
        return self.status is Status.OPTIMAL


def design(problem: Problem, designer: Designer | None = None, **solve_options: object) -> DesignResult:
    """Solve ``problem`` (with a prebuilt ``designer`` if given), verify it, evaluate reports.

    ``solve_options`` go to :meth:`Designer.solve` (``parameters``, ``bounds``, ``initial``).
    A problem with a payload range is designed for the whole range (:mod:`.payload`) unless
    a designer or solve options are given: then it is solved at its nominal payload.
    """
    if problem.payloads and designer is None and not solve_options:
        from .payload import design_payloads

        outcome = design_payloads(problem)
        s = outcome.solution
        return DesignResult(s.problem, outcome.status, outcome.message, s, outcome.verification, evaluate_quantities(s), outcome)
    designer = designer or Designer(problem)
    solution = designer.solve(**solve_options)  # type: ignore[arg-type]
    verification = verify(solution)
    status, message = judge(solution, verification)
    return DesignResult(problem, status, message, solution, verification, evaluate_quantities(solution))
