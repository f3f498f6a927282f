"""The search: the cheapest exact designs of a superstructure on its grid, every minimal
topology, and the Pareto front of cost against added mass (docs/synthesis.md#search).

A decomposition of the mixed-integer program (logic-based Benders):

- the *master* (:class:`~.bound.Relaxation`) chooses a set S of classes: the relaxation
  with every point anywhere in its region, one binary per class, and the cuts learnt;
- the *subproblem* is the exact program on the grid (:class:`~.milp.Program`) restricted
  to the candidates of S. If it has an exact design, that design is the best within S.
  If it has none, no subset of S balances on the grid either, and the master learns the
  cut Σ_{c∉S} y_c ≥ 1 (a design must use some class outside S).

Every cut is valid for every exact design on the grid, and the master is a relaxation, so
its optimum is a lower bound of the grid's optimum at every step: when a subproblem
reaches it, the minimum is proven (no cheaper design balances exactly on the grid).
Without cuts the master's optimum is a lower bound for every point in the regions
(grid-independent). Enumeration adds, for each minimal topology found, the cut that
excludes exactly it, until the master has nothing left at the minimal cost.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .. import progress
from .bound import Relaxation
from .milp import Design, LinearMip, Program, Solved
from .structure import MASS

#: the cost of one design counts as equal to another's within this (costs are ≥ 0 numbers)
COST_TOLERANCE = 1e-6
#: a Pareto step asks for at least this share of the largest counter-mass less added mass
MASS_STEP = 1e-6
#: the objective of a topology's design: the least added mass, then the least total rate
LIGHTEST = "lightest"
#: progress lines: the first after this many seconds, then at most one every this many
NOTE_AFTER_S = 2.0


@dataclass
class Search:
    """The state and answers of one search (see the module)."""

    program: Program
    relaxation: Relaxation
    time_limit: float
    infeasible_sets: list[frozenset[int]] = field(default_factory=list)  # subproblems with no exact design
    rejected: int = 0  # solutions the polish found not exact (the solver's tolerance balanced them)
    timed_out: list[frozenset[int]] = field(default_factory=list)  # subproblems that hit the time limit
    master_solves: int = 0
    sub_solves: int = 0
    started: float = field(default_factory=time.perf_counter)
    _last_note: float = 0.0
    note: Callable[[str], None] = progress.note

    def __post_init__(self) -> None:
        self.exact: LinearMip = self.program.mip()
        self.master: LinearMip = self.relaxation.mip
        self.classes = self.program.classes
        self._members = {c.index: [j.index for j in self.program.candidates if j.cls == c.index] for c in self.classes}

    # -- progress ------------------------------------------------------------------
    def _say(self, what: str, bound: float, incumbent: float | None) -> None:
        now = time.perf_counter()
        if now - self.started < NOTE_AFTER_S or now - self._last_note < NOTE_AFTER_S:
            return
        self._last_note = now
        best = "none yet" if incumbent is None else f"{incumbent:g}"
        self.note(f"synthesis: {what}: bound {bound:g}, incumbent {best} ({self.master_solves} master and {self.sub_solves} grid solves, {now - self.started:.0f} s)")

    # -- the two programs ------------------------------------------------------------
    def _master_rows(self, local: list[frozenset[int]], exclude: list[frozenset[int]], cost_cap: float | None, mass_cap: float | None,
                     objective_cap: tuple[str, float] | None) -> list[tuple[np.ndarray, float]]:
        rows = []
        n = self.master.n
        for s in [*self.infeasible_sets, *local]:  # a design uses some class outside s
            a = np.zeros(n)
            a[[self.relaxation.binary[c.index] for c in self.classes if c.index not in s]] = -1.0
            rows.append((a, -1.0))
        for t in exclude:  # not exactly this topology (nor a superset)
            a = np.zeros(n)
            a[[self.relaxation.binary[i] for i in t]] = 1.0
            rows.append((a, len(t) - 1.0))
        for name, cap in (("cost", cost_cap), ("mass", mass_cap)):
            if cap is not None:
                rows.append((self.master.objectives[name], cap))
        if objective_cap is not None:
            rows.append((self.master.objectives[objective_cap[0]], objective_cap[1]))
        return rows

    def _sub(self, classes: frozenset[int], objective: str, every: bool, cost_cap: float | None, mass_cap: float | None) -> tuple[Solved, Design | None]:
        """The exact program restricted to the candidates of ``classes`` (``every``: each
        of them used), polished; rejected solutions are cut and the solve repeated."""
        fixed = {int(self.exact.binaries[j]): (0.0, 0.0) for c in self.classes if c.index not in classes for j in self._members[c.index]}
        rows: list[tuple[np.ndarray, float]] = []
        n = self.exact.n
        if every:
            for c in classes:
                a = np.zeros(n)
                a[self.exact.binaries[self._members[c]]] = -1.0
                rows.append((a, -1.0))
        for name, cap in (("cost", cost_cap), ("mass", mass_cap)):
            if cap is not None:
                rows.append((self.exact.objectives[name], cap))
        while True:
            self.sub_solves += 1
            solved = self.exact.solve("mass" if objective == LIGHTEST else objective, rows, fixed, self.time_limit)
            if solved.status != "optimal":
                return solved, None
            if objective == LIGHTEST:  # then the least rates at (nearly) that mass
                cap = solved.value + MASS_STEP * max(self.program.spec.max_mass, 1e-12)
                self.sub_solves += 1
                rated = self.exact.solve("rates", [*rows, (self.exact.objectives["mass"], cap)], fixed, self.time_limit)
                if rated.status == "optimal":
                    solved = rated
            design = self.program.design(solved)
            if design is not None:
                return solved, design
            self.rejected += 1  # balanced only to the solver's tolerance: not these candidates again
            z = solved.x[self.exact.binaries] if solved.x is not None else np.zeros(0)
            a = np.zeros(n)
            chosen = np.flatnonzero(z > 0.5)
            a[self.exact.binaries[chosen]] = 1.0
            rows.append((a, len(chosen) - 1.0))

    # -- questions -------------------------------------------------------------------
    def best(self, objective: str, cost_cap: float | None = None, mass_cap: float | None = None) -> tuple[Design | None, str, float]:
        """The exact design on the grid that minimises ``objective`` ('cost' or 'mass')
        within the caps: (design or None, 'optimal' | 'infeasible' | 'time_limit', the
        proven lower bound of the objective)."""
        local: list[frozenset[int]] = []
        incumbent: Design | None = None
        step = COST_TOLERANCE if objective == "cost" else MASS_STEP * max(self.program.spec.max_mass, 1e-12)
        capped = cost_cap is not None or mass_cap is not None
        bound = -math.inf
        status = "optimal"
        while True:
            cap = None if incumbent is None else (objective, self._value(incumbent, objective) - step)
            self.master_solves += 1
            m = self.master.solve(objective, self._master_rows(local, [], cost_cap, mass_cap, cap), time_limit=self.time_limit)
            if m.status == "infeasible":
                if incumbent is None:
                    return None, "infeasible" if status == "optimal" else status, math.inf
                return incumbent, status, self._value(incumbent, objective) if status == "optimal" else bound
            if m.status != "optimal":
                return incumbent, "time_limit", bound
            bound = max(bound, m.value) if incumbent is None else bound
            chosen = self.relaxation.chosen(m)
            self._say(f"least {objective}", m.value, None if incumbent is None else self._value(incumbent, objective))
            solved, design = self._sub(chosen, objective, False, cost_cap, mass_cap)
            if design is not None:
                if incumbent is None or self._value(design, objective) < self._value(incumbent, objective):
                    incumbent = design
                local.append(chosen)  # nothing within it does better
                if objective == "cost" and self._value(design, objective) <= m.value + COST_TOLERANCE:
                    return incumbent, status, m.value
                continue
            if solved.status == "infeasible":
                (local if capped else self.infeasible_sets).append(chosen)
            else:
                self.timed_out.append(chosen)
                status = "time_limit"
                local.append(chosen)

    def topologies(self, cost: float, first: Design, limit: int) -> tuple[list[Design], bool]:
        """Every topology of cost ``cost`` (the minimum) with an exact design on the grid,
        each at its least added mass, ``first`` included; whether the list is complete."""
        found = [first]
        while len(found) < limit:
            self._say(f"enumerating the minimal topologies ({len(found)} found)", cost, cost)
            self.master_solves += 1
            m = self.master.solve("cost", self._master_rows([], [d.classes for d in found], cost + COST_TOLERANCE, None, None), time_limit=self.time_limit)
            if m.status == "infeasible":
                return found, not self.timed_out
            if m.status != "optimal":
                return found, False
            chosen = self.relaxation.chosen(m)
            solved, design = self._sub(chosen, LIGHTEST, True, None, None)
            if design is not None:
                found.append(design)
            elif solved.status == "infeasible":
                self.infeasible_sets.append(chosen)
            else:
                self.timed_out.append(chosen)
                found_cut = chosen
                self.infeasible_sets.append(found_cut)  # not proven: said in the result (timed_out)
        return found, False

    def least_mass(self, design: Design) -> Design:
        """``design``'s topology at its least added mass on the grid."""
        solved, better = self._sub(design.classes, LIGHTEST, True, None, None)
        return better if better is not None and better.added_mass <= design.added_mass + MASS_STEP * self.program.spec.max_mass else design

    def pareto(self, cost: float, mass: float) -> list[Design]:
        """The designs of the Pareto front of cost against added mass beyond the first
        point (cost, mass): each the least cost with less added mass than the one before,
        at its least added mass."""
        if not any(c.kind == MASS for c in self.classes):
            return []
        out: list[Design] = []
        limit = mass
        for _ in range(len(self.classes)):
            if limit <= MASS_STEP * self.program.spec.max_mass:
                break
            cheaper, status, _ = self.best("cost", mass_cap=limit - MASS_STEP * self.program.spec.max_mass)
            if cheaper is None:
                break
            lightest, _, _ = self.best("mass", cost_cap=cheaper.cost + COST_TOLERANCE)
            point = lightest if lightest is not None else cheaper
            out.append(point)
            limit = point.added_mass
        return out

    @staticmethod
    def _value(design: Design, objective: str) -> float:
        return design.cost if objective == "cost" else design.added_mass
