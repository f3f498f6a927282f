"""Part choice for directly attached springs (no pulley): every combination is designed.

With a free length and an initial tension in the energy there are no exact balance
conditions, hence no balanceable rate window to prune with; each combination of parts is
designed by the minimax designer (built once, the part's rate, free length, initial
tension and maximum length passed as parameters), whose constraints keep every spring
within [L0, L_max] on the sampled configurations. The combination with the smallest
worst residual ratio wins (ties: the cheaper).
"""

from __future__ import annotations

import itertools
import math
import time

from ..designer.minimax import MinimaxDesigner
from ..model.problem import Problem
from ..solvers.base import Status
from .search import Choice, SearchResult, SlotCount

#: more combinations than this are refused (one minimax NLP each)
MAX_COMBINATIONS = 20000


def part_parameters(problem: Problem, rows: dict[str, int]) -> dict[str, float]:
    """The parameters that put the parts ``rows`` (slot -> catalogue row) into a design."""
    out: dict[str, float] = {}
    for slot in problem.slots:
        if slot.name not in rows:
            continue
        cat, i = slot.catalogue, rows[slot.name]
        out[slot.name] = cat.rate[i]
        out[f"{slot.name}:free_length"] = cat.free_length[i]
        out[f"{slot.name}:initial_tension"] = cat.initial_tension[i]
        # the longest admissible length: the part's maximum length, or where it reaches its maximum load
        out[f"{slot.name}:max_length"] = min(cat.max_length[i], cat.free_length[i] + (cat.max_load[i] - cat.initial_tension[i]) / cat.rate[i])
    return out


def search_direct(problem: Problem, designer: MinimaxDesigner) -> SearchResult:
    t0 = time.perf_counter()
    slots = list(problem.slots)
    sizes = [len(s.catalogue) for s in slots]
    counts = [SlotCount(s.name, len(s.catalogue), (math.nan, math.nan)) for s in slots]
    total = math.prod(sizes)
    if total > MAX_COMBINATIONS:
        message = f"{total} combinations of parts for directly attached springs (at most {MAX_COMBINATIONS}): use smaller catalogues or fewer slots"
        return SearchResult(None, counts, [tuple(s.name for s in slots)], ["enumeration"], [], 0, time.perf_counter() - t0, message)
    found: list[Choice] = []
    solves = 0
    warm = None
    for combo in itertools.product(*(range(n) for n in sizes)):
        rows = {s.name: i for s, i in zip(slots, combo)}
        sol = designer.solve(initial=warm, parameters=part_parameters(problem, rows))
        solves += 1
        if sol.status is not Status.OPTIMAL or sol.sampled_ratio is None:
            for c, i in zip(counts, combo):
                c.failed_limits += 1
            continue
        warm = sol.values
        price = sum(len(s.springs) * s.catalogue.price[rows[s.name]] for s in slots)
        found.append(Choice(rows, {s.name: s.catalogue.rate[rows[s.name]] for s in slots}, sol.objective, float(price), robust=float(sol.sampled_ratio)))
        for c in counts:
            c.fitting += 1
    for c in counts:
        c.rates_solved = solves
    found.sort(key=lambda c: (c.robust, c.price if not math.isnan(c.price) else math.inf))
    message = "" if found else "no combination of parts keeps every directly attached spring within its lengths"
    return SearchResult(found[0] if found else None, counts, [tuple(s.name for s in slots)], ["enumeration"], [], solves, time.perf_counter() - t0, message, found)
