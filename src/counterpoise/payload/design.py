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
from dataclasses import dataclass, field, replace
from typing import Any

from ..designer.designer import Designer
from ..designer.methods import DesignMethod, Plain
from ..errors import ProblemFileError
from ..designer.solution import Solution
from ..model import expr as ex
from ..model.payload import MAX_PAYLOAD_RANGE, Payload
from ..model.problem import Problem, ReportQuantity
from ..solvers.base import Status
from ..verify.check import verify
from ..verify.checks import Verification
from ..verify.judge import judge
from ..formulation.layout import Slot
from .scenarios import Sampled, design_bounds, is_pinned, modes, payload_of, sampled_problem, setting_name
from .schedule import AdjustmentSolver, Schedule, Setting, schedule

#: re-designs with an added failing payload before the schedule's failure is final
REFINEMENTS = 3
#: the widest-range search stops doubling after this many steps (reports "no limit found")
MAX_DOUBLINGS = 30
#: payloads scanned between the last feasible and the first infeasible one (holes)
SCAN = 16
#: bisection steps on each end of a declared range too wide to balance (1/4096 of its span)
NARROW_STEPS = 12
#: two payloads closer than this share of the display unit are the same (bisection ends)
PAYLOAD_RESOLUTION = 1e-9


@dataclass(frozen=True)
class WidestRange:
    """The payloads a fixed design balances, from the nominal outwards both ways."""

    lower: float  # kg
    upper: float  # kg
    limit: str  # what stops it at the upper end, for the report
    lower_limit: str = ""  # what stops it at the lower end ("" at 0)
    #: (adjustment, 'lower'|'upper', bound SI) at a limit at each end; None: no adjustment at one
    upper_at: tuple[str, str, float] | None = None
    lower_at: tuple[str, str, float] | None = None

    def text(self, payload: Payload, problem: Problem) -> str:
        """'balanceable from 0 g to 100 g; dL_c1 reaches its upper limit 50 mm at 100 g'."""
        out = f"balanceable from {payload.label(self.lower)} to {payload.label(self.upper)}"
        for at, mass in ((self.upper_at, self.upper), (self.lower_at, self.lower)):
            if at is not None:
                name, side, bound = at
                v = problem.variable[name]
                out += f"; {name} reaches its {side} limit {v.unit.from_si(bound):.6g} {v.unit.label} at {payload.label(mass)}"
        return out


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
        assert self.adjuster is not None and self.schedule is not None  # noqa: S101 (internal: only called on a schedule)
        masses = [s.payload for s in self.schedule.rows + self.schedule.between if s.feasible]
        return sampled_problem(self.adjuster.source, masses or self.samples)

    def schedule_solution(self) -> Solution:
        """The design on every feasible payload of its schedule (grid and between), one
        scenario per working mode and payload, each with that payload's adjustments: what
        a check that must hold at every payload (a part's limits) is run on."""
        sampled = self._scheduled()
        n_modes = len(modes(self.adjuster.source)) or 1  # type: ignore[union-attr]
        first = list(self.solution.scenario_parameters.values())[:n_modes]
        values: dict[Slot, float] = {slot: v for slot, v in self.solution.values.items() if slot.scenario is None}
        by_mass = {s.payload: s for s in self.schedule.rows + self.schedule.between if s.feasible}  # type: ignore[union-attr]
        scenario_parameters = {}
        for i, scenario in enumerate(sampled.problem.scenarios):
            mass = sampled.setting_mass[scenario.setting or ""]
            gravity, base = first[i % n_modes]
            scenario_parameters[scenario.name] = (gravity, {**base, self.payload.name: mass})
            for name, v in by_mass[mass].values.items():
                values[Slot(name, scenario.setting)] = v
        return replace(self.solution, problem=sampled.problem, values=values, scenario_parameters=scenario_parameters)

    def mass_of(self, scenario: str) -> float | None:
        """The payload mass of a scenario of :meth:`schedule_solution` or of the design."""
        for sampled in (self._scheduled(), sampled_problem(self.adjuster.source, self.samples)):  # type: ignore[union-attr]
            if any(s.name == scenario for s in sampled.problem.scenarios):
                return sampled.setting_mass[sampled.problem.setting(scenario) or ""]
        return None


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
    bounds: Mapping[Any, tuple[float, float]] | None = None,
    initial: Mapping[Slot, float] | None = None,
) -> PayloadDesign:
    """Design ``problem`` for its payload range (see the module docstring).

    ``core`` builds the design method of a sampled problem (default: the plain designer);
    ``parameters``, ``bounds`` (by variable name) and ``initial`` (by slot or variable of
    ``problem``) act on every sample and on the schedule's adjustments."""
    payload = payload_of(problem)
    check_options(problem, parameters, bounds)
    core = core or (lambda p: Plain(Designer(p)))
    masses = {payload.lower, payload.nominal, payload.upper}
    for _ in range(REFINEMENTS + 1):
        sampled, solution, verification, status, message = _solve_samples(problem, core, masses, parameters, bounds, initial)
        solver = AdjustmentSolver(problem, _shared(solution), parameters, adjustment_bounds(problem, bounds))
        plan = schedule(solver, payload.lower, payload.upper)
        failure = plan.first_failure
        if status is not Status.OPTIMAL or failure is None or failure.payload in masses:
            break
        masses.add(failure.payload)
    range_text = f"{payload.label(payload.lower)} to {payload.label(payload.upper)}"
    widest = None
    if status is Status.INFEASIBLE:
        message = _infeasible_message(sampled, solution, range_text, message)
        narrowed = _narrowed(problem, core, parameters, bounds, initial)
        if narrowed is not None:  # report the design that balances the most of the range
            sampled, solution, verification = narrowed
            solver = AdjustmentSolver(problem, _shared(solution), parameters, adjustment_bounds(problem, bounds))
            widest, plan = widest_range(solver, schedule(solver, min(sampled.masses), max(sampled.masses)))
            message += f"; {widest.text(payload, solver.problem)} (the design reported)"
    elif status is Status.OPTIMAL and failure is not None:
        status = Status.FAILED
        message = (
            f"the schedule fails inside the declared range {range_text}: first failing payload "
            f"{payload.label(failure.payload)} ({failure.message})"
        )
    elif status is Status.OPTIMAL:
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
    checked = (plan.rows[0].payload, plan.rows[-1].payload)
    return PayloadDesign(solution.problem, payload, status, message, solution, verification, sampled.masses, plan, checked, widest, solver)


