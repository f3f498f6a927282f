"""Adjustment schedules: the adjustments of a fixed design, solved payload by payload.

:class:`AdjustmentSolver` builds one solver for :func:`.scenarios.adjustment_problem` and
solves it for any payload mass (the mass is a parameter of the NLP: nothing is rebuilt);
each solution is verified densely (every working mode, random configurations plus the
corners of the coordinate box) before it counts as feasible.

:func:`schedule` solves a grid of at least ``settings.schedule_points`` payloads with a
round step, then checks :data:`BETWEEN` more payloads inside every grid interval, so that
a range is never declared balanced from its grid points alone. An adjustment whose solved
values all lie on the straight line through its end values (to :data:`LINEAR_TOLERANCE` of
its bound span) is reported as linear in the payload, with slope and intercept.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..designer.designer import Designer
from ..designer.methods import Minimax, MultiStart, Plain, core_method
from ..designer.unbalanceable import unbalanceable
from ..formulation.layout import Slot
from ..kept import Kept
from ..model.digest import content_key
from ..model.problem import Problem, bound_side
from ..solvers.base import Status
from ..verify.check import verify
from ..verify.judge import judge
from .scenarios import adjustable, adjustment_problem, payload_of

#: payloads checked inside every grid interval, evenly spaced
BETWEEN = 3
#: largest deviation from the line through the end values, as a share of the bound span,
#: for an adjustment to count as linear in the payload
LINEAR_TOLERANCE = 1e-7
#: a schedule point is verified on this share of settings.verify_samples (at least 200)
VERIFY_SHARE = 20
#: payload solves an :class:`AdjustmentSolver` remembers (see :meth:`AdjustmentSolver.at`)
KEPT_SETTINGS = 4096


@dataclass(frozen=True)
class Setting:
    """The adjustments for one payload mass and whether they balance."""

    payload: float  # kg
    values: dict[str, float]  # adjustable variable -> SI value
    residual_ratio: float
    feasible: bool
    message: str


@dataclass(frozen=True)
class Line:
    """An adjustment linear in the payload: value = intercept + slope · payload (SI)."""

    variable: str
    slope: float
    intercept: float
    deviation: float  # largest distance of a solved value from the line (SI)


@dataclass(frozen=True)
class Schedule:
    rows: tuple[Setting, ...]  # the grid, ascending
    between: tuple[Setting, ...]  # the checks inside grid intervals
    lines: tuple[Line, ...]  # adjustments found linear in the payload

    @property
    def first_failure(self) -> Setting | None:
        bad = [s for s in self.rows + self.between if not s.feasible]
        return min(bad, key=lambda s: s.payload) if bad else None

    @property
    def feasible(self) -> bool:
        return self.first_failure is None


#: adjustment methods an :class:`Adjusters` keeps (a study's designs share one, mostly)
KEPT_ADJUSTERS = 4


class Adjusters:
    """The adjustments' design methods of one payload design method, built once per content.

    A fixed design's shared variables are parameters of its adjustment problem
    (:func:`.scenarios.adjustment_problem`), so one method serves every design of the same
    problem: the shared values are passed per solve, like a study's parameters. Its key is
    the adjustment problem's content (:func:`~counterpoise.model.digest.content_key`) with
    the shared values left out, and which of them are exactly zero (the balance conditions
    are compressed at the build's values, where a zero may hide a condition). Directly
    attached springs are not kept: the minimax designer's reference torque is taken at its
    build values (:class:`AdjustmentSolver` builds one per design)."""

    def __init__(self) -> None:
        self._built: Kept[tuple[str, tuple[str, ...]], Plain | Minimax | MultiStart] = Kept(KEPT_ADJUSTERS)

    def method(self, problem: Problem, shared: Mapping[str, float]) -> Plain | Minimax | MultiStart:
        """The design method of the adjustment problem ``problem`` of a design whose shared
        variables have the values ``shared`` (SI): built on first use with these values."""
        template = replace(problem, parameters=tuple(replace(p, value=0.0) if p.name in shared else p for p in problem.parameters))
        key = (content_key(template), tuple(sorted(n for n, v in shared.items() if v == 0.0)))
        return self._built.get(key, lambda: core_method(problem))


class AdjustmentSolver:
    """One solver for the adjustments of a fixed design; :meth:`at` solves one payload."""

    def __init__(
        self,
        problem: Problem,
        shared: dict[str, float],
        parameters: Mapping[str, float] | None = None,
        bounds: Mapping[str, tuple[float, float]] | None = None,
        adjusters: Adjusters | None = None,
    ) -> None:
        """``parameters``: base parameters (SI) that differ from the file's (a study point,
        the chosen catalogue parts); ``bounds``: narrower bounds of adjustments (SI);
        ``adjusters``: where the method is kept across designs (None: built for this one)."""
        from ..designer.minimax import needs_minimax

        self.source = problem
        self.payload = payload_of(problem)
        self.problem = adjustment_problem(problem, shared)
        #: the adjustments' design method: the plain designer, or the minimax one when a
        #: spring is attached directly (then "feasible" means its minimax solve converged)
        frozen = {v.name: float(shared[v.name]) for v in problem.variables if not v.adjustable}
        if adjusters is None or needs_minimax(problem):
            self.method = core_method(self.problem)
            frozen = {}  # the method was built on these values
        else:
            self.method = adjusters.method(self.problem, frozen)
        self.designer = self.method.designer
        self.samples = max(200, problem.settings.verify_samples // VERIFY_SHARE)
        self.parameters = {**frozen, **dict(parameters or {})}
        given: dict[Slot | str, tuple[float, float]] = {k: v for k, v in (bounds or {}).items()}
        self.bounds = given or None
        self._last: dict[Slot, float] = {}
        #: the payloads solved, by (mass, start): see :meth:`at` (None: not kept)
        self._solved: dict[tuple[float, tuple[tuple[Slot, float], ...]], tuple[Setting, dict[Slot, float]]] | None = (
            {} if type(self.method) is Plain and not self.problem.constraints else None
        )

    def at(self, mass: float) -> Setting:
        """Solve and verify the adjustments for payload ``mass`` (kg).

        Each solve starts from the adjustments of the last feasible one, so a solve is fixed
        by the mass and that start; the same pair again (a widest-range search re-solves the
        schedule it started from, :mod:`.widest`) returns the setting already found, the very
        numbers a new solve would give: the plain designer solves the same NLP from the same
        point, and without design constraints it keeps no state between solves (constraint
        rows may add verification rounds, so such a problem, and the minimax designer of
        directly attached springs, is always solved again)."""
        key = self._key(mass)
        if self._solved is not None and key in self._solved:
            setting, self._last = self._solved[key]
            return setting
        parameters = {**self.parameters, self.payload.name: mass}
        solution = self.method.solve(parameters, self.bounds, self._last or None, certify=False)
        verification = verify(solution, samples=self.samples)
        status, message = judge(solution, verification)
        values = {slot.variable: v for slot, v in solution.values.items()}
        feasible = status is Status.OPTIMAL
        if feasible:
            self._last = dict(solution.values)
        setting = Setting(mass, values, verification.residual_ratio, feasible, message)
        if self._solved is not None and len(self._solved) < KEPT_SETTINGS:
            self._solved[key] = (setting, self._last)
        return setting

    def probe(self, mass: float) -> Setting | None:
        """:meth:`at`, or None when payload ``mass`` certainly cannot be balanced: for a search
        that needs only whether a payload balances (a bisection). An infeasible solve is
        mostly the closest-design restarts that settle IPOPT's local verdict; when the
        adjustments enter the balance conditions affinely, a certificate settles it instead
        (:func:`~counterpoise.designer.unbalanceable.unbalanceable`: True only when the
        solve would end infeasible). Everything else is solved by :meth:`at`."""
        if self._solved is not None and self._key(mass) in self._solved:
            return self.at(mass)
        if self._solved is not None and type(self.designer) is Designer:  # the plain designer, no state
            parameters = {**self.parameters, self.payload.name: mass}
            if unbalanceable(self.designer, self._last or None, parameters, self.bounds):
                return None
        return self.at(mass)

    def _key(self, mass: float) -> tuple[Any, ...]:
        """What fixes a solve of :meth:`at`: the mass and the start (the last feasible adjustments)."""
        return (mass, tuple(self._last.items()))

    def limit(self, setting: Setting, tolerance: float = 1e-4) -> tuple[str, str, float] | None:
        """(variable, 'lower'|'upper', bound) of the adjustment at a limit of its travel or
        bounds in ``setting`` (the one closest to it, within ``tolerance`` of its span)."""
        best: tuple[float, str, str, float] | None = None
        for v in self.problem.variables:
            value = setting.values[v.name]
            span = v.upper - v.lower
            if span <= 0:
                continue
            side = bound_side(value, v.lower, v.upper, tolerance)
            if side:
                bound = v.lower if side == "lower" else v.upper
                distance = abs(value - bound) / span
                if best is None or distance < best[0]:
                    best = (distance, v.name, side, bound)
        return None if best is None else best[1:]


def grid(lower: float, upper: float, to_si: float, points: int) -> list[float]:
    """At least ``points`` payloads from ``lower`` to ``upper`` (SI), on a round step in
    the display unit (1, 2, 2.5 or 5 × 10^k), end points included."""
    if upper <= lower:
        return [lower]
    lo, hi = lower / to_si, upper / to_si
    span = hi - lo
    need = points - 1
    step = span / need  # fallback; the loop below always finds a round step
    for k in range(math.floor(math.log10(span)), math.floor(math.log10(span / need)) - 2, -1):
        fits = [m * 10.0**k for m in (5.0, 2.5, 2.0, 1.0) if span / (m * 10.0**k) >= need]
        if fits:
            step = fits[0]
            break
    values = [lo]
    n = math.ceil(lo / step - 1e-9)
    while n * step < hi - 1e-9 * span:
        x = n * step
        if x > lo + 1e-9 * span:
            values.append(x)
        n += 1
    values.append(hi)
    return [round(v, 12) * to_si for v in values]


def schedule(solver: AdjustmentSolver, lower: float, upper: float) -> Schedule:
    """The schedule over [lower, upper] (SI): grid rows, checks between them, linear fits."""
    payload = solver.payload
    masses = grid(lower, upper, payload.unit.to_si, solver.source.settings.schedule_points)
    rows = tuple(solver.at(m) for m in masses)
    between = []
    for a, b in zip(masses[:-1], masses[1:]):
        for i in range(1, BETWEEN + 1):
            between.append(solver.at(a + (b - a) * i / (BETWEEN + 1)))
    return Schedule(rows, tuple(between), _lines(solver.problem, rows + tuple(between), lower, upper))


def _lines(problem: Problem, settings: tuple[Setting, ...], lower: float, upper: float) -> tuple[Line, ...]:
    if upper <= lower or not all(s.feasible for s in settings):
        return ()
    ordered = sorted(settings, key=lambda s: s.payload)
    first, last = ordered[0], ordered[-1]
    out = []
    for v in problem.variables:
        slope = (last.values[v.name] - first.values[v.name]) / (last.payload - first.payload)
        intercept = first.values[v.name] - slope * first.payload
        m = np.array([s.payload for s in ordered])
        x = np.array([s.values[v.name] for s in ordered])
        deviation = float(np.abs(x - (intercept + slope * m)).max())
        tolerance = LINEAR_TOLERANCE * max(v.upper - v.lower, abs(x).max(), 1e-300)
        if deviation <= tolerance:
            out.append(Line(v.name, slope, intercept, deviation))
    return tuple(out)


__all__ = ["AdjustmentSolver", "Adjusters", "BETWEEN", "Line", "Schedule", "Setting", "adjustable", "grid", "schedule"]
