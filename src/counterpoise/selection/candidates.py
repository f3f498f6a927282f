"""Which rate combinations of a slot group are solved: every combination (enumeration)
when there are at most ``selection.max_enumeration``, else best-first branch and bound
over index ranges of the sorted distinct rates. Parts sharing a rate share one solve."""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from .results import TIE

#: solve(fixed rates or rate intervals) -> solution, or None when not optimal
Solve = Callable[[Mapping[str, tuple[float, float]]], Any]
#: fits(fixed rates, solution) -> whether some parts at these rates meet their limits
Fits = Callable[[dict[str, float], Any], bool]


def enumerate_rates(group: tuple[str, ...], rates: Mapping[str, np.ndarray], solve: Solve) -> list[tuple[dict[str, float], Any]]:
    """Every combination of distinct rates, solved."""
    out = []
    for combo in itertools.product(*(rates[n] for n in group)):
        fixed = dict(zip(group, (float(k) for k in combo)))
        sol = solve({n: (k, k) for n, k in fixed.items()})
        if sol is not None:
            out.append((fixed, sol))
    return out


def branch_and_bound(group: tuple[str, ...], rates: Mapping[str, np.ndarray], solve: Solve, fits: Fits) -> list[tuple[dict[str, float], Any]]:
    """Best-first branch and bound over index ranges of the sorted distinct rates.

    A node's lower bound is the relaxed problem with each rate in its interval; nodes
    whose bound exceeds the incumbent (beyond ties) are dropped; leaves are exact solves,
    and a leaf becomes the incumbent only when some of its parts meet their limits.
    """
    out: list[tuple[dict[str, float], Any]] = []
    incumbent = math.inf
    counter = itertools.count()
    root = tuple((0, len(rates[n]) - 1) for n in group)
    heap: list[tuple[float, int, tuple[tuple[int, int], ...]]] = [(-math.inf, next(counter), root)]
    while heap:
        bound, _, node = heapq.heappop(heap)
        if bound > incumbent + TIE * max(1.0, abs(incumbent)):
            break
        if all(a == b for a, b in node):
            fixed = {n: float(rates[n][a]) for n, (a, _) in zip(group, node)}
            sol = solve({n: (k, k) for n, k in fixed.items()})
            if sol is not None:
                out.append((fixed, sol))
                if fits(fixed, sol):
                    incumbent = min(incumbent, sol.objective)
            continue
        widest = max(range(len(group)), key=lambda i: node[i][1] - node[i][0])
        a, b = node[widest]
        mid = (a + b) // 2
        for part in ((a, mid), (mid + 1, b)):
            child = node[:widest] + (part,) + node[widest + 1 :]
            if all(lo == hi for lo, hi in child):
                heapq.heappush(heap, (bound, next(counter), child))
                continue
            sol = solve({n: (float(rates[n][lo]), float(rates[n][hi])) for n, (lo, hi) in zip(group, child)})
            if sol is not None:
                heapq.heappush(heap, (sol.objective, next(counter), child))
    return out