def _shared(solution: Solution) -> dict[str, float]:
    return {slot.variable: v for slot, v in solution.values.items() if slot.scenario is None}


def _solve_samples(
    problem: Problem,
    core: "Callable[[Problem], DesignMethod]",
    masses: set[float],
    parameters: Mapping[str, float] | None,
    bounds: Mapping[Any, tuple[float, float]] | None,
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
    bounds: Mapping[Any, tuple[float, float]] | None,
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


def check_options(problem: Problem, parameters: Mapping[str, float] | None, bounds: Mapping[Any, tuple[float, float]] | None) -> None:
    """The payload's own mass is set by the range, not by ``parameters``; bounds name variables."""
    payload = payload_of(problem)
    if parameters and payload.name in parameters:
        raise ProblemFileError(problem.path, "parameters", f"'{payload.name}' is the payload of a payload range: change payloads.{payload.name}.range instead")
    for key in bounds or {}:
        name = key.variable if isinstance(key, Slot) else key
        if name not in problem.variable:
            raise ProblemFileError(problem.path, "bounds", f"no design variable '{name}'")


def merged_bounds(sampled: Sampled, bounds: Mapping[Any, tuple[float, float]] | None) -> dict[Slot | str, tuple[float, float]]:
    """The call's bounds (by variable, on every sample) with the adjustments' pins and travel
    windows (:func:`.scenarios.design_bounds`) inside them."""
    given = {(k.variable if isinstance(k, Slot) else k): v for k, v in (bounds or {}).items()}
    out: dict[Slot | str, tuple[float, float]] = dict(given)
    for slot, (lo, hi) in design_bounds(sampled).items():
        if slot.variable in given:
            a, b = given[slot.variable]
            lo, hi = (lo, hi) if lo == hi else (max(lo, a), min(hi, b))
        out[slot] = (lo, hi)
    return out


def adjustment_bounds(problem: Problem, bounds: Mapping[Any, tuple[float, float]] | None) -> dict[str, tuple[float, float]]:
    """The call's bounds on adjustable variables, for the schedule's adjustment solves."""
    out = {}
    for key, (a, b) in (bounds or {}).items():
        name = key.variable if isinstance(key, Slot) else key
        v = problem.variable[name]
        if v.adjustable:
            lo, hi = v.adjusted_bounds()
            out[name] = (max(lo, a), min(hi, b))
    return out


def sampled_initial(sampled: Sampled, initial: Mapping[Any, float] | None) -> dict[Slot, float] | None:
    """Initial values given for ``problem``'s slots (or variable names), on every sample's slot."""
    if not initial:
        return None
    by_name = {(k.variable if isinstance(k, Slot) else k): v for k, v in initial.items()}
    out = {}
    for v in sampled.problem.variables:
        if v.name not in by_name:
            continue
        if v.adjustable:
            out.update({Slot(v.name, setting): by_name[v.name] for setting in sampled.setting_mass})
        else:
            out[Slot(v.name, None)] = by_name[v.name]
    return out


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


def widest_range(solver: AdjustmentSolver, plan: Schedule) -> tuple[WidestRange, Schedule]:
    """The balanceable range of a fixed design: both ends of a feasible schedule pushed out
    (the upper one by doubling steps, a scan for holes and bisection; the lower one down
    toward 0 by bisection) until the adjustments cannot follow. ``max_payload_range``,
    ``counterpoise schedule`` and a declared range too wide all use this one definition."""
    payload = solver.payload
    lower, a = plan.rows[0].payload, plan.rows[-1].payload
    step = max(a - lower, 1e-3 * payload.unit.to_si, 1e-6)
    last = plan.rows[-1]
    upper_bad: Setting | None = None
    for _ in range(MAX_DOUBLINGS):
        s = solver.at(a + step)
        if not s.feasible:
            upper_bad = s
            break
        a, last, step = s.payload, s, 2 * step
    if upper_bad is None:
        return _with_lower_end(solver, lower, a, schedule(solver, lower, a), f"no limit found up to {payload.label(a)}", None)
    for _ in range(REFINEMENTS + 1):
        a, last = _bisect(solver, a, last, upper_bad.payload)
        full = schedule(solver, lower, a)
        failure = full.first_failure
        if failure is None:
            break
        upper_bad = failure  # a hole below the end found: the range stops before it
        below = [s for s in full.rows + full.between if s.feasible and s.payload < failure.payload]
        last = max(below, key=lambda s: s.payload) if below else plan.rows[0]
        a = last.payload
    limit = solver.limit(last)
    return _with_lower_end(solver, lower, a, full, _limit_text(solver, limit, upper_bad.message), limit)


def _with_lower_end(
    solver: AdjustmentSolver, lower: float, a: float, full: Schedule, text: str, limit: tuple[str, str, float] | None
) -> tuple[WidestRange, Schedule]:
    """The range [lower, a] pushed down toward 0 as far as the adjustments follow."""
    low, low_setting = _lowest(solver, full.rows[0])
    low_limit, low_at = "", None
    if low_setting is not None:
        low_at = solver.limit(low_setting)
        low_limit = _limit_text(solver, low_at, "")
    if low < lower:
        full = schedule(solver, low, a)
    return WidestRange(low, a, text, low_limit, limit, low_at), full


def _limit_text(solver: AdjustmentSolver, limit: tuple[str, str, float] | None, message: str) -> str:
    if limit is None:
        return f"beyond it the adjustments do not balance ({message})" if message else "beyond it the adjustments do not balance"
    name, side, bound = limit
    v = solver.problem.variable[name]
    return f"limited by {name} at its {side} limit {v.unit.from_si(bound):.6g} {v.unit.label}"


def _lowest(solver: AdjustmentSolver, first: Setting) -> tuple[float, Setting | None]:
    """The smallest payload (≥ 0) down to which the design balances, from a feasible one,
    and its setting when a limit stops it above 0 (None: it reaches 0)."""
    if first.payload <= 0 or solver.at(0.0).feasible:
        return min(first.payload, 0.0), None
    return _bisect(solver, first.payload, first, 0.0)


def _bisect(solver: AdjustmentSolver, good: float, good_setting: Setting, bad: float) -> tuple[float, Setting]:
    """Largest feasible payload between ``good`` and ``bad``: scan for holes, then bisect."""
    for i in range(1, SCAN):
        t = good + (bad - good) * i / SCAN
        s = solver.at(t)
        if not s.feasible:
            bad = t
            break
        good, good_setting = t, s
    while abs(bad - good) > PAYLOAD_RESOLUTION * max(abs(bad), solver.payload.unit.to_si):
        mid = 0.5 * (good + bad)
        s = solver.at(mid)
        if s.feasible:
            good, good_setting = mid, s
        else:
            bad = mid
    return good, good_setting
