"""A design's final status and the one-line explanation a user reads."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..designer.minimax import minimax_of
from ..model.tilt import tilt_text
from ..solvers.base import Status
from ..designer.checks import FORCE_NAME, CoordinateCheck, Verification

if TYPE_CHECKING:
    from ..designer.solution import Solution, Verdict


def verdict(solution: "Solution", verification: Verification) -> "Verdict":
    """The final :class:`~counterpoise.designer.solution.Verdict` of a design: the outermost
    layer's own (its ``source`` names the layer), the minimax rule for a minimax design, else
    the dense check's (source ``check``, :func:`judge`)."""
    from ..designer.solution import Verdict

    if solution.verdict is not None:
        return solution.verdict
    status, message = judge(solution, verification)
    return Verdict(status, message, "minimax" if minimax_of(solution) is not None else "check")


def judge(solution: "Solution", verification: Verification) -> tuple[Status, str]:
    """``optimal`` needs the solver's optimum *and* the dense check; otherwise say why not.

    The outermost layer's own verdict (``solution.verdict``, which names its layer: a payload
    schedule, catalogue limits, the robust counterpart, the design constraints) stands as
    given; a minimax design (directly attached springs) is judged by :func:`judge_minimax`."""
    if solution.verdict is not None:
        return solution.verdict.status, solution.verdict.message
    if minimax_of(solution) is not None:
        return judge_minimax(solution, verification)
    if solution.status is Status.OPTIMAL:
        if verification.balanced:
            return Status.OPTIMAL, solution.message
        worst = verification.worst()
        if worst is None or verification.ratio(worst) != verification.ratio(worst):  # NaN
            return Status.FAILED, "verification failed: the residual could not be evaluated (NaN)"
        return Status.FAILED, (
            f"verification failed: subsystem '{worst.subsystem}', coordinate '{worst.coordinate}'"
            f"{_scenario_text(solution, worst.scenario, worst)} keeps a residual of {worst.max_residual:.3g} {worst.unit} "
            f"(ratio {verification.residual_ratio:.2g} > {verification.tolerance:.0e})"
        )
    if solution.status is Status.INFEASIBLE:
        return Status.INFEASIBLE, _unmet_message(solution, verification)
    return Status.FAILED, solution.message


def judge_minimax(solution: "Solution", verification: Verification) -> tuple[Status, str]:
    """A minimax design is optimal when IPOPT converged and its dense ratio is within
    ``settings.minimax_tolerance``; beyond it, "not balanced"."""
    if solution.status is not Status.OPTIMAL:
        return Status.FAILED, solution.message
    dense = verification.residual_ratio
    if dense != dense:
        return Status.FAILED, "verification failed: the residual could not be evaluated (NaN)"
    tolerance = solution.problem.settings.minimax_tolerance
    if dense > tolerance:
        return Status.NOT_BALANCED, (
            f"not balanced: the best design of these real springs leaves a worst residual ratio of {dense:.4g} on the dense check, "
            f"more than minimax_tolerance {tolerance:.4g} ({solution.message})"
        )
    return Status.OPTIMAL, f"{solution.message}; dense check: worst residual ratio {dense:.6g}"


def _scenario_text(solution: "Solution", scenario: str, check: CoordinateCheck | None = None) -> str:
    problem = solution.problem
    if problem.tilts and check is not None and check.worst_tilt:
        # a tilting base: the tilt where the worst residual was found, and the working mode
        own = next((s for s in problem.scenarios if s.name == scenario), None)
        modes = {s.setting for s in problem.scenarios}
        mode = f" in working mode '{own.setting}'" if own is not None and len(modes) > 1 else ""
        return f"{mode} with the {tilt_text(problem.tilts, check.worst_tilt)}"
    return f" in scenario '{scenario}'" if len(problem.scenarios) > 1 else ""


def _share(verification: Verification, check: CoordinateCheck) -> str:
    ratio = verification.ratio(check)
    if ratio != ratio or verification.reference(check.kind) <= 0:
        return ""
    return f" ({100 * ratio:.3g} % of the largest unbalanced {FORCE_NAME[check.kind]})"


def _unmet_message(solution: "Solution", verification: Verification) -> str:
    problem = solution.problem
    parts = [
        f"subsystem '{c.subsystem}', coordinate '{c.coordinate}'{_scenario_text(solution, c.scenario, c)}: "
        f"residual up to {c.max_residual:.3g} {c.unit}{_share(verification, c)}"
        for c in verification.unmet()[:3]
    ]
    at_bounds = []
    for slot, value in solution.values.items():
        v = problem.variable[slot.variable]
        side = v.bound_side(value)
        if side:
            name = slot.variable if slot.scenario is None else f"{slot.variable}@{slot.scenario}"
            bound = v.lower if side == "lower" else v.upper
            at_bounds.append(f"{name} at its {side} bound {v.unit.from_si(bound):.6g} {v.unit.label}")
    text = "balance cannot be met within the bounds: " + ("; ".join(parts) or solution.message)
    kind = f" ({solution.closest})" if solution.closest else ""
    if at_bounds:
        text += f"; at the closest design{kind} " + ", ".join(at_bounds)
    elif kind:
        text += f"; at the closest design{kind} no variable is reported at a bound"
    return text
