"""Choose one catalogue part per spring slot, and re-solve the continuous design for it.

The search works on the *relaxed* problem, in which every slot's rate is a continuous
design variable bounded by its catalogue's range. What it builds (:class:`SearchModel`: the
relaxed problem's :class:`~counterpoise.designer.Designer` and its rate-window NLP) is built
once per problem content and kept by the design method (:class:`SearchModels`, keyed by
:func:`~counterpoise.model.digest.content_key`, never by a name or path): a search takes
the call's parameters and bounds as solve arguments, so a study's points reuse it, and a
candidate part is tried by fixing its rate through per-call bounds, without rebuilding anything.

1. **Relaxation.** Solve the relaxed problem. If no rate in the catalogue's range
   balances, no part can: stop and say so.
2. **Rate window (before any per-part solve).** For each slot, the smallest and largest
   rate of a balanced design within the bounds (two small NLPs per slot); parts outside
   the window are pruned at once, vectorised.
3. **Independent slots.** Slots whose balance conditions do not share a variable are
   searched separately (the connected components of the column matroid of the condition
   Jacobian, at random points): the number of solves adds up instead of multiplying.
   While one group is searched, the other slots' rates stay free within their windows,
   which does not change the group's optimum because objectives and conditions separate.
4. **Candidates.** Per group, every combination of distinct rates is solved exactly when
   there are at most ``selection.max_enumeration`` of them; otherwise branch and bound on
   the sorted rate lists, with the relaxed problem on a rate interval as the lower bound.
   Parts sharing a rate share one solve.
5. **Limits, vectorised.** For each solved rate the spring distances over sampled
   configurations of every scenario give each part's three margins
   (:mod:`counterpoise.catalogue.limits`) in one numpy evaluation over all its parts.
6. **Choice.** ``selection.prefer``: ``objective`` (then least sensitive, then cheapest),
   ``robust`` (least sensitive to the tolerance band first) or ``price``. At a given rate
   the fitting part with the smallest initial tension is the least sensitive.

When nothing fits, the nearest candidates and the limit each violates are reported from
the numbers already computed (no solve per failing part).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..designer.designer import Designer
from ..formulation.layout import Slot
from ..formulation.manifold import changed_geometry, with_values
from ..kept import Kept
from ..model.digest import content_key
from ..model.parts import SpringSlot
from ..model.problem import Problem
from ..solvers.base import Status
from . import ranking
from .candidates import branch_and_bound, enumerate_rates
from .geometry import sample_configurations
from .groups import slot_groups
from .limits import fitting_parts
from .nearest import rate_misses
from .rates import EXACT_RATES, PREDICTION_MARGIN, RateScreen, screen_rates
from .results import TIE, Choice, NearMiss, SearchResult, SlotCount
from .windows import RateWindows, inside_window, relaxed_problem

__all__ = ["TIE", "Choice", "NearMiss", "PartSearch", "SearchModel", "SearchModels", "SearchResult", "SlotCount", "relaxed_problem"]

#: how a limit is named in the evidence
LIMIT_NAME = {"initial_tension": "slack string", "max_length": "max length", "max_load": "max load"}

#: seed offsets (added to settings.seed) of the limit-check sample and of the grouping's random points
LIMIT_SEED, GROUP_SEED = 7, 3


#: search models a design method keeps (a payload range's refinements search other sample sets)
KEPT_MODELS = 4


class SearchModel:
    """What the part search of one problem builds, once: the relaxed problem's designer and
    its rate-window NLP (:class:`~.windows.RateWindows`). Every search with it passes its
    parameters and bounds per solve, so nothing is rebuilt for another study point."""

    def __init__(self, problem: Problem) -> None:
        self.problem = problem
        self.relaxed = relaxed_problem(problem)
        self.designer = Designer(self.relaxed)
        self.windows = RateWindows(self.designer)


class SearchModels:
    """The search models of one design method, one per problem content (at most
    :data:`KEPT_MODELS`, least recently used dropped): the method is built once per worker,
    so each problem's search designer is built once per problem content and worker."""

    def __init__(self) -> None:
        self._built: Kept[tuple[str, tuple[tuple[str, float], ...]], SearchModel] = Kept(KEPT_MODELS)

    def of(self, problem: Problem, parameters: Mapping[str, float] | None = None) -> SearchModel:
        """The model of ``problem`` (a problem without the call's options), built on first use.
        Call ``parameters`` that change a closed loop's geometry get a model built on that
        geometry (the rate windows and slot groups read the built equalities directly, and
        the manifold equalities hold at the build's geometry, docs/loops.md)."""
        changed = changed_geometry(problem, parameters)
        return self._built.get((content_key(problem), changed), lambda: SearchModel(with_values(problem, dict(changed)) if changed else problem))


