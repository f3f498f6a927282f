"""The catalogue-part design method: choose a part per slot, then the inner method for it.

:class:`PartsMethod` wraps any inner design method (plain, convex, minimax, multi-start,
or a payload-range design around one of them). Each :meth:`~PartsMethod.solve`:

1. searches the parts (:func:`.parts.choose`, or :func:`.direct.search_direct` for
   directly attached springs) on the problem the inner method exposes as its
   ``search_problem`` (a payload range: its samples, so a part is chosen for the range),
   with the call's parameters and bounds applied;
2. solves the inner method with the parts' parameters;
3. checks every spring against its part's limits in every scenario of the design (a
   payload range: at every payload of its schedule, the inner method's ``scheduled``);
   a payload where a part leaves its limits joins the search's samples and the search
   runs again (at most :data:`REFINEMENTS` times).

It returns a new solution with the :class:`.result.PartsReport` as its extra and whose
verdict (source ``parts``) the status and message.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from ..designer.methods import DesignMethod, SampledMethod
from ..designer.options import BoundsOverride, SolveOptions
from ..designer.solution import Solution
from ..errors import ProblemFileError
from ..formulation.layout import Slot
from ..model.problem import Problem
from ..solvers.base import Status
from ..verify.check import verify
from ..verify.judge import judge
from . import parts
from .direct import part_parameters, search_direct
from .search import SearchModels

if TYPE_CHECKING:
    from ..designer.minimax import MinimaxDesigner

#: searches re-run with a payload added where a part left its limits
REFINEMENTS = 2


def with_options(problem: Problem, parameters: Mapping[str, float] | None, bounds: BoundsOverride | None) -> Problem:
    """``problem`` with these base-parameter values (in every scenario) and variable bounds,
    so that a part search sees the same problem as the solve after it."""
    if not parameters and not bounds:
        return problem
    values = dict(parameters or {})
    given = {(k.variable if isinstance(k, Slot) else k): v for k, v in (bounds or {}).items()}
    params = tuple(replace(p, value=values[p.name]) if p.name in values else p for p in problem.parameters)
    scenarios = tuple(replace(s, parameters={k: v for k, v in s.parameters.items() if k not in values}) for s in problem.scenarios)
    variables = tuple(replace(v, lower=given[v.name][0], upper=given[v.name][1]) if v.name in given else v for v in problem.variables)
    return replace(problem, parameters=params, scenarios=scenarios, variables=variables)


class _Given:
    """A designer seen through the call's parameters and bounds (for :func:`search_direct`)."""

    def __init__(self, designer: MinimaxDesigner, parameters: Mapping[str, float] | None, bounds: BoundsOverride | None) -> None:
        self.designer = designer
        self.parameters = dict(parameters or {})
        self.bounds = bounds

    def __getattr__(self, name: str) -> Any:
        # the screening reads the designer's formulation, reference and samples
        return getattr(self.designer, name)

    def restricted(self, coordinates: Collection[str], springs: Collection[str]) -> _Given:
        """The designer of these rows alone (:meth:`MinimaxDesigner.restricted`), seen the same way."""
        return _Given(self.designer.restricted(coordinates, springs), self.parameters, self.bounds)

    def solve(self, initial: Mapping[Slot, float] | None = None, parameters: Mapping[str, float] | None = None, bounds: BoundsOverride | None = None) -> Solution:
        merged = {**self.parameters, **(parameters or {})}
        return self.designer.solve(initial=initial, parameters=merged, bounds=bounds or self.bounds)


