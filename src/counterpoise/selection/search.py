"""Choose one catalogue part per spring slot, and re-solve the continuous design for it.

The search works on the *relaxed* problem, in which every slot's rate is a continuous
design variable bounded by its catalogue's range; it is built once (one
:class:`~counterpoise.designer.Designer`) and a candidate part is tried by fixing its
rate through per-call bounds, without rebuilding anything.

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

import heapq
import itertools
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..catalogue.limits import LIMIT_TEXT, LIMITS, margins, violation
from ..designer.designer import Designer
from ..formulation.layout import Slot
from ..model.parts import SpringSlot
from ..model.problem import Problem, Variable
from ..model.units import display_unit
from ..solvers.base import Status
from ..solvers.ipopt import IpoptBackend
from .geometry import sample_configurations, spring_lengths
from .tolerance import tolerance_band

#: objectives within this relative amount count as tied (the preference then decides)
TIE = 1e-9


@dataclass(frozen=True)
class NearMiss:
    """A part that does not fit, and why (for the report when none fits)."""

    slot: str
    part_number: str
    limit: str  # one of catalogue.limits.LIMITS, or 'rate'
    spring: str
    violation: float  # relative amount by which the limit is exceeded
    rates: tuple[tuple[str, float], ...] = ()  # slot rates of its design (when it was solved)

    def text(self) -> str:
        if self.limit == "rate":
            return f"{self.part_number} (slot {self.slot}): no balanced design within the bounds uses its rate ({100 * self.violation:.3g} % outside the balanceable range)"
        return f"{self.part_number} (slot {self.slot}, spring {self.spring}): {LIMIT_TEXT[self.limit]} ({100 * self.violation:.3g} % beyond)"


@dataclass
class SlotCount:
    """How a slot's parts fared."""

    slot: str
    parts: int
    window: tuple[float, float]  # balanceable rate range (N/m)
    pruned: int = 0  # outside the window: pruned before any per-part solve
    rates_solved: int = 0  # distinct rates whose design was solved
    failed_limits: int = 0  # solved, but a limit does not hold
    fitting: int = 0


@dataclass
class Choice:
    parts: dict[str, int]  # slot -> row of its catalogue
    rates: dict[str, float]
    objective: float
    price: float
    robust: float = math.nan  # worst-case residual ratio over the tolerance band


@dataclass
class SearchResult:
    choice: Choice | None
    counts: list[SlotCount]
    groups: list[tuple[str, ...]]
    methods: list[str]
    nearest: list[NearMiss]
    solves: int
    seconds: float
    message: str = ""
    candidates: list[Choice] = field(default_factory=list)  # every fitting combination found, best first


def relaxed_problem(problem: Problem) -> Problem:
    """The problem with each slot's rate a continuous variable over its catalogue's range."""
    names = {s.name for s in problem.slots}
    unit = display_unit("N/mm")
    extra = []
    for s in problem.slots:
        rates = s.catalogue.array("rate")
        lo, hi = float(rates.min()), float(rates.max())
        extra.append(Variable(s.name, lo, hi if hi > lo else lo, float(np.median(rates)), unit, description=f"rate of slot {s.name}"))
    return replace(
        problem,
        parameters=tuple(p for p in problem.parameters if p.name not in names),
        variables=problem.variables + tuple(extra),
        slots=problem.slots,
    )


