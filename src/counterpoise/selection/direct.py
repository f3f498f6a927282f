"""Part choice for directly attached springs (no pulley).

With a free length and an initial tension in the energy there are no exact balance
conditions, hence no balanceable rate window to prune with. Each candidate part is
designed by the minimax designer (built once, the part's rate, free length, initial
tension and maximum length passed as parameters), whose constraints keep every spring
within [L0, L_max] on the sampled configurations. The part with the smallest worst
residual ratio wins (ties: the cheaper).

When the slot fits the screening (:mod:`.screening`: one slot, one scenario, one or two
springs), every part is first screened at once on a geometry grid; parts are then designed
most promising first, from their best screened design. With one spring, once a design
exists, every part gets a certified lower bound (:mod:`.bounds`); parts whose bound is at
least the best ratio are skipped, and the search stops, certified, when every remaining
part's is. Otherwise it stops when no remaining part's screened ratio is within
:data:`SCREEN_MARGIN` of the incumbent (or after :data:`MAX_REFINED` designs). Without
screening every combination of parts is designed.
"""

from __future__ import annotations

import itertools
import math
import sys
import time
from collections.abc import Callable

import numpy as np

from ..designer.minimax import MinimaxDesigner
from ..formulation.layout import Slot
from ..model.problem import Problem
from ..solvers.base import Status
from .results import Choice, SearchResult, SlotCount
from .bounds import Bounds, certifiable, part_bounds
from .screening import Screen, screen, screened_order

#: more combinations than this are refused (one minimax NLP each)
MAX_COMBINATIONS = 20000
#: parts are designed while their screened ratio is at most this times the incumbent's
SCREEN_MARGIN = 2.0
#: at least this many of the most promising parts are designed
MIN_REFINED = 6
#: at most this many parts are designed after screening
MAX_REFINED = 40
#: (part, cell) bounds of the branch and bound of the per-part lower bounds (≈ 0.6 s for 80000)
BOUND_EVALUATIONS = 80000

#: progress(done, total) callback; None: a one-line counter on stderr when it is a terminal
Progress = Callable[[int, int], None]


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


def _terminal_progress(done: int, total: int) -> None:
    if sys.stderr.isatty():
        end = "\n" if done >= total else ""
        sys.stderr.write(f"\rpart search: {done}/{total} designs{end}")
        sys.stderr.flush()


def _choice(problem: Problem, rows: dict[str, int], sol: object) -> Choice:
    price = sum(len(s.springs) * s.catalogue.price[rows[s.name]] for s in problem.slots)
    return Choice(rows, {s.name: s.catalogue.rate[rows[s.name]] for s in problem.slots}, sol.objective, float(price), robust=float(sol.sampled_ratio))  # type: ignore[attr-defined]  # a minimax Solution (objective, sampled_ratio)


def _order(c: Choice) -> tuple[float, float]:
    return (c.robust, c.price if not math.isnan(c.price) else math.inf)


def search_direct(problem: Problem, designer: MinimaxDesigner, progress: Progress | None = None) -> SearchResult:
    """The best part(s) for the directly attached slots (see the module docstring)."""
    t0 = time.perf_counter()
    progress = progress or _terminal_progress
    slots = list(problem.slots)
    if len(slots) == 1 and len(slots[0].catalogue) > MIN_REFINED:
        screened = screen(problem, designer, part_parameters(problem, {slots[0].name: 0}))
        if screened.supported and np.isfinite(screened.ratio).any():
            return _search_screened(problem, designer, screened, progress, t0)
        reason = screened.reason or "no part within its lengths at any grid geometry"
        note = f"every part designed ({reason})"
    else:
        note = "every combination of parts designed"
    return _enumerate(problem, designer, progress, t0, note)


def _enumerate(problem: Problem, designer: MinimaxDesigner, progress: Progress, t0: float, note: str) -> SearchResult:
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
        progress(solves, total)
        if sol.status is not Status.OPTIMAL or sol.sampled_ratio is None:
            for c in counts:
                c.failed_limits += 1
            continue
        warm = sol.values
        found.append(_choice(problem, rows, sol))
        for c in counts:
            c.fitting += 1
    for c in counts:
        c.rates_solved = solves
    found.sort(key=_order)
    message = "" if found else "no combination of parts keeps every directly attached spring within its lengths"
    evidence = (f"search: {note}; {solves} minimax designs, {len(found)} within their lengths; exhaustive over the catalogue (no bound computed)",)
    return SearchResult(found[0] if found else None, counts, [tuple(s.name for s in slots)], ["enumeration"], [], solves, time.perf_counter() - t0, message, found, evidence=evidence)


