"""The balanceable range of a fixed design: both ends pushed out until the adjustments cannot follow.

One definition for ``objective = "max_payload_range"``, ``counterpoise schedule`` and the
message of a declared range too wide (:mod:`.design`).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..model.payload import Payload
from ..model.problem import Problem
from .schedule import AdjustmentSolver, Schedule, Setting, schedule

#: re-checks of the range found when its schedule shows a hole below the end
REFINEMENTS = 3
#: the widest-range search stops doubling after this many steps (reports "no limit found")
MAX_DOUBLINGS = 30
#: payloads scanned between the last feasible and the first infeasible one (holes)
SCAN = 16
#: two payloads closer than this share of the display unit are the same (bisection ends)
PAYLOAD_RESOLUTION = 1e-9
#: the first step beyond a range of zero width: this share of the display unit, at least
#: FIRST_STEP_FLOOR kg
FIRST_STEP_SHARE = 1e-3
FIRST_STEP_FLOOR = 1e-6


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


def widest_range(solver: AdjustmentSolver, plan: Schedule) -> tuple[WidestRange, Schedule]:
    """The balanceable range of a fixed design: both ends of a feasible schedule pushed out
    (the upper one by doubling steps, a scan for holes and bisection; the lower one down
    toward 0 by bisection) until the adjustments cannot follow. ``max_payload_range``,
    ``counterpoise schedule`` and a declared range too wide all use this one definition."""
    payload = solver.payload
    lower, a = plan.rows[0].payload, plan.rows[-1].payload
    step = max(a - lower, FIRST_STEP_SHARE * payload.unit.to_si, FIRST_STEP_FLOOR)
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
    and its setting when a limit stops it above 0 (None: it reaches 0). The way down is
    scanned for holes (:data:`SCAN` payloads), as the way up is: a design that balances 0 g
    and the first payload need not balance every payload between them."""
    if first.payload <= 0:
        return first.payload, None
    good, good_setting = first.payload, first
    for i in range(1, SCAN + 1):
        t = first.payload * (1 - i / SCAN)
        s = solver.probe(t)
        if s is None or not s.feasible:
            return _bisect(solver, good, good_setting, t)
        good, good_setting = t, s
    return 0.0, None


def _bisect(solver: AdjustmentSolver, good: float, good_setting: Setting, bad: float) -> tuple[float, Setting]:
    """Largest feasible payload between ``good`` and ``bad``: scan for holes, then bisect."""
    for i in range(1, SCAN):
        t = good + (bad - good) * i / SCAN
        s = solver.probe(t)  # only whether it balances counts here (None: it cannot)
        if s is None or not s.feasible:
            bad = t
            break
        good, good_setting = t, s
    while abs(bad - good) > PAYLOAD_RESOLUTION * max(abs(bad), solver.payload.unit.to_si):
        mid = 0.5 * (good + bad)
        s = solver.probe(mid)
        if s is not None and s.feasible:
            good, good_setting = mid, s
        else:
            bad = mid
    return good, good_setting