class PartSearch:
    """The search for one problem; :meth:`run` returns a :class:`SearchResult`.

    ``problem``: the problem as this search sees it (the call's parameter values and bounds
    in it: limits and tolerance bands are evaluated on it). ``model``: a
    :class:`SearchModel` built once for the problem without them (default: one built for
    ``problem``); ``parameters`` and ``bounds`` (SI) are then passed to each of its solves."""

    def __init__(
        self,
        problem: Problem,
        model: SearchModel | None = None,
        parameters: Mapping[str, float] | None = None,
        bounds: Mapping[Slot | str, tuple[float, float]] | None = None,
    ) -> None:
        self.problem = problem
        self.slots: dict[str, SpringSlot] = {s.name: s for s in problem.slots}
        self.relaxed = relaxed_problem(problem)
        self.model = model or SearchModel(problem)
        self.designer = self.model.designer
        self.parameters = dict(parameters or {}) or None
        # by variable, on every slot of it, as the problem this search sees has them
        self.bounds: dict[Slot | str, tuple[float, float]] = {(k.variable if isinstance(k, Slot) else k): v for k, v in (bounds or {}).items()}
        self.solves = 0
        self.screens: dict[str, RateScreen] = {}
        self.q = sample_configurations(problem, problem.selection.limit_samples, problem.settings.seed + LIMIT_SEED)

    def run(self) -> SearchResult:
        t0 = time.perf_counter()
        d = self.designer
        nearest_count = self.problem.selection.nearest
        counts = {n: SlotCount(n, len(s.catalogue), (math.nan, math.nan)) for n, s in self.slots.items()}
        base = self.solve_relaxed()
        self.solves += 1
        if base.status is not Status.OPTIMAL:
            message = (
                "no rate within the catalogues' ranges balances the mechanism within the bounds "
                f"(the continuous relaxation is {base.status.value}): no part can fit"
            )
            nearest = rate_misses(self.slots, {n: (math.nan, math.nan) for n in self.slots}, base.values, nearest_count)
            return SearchResult(None, list(counts.values()), [], [], nearest, self.solves, time.perf_counter() - t0, message)
        self.base = base
        windows, solves = self.model.windows.solve(self.relaxed, list(self.slots), base, self.parameters, self.bounds)
        self.solves += solves
        kept: dict[str, np.ndarray] = {}
        for name, s in self.slots.items():
            inside = inside_window(s.catalogue.array("rate"), windows[name])
            counts[name].window = windows[name]
            counts[name].pruned = int((~inside).sum())
            kept[name] = np.flatnonzero(inside)
        nearest = rate_misses(self.slots, windows, base.values, nearest_count)
        groups = slot_groups(d, list(self.slots), base.values, self.problem.settings.seed + GROUP_SEED, self.parameters, self.bounds)
        methods, choices_per_group = [], []
        for group in groups:
            method, found, misses = self._search_group(group, kept, windows, counts)
            methods.append(method)
            nearest += misses
            choices_per_group.append(found)
        failed = {n for g, found in zip(groups, choices_per_group) if not found for n in g}
        if failed:  # the nearest candidates of the slots that nothing fits
            nearest = [m for m in nearest if m.slot in failed]
        nearest.sort(key=lambda m: m.violation)
        nearest = nearest[:nearest_count]
        if failed:
            empty = [" ".join(g) for g, found in zip(groups, choices_per_group) if not found]
            message = f"no catalogue part fits slot(s) {', '.join(empty)}"
            fitting = [found[0] for found in choices_per_group if found]
            partial = Choice(
                {k: v for c in fitting for k, v in c.parts.items()}, {k: v for c in fitting for k, v in c.rates.items()}, math.nan, math.nan
            )
            return SearchResult(None, list(counts.values()), groups, methods, nearest, self.solves, time.perf_counter() - t0, message, [partial])
        best = [found[0] for found in choices_per_group]
        choice = Choice(
            parts={k: v for c in best for k, v in c.parts.items()},
            rates={k: v for c in best for k, v in c.rates.items()},
            objective=float("nan"),
            price=sum(c.price for c in best),
            robust=max((c.robust for c in best), default=math.nan),
        )
        ranked = sorted((c for found in choices_per_group for c in found), key=self._key)
        evidence = self._evidence(counts, groups, methods)
        # every solved design meets the balance conditions exactly: the ratio's bound is 0
        return SearchResult(choice, list(counts.values()), groups, methods, nearest, self.solves, time.perf_counter() - t0, "", ranked, 0.0, evidence)

    def solve_relaxed(self, initial: Mapping[Slot, float] | None = None, bounds: Mapping[Slot | str, tuple[float, float]] | None = None) -> Any:
        """The relaxed problem solved with this search's parameters and bounds, and ``bounds``
        (a candidate's rate interval, the other slots' windows) on top."""
        given = {**self.bounds, **(bounds or {})} or None
        return self.designer.solve(initial=initial, parameters=self.parameters, bounds=given, certify=False)

    def _evidence(self, counts: Mapping[str, SlotCount], groups: list[tuple[str, ...]], methods: list[str]) -> tuple[str, ...]:
        """What the search did and what it guarantees, one line per slot and group."""
        lines = []
        for n, c in counts.items():
            limits = "".join(f", {k} by {LIMIT_NAME.get(lim, lim)}" for lim, k in sorted(c.failed_by.items()))
            lines.append(f"slot {n}: {c.pruned} of {c.parts} parts pruned by the rate window; {c.rates_solved} rates solved; {c.failed_limits} failing a limit{limits}; {c.fitting} fitting")
        for g, m in zip(groups, methods):
            if m == "enumeration":
                guarantee = "every rate in the window solved: the choice is exact over the catalogue"
            elif m == "screening":
                r = self.screens[g[0]]
                pruned = ", ".join(f"{k} by {LIMIT_NAME.get(lim, lim)}" for lim, k in sorted(r.predicted_fail.items())) or "none"
                guarantee = (
                    f"designs solved at {len(r.nodes)} node rates and interpolated; parts predicted to break a limit by more than "
                    f"{100 * PREDICTION_MARGIN:g} % pruned without a solve ({pruned}); {r.candidates} predicted to fit, ranked by "
                    f"objective, tolerance sensitivity and price; the best {EXACT_RATES} rates solved exactly ({r.beyond_budget} "
                    "predicted-fitting parts left unsolved): exact over the solved rates, a screened search over the rest"
                )
            else:
                guarantee = "every node left has a relaxed bound above the best fitting design: the choice is exact over the catalogue"
            lines.append(f"group {' '.join(g)}: {m}; {guarantee}")
        lines.append("lower bound of the residual ratio: 0 (every solved design meets its balance conditions exactly)")
        return tuple(lines)

    # -- one group ---------------------------------------------------------------------
    def _search_group(
        self, group: tuple[str, ...], kept: Mapping[str, np.ndarray], windows: Mapping[str, tuple[float, float]], counts: Mapping[str, SlotCount]
    ) -> tuple[str, list[Choice], list[NearMiss]]:
        rates = {n: np.unique(self.slots[n].catalogue.array("rate")[kept[n]]) for n in group}
        size = math.prod(len(r) for r in rates.values())
        others = {n: windows[n] for n in self.slots if n not in group}
        if size == 0:
            return "none", [], []

        def solve(intervals: Mapping[str, tuple[float, float]]) -> Any | None:
            bounds: dict[Slot | str, tuple[float, float]] = {k: v for part in (intervals, others) for k, v in part.items()}
            sol = self.solve_relaxed(self.base.values, bounds)
            self.solves += 1
            return sol if sol.status is Status.OPTIMAL else None

        def fits(fixed: dict[str, float], sol: Any) -> bool:
            scratch = {n: SlotCount(n, 0, (math.nan, math.nan)) for n in group}
            found, _ = fitting_parts(self.relaxed, self.slots, group, kept, [(fixed, sol)], self.q, scratch)
            return all(found[n][0] for n in group)

        if size <= self.problem.selection.max_enumeration:
            method, evaluated = "enumeration", enumerate_rates(group, rates, solve)
        elif len(group) == 1:
            (name,) = group
            screened = screen_rates(self, name, rates[name], kept[name], others)
            evaluated = list(screened.nodes)
            done = {fixed[name] for fixed, _ in evaluated}
            for i in screened.order:
                k = float(rates[name][i])
                if k not in done:
                    sol = solve({name: (k, k)})
                    if sol is not None:
                        evaluated.append(({name: k}, sol))
            method = "screening"
            self.screens[name] = screened
        else:
            method, evaluated = "branch-and-bound", branch_and_bound(group, rates, solve, fits)
        for n in group:
            counts[n].rates_solved += len({fixed[n] for fixed, _ in evaluated})
        if not evaluated:
            return method, [], []
        fit_rows, misses = fitting_parts(self.relaxed, self.slots, group, kept, evaluated, self.q, counts)
        prefer = self.problem.selection.prefer
        found = ranking.choices(self.slots, group, evaluated, fit_rows, prefer)
        for c in ranking.needs_robustness(found, prefer):
            c.robust = self.robustness(c, self._solution_of(evaluated, c))
        found.sort(key=self._key)
        return method, found, misses

    @staticmethod
    def _solution_of(evaluated: Any, choice: Choice) -> Any:
        for fixed, sol in evaluated:
            if fixed == choice.rates:
                return sol
        raise KeyError(choice.rates)

    def robustness(self, choice: Choice, solution: Any) -> float:
        """Worst-case residual ratio over the tolerance band of the chosen parts' springs."""
        return ranking.robustness(self.relaxed, self.slots, self.q, choice, solution)

    def _key(self, c: Choice) -> tuple[float, ...]:
        return ranking.key(c, self.problem.selection.prefer)
