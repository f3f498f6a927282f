"""Solve, verify and evaluate a problem: the result a report is written from."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .designer.designer import Designer
from .designer.minimax import MinimaxDesigner, has_direct_springs
from .designer.quantities import QuantityValue, evaluate_quantities
from .designer.solution import Solution
from .model.problem import Problem
from .solvers.base import Status
from .verify.check import verify
from .verify.checks import Verification
from .verify.judge import judge

if TYPE_CHECKING:
    from .selection.parts import PartsReport


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
    parts: "PartsReport | None" = None  # chosen catalogue parts (problems with spring slots)

    @property
    def optimal(self) -> bool:
        return self.status is Status.OPTIMAL


def design(problem: Problem, designer: Designer | None = None, starts: int = 1, **solve_options: object) -> DesignResult:
    """Solve ``problem`` (with a prebuilt ``designer`` if given), verify it, evaluate reports.

    ``solve_options`` go to :meth:`Designer.solve` (``parameters``, ``bounds``, ``initial``).
    A problem with a payload range is designed for the whole range (:mod:`.payload`) unless
    a designer or solve options are given: then it is solved at its nominal payload. A
    problem with spring slots first chooses its parts (:mod:`counterpoise.selection`) and
    solves for their rates; one with directly attached springs minimises the worst residual.
    ``starts`` > 1 (plain problems): a seeded multi-start over the free geometry (seed: ``settings.seed``),
    see :func:`counterpoise.designer.convex.multistart`.
    """
    if problem.slots:
        return _design_with_parts(problem, designer, **solve_options)
    if has_direct_springs(problem):
        return _design_minimax(problem, designer, **solve_options)
    if problem.payloads and designer is None and not solve_options:
        from .payload import design_payloads

        outcome = design_payloads(problem)
        s = outcome.solution
        return DesignResult(s.problem, outcome.status, outcome.message, s, outcome.verification, evaluate_quantities(s), payload=outcome)
    designer = designer or Designer(problem)
    if starts > 1:
        from .designer.convex import multistart

        solution = multistart(designer, starts, problem.settings.seed, **solve_options)
    else:
        solution = designer.solve(**solve_options)  # type: ignore[arg-type]
    verification = verify(solution)
    status, message = judge(solution, verification)
    return DesignResult(problem, status, message, solution, verification, evaluate_quantities(solution))


def _design_with_parts(problem: Problem, designer: "Designer | MinimaxDesigner | None", **solve_options: object) -> DesignResult:
    from .selection import parts
    from .selection.direct import part_parameters, search_direct

    given = dict(solve_options.pop("parameters", None) or {})  # type: ignore[call-overload]
    if has_direct_springs(problem):
        designer = designer if isinstance(designer, MinimaxDesigner) else MinimaxDesigner(problem)
        search = search_direct(problem, designer)
        rows = dict(search.choice.parts) if search.choice else {s.name: 0 for s in problem.slots}
        solution = designer.solve(parameters={**given, **part_parameters(problem, rows)}, **solve_options)  # type: ignore[arg-type]
        verification = verify(solution)
        status, message = _judge_minimax(solution, verification)
    else:
        search, rows, rates = parts.choose(problem)
        designer = designer or Designer(problem)
        solution = designer.solve(parameters={**given, **part_parameters(problem, rows)}, **solve_options)  # type: ignore[arg-type]
        verification = verify(solution)
        status, message = judge(solution, verification)
    chosen = parts.report(problem, designer, solution, search, rows)
    if search.choice is None:
        near = "; ".join(m.text() for m in search.nearest) or "none could be evaluated"
        status, message = Status.INFEASIBLE, f"{search.message}. Nearest candidates: {near}"
    elif status is Status.OPTIMAL and not chosen.fits:
        bad = next(u for u in chosen.springs if not u.fits)
        status = Status.INFEASIBLE
        message = f"part {bad.part_number} of spring {bad.spring} leaves its limits on the dense check (margins: slack {bad.margin_slack:.3g} m, length {bad.margin_length:.3g} m, load {bad.margin_load:.3g} N)"
    elif status is Status.OPTIMAL:
        picked = ", ".join(f"{s.name}: {s.catalogue.part_number[rows[s.name]]}" for s in problem.slots)
        message = f"{message}; parts {picked}"
    return DesignResult(problem, status, message, solution, verification, evaluate_quantities(solution), parts=chosen)


def _judge_minimax(solution: Solution, verification: Verification) -> tuple[Status, str]:
    """A minimax design is optimal when IPOPT converged; its dense ratio is reported as is."""
    if solution.status is not Status.OPTIMAL:
        return solution.status if solution.status is Status.FAILED else Status.FAILED, solution.message
    dense = verification.residual_ratio
    if dense != dense:
        return Status.FAILED, "verification failed: the residual could not be evaluated (NaN)"
    return Status.OPTIMAL, f"{solution.message}; dense check: worst residual ratio {dense:.6g}"


def _design_minimax(problem: Problem, designer: "Designer | MinimaxDesigner | None", **solve_options: object) -> DesignResult:
    designer = designer if isinstance(designer, MinimaxDesigner) else MinimaxDesigner(problem)
    solution = designer.solve(**solve_options)  # type: ignore[arg-type]
    verification = verify(solution)
    status, message = _judge_minimax(solution, verification)
    return DesignResult(problem, status, message, solution, verification, evaluate_quantities(solution))