class PartSearch:
    """The search for one problem; :meth:`run` returns a :class:`SearchResult`."""

    def __init__(self, problem: Problem) -> None:
        self.problem = problem
        self.slots: dict[str, SpringSlot] = {s.name: s for s in problem.slots}
        self.relaxed = relaxed_problem(problem)
        self.designer = Designer(self.relaxed)
        self.solves = 0
        settings = problem.selection
        self.q = sample_configurations(problem, settings.limit_samples, problem.settings.seed + 7)

    # -- steps -------------------------------------------------------------------------
    def run(self) -> SearchResult:
        t0 = time.perf_counter()
        d = self.designer
        counts = {n: SlotCount(n, len(s.catalogue), (math.nan, math.nan)) for n, s in self.slots.items()}
        base = d.solve(certify=False)
        self.solves += 1
        if base.status is not Status.OPTIMAL:
            message = (
                "no rate within the catalogues' ranges balances the mechanism within the bounds "
                f"(the continuous relaxation is {base.status.value}): no part can fit"
            )
            nearest = self._rate_misses({n: (math.nan, math.nan) for n in self.slots}, base.values)
            return SearchResult(None, list(counts.values()), [], [], nearest, self.solves, time.perf_counter() - t0, message)
        self.base = base
        windows = self._windows(base)
        kept: dict[str, np.ndarray] = {}
        for name, s in self.slots.items():
            rates = s.catalogue.array("rate")
            lo, hi = windows[name]
            inside = (rates >= lo * (1 - 1e-9)) & (rates <= hi * (1 + 1e-9))
            counts[name].window = (lo, hi)
            counts[name].pruned = int((~inside).sum())
            kept[name] = np.flatnonzero(inside)
        nearest = self._rate_misses(windows, base.values)
        groups = self._groups()
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
        nearest = nearest[: self.problem.selection.nearest]
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
        return SearchResult(choice, list(counts.values()), groups, methods, nearest, self.solves, time.perf_counter() - t0, "", ranked)

    def _windows(self, base: Any) -> dict[str, tuple[float, float]]:
        """Smallest and largest balanceable rate of each slot (two NLPs per slot)."""
        import casadi as ca

        d = self.designer
        f = d.formulation
        names = list(self.slots)
        if d.n_equalities > len(f.design):
            return {n: (float(self.relaxed.variable[n].lower), float(self.relaxed.variable[n].upper)) for n in names}
        w = ca.SX.sym("w", len(names))
        index = [f.design.index[Slot(n, None)] for n in names]
        objective = sum(w[i] * f.z[index[i]] for i in range(len(names)))
        nlp = {"x": f.z, "p": ca.vertcat(f.p, w), "f": objective, "g": ca.vertcat(d.conditions.equalities, f.nonnegative)}
        backend = IpoptBackend(nlp, d.options, "rate_window")
        bounds = d.bounds(d.n_equalities)
        z0 = f.design.to_z(f.design.vector(base.values))
        out = {}
        for i, n in enumerate(names):
            ends = []
            for sign in (1.0, -1.0):
                weights = np.zeros(len(names))
                weights[i] = sign
                res = backend.solve(z0, np.concatenate([d.parameters, weights]), bounds)
                self.solves += 1
                if res.status is Status.OPTIMAL:
                    ends.append(float(f.design.to_x(res.z)[index[i]]))
                else:  # not settled: do not prune on this side
                    ends.append(self.relaxed.variable[n].lower if sign > 0 else self.relaxed.variable[n].upper)
            out[n] = (min(ends), max(ends))
        return out

    def _groups(self) -> list[tuple[str, ...]]:
        """Slots whose conditions share variables (column-matroid components of the Jacobian)."""
        d = self.designer
        f = d.formulation
        names = list(self.slots)
        n = len(f.design)
        parent = list(range(n))

        def find(i: int) -> int:
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        def union(i: int, j: int) -> None:
            parent[find(i)] = find(j)

        rng = np.random.default_rng(self.problem.settings.seed + 3)
        lo, hi = f.design.lower, f.design.upper
        points = [f.design.to_z(f.design.vector(self.base.values))] + [f.design.to_z(lo + (hi - lo) * rng.random(n)) for _ in range(2)]
        gj = d.residual_jacobian()
        for z in points:
            _, jac, _ = (np.array(v) for v in gj(z, d.parameters))
            if jac.size == 0:
                continue
            jac = jac / max(np.abs(jac).max(), 1e-300)
            _, s, vt = np.linalg.svd(jac, full_matrices=True)
            rank = int(np.sum(s > 1e-9 * (s[0] if s.size else 1)))
            null = vt[rank:].T  # columns: the null space of the Jacobian
            # columns in one matroid component share a circuit: a null vector touching both
            if null.size:
                # an echelon basis of the null space gives the fundamental circuits
                q, r, piv = _qr_pivot(null.T)
                for row in r:
                    support = np.flatnonzero(np.abs(row) > 1e-8 * max(np.abs(row).max(), 1e-300))
                    for a, b in zip(support[:-1], support[1:]):
                        union(int(piv[a]), int(piv[b]))
        # sign constraints couple the variables they mention
        import casadi as ca

        nonneg = f.nonnegative
        if nonneg.numel():
            sparsity = ca.jacobian(nonneg, f.z).sparsity()
            rows: dict[int, list[int]] = {}
            for r_, c_ in zip(*sparsity.get_triplet()):
                rows.setdefault(r_, []).append(c_)
            for cols in rows.values():
                for a, b in zip(cols[:-1], cols[1:]):
                    union(a, b)
        # a non-additive objective term (M·d²) couples its variables too
        import casadi as ca

        hessian = ca.hessian(f.objective, f.z)[0].sparsity()
        for r_, c_ in zip(*hessian.get_triplet()):
            union(r_, c_)
        slot_index = {nm: f.design.index[Slot(nm, None)] for nm in names}
        groups: dict[int, list[str]] = {}
        for nm in names:
            groups.setdefault(find(slot_index[nm]), []).append(nm)
        return [tuple(g) for g in groups.values()]

    # -- one group ---------------------------------------------------------------------
    def _search_group(
        self, group: tuple[str, ...], kept: Mapping[str, np.ndarray], windows: Mapping[str, tuple[float, float]], counts: Mapping[str, SlotCount]
    ) -> tuple[str, list[Choice], list[NearMiss]]:
        rates = {n: np.unique(self.slots[n].catalogue.array("rate")[kept[n]]) for n in group}
        size = math.prod(len(r) for r in rates.values())
        others = {n: windows[n] for n in self.slots if n not in group}
        if size == 0:
            return "none", [], []
        evaluated: list[tuple[dict[str, float], Any]] = []
        if size <= self.problem.selection.max_enumeration:
            method = "enumeration"
            for combo in itertools.product(*(rates[n] for n in group)):
                fixed = dict(zip(group, (float(k) for k in combo)))
                sol = self._solve(fixed, others)
                if sol is not None:
                    evaluated.append((fixed, sol))
        else:
            method = "branch-and-bound"
            evaluated = self._branch_and_bound(group, rates, others, kept)
        for n in group:
            counts[n].rates_solved += len({fixed[n] for fixed, _ in evaluated})
        found, misses = self._limits(group, kept, evaluated, counts)
        return method, found, misses

    def _solve(self, fixed: Mapping[str, float], others: Mapping[str, tuple[float, float]]) -> Any | None:
        bounds = {**{n: (k, k) for n, k in fixed.items()}, **others}
        sol = self.designer.solve(initial=self.base.values, bounds=bounds, certify=False)
        self.solves += 1
        return sol if sol.status is Status.OPTIMAL else None

    def _branch_and_bound(
        self, group: tuple[str, ...], rates: Mapping[str, np.ndarray], others: Mapping[str, tuple[float, float]], kept: Mapping[str, np.ndarray]
    ) -> list[tuple[dict[str, float], Any]]:
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
                sol = self._solve(fixed, others)
                if sol is not None:
                    out.append((fixed, sol))
                    scratch = {n: SlotCount(n, 0, (math.nan, math.nan)) for n in group}
                    if self._limits(group, kept, [(fixed, sol)], scratch, rank=False)[0]:  # some parts fit
                        incumbent = min(incumbent, sol.objective)
                continue
            widest = max(range(len(group)), key=lambda i: node[i][1] - node[i][0])
            a, b = node[widest]
            mid = (a + b) // 2
            for part in ((a, mid), (mid + 1, b)):
                child = node[:widest] + (part,) + node[widest + 1 :]
                intervals = {n: (float(rates[n][lo]), float(rates[n][hi])) for n, (lo, hi) in zip(group, child)}
                if all(lo == hi for lo, hi in child):
                    heapq.heappush(heap, (bound, next(counter), child))
                    continue
                sol = self.designer.solve(initial=self.base.values, bounds={**intervals, **others}, certify=False)
                self.solves += 1
                if sol.status is Status.OPTIMAL:
                    heapq.heappush(heap, (sol.objective, next(counter), child))
        return out

    def _limits(
        self,
        group: tuple[str, ...],
        kept: Mapping[str, np.ndarray],
        evaluated: Sequence[tuple[dict[str, float], Any]],
        counts: Mapping[str, SlotCount],
        rank: bool = True,
    ) -> tuple[list[Choice], list[NearMiss]]:
        """Margins of every kept part of the group's slots, for the solved designs (vectorised)."""
        if not evaluated:
            return [], []
        problem = self.relaxed
        springs = [s for n in group for s in self.slots[n].springs]
        d_min = {s: np.full(len(evaluated), np.inf) for s in springs}
        d_max = {s: np.zeros(len(evaluated)) for s in springs}
        names = [v.name for v in problem.variables]
        for scenario in problem.scenarios:
            variables = {v: np.array([[sol.variable_values(scenario.name)[v]] for _, sol in evaluated]) for v in names}
            gravity, base = evaluated[0][1].scenario_parameters[scenario.name]
            lengths = spring_lengths(problem, springs, self.q, variables, base, gravity)
            for s, dist in lengths.items():
                d_min[s] = np.minimum(d_min[s], dist.min(axis=1))
                d_max[s] = np.maximum(d_max[s], dist.max(axis=1))
        fits: dict[str, list[list[int]]] = {n: [[] for _ in evaluated] for n in group}
        misses: list[NearMiss] = []
        fitting: dict[str, set[int]] = {n: set() for n in group}
        failing: dict[str, set[int]] = {n: set() for n in group}
        for n in group:
            cat = self.slots[n].catalogue
            a = cat.arrays
            rows = kept[n]
            lo = np.min([d_min[s] for s in self.slots[n].springs], axis=0)
            hi = np.max([d_max[s] for s in self.slots[n].springs], axis=0)
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
                worst_spring = self.slots[n].springs[0]
                for i in np.flatnonzero(~ok):
                    misses.append(NearMiss(n, cat.part_number[int(mine[i])], LIMITS[int(which[i])], worst_spring, float(amount[i]), tuple(evaluated[e][0].items())))
        for n in group:  # a part fits when it fits in some solved design
            counts[n].fitting += len(fitting[n])
            counts[n].failed_limits += len(failing[n] - fitting[n])
        found = []
        prefer = self.problem.selection.prefer
        for e, (fixed, sol) in enumerate(evaluated):
            if any(not fits[n][e] for n in group):
                continue
            parts = {}
            for n in group:
                a = self.slots[n].catalogue.arrays
                options = fits[n][e]
                if prefer == "price":
                    key = lambda i, a=a: (np.nan_to_num(a["price"][i], nan=np.inf), a["initial_tension"][i])  # noqa: E731
                else:
                    key = lambda i, a=a: (a["initial_tension"][i], np.nan_to_num(a["price"][i], nan=np.inf))  # noqa: E731
                parts[n] = min(options, key=key)
            price = sum(len(self.slots[n].springs) * self.slots[n].catalogue.price[parts[n]] for n in group)
            found.append(Choice(parts, dict(fixed), sol.objective, float(price)))
        if not rank:
            return found, misses
        if prefer == "robust":
            for c in found:
                c.robust = self.robustness(c, self._solution_of(evaluated, c))
        elif found:
            best = min(c.objective for c in found)
            for c in found:
                if c.objective <= best + TIE * max(1.0, abs(best)):
                    c.robust = self.robustness(c, self._solution_of(evaluated, c))
        found.sort(key=self._key)
        return found, misses

    @staticmethod
    def _solution_of(evaluated: Sequence[tuple[dict[str, float], Any]], choice: Choice) -> Any:
        for fixed, sol in evaluated:
            if fixed == choice.rates:
                return sol
        raise KeyError(choice.rates)

    def robustness(self, choice: Choice, solution: Any) -> float:
        """Worst-case residual ratio over the tolerance band of the chosen parts' springs."""
        values = {}
        for scenario in self.relaxed.scenarios:
            gravity, base = solution.scenario_parameters[scenario.name]
            values[scenario.name] = (solution.variable_values(scenario.name), base, gravity)
        tension, rate_tol, tension_tol = {}, {}, {}
        for n, row in choice.parts.items():
            slot = self.slots[n]
            for s in slot.springs:
                tension[s] = slot.catalogue.initial_tension[row]
                rate_tol[s] = slot.rate_tolerance
                tension_tol[s] = slot.initial_tension_tolerance
        return tolerance_band(self.relaxed, values, tension, rate_tol, tension_tol, self.q).worst

    def _key(self, c: Choice) -> tuple[float, ...]:
        robust = c.robust if not math.isnan(c.robust) else math.inf
        price = c.price if not math.isnan(c.price) else math.inf
        objective = round(c.objective / max(1.0, abs(c.objective)), 9)
        prefer = self.problem.selection.prefer
        if prefer == "robust":
            return (robust, objective, price)
        if prefer == "price":
            return (price, objective, robust)
        return (objective, robust, price)

    def _rate_misses(self, windows: Mapping[str, tuple[float, float]], values: Mapping[Slot, float]) -> list[NearMiss]:
        """Parts pruned by the rate window, with their relative distance to it."""
        out = []
        for n, s in self.slots.items():
            lo, hi = windows[n]
            rates = s.catalogue.array("rate")
            if math.isnan(lo):
                target = values.get(Slot(n, None), float(np.median(rates)))
                lo = hi = target
            distance = np.where(rates < lo, (lo - rates) / lo, np.where(rates > hi, (rates - hi) / hi, 0.0))
            for i in np.argsort(distance)[: self.problem.selection.nearest]:
                if distance[i] > 0:
                    out.append(NearMiss(n, s.catalogue.part_number[int(i)], "rate", s.springs[0], float(distance[i])))
        return out


def _qr_pivot(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Row echelon form of ``a`` (rows: a basis of a space) with column pivoting: R with
    columns permuted by ``piv``; each row of R (reduced) is a circuit's support."""
    m = a.copy()
    rows, cols = m.shape
    piv = np.arange(cols)
    r = 0
    for c in range(cols):
        if r >= rows:
            break
        k = r + int(np.argmax(np.abs(m[r:, c])))
        if abs(m[k, c]) < 1e-10 * max(np.abs(m).max(), 1e-300):
            continue
        m[[r, k]] = m[[k, r]]
        m[r] /= m[r, c]
        for i in range(rows):
            if i != r:
                m[i] -= m[i, c] * m[r]
        r += 1
    return np.eye(rows), m[:r], piv
