"""Limit checks of every candidate part at once: for each solved design, the spring
distances over sampled configurations of every scenario give each part's three margins
(:mod:`counterpoise.catalogue.limits`) in one numpy evaluation over all its parts."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..catalogue.limits import LIMITS, margins, violation
from ..model.parts import SpringSlot
from ..model.problem import Problem
from .geometry import spring_lengths
from .results import NearMiss, SlotCount

#: (slot rates fixed, solution) of one solved design
Evaluated = Sequence[tuple[dict[str, float], Any]]


def distance_ranges(problem: Problem, springs: Sequence[str], q: Mapping[str, np.ndarray], evaluated: Evaluated) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Per spring: the smallest and largest distance of its ends, per evaluated design."""
    d_min = {s: np.full(len(evaluated), np.inf) for s in springs}
    d_max = {s: np.zeros(len(evaluated)) for s in springs}
    names = [v.name for v in problem.variables]
    for scenario in problem.scenarios:
        variables = {v: np.array([[sol.variable_values(scenario.name)[v]] for _, sol in evaluated]) for v in names}
        gravity, base = evaluated[0][1].scenario_parameters[scenario.name]
        lengths = spring_lengths(problem, springs, q, variables, base, gravity)
        for s, dist in lengths.items():
            d_min[s] = np.minimum(d_min[s], dist.min(axis=1))
            d_max[s] = np.maximum(d_max[s], dist.max(axis=1))
    return d_min, d_max


def fitting_parts(
    relaxed: Problem,
    slots: Mapping[str, SpringSlot],
    group: tuple[str, ...],
    kept: Mapping[str, np.ndarray],
    evaluated: Evaluated,
    q: Mapping[str, np.ndarray],
    counts: Mapping[str, SlotCount],
) -> tuple[dict[str, list[list[int]]], list[NearMiss]]:
    """Per slot and evaluated design, the rows of the kept parts at its rate that meet every
    limit; and the near misses of those that do not. ``counts`` are updated."""
    springs = [s for n in group for s in slots[n].springs]
    d_min, d_max = distance_ranges(relaxed, springs, q, evaluated)
    fits: dict[str, list[list[int]]] = {n: [[] for _ in evaluated] for n in group}
    misses: list[NearMiss] = []
    fitting: dict[str, set[int]] = {n: set() for n in group}
    failing: dict[str, set[int]] = {n: set() for n in group}
    limit_of: dict[str, dict[int, str]] = {n: {} for n in group}
    for n in group:
        cat = slots[n].catalogue
        a = cat.arrays
        rows = kept[n]
        margin = {s.name: s.slack_margin for s in relaxed.springs}
        lo = np.min([d_min[s] - margin[s] for s in slots[n].springs], axis=0)  # the slack margin kept beyond F0/k
        hi = np.max([d_max[s] for s in slots[n].springs], axis=0)
        rate_of = np.array([fixed[n] for fixed, _ in evaluated])
        for e in range(len(evaluated)):
            mine = rows[a["rate"][rows] == rate_of[e]]
            if not mine.size:
                continue
            part = {k: a[k][mine] for k in ("rate", "free_length", "initial_tension", "max_load", "max_length")}
            m = margins(lo[e], hi[e], **part)
            ok = m.ok()
            fits[n][e] = [int(i) for i in mine[ok]]
            fitting[n].update(int(i) for i in mine[ok])
            failing[n].update(int(i) for i in mine[~ok])
            amount, which = violation(m, **part)
            worst_spring = slots[n].springs[0]
            for i in np.flatnonzero(~ok):
                limit_of[n].setdefault(int(mine[i]), LIMITS[int(which[i])])
                misses.append(NearMiss(n, cat.part_number[int(mine[i])], LIMITS[int(which[i])], worst_spring, float(amount[i]), tuple(evaluated[e][0].items())))
    for n in group:  # a part fits when it fits in some solved design
        counts[n].fitting += len(fitting[n])
        counts[n].failed_limits += len(failing[n] - fitting[n])
        for row in failing[n] - fitting[n]:
            limit = limit_of[n][row]
            counts[n].failed_by[limit] = counts[n].failed_by.get(limit, 0) + 1
    return fits, misses
