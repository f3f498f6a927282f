"""Synthesis from a problem to verified topologies: the search on the grid, each minimal
topology written as an ordinary problem and designed by the engine (the grid design, then
its points freed in their regions), and what is proven (docs/synthesis.md).

:func:`synthesise` is the Python entry point; :mod:`.report` writes the result.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import progress
from ..errors import ProblemFileError
from ..model.problem import Problem
from ..pipeline import DesignResult, design
from ..solvers.base import Status
from .conditions import Conditions, conditions
from .milp import Design, Element, Program
from .problemfile import FIXED, FREE, Written, toml_text, topology_data
from .structure import MASS, SPRING, ElementClass, element_classes

OPTIMAL, INFEASIBLE, TIME_LIMIT = "optimal", "infeasible", "time_limit"
#: a refined design replaces the grid's when its objective is not above it by more than this share
REFINE_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Topology:
    """One synthesised topology: its rank, name (of its problem file and report folder),
    classes, grid design and the verified design (``result``, the engine's design of the
    written problem ``written``)."""

    rank: int
    name: str
    labels: tuple[str, ...]
    grid: Design
    result: DesignResult
    written: Written
    text: str  # the problem file
    form: str  # 'fixed' (the grid's points) or 'free' (refined: the points freed)
    note: str  # what the refinement did

    @property
    def verified(self) -> bool:
        return self.result.status is Status.OPTIMAL

    @property
    def objective(self) -> float:
        return float(self.result.solution.objective)


@dataclass(frozen=True)
class ParetoPoint:
    cost: float
    added_mass: float
    labels: tuple[str, ...]


@dataclass(frozen=True)
class SynthesisResult:
    """What :func:`synthesise` found and proved (see docs/synthesis.md)."""

    problem: Problem
    status: str  # optimal | infeasible | time_limit
    message: str
    cost: float  # the least cost on the grid (nan when none)
    grid_bound: float  # proven: no exact design on the grid costs less
    relaxation_bound: float  # proven for every point in the regions (grid-independent)
    topologies: tuple[Topology, ...]
    complete: bool  # every minimal topology is listed
    pareto: tuple[ParetoPoint, ...]
    unbalanced: tuple[tuple[str, float], ...]  # infeasible: the terms left (J)
    conditions_exact: bool
    sampled_reasons: tuple[str, ...]
    terms: tuple[dict[str, Any], ...]  # per term: its coefficient and the classes that can produce it
    classes: tuple[ElementClass, ...]
    rejected: int
    timed_out: int
    master_solves: int
    grid_solves: int
    seconds: float
    candidates: int = 0
    rows: int = 0
    warnings: tuple[str, ...] = field(default_factory=tuple)

    @property
    def proof(self) -> str:
        """One line: what is proven about the minimum."""
        if self.status == INFEASIBLE:
            if math.isinf(self.relaxation_bound):
                return "no design balances, for any points in the regions (the relaxation is infeasible)"
            return "no design balances with spring ends on the grid points (the relaxation, with every point anywhere in its region, does not exclude one)"
        if self.status == TIME_LIMIT or math.isnan(self.cost):
            return f"not proven: a solve hit the time limit (cost {self.cost:g} found, proven lower bound {self.grid_bound:g})"
        where = "" if self.conditions_exact else " at the sampled configurations"
        text = f"minimal on the grid{where}: no design of cost below {self.cost:g} balances exactly"
        if self.relaxation_bound >= self.cost - 1e-6:
            return text + "; also for every point anywhere in the regions (the relaxation's bound equals it)"
        return text + f"; grid-independent lower bound {self.relaxation_bound:g} (the relaxation, every point anywhere in its region)"


def _labels(classes: tuple[ElementClass, ...], design: Design) -> tuple[str, ...]:
    return tuple(classes[i].label for i in sorted(design.classes))


def _term_rows(classes: tuple[ElementClass, ...], cond: Conditions) -> tuple[dict[str, Any], ...]:
    out = []
    for r, name in enumerate(cond.names):
        row: dict[str, Any] = {"term": name, "mechanism_J": float(cond.fixed[r])}
        row["produced_by"] = "; ".join(c.label for c in classes if np.any(cond.matrix[c.index][r] != 0))
        out.append(row)
    return tuple(out)


def synthesise(problem: Problem, raw: Mapping[str, Any] | None = None, refine: bool | None = None) -> SynthesisResult:
    """Synthesise the balancers of ``problem`` (its ``[synthesis]`` table): every minimal
    topology on the grid, verified by the engine, with what is proven. ``raw``: the file's
    parsed data (its topologies are written from it; default: read ``problem.path``).
    ``refine``: free the points in their regions (default: the file's ``refine``)."""
    spec = problem.synthesis
    if spec is None:
        raise ProblemFileError(problem.path, "synthesis", "missing: the problem has no [synthesis] table (the elements a balancer may be made of)")
    started = time.perf_counter()
    if raw is None:
        raw = _read(problem)
    classes = element_classes(spec)
    with progress.phase(f"{problem.name}: the exact conditions"):
        cond = conditions(problem, classes)
    from .bound import Relaxation
    from .search import Search

    with progress.phase(f"{problem.name}: the mixed-integer programs"):
        program = Program(spec, classes, cond)
        relaxation = Relaxation(spec, classes, cond)
        search = Search(program, relaxation, spec.time_limit)
        free = relaxation.mip.solve("cost", time_limit=spec.time_limit)
        relaxation_bound = free.value if free.status == "optimal" else (math.inf if free.status == "infeasible" else -math.inf)
        first, status, bound = search.best("cost")
    reasons = tuple(sorted({f"{b.subsystem}: {b.reason}" for b in cond.blocks if not b.exact}))
    terms = _term_rows(classes, cond)
    if first is None:
        unbalanced = tuple((cond.names[r], v) for r, v in relaxation.least_residual(spec.time_limit)[:12])
        if status == INFEASIBLE and not unbalanced:
            unbalanced = _grid_unbalanced(program, cond)
        names = ", ".join(f"{n} {v:+.4g} J" for n, v in unbalanced[:6])
        message = (
            f"the superstructure cannot balance exactly: {'unbalanced terms ' + names if names else 'no exact design on the grid'}"
            if status == INFEASIBLE
            else "the search hit the time limit before an exact design was found"
        )
        return SynthesisResult(problem, status, message, math.nan, bound, relaxation_bound, (), False, (), unbalanced, cond.exact, reasons, terms, classes,
                               search.rejected, len(search.timed_out), search.master_solves, search.sub_solves, time.perf_counter() - started,
                               len(program.candidates), cond.rows)
    with progress.phase(f"{problem.name}: enumerating the minimal topologies"):
        lightest = search.least_mass(first)
        designs, complete = search.topologies(first.cost, lightest, spec.max_topologies)
        designs = sorted(designs, key=lambda d: (d.added_mass, _labels(classes, d)))
        pareto_designs = search.pareto(first.cost, min(d.added_mass for d in designs)) if complete else []
    pareto = tuple(ParetoPoint(d.cost, d.added_mass, _labels(classes, d)) for d in [designs[0], *pareto_designs])
    do_refine = spec.refine if refine is None else refine
    topologies = []
    for rank, d in enumerate(designs, start=1):
        with progress.phase(f"{problem.name}: topology {rank} of {len(designs)}: designing and verifying"):
            topologies.append(_topology(problem, raw, classes, d, rank, do_refine))
    topologies.sort(key=lambda t: (not t.verified, t.objective, t.grid.added_mass, t.labels))
    topologies = [_renumbered(problem, raw, classes, t, i) for i, t in enumerate(topologies, start=1)]
    unverified = [t.name for t in topologies if not t.verified]
    message = f"{len(topologies)} minimal topolog{'y' if len(topologies) == 1 else 'ies'} of cost {first.cost:g}" + ("" if complete else " (the enumeration stopped: there may be more)")
    if unverified:
        message += f"; not verified by the engine: {', '.join(unverified)}"
    return SynthesisResult(problem, status if not unverified else "failed", message, first.cost, bound, relaxation_bound, tuple(topologies), complete, pareto, (),
                           cond.exact, reasons, terms, classes, search.rejected, len(search.timed_out), search.master_solves, search.sub_solves,
                           time.perf_counter() - started, len(program.candidates), cond.rows)


def _read(problem: Problem) -> dict[str, Any]:
    import sys

    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    try:
        return tomllib.loads(Path(problem.path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ProblemFileError(problem.path, "file", f"cannot read the file the problem came from (give its data): {exc}") from None


def _grid_unbalanced(program: Program, cond: Conditions) -> tuple[tuple[str, float], ...]:
    """The mechanism's own largest terms (when the relaxation balances but the grid cannot)."""
    order = np.argsort(-np.abs(cond.fixed))
    return tuple((cond.names[i], float(cond.fixed[i])) for i in order[:6] if cond.fixed[i] != 0)


def _title(problem: Problem, rank: int, labels: tuple[str, ...]) -> str:
    return f"{problem.title or problem.name}: synthesised topology {rank} ({', '.join(labels)})"


def _name(problem: Problem, rank: int) -> str:
    suffix = f"_t{rank}"
    return problem.name[: 128 - len(suffix)] + suffix


def _solve(text: str, label: str) -> DesignResult:
    from ..io.loader import load_problem_text

    return design(load_problem_text(text, label))


def _topology(problem: Problem, raw: Mapping[str, Any], classes: tuple[ElementClass, ...], d: Design, rank: int, refine: bool) -> Topology:
    spec = problem.synthesis
    if spec is None:  # synthesise() checked it
        raise ValueError("a problem without [synthesis]")
    labels = _labels(classes, d)
    name, title = _name(problem, rank), _title(problem, rank, labels)
    elements = list(d.elements)
    free_ends: list[int | None] = [e.free if e.free >= 0 else None for e in elements]
    fixed = topology_data(raw, problem, spec, classes, elements, FIXED, name, title, free_ends)
    header = _header(problem, labels, FIXED)
    fixed_text = toml_text(fixed.data, header)
    label = f"{Path(problem.path).parent / name}.toml"
    result = _solve(fixed_text, label)
    chosen = (fixed, fixed_text, result, FIXED)
    note = "the grid's design"
    objective_depends = any(classes[e.cls].kind == MASS for e in elements) or problem.objective.stiffness_weight > 0
    convex = any(r.convex for e in elements for r in classes[e.cls].regions)
    if refine and objective_depends and convex:
        free_data = topology_data(raw, problem, spec, classes, _values(result, fixed, elements), FREE, name, title, free_ends)
        free_text = toml_text(free_data.data, _header(problem, labels, FREE))
        refined = _solve(free_text, label)
        if refined.status is Status.OPTIMAL and (result.status is not Status.OPTIMAL or refined.solution.objective <= result.solution.objective * (1 + REFINE_TOLERANCE) + 1e-15):
            gain = result.solution.objective - refined.solution.objective
            note = f"refined: the points freed in their regions (objective {refined.solution.objective:.6g} kg, {gain:.3g} kg below the grid's)"
            chosen = (free_data, free_text, refined, FREE)
        elif refined.status is Status.OPTIMAL:
            note = f"the grid's design (the refinement's design is not lighter: objective {refined.solution.objective:.6g} kg)"
        else:
            note = f"the grid's design (the refinement ended {refined.status.value}: {refined.message})"
    elif refine:
        note = "the grid's design (nothing to refine: the objective does not depend on the points)" if convex else "the grid's design (every point is a hole)"
    written, text, final, form = chosen
    return Topology(rank, name, labels, d, final, written, text, form, note)


def _values(result: DesignResult, written: Written, elements: list[Element]) -> list[Element]:
    """The elements with the engine's rates and masses (the grid's points)."""
    if result.status is not Status.OPTIMAL:
        return elements
    values = {slot.variable: v for slot, v in result.solution.values.items() if slot.scenario is None}
    return [Element(e.cls, float(values.get(name, e.magnitude)), e.points, e.free) for e, name in zip(elements, written.magnitudes)]


def _renumbered(problem: Problem, raw: Mapping[str, Any], classes: tuple[ElementClass, ...], t: Topology, rank: int) -> Topology:
    """``t`` as topology ``rank`` (after ranking): its name, title and file."""
    if t.rank == rank:
        return t
    name, title = _name(problem, rank), _title(problem, rank, t.labels)
    data = dict(t.written.data)
    data["problem"] = {**data["problem"], "name": name, "title": title}
    written = Written(data, t.written.magnitudes, t.written.point_variables)
    from dataclasses import replace

    solution = replace(t.result.solution, problem=replace(t.result.solution.problem, name=name, title=title))
    result = replace(t.result, solution=solution)
    return Topology(rank, name, t.labels, t.grid, result, written, toml_text(data, _header(problem, t.labels, t.form)), t.form, t.note)


def _header(problem: Problem, labels: tuple[str, ...], form: str) -> str:
    how = ("the points where the grid design has them; the rates and masses are solved (the LP path)" if form == FIXED
           else "every point of a box or segment written through variables u in [0, 1] (its place in its region), solved with the rates and masses (the NLP)")
    return (f"Synthesised by `counterpoise synthesise {problem.path}` (docs/synthesis.md):\n"
            f"a minimal topology: {', '.join(labels)}.\n{how}.\n`counterpoise solve` on this file designs and verifies it.")


def element_rows(t: Topology, classes: tuple[ElementClass, ...]) -> list[dict[str, Any]]:
    """The grid design's elements of ``t``: class, rate or mass, points (for synthesis.csv)."""
    out = []
    for e in t.grid.elements:
        c = classes[e.cls]
        pts = e.points[0]
        out.append({"kind": c.kind, "name": c.name, "value": e.magnitude, "unit": "N/m" if c.kind == SPRING else "kg",
                    "points_mm": " / ".join("(" + ", ".join(f"{1e3 * v:.6g}" for v in p) + ")" for p in pts)})
    return out
