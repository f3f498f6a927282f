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

Several slots are first split into groups that do not interact (:func:`.groups.direct_groups`:
no slot's part or geometry enters another group's residual rows or spring lengths); each
group is searched alone, by the minimax designer of its own rows
(:meth:`~counterpoise.designer.minimax.MinimaxDesigner.restricted`), and the groups' best
parts together are the best combination (the worst ratio is the largest of the groups').
A group of interacting slots is enumerated when it has at most :data:`MAX_COMBINATIONS`
combinations of parts; above that it is screened slot by slot, then the combinations of
each slot's best screened parts are designed (:data:`COUPLED_COMBINATIONS` in all). A search
that can do neither is refused as an input limit (:func:`refusal`, exit status 2).
"""

from __future__ import annotations

import itertools
import math
import sys
import time
from collections.abc import Callable

import numpy as np

from ..designer.minimax import MinimaxDesign, MinimaxDesigner, minimax_of
from ..designer.solution import Solution
from ..errors import ProblemFileError
from ..formulation.layout import Slot
from ..model.parts import SpringSlot
from ..model.problem import Problem
from ..solvers.base import Status
from .results import Choice, SearchResult, SlotCount
from .bounds import Bounds, certifiable, part_bounds
from .groups import DirectGroup, direct_groups
from .screening import Screen, screen, screened_order

#: more combinations than this are refused (one minimax NLP each)
MAX_COMBINATIONS = 20000
#: parts are designed while their screened ratio is at most this times the incumbent's
SCREEN_MARGIN = 2.0
#: at least this many of the most promising parts are designed
MIN_REFINED = 6
#: at most this many parts are designed after screening
MAX_REFINED = 40
#: (part, cell) bounds of the branch and bound of the per-part lower bounds (≈ 0.6 s for 80000),
#: shared by the slots of a problem whose slots are searched in groups
BOUND_EVALUATIONS = 80000

#: a coupled group too large to enumerate: combinations of each slot's best screened parts designed, at most
COUPLED_COMBINATIONS = 16
#: sweeps of the slot-by-slot screening of a coupled group (each slot screened with the others at their best so far)
COUPLED_SWEEPS = 2
#: seed offset (added to settings.seed) of the random points of the grouping
GROUP_SEED = 3

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


def _choice(problem: Problem, rows: dict[str, int], sol: Solution, minimax: MinimaxDesign) -> Choice:
    slots = [s for s in problem.slots if s.name in rows]
    price = sum(len(s.springs) * s.catalogue.price[rows[s.name]] for s in slots)
    choice = Choice(rows, {s.name: s.catalogue.rate[rows[s.name]] for s in slots}, sol.objective, float(price), robust=float(minimax.sampled_ratio))
    choice.values = dict(sol.values)
    return choice


def _order(c: Choice) -> tuple[float, float]:
    return (c.robust, c.price if not math.isnan(c.price) else math.inf)


def search_direct(problem: Problem, designer: MinimaxDesigner, progress: Progress | None = None) -> SearchResult:
    """The best part(s) for the directly attached slots (see the module docstring).

    Raises :class:`~counterpoise.errors.ProblemFileError` (an input limit, not an
    infeasibility) when interacting slots have too many combinations of parts to design
    and cannot be screened."""
    t0 = time.perf_counter()
    progress = progress or _terminal_progress
    slots = list(problem.slots)
    if len(slots) == 1:
        return _search_slot(problem, designer, slots[0], progress, t0)
    groups = direct_groups(problem, designer, lambda rows: part_parameters(problem, rows), problem.settings.seed + GROUP_SEED)
    if len(groups) == 1:
        (group,) = groups
        direct = {s.name for s in problem.springs if s.direct is not None}
        if group.coordinates != {c.name for c in problem.coordinates} or group.springs != direct:
            designer = designer.restricted(group.coordinates, group.springs)  # rows no part can change left out
        return _search_group(problem, designer, group, progress, t0)
    results = []
    for group in groups:
        restricted = designer.restricted(group.coordinates, group.springs)
        results.append(_search_group(problem, restricted, group, progress, time.perf_counter(), others=groups))
    return _combine(groups, results, t0)


def _search_slot(
    problem: Problem,
    designer: MinimaxDesigner,
    slot: SpringSlot,
    progress: Progress,
    t0: float,
    group: DirectGroup | None = None,
    exclude: frozenset[str] = frozenset(),
) -> SearchResult:
    """One slot: screened when it can be, else every part designed."""
    if len(slot.catalogue) > MIN_REFINED:
        coordinates, variables = (None, None) if group is None else (group.coordinates, group.variables)
        screened = screen(problem, designer, part_parameters(problem, {slot.name: 0}), slot.name, coordinates, exclude, variables)
        if screened.supported and np.isfinite(screened.ratio).any():
            share = len(problem.slots) if group is not None else 1  # the bound's budget is shared by the groups
            return _search_screened(problem, designer, screened, progress, t0, slot, BOUND_EVALUATIONS // share)
        reason = screened.reason or "no part within its lengths at any grid geometry"
        note = f"every part designed ({reason})"
    else:
        note = "every combination of parts designed"
    return _enumerate(problem, designer, progress, t0, note, [slot], reason_of_size=note)


def _search_group(problem: Problem, designer: MinimaxDesigner, group: DirectGroup, progress: Progress, t0: float, others: list[DirectGroup] | None = None) -> SearchResult:
    """One group of interacting slots, with the designer of its rows alone."""
    slots = [s for s in problem.slots if s.name in group.slots]
    exclude = frozenset(s.name for s in problem.springs if s.slot is not None and s.slot not in group.slots)
    if len(slots) == 1:
        return _search_slot(problem, designer, slots[0], progress, t0, group if others else None, exclude)
    if math.prod(len(s.catalogue) for s in slots) <= MAX_COMBINATIONS:
        return _enumerate(problem, designer, progress, t0, "every combination of parts designed", slots)
    return _search_coupled(problem, designer, group, slots, exclude, progress, t0)


def refusal(problem: Problem, slots: list[SpringSlot], total: int, why: str) -> ProblemFileError:
    """The input limit of a search that can neither enumerate nor screen: exit status 2."""
    largest = max(slots, key=lambda s: len(s.catalogue))
    names = ", ".join(s.name for s in slots)
    kind = "interacting directly attached slots" if len(slots) > 1 else "directly attached slot"
    return ProblemFileError(
        str(problem.path),
        f"slots.{largest.name}.catalogue",
        f"{total} combinations of parts for the {kind} {names} (at most {MAX_COMBINATIONS} are designed one by one) and {why}: "
        f"use a smaller catalogue (slot {largest.name} has {len(largest.catalogue)} parts), fewer slots, "
        "or attach the springs so that the slots do not interact (docs/catalogues.md, directly attached springs)",
    )


def _enumerate(problem: Problem, designer: MinimaxDesigner, progress: Progress, t0: float, note: str, slots: list[SpringSlot] | None = None, reason_of_size: str = "") -> SearchResult:
    """Every combination of parts of ``slots`` (default: the problem's) designed."""
    slots = list(problem.slots) if slots is None else slots
    sizes = [len(s.catalogue) for s in slots]
    counts = [SlotCount(s.name, len(s.catalogue), (math.nan, math.nan)) for s in slots]
    total = math.prod(sizes)
    if total > MAX_COMBINATIONS:
        raise refusal(problem, slots, total, reason_of_size or "they cannot be screened")
    found: list[Choice] = []
    solves = 0
    warm = None
    for combo in itertools.product(*(range(n) for n in sizes)):
        rows = {s.name: i for s, i in zip(slots, combo)}
        sol = designer.solve(initial=warm, parameters=part_parameters(problem, rows))
        solves += 1
        progress(solves, total)
        if sol.status is not Status.OPTIMAL or (minimax := minimax_of(sol)) is None:
            for c in counts:
                c.failed_limits += 1
            continue
        warm = sol.values
        found.append(_choice(problem, rows, sol, minimax))
        for c in counts:
            c.fitting += 1
    for c in counts:
        c.rates_solved = solves
    found.sort(key=_order)
    message = "" if found else "no combination of parts keeps every directly attached spring within its lengths"
    evidence = (f"search: {note}; {solves} minimax designs, {len(found)} within their lengths; exhaustive over the catalogue (no bound computed)",)
    return SearchResult(found[0] if found else None, counts, [tuple(s.name for s in slots)], ["enumeration"], [], solves, time.perf_counter() - t0, message, found, evidence=evidence)


def _search_screened(problem: Problem, designer: MinimaxDesigner, screened: Screen, progress: Progress, t0: float, slot: SpringSlot, budget_of_bound: int = BOUND_EVALUATIONS) -> SearchResult:
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
            bounds = part_bounds(screened.context, designer, incumbent, budget_of_bound)
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
        if sol.status is not Status.OPTIMAL or (minimax := minimax_of(sol)) is None:
            count.failed_limits += 1
            continue
        count.fitting += 1
        found.append(_choice(problem, rows, sol, minimax))
        incumbent = min(incumbent, float(minimax.sampled_ratio))
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


def _search_coupled(problem: Problem, designer: MinimaxDesigner, group: DirectGroup, slots: list[SpringSlot], exclude: frozenset[str], progress: Progress, t0: float) -> SearchResult:
    """Interacting slots with too many combinations to design: each slot screened in turn
    (the others at their best screened part so far, starting from their median-rate part),
    then every combination of the best screened parts of each slot designed."""
    total = math.prod(len(s.catalogue) for s in slots)
    reference = {s.name: int(np.argsort(s.catalogue.array("rate"))[len(s.catalogue) // 2]) for s in slots}
    keep = max(2, int(math.floor(COUPLED_COMBINATIONS ** (1.0 / len(slots)) + 1e-9)))
    best: dict[str, np.ndarray] = {}
    starts: dict[str, list[dict[str, float]]] = {}
    counts = []
    lines = []
    screens: dict[str, Screen] = {}
    for slot in [s for _ in range(COUPLED_SWEEPS) for s in slots][: COUPLED_SWEEPS * len(slots) - 1]:  # the last slot's screen is the last sweep's
        screened = screen(problem, designer, part_parameters(problem, reference), slot.name, group.coordinates, exclude, group.variables)
        if not screened.supported:
            raise refusal(problem, slots, total, f"slot {slot.name} cannot be screened ({screened.reason})")
        order = screened_order(screened)
        if not order.size:
            raise refusal(problem, slots, total, f"no part of slot {slot.name} stays within its lengths at any grid geometry of the screening")
        best[slot.name] = order[:keep]
        starts[slot.name] = screened.start
        reference[slot.name] = int(order[0])
        screens[slot.name] = screened
    for slot in slots:
        screened, kept = screens[slot.name], best[slot.name]
        count = SlotCount(slot.name, len(slot.catalogue), (math.nan, math.nan))
        count.pruned = screened.infeasible
        counts.append(count)
        lines.append(
            f"screening of slot {slot.name} (the other slots at their best screened part, {COUPLED_SWEEPS} sweeps): {len(slot.catalogue)} parts, {screened.infeasible} pruned "
            f"(no grid geometry within their lengths); the best {len(kept)} kept (screened ratios {screened.ratio[kept[0]]:.4g} to {screened.ratio[kept[-1]]:.4g})"
        )
    combos = list(itertools.product(*(best[s.name] for s in slots)))
    found: list[Choice] = []
    for n, combo in enumerate(combos):
        rows = {s.name: int(i) for s, i in zip(slots, combo)}
        start: dict[str, float] = {}
        for s, i in zip(slots, combo):
            start.update({v: x for v, x in starts[s.name][int(i)].items() if v in group.variables or v not in start})
        sol = designer.solve(initial={Slot(v, None): x for v, x in start.items()}, parameters=part_parameters(problem, rows))
        progress(n + 1, len(combos))
        if sol.status is not Status.OPTIMAL or (minimax := minimax_of(sol)) is None:
            for c in counts:
                c.failed_limits += 1
            continue
        found.append(_choice(problem, rows, sol, minimax))
        for c in counts:
            c.fitting += 1
    for c in counts:
        c.rates_solved = len(combos)
    found.sort(key=_order)
    lines.append(
        f"search: {total} combinations of parts too many to design one by one (at most {MAX_COMBINATIONS}); {len(combos)} combinations of the slots' best screened parts "
        f"designed by the minimax NLP, {len(found)} within their lengths; coverage: a screened search, not a certificate (the parts of each slot were screened with the other slots at one part)"
    )
    message = "" if found else "no combination of the best screened parts keeps every directly attached spring within its lengths"
    names = tuple(s.name for s in slots)
    return SearchResult(found[0] if found else None, counts, [names], ["screened combinations"], [], len(combos), time.perf_counter() - t0, message, found, evidence=tuple(lines))


def _combine(groups: list[DirectGroup], results: list[SearchResult], t0: float) -> SearchResult:
    """The groups' searches as one: each group's best parts (the worst ratio is the largest
    of the groups', which each group's best minimises independently of the others)."""
    counts = [c for r in results for c in r.counts]
    names = [r.groups[0] if r.groups else g.slots for g, r in zip(groups, results)]
    methods = [m for r in results for m in r.methods]
    solves = sum(r.solves for r in results)
    lines = [
        f"groups: {len(groups)} groups of directly attached slots that do not interact (no slot's part or geometry enters another group's residual rows or spring lengths), searched one by one: "
        + "; ".join(f"{' '.join(g.slots)} (rows {', '.join(sorted(g.coordinates))})" for g in groups)
    ]
    for g, r in zip(groups, results):
        lines += [f"group {' '.join(g.slots)}: {line}" for line in r.evidence]
    failed = [" ".join(g.slots) for g, r in zip(groups, results) if r.choice is None]
    if failed:
        message = "; ".join(r.message for r in results if r.choice is None) + f" (group(s) {', '.join(failed)})"
        return SearchResult(None, counts, names, methods, [m for r in results for m in r.nearest], solves, time.perf_counter() - t0, message, evidence=tuple(lines))
    best = [r.choice for r in results if r.choice is not None]  # every group found one (above)
    choice = Choice(
        {k: v for c in best for k, v in c.parts.items()},
        {k: v for c in best for k, v in c.rates.items()},
        max(c.objective for c in best),
        sum(c.price for c in best),
        robust=max(c.robust for c in best),
    )
    values: dict[Slot, float] = {}
    for g, c in zip(groups, best):
        # the variables shared by every scenario (a payload range's design has scenarios of its own)
        values.update({k: v for k, v in (c.values or {}).items() if k.variable in g.variables and k.scenario is None})
    choice.values = values
    bounds = [r.lower_bound_ratio for r in results if not math.isnan(r.lower_bound_ratio)]
    lower = max(bounds) if bounds else math.nan  # the worst ratio is at least each group's
    return SearchResult(choice, counts, names, methods, [], solves, time.perf_counter() - t0, "", [choice], lower_bound_ratio=lower, evidence=tuple(lines))


__all__ = ["MAX_COMBINATIONS", "part_parameters", "refusal", "search_direct"]
