"""The chosen parts of a design: how each spring uses its part, the bill of materials and
the tolerance report. Built after the final (parametric) solve and its dense verification.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from ..catalogue.limits import margins
from ..designer.solution import Solution
from ..formulation.layout import Slot
from ..mechanics import Mechanics
from ..model.elements import ZeroFreeLengthSpring
from ..model.parts import SpringSlot
from ..model.problem import Problem
from ..solvers.base import Status
from ..verify.check import verify
from .geometry import sample_configurations, spring_lengths
from .search import PartSearch, SearchModel, SearchResult
from .result import BillLine, Corner, PartsReport, SpringUse
from .tolerance import tolerance_band

#: at most this many tolerance corners are re-adjusted (2 per slot, all combinations)
MAX_CORNERS = 64


def choose(
    problem: Problem,
    model: SearchModel | None = None,
    parameters: Mapping[str, float] | None = None,
    bounds: Mapping[Any, tuple[float, float]] | None = None,
) -> tuple[SearchResult, dict[str, int], dict[str, float]]:
    """Run the search; the chosen rows and rates (the nearest candidate's when none fits).
    ``model``, ``parameters``, ``bounds``: see :class:`~.search.PartSearch`."""
    result = PartSearch(problem, model, parameters, bounds).run()
    if result.choice is not None:
        return result, dict(result.choice.parts), dict(result.choice.rates)
    rows: dict[str, int] = {}
    rates: dict[str, float] = {}
    slots = {s.name: s for s in problem.slots}
    if result.candidates:  # the slots that have fitting parts keep their best one
        rows.update(result.candidates[0].parts)
        rates.update(result.candidates[0].rates)
    for miss in result.nearest:
        if miss.slot in rows:
            continue
        catalogue = slots[miss.slot].catalogue
        row = catalogue.part_number.index(miss.part_number)
        rows[miss.slot] = row
        rates[miss.slot] = catalogue.rate[row]
        for other, rate in miss.rates:
            if other not in rows:
                match = [i for i, k in enumerate(slots[other].catalogue.rate) if k == rate]
                if match:
                    rows[other], rates[other] = match[0], rate
    for name, slot in slots.items():  # a slot with no near miss: its median part
        if name not in rows:
            order = np.argsort(slot.catalogue.array("rate"))
            rows[name] = int(order[len(order) // 2])
            rates[name] = slot.catalogue.rate[rows[name]]
    return result, rows, rates


def report(
    problem: Problem,
    designer: Any,
    solution: Solution,
    search: SearchResult,
    rows: dict[str, int],
    checked: Solution | None = None,
    given: Mapping[str, float] | None = None,
) -> PartsReport:
    """Dense limit check, bill of materials and tolerance report of the chosen parts.

    ``checked``: the design on every scenario whose limits must hold (a payload range: one
    scenario per payload of its schedule); default ``solution``. The tolerance report and
    the corners are taken on ``solution`` (solved by ``designer`` with the call's
    parameters ``given``, which the corners keep: a study point's values, not the file's)."""
    checked = checked or solution
    slots = {s.name: s for s in problem.slots}
    springs = [s for s in checked.problem.springs if s.slot is not None]
    per_scenario, cable = spring_extremes(checked, springs)
    by_scenario = [use(slots, rows, s, lo, hi, cable[s.name], name) for name, extremes in per_scenario.items() for s in springs for lo, hi in [extremes[s.name]]]
    uses = []
    for s in springs:
        lo = min(extremes[s.name][0] for extremes in per_scenario.values())
        hi = max(extremes[s.name][1] for extremes in per_scenario.values())
        uses.append(use(slots, rows, s, lo, hi, cable[s.name], ""))
    bill: dict[str, BillLine] = {}
    for u in uses:
        cat = slots[u.slot].catalogue
        row = rows[u.slot]
        n = cat.parts_in_parallel(row)  # a slot with ``count``: n identical base parts per spring
        base = cat.base_part_number(row)
        line = bill.get(base)
        quantity = (line.quantity if line else 0) + n
        bill[base] = BillLine(base, quantity, cat.price[row] / n, cat.currency)
    tolerance = None
    corners: tuple[Corner, ...] = ()
    if solution.status is Status.OPTIMAL:
        tq = sample_configurations(problem, min(problem.settings.verify_samples, 4000), problem.settings.seed + 13)
        per_design: dict[str, Any] = {}
        for scenario in problem.scenarios:
            gravity, parameters = solution.scenario_parameters[scenario.name]
            per_design[scenario.name] = (solution.variable_values(scenario.name), parameters, gravity)
        tension = {u.spring: u.initial_tension for u in uses}
        offsets = {s.name: cable[s.name] + rows_free_length(slots, rows, s) for s in problem.springs if s.slot is not None and s.direct is not None}
        rate_tol = {u.spring: slots[u.slot].rate_tolerance for u in uses}
        tension_tol = {u.spring: slots[u.slot].initial_tension_tolerance for u in uses}
        tolerance = tolerance_band(problem, per_design, tension, rate_tol, tension_tol, tq, offsets)
        corners = adjust_corners(problem, designer, solution, rows, given)
    return PartsReport(search, dict(rows), tuple(uses), tuple(bill.values()), tolerance, corners, tuple(by_scenario))


def spring_extremes(solution: Solution, springs: list[ZeroFreeLengthSpring]) -> tuple[dict[str, dict[str, tuple[float, float]]], dict[str, float]]:
    """Per scenario and spring: the smallest and largest distance between its ends over the
    dense sample (minus the cable of a directly attached spring); and each spring's cable."""
    problem = solution.problem
    q = sample_configurations(problem, problem.settings.verify_samples, problem.settings.seed + 11)
    cable = {s.name: 0.0 for s in springs}  # directly attached springs: d − cable is the spring's length
    out: dict[str, dict[str, tuple[float, float]]] = {}
    for scenario in problem.scenarios:
        values = solution.variable_values(scenario.name)
        variables = {k: np.array([[v]]) for k, v in values.items()}
        gravity, base = solution.scenario_parameters[scenario.name]
        lengths = spring_lengths(problem, [s.name for s in springs], q, variables, base, gravity)
        mech = Mechanics(problem, base, values, {c.name: c.home for c in problem.coordinates}, gravity)
        here = {}
        for s in springs:
            c = float(mech.value(s.direct.cable)) if s.direct is not None else 0.0
            cable[s.name] = c
            here[s.name] = (float(lengths[s.name].min()) - c, float(lengths[s.name].max()) - c)
        out[scenario.name] = here
    return out, cable


def use(slots: Mapping[str, SpringSlot], rows: dict[str, int], s: ZeroFreeLengthSpring, lo: float, hi: float, cable: float, scenario: str) -> SpringUse:
    """How spring ``s`` uses its part when the distance of its ends spans [lo, hi] (SI)."""
    slot = _slot_of(s)
    cat = slots[slot].catalogue
    i = rows[slot]
    k, l0, f0, fmax, lmax = cat.rate[i], cat.free_length[i], cat.initial_tension[i], cat.max_load[i], cat.max_length[i]
    if s.direct is None:  # behind a string: length d + L0 − F0/k, force k·d; slack: beyond F0/k by the slack margin
        m = margins(np.array(lo - s.slack_margin), np.array(hi), k, l0, f0, fmax, lmax)
        v = (lo, hi, lo + l0 - f0 / k, hi + l0 - f0 / k, k * lo, k * hi, float(m.slack), float(m.length), float(m.load))
    else:  # attached directly: length d − c, force F0 + k (d − c − L0); slack: beyond L0 by the slack margin
        v = (lo + cable, hi + cable, lo, hi, f0 + k * (lo - l0), f0 + k * (hi - l0), lo - l0 - s.slack_margin, lmax - hi, fmax - (f0 + k * (hi - l0)))
    return SpringUse(s.name, slot, cat.part_number[i], *v[:6], l0, lmax, f0, fmax, *v[6:], scenario=scenario)


def rows_free_length(slots: Mapping[str, SpringSlot], rows: dict[str, int], spring: ZeroFreeLengthSpring) -> float:
    slot = _slot_of(spring)
    return float(slots[slot].catalogue.free_length[rows[slot]])


def _slot_of(spring: ZeroFreeLengthSpring) -> str:
    """The slot of a spring whose part is chosen from a catalogue (callers pass only those)."""
    if spring.slot is None:
        raise ValueError(f"spring {spring.name} takes no catalogue part (no slot)")
    return spring.slot


def adjust_corners(
    problem: Problem, designer: Any, solution: Solution, rows: dict[str, int], parameters: Mapping[str, float] | None = None
) -> tuple[Corner, ...]:
    """Each combination of slot rates at ±tolerance: the residual left, and, with
    ``selection.adjust`` variables, what they must be re-set to (the others kept).
    ``parameters``: the call's values the design was solved with (a study point's), kept at
    every corner; the slots' rates are the parts' own."""
    slots = [s for s in problem.slots if s.rate_tolerance > 0]
    if not slots or 2 ** len(slots) > MAX_CORNERS:
        return ()
    adjust = set(problem.selection.adjust)
    nominal = {s.name: s.catalogue.rate[rows[s.name]] for s in problem.slots}
    out = []
    samples = min(problem.settings.verify_samples, 2000)
    for signs in itertools.product((-1.0, 1.0), repeat=len(slots)):
        rates = {**(parameters or {}), **nominal}
        deviation = []
        for s, sign in zip(slots, signs):
            rates[s.name] = nominal[s.name] * (1 + sign * s.rate_tolerance)
            deviation.append((s.name, sign * s.rate_tolerance))
        p = designer.formulation.parameters.values(rates)
        shifted = replace(solution, scenario_parameters=designer.formulation.parameters.scenario_values(p))
        ratio = verify(shifted, samples=samples).residual_ratio
        adjusted_ratio = math.nan
        changes: list[tuple[str, float, float]] = []
        if adjust:
            bounds: dict[Slot | str, tuple[float, float]] = {
                slot: (value, value) for slot, value in solution.values.items() if slot.variable not in adjust
            }
            again = designer.solve(initial=solution.values, parameters=rates, bounds=bounds, certify=False)
            if again.status is Status.OPTIMAL:
                adjusted_ratio = verify(again, samples=samples).residual_ratio
                for slot, value in solution.values.items():
                    if slot.variable in adjust:
                        changes.append((_slot_name(slot), value, again.values[slot]))
        out.append(Corner(tuple(deviation), ratio, adjusted_ratio, tuple(changes)))
    return tuple(out)


def _slot_name(slot: Slot) -> str:
    return slot.variable if slot.scenario is None else f"{slot.variable}@{slot.scenario}"