def _search_screened(problem: Problem, designer: MinimaxDesigner, screened: Screen, progress: Progress, t0: float) -> SearchResult:
    slot = problem.slots[0]
    count = SlotCount(slot.name, len(slot.catalogue), (math.nan, math.nan))
    order = screened_order(screened)
    count.pruned = len(slot.catalogue) - len(order)  # no grid geometry keeps the spring within its lengths
    found: list[Choice] = []
    solves = 0
    incumbent = math.inf
    stopped = ""
    why_not = certifiable(screened.context)
    bounds: Bounds | None = None
    excluded = 0
    budget = min(len(order), MAX_REFINED)
    designed: list[int] = []
    for rank, i in enumerate(order):
        if bounds is None and not why_not and math.isfinite(incumbent):
            bounds = part_bounds(screened.context, designer, incumbent, BOUND_EVALUATIONS)
        if bounds is not None:
            rest = order[rank:]
            if (bounds.value[rest] >= incumbent).all():
                stopped = f"every remaining part's lower bound is at least the best ratio {incumbent:.4g}"
                break
            if bounds.value[i] >= incumbent:
                excluded += 1
                continue
        if len(designed) >= MIN_REFINED and screened.ratio[i] > SCREEN_MARGIN * incumbent:
            stopped = f"the next part's screened ratio {screened.ratio[i]:.4g} is above {SCREEN_MARGIN:g} × the best {incumbent:.4g}"
            break
        if len(designed) >= MAX_REFINED:
            stopped = f"design budget of {MAX_REFINED} parts reached (next screened ratio {screened.ratio[i]:.4g}, best {incumbent:.4g})"
            break
        rows = {slot.name: int(i)}
        initial = {Slot(v, None): x for v, x in screened.start[i].items()}
        sol = designer.solve(initial=initial, parameters=part_parameters(problem, rows))
        solves += 1
        designed.append(int(i))
        progress(min(solves, budget), budget)
        if sol.status is not Status.OPTIMAL or sol.sampled_ratio is None:
            count.failed_limits += 1
            continue
        count.fitting += 1
        found.append(_choice(problem, rows, sol))
        incumbent = min(incumbent, float(sol.sampled_ratio))
    if not stopped:
        stopped = "every screened part designed"
    count.rates_solved = solves
    found.sort(key=_order)
    left = np.setdiff1d(order, designed)
    next_screened = float(screened.ratio[left].min()) if left.size else math.inf
    kind = "unordered pairs of grid geometries (the springs are alike)" if screened.pairs else "grid geometries"
    evidence = [
        f"screening: {len(slot.catalogue)} parts on {screened.geometries} {kind} × {screened.configurations} configurations "
        f"then a compass search from each part's best ({screened.evaluated} part-geometry evaluations); {screened.infeasible} parts pruned, no grid geometry keeping them within their lengths"
        + "".join(f"; {n} by {limit}" for limit, n in sorted(screened.pruned_by.items())),
        f"refinement: {solves} parts designed by the minimax NLP, most promising first; {len(found)} within their lengths; {excluded} skipped, their lower bound at least the best ratio; stopped: {stopped}",
    ]
    lower = math.nan
    if bounds is not None:
        undesigned = np.setdiff1d(np.arange(len(slot.catalogue)), designed)
        open_parts = undesigned[bounds.value[undesigned] < incumbent]
        certified = float(min(bounds.value.min(), incumbent))
        lower = certified if certified > 0 else math.nan  # 0 certifies nothing: left empty
        infeasible = int(np.isinf(bounds.value).sum())
        evidence.append(
            f"bound: a certified lower bound per part (interval bound of the residual over geometry cells on {bounds.configurations} of the designer's configurations, "
            f"{bounds.cells} part-cell bounds, {bounds.depth} refinement levels); {infeasible} parts certified unable to stay within their lengths; "
            f"{len(undesigned) - len(open_parts)} parts not designed are excluded by their bound (≥ the best ratio {incumbent:.4g})"
            + (f"; {len(open_parts)} neither designed nor excluded (least bound {bounds.value[open_parts].min():.4g}, least screened ratio {next_screened:.4g})" if len(open_parts) else "")
            + (f"; catalogue lower bound {certified:.4g} (the best design is within × {incumbent / certified:.3g} of it)" if certified > 0 else "; catalogue lower bound 0 at the cell size reached: no certificate on the catalogue, lower_bound_ratio left empty")
        )
        evidence.append(
            "coverage: "
            + ("certified: no part not designed can beat the best design (on the bound's configurations, for the designer's reference torque)" if not len(open_parts)
               else f"screened, not certified, for the {len(open_parts)} parts neither designed nor excluded: each has a screened ratio of at least {next_screened:.4g} on the grid")
        )
    else:
        evidence.append(
            f"coverage: every part not designed has a screened ratio of at least {next_screened:.4g} on the grid "
            f"(the best design's is {incumbent:.4g}); no bound ({why_not or 'no part within its lengths'}): the screened ratio is that of a grid design, so the search is a screened search, not a certificate"
        )
    message = "" if found else "no part keeps every directly attached spring within its lengths"
    return SearchResult(found[0] if found else None, [count], [(slot.name,)], ["screening"], [], solves, time.perf_counter() - t0, message, found, lower_bound_ratio=lower, evidence=tuple(evidence))


__all__ = ["MAX_COMBINATIONS", "part_parameters", "search_direct"]
