"""Solve, verify and evaluate a problem: the result a report is written from."""

from __future__ import annotations

from dataclasses import dataclass

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

    @property
    def optimal(self) -> bool:
        return self.status is Status.OPTIMAL


def design(problem: Problem, designer: Designer | None = None, starts: int = 1, **solve_options: object) -> DesignResult:
    """Solve ``problem`` (with a prebuilt ``designer`` if given), verify it, evaluate reports.

    ``solve_options`` go to :meth:`Designer.solve` (``parameters``, ``bounds``, ``initial``).
    ``starts`` > 1: a seeded multi-start over the free geometry (seed: ``settings.seed``),
    see :func:`counterpoise.designer.convex.multistart`.
    """
    designer = designer or Designer(problem)
    if starts > 1:
        from .designer.convex import multistart

        solution = multistart(designer, starts, problem.settings.seed, **solve_options)
    else:
        solution = designer.solve(**solve_options)  # type: ignore[arg-type]
    verification = verify(solution)
    status, message = judge(solution, verification)
    return DesignResult(problem, status, message, solution, verification, evaluate_quantities(solution))