class PartsMethod(DesignMethod):
    """Choose catalogue parts for the slots of ``problem``, then design with ``inner``."""

    #: what a solve is doing, for the progress line of a slow one (:func:`counterpoise.progress.phase`)
    phase = "searching catalogue parts"

    def __init__(self, problem: Problem, inner: DesignMethod, direct: bool) -> None:
        self._problem = problem
        self.inner = inner
        self.direct = direct
        #: the part search's designers, one per searched problem's content (built once per worker)
        self._searches = SearchModels()

    @property
    def problem(self) -> Problem:
        return self._problem

    def _search_problem(self, extra: tuple[float, ...]) -> Problem:
        return self.inner.search_problem_with(extra) if isinstance(self.inner, SampledMethod) else self.problem

    def _method_of(self, problem: Problem) -> Any:
        """The innermost method that designs ``problem`` (a sampled one for a payload range;
        through a robust layer, the ordinary method it wraps)."""
        method: Any = self.inner.core(problem) if isinstance(self.inner, SampledMethod) else self.inner
        while not hasattr(method, "designer") and hasattr(method, "inner"):
            method = method.inner
        return method

    def _designer_of(self, solution: Solution) -> Any:
        return self._method_of(solution.problem).designer

    def solve_with(self, options: SolveOptions) -> Solution:
        given = dict(options.parameters or {})
        bounds = options.bounds
        taken = sorted(set(given) & set(part_parameters(self.problem, {s.name: 0 for s in self.problem.slots})))
        if taken:
            raise ProblemFileError(self.problem.path, "parameters", f"'{taken[0]}' is set by the catalogue part chosen for its slot")
        extra: tuple[float, ...] = ()
        for _ in range(REFINEMENTS + 1):
            searched = self._search_problem(extra)
            start = options.initial
            if self.direct:
                search = search_direct(searched, _Given(self._method_of(searched).designer, given, bounds))  # type: ignore[arg-type]  # _Given answers the designer calls search_direct makes
                rows = dict(search.choice.parts) if search.choice else {s.name: 0 for s in self.problem.slots}
                if start is None and search.choice is not None and len(search.groups) > 1:
                    start = search.choice.values  # the groups' designs, searched one by one, put together
            else:
                # the search designer of ``searched`` is built once (per content) and solved with the call's options
                search, rows, _rates = parts.choose(with_options(searched, given, bounds), self._searches.of(searched, given), given, bounds)  # rows carry the rates
            # a robust layer inside: its corners take the chosen parts' rate tolerances and limits
            for_parts = getattr(self.inner, "for_parts", None)
            inner: DesignMethod = for_parts(rows) if for_parts is not None and search.choice is not None else self.inner
            solution = inner.solve_with(replace(options, parameters={**given, **part_parameters(self.problem, rows)}, initial=start))
            sampled = self.inner if isinstance(self.inner, SampledMethod) else None
            checked = sampled.scheduled(solution) if sampled is not None else None  # a payload range: every payload of its schedule
            chosen = parts.report(solution.problem, self._designer_of(solution), solution, search, rows, checked, given)
            misfit = chosen.first_misfit()
            if sampled is None or misfit is None or search.choice is None or checked is None:
                break
            mass = sampled.sample_of(solution, misfit.scenario)
            if mass is None or mass in extra:
                break
            extra = (*extra, mass)
        verification = solution.verification or verify(solution)
        status, message = judge(solution, verification)
        if search.choice is None:
            near = "; ".join(m.text() for m in search.nearest) or "none could be evaluated"
            status, message = Status.INFEASIBLE, f"{search.message}. Nearest candidates: {near}"
        elif status is Status.OPTIMAL and misfit is not None:
            status = Status.INFEASIBLE
            where = f" at {misfit.scenario}" if misfit.scenario and len(checked.problem.scenarios if checked else solution.problem.scenarios) > 1 else ""
            message = (
                f"part {misfit.part_number} of spring {misfit.spring} leaves its limits on the dense check{where} (margins: slack "
                f"{misfit.margin_slack:.3g} m, length {misfit.margin_length:.3g} m, load {misfit.margin_load:.3g} N)"
            )
        elif status is Status.OPTIMAL:
            picked = ", ".join(f"{s.name}: {s.catalogue.part_number[rows[s.name]]}" for s in self.problem.slots)
            message = f"{message}; parts {picked}"
        return replace(solution, verification=verification).with_extra(chosen).judged(status, message, "parts")

    def __repr__(self) -> str:
        return f"PartsMethod({self.inner!r})"
