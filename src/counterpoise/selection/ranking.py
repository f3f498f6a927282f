"""Ranking of fitting candidates: ``selection.prefer`` is ``objective`` (then least
sensitive, then cheapest), ``robust`` (least sensitive to the tolerance band first) or
``price``. At a given rate the fitting part with the smallest initial tension is the least
sensitive."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..model.parts import SpringSlot
from ..model.problem import Problem
from .results import TIE, Choice
from .tolerance import tolerance_band

#: objectives are compared after rounding to this many significant decimals (ties)
OBJECTIVE_DECIMALS = 9


def pick_part(slot: SpringSlot, options: Sequence[int], prefer: str) -> int:
    """The part among ``options`` (rows, all at one rate) that the preference picks."""
    a = slot.catalogue.arrays
    price = np.nan_to_num(a["price"], nan=np.inf)
    if prefer == "price":
        return min(options, key=lambda i: (price[i], a["initial_tension"][i]))
    return min(options, key=lambda i: (a["initial_tension"][i], price[i]))


def choices(slots: Mapping[str, SpringSlot], group: tuple[str, ...], evaluated: Sequence[tuple[dict[str, float], Any]], fits: Mapping[str, list[list[int]]], prefer: str) -> list[Choice]:
    """One choice per evaluated design in which every slot of the group has a fitting part."""
    found = []
    for e, (fixed, sol) in enumerate(evaluated):
        if any(not fits[n][e] for n in group):
            continue
        parts = {n: pick_part(slots[n], fits[n][e], prefer) for n in group}
        price = sum(len(slots[n].springs) * slots[n].catalogue.price[parts[n]] for n in group)
        found.append(Choice(parts, dict(fixed), sol.objective, float(price)))
    return found


def robustness(relaxed: Problem, slots: Mapping[str, SpringSlot], q: Mapping[str, np.ndarray], choice: Choice, solution: Any) -> float:
    """Worst-case residual ratio over the tolerance band of the chosen parts' springs."""
    values = {}
    for scenario in relaxed.scenarios:
        gravity, base = solution.scenario_parameters[scenario.name]
        values[scenario.name] = (solution.variable_values(scenario.name), base, gravity)
    tension, rate_tol, tension_tol = {}, {}, {}
    for n, row in choice.parts.items():
        slot = slots[n]
        for s in slot.springs:
            tension[s] = slot.catalogue.initial_tension[row]
            rate_tol[s] = slot.rate_tolerance
            tension_tol[s] = slot.initial_tension_tolerance
    return tolerance_band(relaxed, values, tension, rate_tol, tension_tol, q).worst


def needs_robustness(found: Sequence[Choice], prefer: str) -> list[Choice]:
    """The choices whose tolerance band the ranking needs: all (``robust``), else the tied best."""
    if prefer == "robust" or not found:
        return list(found)
    best = min(c.objective for c in found)
    return [c for c in found if c.objective <= best + TIE * max(1.0, abs(best))]


def key(c: Choice, prefer: str) -> tuple[float, ...]:
    """Sort key of a choice under the preference."""
    robust = c.robust if not math.isnan(c.robust) else math.inf
    price = c.price if not math.isnan(c.price) else math.inf
    objective = round(c.objective / max(1.0, abs(c.objective)), OBJECTIVE_DECIMALS)
    if prefer == "robust":
        return (robust, objective, price)
    if prefer == "price":
        return (price, objective, robust)
    return (objective, robust, price)
