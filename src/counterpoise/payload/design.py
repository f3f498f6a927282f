"""Designing for a payload range: samples, the shared design, its schedule, its widest range.

:func:`design_payloads` is what :func:`counterpoise.pipeline.design` runs for a problem with
a ``[payloads]`` range:

1. **Samples.** The design is solved on the end points of the range and the nominal mass
   (one scenario per working mode and mass; adjustments pinned to their ``nominal`` at the
   nominal mass and kept within their ``travel`` elsewhere).
2. **Schedule.** The shared variables are fixed and the adjustments alone are solved on a
   grid of the declared range and between its points (:mod:`.schedule`). If some payload
   fails, it joins the samples and the design is solved again (at most
   :data:`REFINEMENTS` times): the samples are chosen by the schedule, so a design that
   needs an interior payload to be feasible gets it. Adjustments linear in the payload
   need only the end points (the values between are convex combinations of feasible
   ones); the schedule confirms it and states their formulas.
3. **Widest range** (``objective = "max_payload_range"``): with the design fixed, both
   ends are pushed out until an adjustment reaches a limit (:func:`widest_range`: the
   upper end by doubling steps, a scan for holes and bisection, the lower end down toward
   0), and the schedule is re-solved on the range found. ``counterpoise schedule`` reports
   the same range for a payload it cannot balance.
4. **A declared range too wide.** The message names the limiting adjustments of the
   least-squares closest design, and the design reported is the one that balances the
   widest sub-range around the nominal (:func:`_narrowed`): it is balanced at least at
   the nominal, and the message says what it balances ("balanceable from 0 g to 100 g;
   dL_c1 reaches its upper limit 50 mm at 100 g").
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

from ..designer.designer import Designer
from ..designer.methods import DesignMethod, Plain
from ..designer.options import BoundsOverride
from ..designer.solution import Solution
from ..model import expr as ex
from ..model.payload import MAX_PAYLOAD_RANGE
from ..model.problem import Problem, ReportQuantity
from ..solvers.base import Status
from ..verify.check import verify
from ..designer.checks import Verification
from ..verify.judge import judge
from ..formulation.layout import Slot
from .result import PayloadDesign
from .options import adjustment_bounds, check_options, merged_bounds, sampled_initial
from .scenarios import Sampled, is_pinned, payload_of, sampled_problem
from .schedule import Adjusters, AdjustmentSolver, Schedule, Setting, schedule
from .widest import PAYLOAD_RESOLUTION, WidestRange, widest_range

#: re-designs with an added failing payload before the schedule's failure is final
REFINEMENTS = 3
#: bisection steps on each end of a declared range too wide to balance (1/4096 of its span)
NARROW_STEPS = 12



@dataclass(frozen=True)
class OperatorSettings:
    """What ``counterpoise schedule --payload`` prints: the adjustments for one payload."""

    design: PayloadDesign
    setting: Setting | None  # None when the design itself is not optimal
    balanceable: tuple[float, float] | None  # computed when the payload cannot be balanced
    #: said when the payload lies outside the declared range ("" inside it)
    note: str = ""


def settings_for(problem: Problem, mass: float, outcome: PayloadDesign | None = None) -> OperatorSettings:
    """Design ``problem`` for its range (or take its design ``outcome``), then solve the
    adjustments for payload ``mass``; when they do not balance, also find the range of
    payloads the design can balance."""
    outcome = outcome or design_payloads(problem)
    if outcome.status is not Status.OPTIMAL or outcome.schedule is None:
        return OperatorSettings(outcome, None, None)
    solver = outcome.adjuster or AdjustmentSolver(problem, outcome.shared())
    payload = outcome.payload
    note = ""
    if not payload.lower <= mass <= payload.upper:
        note = f"payload {payload.label(mass)} lies outside the declared range {payload.label(payload.lower)} to {payload.label(payload.upper)}"
    setting = solver.at(mass)
    if setting.feasible:
        return OperatorSettings(outcome, setting, None, note)
    widest = outcome.widest or widest_range(solver, outcome.schedule)[0]
    return OperatorSettings(outcome, setting, (widest.lower, widest.upper), note)


def design_payloads(
    problem: Problem,
    core: "Callable[[Problem], DesignMethod] | None" = None,
    parameters: Mapping[str, float] | None = None,
    bounds: BoundsOverride | None = None,
    initial: Mapping[Slot, float] | None = None,
    certify: bool = True,
    adjusters: Adjusters | None = None,
) -> PayloadDesign:
    """Design ``problem`` for its payload range (see the module docstring).

    ``core`` builds the design method of a sampled problem (default: the plain designer);
    ``parameters``, ``bounds`` (by variable name) and ``initial`` (by slot or variable of
    ``problem``) act on every sample and on the schedule's adjustments. ``adjusters``: where
    the schedule's adjustment methods are kept across designs (a payload method's; None:
    built for each design)."""
    payload = payload_of(problem)
    check_options(problem, parameters, bounds)
    core = core or (lambda p: Plain(Designer(p)))
    masses = {payload.lower, payload.nominal, payload.upper}
    plan: Schedule | None = None
    failure: Setting | None = None
    for _ in range(REFINEMENTS + 1):
        sampled, solution, verification, status, message = _solve_samples(problem, core, masses, parameters, bounds, initial, certify)
        solver = AdjustmentSolver(problem, _shared(solution), parameters, adjustment_bounds(problem, bounds), adjusters)
        if status is not Status.OPTIMAL:
            # the schedule of a design that is not optimal is reported only when no narrowed
            # design replaces it (below): solved then, by this solver, as it would be here
            break
        plan = schedule(solver, payload.lower, payload.upper)
        failure = plan.first_failure
        if failure is None or failure.payload in masses:
            break
        masses.add(failure.payload)
    range_text = f"{payload.label(payload.lower)} to {payload.label(payload.upper)}"
    widest = None
    narrowed = None
    if status is Status.INFEASIBLE:
        message = _infeasible_message(sampled, solution, range_text, message)
        narrowed = _narrowed(problem, core, parameters, bounds, initial)
        if narrowed is not None:  # report the design that balances the most of the range
            sampled, solution, verification = narrowed
            solver = AdjustmentSolver(problem, _shared(solution), parameters, adjustment_bounds(problem, bounds), adjusters)
            widest, plan = widest_range(solver, schedule(solver, min(sampled.masses), max(sampled.masses)))
            message += f"; {widest.text(payload, solver.problem)} (the design reported)"
    elif status is Status.OPTIMAL and failure is not None:
        status = Status.FAILED
        message = (
            f"the schedule fails inside the declared range {range_text}: first failing payload "
            f"{payload.label(failure.payload)} ({failure.message})"
        )
    elif status is Status.OPTIMAL and plan is not None:  # an optimal design has its schedule
        message = f"{message}; schedule feasible over {range_text} ({len(plan.rows)} grid payloads, {len(plan.between)} between them)"
        if problem.objective.goal == MAX_PAYLOAD_RANGE:
            widest, plan = widest_range(solver, plan)
            message += f"; widest range {payload.label(widest.lower)} to {payload.label(widest.upper)}, {widest.limit}"
            if widest.lower_limit:
                message += f"; below {payload.label(widest.lower)} {widest.lower_limit}"
            width = widest.upper - widest.lower
            quantity = ReportQuantity(
                "max_payload_range", ex.Num(width), payload.unit, f"widest payload range the design balances ({widest.limit})"
            )
            solved = replace(sampled.problem, report=sampled.problem.report + (quantity,))
            solution = replace(solution, problem=solved)
    if plan is None:  # a design that is not optimal, not replaced by a narrowed one
        plan = schedule(solver, payload.lower, payload.upper)
    checked = (plan.rows[0].payload, plan.rows[-1].payload)
    return PayloadDesign(solution.problem, payload, status, message, solution, verification, sampled.masses, plan, checked, widest, solver)


def _shared(solution: Solution) -> dict[str, float]:
    return {slot.variable: v for slot, v in solution.values.items() if slot.scenario is None}


def _solve_samples(
    problem: Problem,
    core: "Callable[[Problem], DesignMethod]",
    masses: set[float],
    parameters: Mapping[str, float] | None,
    bounds: BoundsOverride | None,
    initial: Mapping[Slot, float] | None,
    certify: bool = True,
) -> tuple[Sampled, Solution, Verification, Status, str]:
    """The shared design on the payload samples ``masses``, verified and judged."""
    sampled = sampled_problem(problem, masses)
    solution = core(sampled.problem).solve(parameters, merged_bounds(sampled, bounds), sampled_initial(sampled, initial), certify=certify)
    verification = verify(solution)
    status, message = judge(solution, verification)
    return sampled, solution, verification, status, message


def _narrowed(
    problem: Problem,
    core: "Callable[[Problem], DesignMethod]",
    parameters: Mapping[str, float] | None,
    bounds: BoundsOverride | None,
    initial: Mapping[Slot, float] | None,
) -> tuple[Sampled, Solution, Verification] | None:
    """A declared range too wide to balance: the design of the widest sub-range around the
    nominal that can be (the upper end bisected toward the nominal, the lower end kept;
    if even that fails, the lower end bisected first). None when not even the nominal can."""
    payload = payload_of(problem)
    nominal = payload.nominal

    def attempt(lo: float, hi: float) -> tuple[Sampled, Solution, Verification] | None:
        sampled, solution, verification, status, _ = _solve_samples(problem, core, {lo, nominal, hi}, parameters, bounds, initial, False)
        return (sampled, solution, verification) if status is Status.OPTIMAL else None

    def bisect(good: float, bad: float, found: tuple[Sampled, Solution, Verification], make: Callable[[float], tuple[float, float]]) -> tuple[float, tuple[Sampled, Solution, Verification]]:
        for _ in range(NARROW_STEPS):
            if abs(bad - good) <= PAYLOAD_RESOLUTION * payload.unit.to_si:
                break
            mid = 0.5 * (good + bad)
            tried = attempt(*make(mid))
            if tried is not None:
                good, found = mid, tried
            else:
                bad = mid
        return good, found

    lower = payload.lower
    found = attempt(lower, nominal)
    if found is None:
        found = attempt(nominal, nominal)
        if found is None:
            return None
        lower, found = bisect(nominal, payload.lower, found, lambda m: (m, nominal))
    if payload.upper > nominal:
        _, found = bisect(nominal, payload.upper, found, lambda m: (lower, m))
    return found


def _infeasible_message(sampled: Sampled, solution: Solution, range_text: str, fallback: str) -> str:
    """Name the adjustments at a limit in the closest design, and shared variables on a
    bound; an adjustment pinned to its nominal is not a limit (it is fixed by the file)."""
    problem = sampled.problem
    payload = payload_of(problem)
    limits, shared = [], []
    for slot, value in solution.values.items():
        v = problem.variable[slot.variable]
        if not v.adjustable:
            side = v.bound_side(value)
            if side:
                shared.append(f"{v.name} at its {side} bound")
            continue
        if is_pinned(problem, slot, sampled.setting_mass):
            continue
        lo, hi = v.adjusted_bounds()
        band = 1e-6 * (v.upper - v.lower)
        side = "lower" if value - lo <= band else "upper" if hi - value <= band else ""
        if side:
            bound = lo if side == "lower" else hi
            what = "bound" if bound == (v.lower if side == "lower" else v.upper) else "travel limit"
            mass = payload.label(sampled.setting_mass[slot.scenario or ""])
            limits.append(f"{v.name} at its {side} {what} {v.unit.from_si(bound):.6g} {v.unit.label} at {mass}")
    text = f"the required payload range {range_text} ({payload.name}) cannot be balanced"
    text += ": limiting adjustment " + "; ".join(limits) if limits else ": no adjustment reaches a limit"
    if shared:
        text += "; " + ", ".join(shared)
    unmet = fallback.split("; at the closest design")[0].removeprefix("balance cannot be met within the bounds: ")
    return f"{text} (closest design: {unmet})"


__all__ = ["OperatorSettings", "PayloadDesign", "WidestRange", "design_payloads", "settings_for", "widest_range"]
