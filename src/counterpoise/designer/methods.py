"""Design methods: one interface, built once per problem, nested by the problem's content.

A design method answers ``solve(parameters=None, bounds=None, initial=None) -> Solution``
(SI values; ``bounds`` maps a variable name or a :class:`Slot` to (lower, upper);
``initial`` maps slots to start values), and may be called many times: whatever it builds
(solvers, samples) is built once. Each method implements ``solve_with(options)`` with one
:class:`SolveOptions`; :class:`DesignMethod` writes ``solve`` once for all. The innermost
methods live here:

- :class:`Plain`: the :class:`~counterpoise.designer.designer.Designer` (IPOPT, or the LP
  path through Clarabel when every variable enters linearly);
- :class:`Minimax`: the :class:`~counterpoise.designer.minimax.MinimaxDesigner`
  (directly attached springs: smallest worst residual on sampled configurations);
- :class:`MultiStart`: seeded random starts of the free geometry around either of them.

Outer methods wrap an inner one and live in the layer that owns their job:
:class:`counterpoise.payload.method.PayloadMethod` (a payload range) and
:class:`counterpoise.selection.method.PartsMethod` (catalogue parts).
:func:`counterpoise.pipeline.build_method` nests them; :func:`counterpoise.pipeline.run`
verifies and judges what the outermost returns. Compare cvxpy's solving chain (each
reduction wraps the next) and rockit's method objects (a method attached to a problem).
"""

from __future__ import annotations

import abc
from dataclasses import replace
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from ..formulation.formulation import Formulation
from ..formulation.layout import Slot
from ..model.problem import Problem
from ..solvers.base import Status
from .options import BoundsOverride, Initial, Parameters, SolveOptions
from .solution import Solution

if TYPE_CHECKING:
    from .designer import Designer
    from .minimax import MinimaxDesigner

#: two objectives agree (multi-start) when within this relative distance
SAME_OBJECTIVE = 1e-7



class DesignMethod(abc.ABC):
    """A way to design one problem; built once, solved many times.

    A method implements :meth:`solve_with` (one :class:`SolveOptions`); :meth:`solve`, the
    keyword form of the public API, is written here once for all of them."""

    @property
    @abc.abstractmethod
    def problem(self) -> Problem:
        """The problem whose design :meth:`solve` returns (an outer method may solve a
        derived one). Read-only: the innermost methods answer their designer's."""

    @abc.abstractmethod
    def solve_with(self, options: SolveOptions) -> Solution:
        """The design for these options (a new :class:`Solution`; the method's inner
        solutions are left as they were)."""

    def solve(
        self, parameters: Parameters | None = None, bounds: BoundsOverride | None = None, initial: Initial | None = None, *, certify: bool = True
    ) -> Solution:
        """Design with these base parameters, bounds and initial values (see :class:`SolveOptions`)."""
        return self.solve_with(SolveOptions(parameters, bounds, initial, certify))


@runtime_checkable
class SampledMethod(Protocol):
    """A method that designs a derived, sampled problem (a payload range: one scenario per
    payload sample): what an outer part search must search on, and the inner method of each
    sampled problem. :class:`counterpoise.payload.method.PayloadMethod` is one."""

    @property
    def problem(self) -> Problem:
        """The problem as given (before sampling)."""
        ...

    def search_problem_with(self, extra: tuple[float, ...] = ()) -> Problem:
        """The sampled problem a part search sees, with ``extra`` samples (SI) added."""
        ...

    def core(self, sampled: Problem) -> DesignMethod:
        """The inner method of a sampled problem (built once per set of samples)."""
        ...

    def scheduled(self, solution: Solution) -> Solution | None:
        """``solution`` (one this method returned) on every sample its schedule covers, each
        with its own adjustments: what a check that must hold over the whole range (a
        part's limits) runs on; None when it has no schedule."""
        ...

    def sample_of(self, solution: Solution, scenario: str) -> float | None:
        """The sample (a payload mass, SI) of a scenario of ``solution`` or of :meth:`scheduled`."""
        ...


class Core(DesignMethod):
    """Shared by the innermost methods: a designer with a formulation."""

    designer: Designer | MinimaxDesigner

    @property
    def problem(self) -> Problem:
        return self.designer.problem

    @property
    def formulation(self) -> Formulation:
        return self.designer.formulation

    def certify(self, solution: Solution, options: SolveOptions = SolveOptions()) -> Solution:
        """``solution`` (solved with ``certify=False`` and these options) as a solve with
        ``certify=True`` would have returned it: a new value."""
        return solution

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.problem.name})"


class Plain(Core):
    """Balance conditions solved by IPOPT, or as an LP by Clarabel (see :class:`Designer`)."""

    designer: Designer

    def __init__(self, designer: Designer) -> None:
        self.designer = designer

    def solve_with(self, options: SolveOptions) -> Solution:
        # the designer's keyword form: an object with the designer's solve() may stand for it (a study's)
        return self.designer.solve(initial=options.initial, parameters=options.parameters, bounds=options.bounds, certify=options.certify)

    def certify(self, solution: Solution, options: SolveOptions = SolveOptions()) -> Solution:
        return self.designer.certify(solution, options.parameters, options.bounds)


class Minimax(Core):
    """The smallest worst residual on sampled configurations (directly attached springs)."""

    designer: MinimaxDesigner

    def __init__(self, designer: MinimaxDesigner) -> None:
        self.designer = designer

    def solve_with(self, options: SolveOptions) -> Solution:
        return self.designer.solve(initial=options.initial, parameters=options.parameters, bounds=options.bounds)


class MultiStart(Core):
    """``starts`` solves of ``inner``: from the given initial design, then from seeded random
    geometries; the best optimal design wins.

    Only the variables that move a point are drawn (uniformly in their bounds, the call's
    ``bounds`` included); the others keep their initial values (they enter linearly). The
    best optimal solution is returned (the best of all when none is optimal), with
    ``stats.starts = (reached, run)``: how many starts ended within :data:`SAME_OBJECTIVE`
    (relative) of the best objective. Seeded: the same starts on every call.
    """

    def __init__(self, inner: Plain | Minimax, starts: int, seed: int) -> None:
        if starts < 1:
            raise ValueError("starts must be at least 1")
        self.inner = inner
        self.designer = inner.designer
        self.starts = starts
        self.seed = seed

    def solve_with(self, options: SolveOptions) -> Solution:
        from .convex import geometric_variables

        d = self.formulation.design
        if options.bounds:
            lbz, ubz = d.bounds(options.bounds)
            lower, upper = lbz * d.scale, ubz * d.scale
        else:
            lower, upper = d.lower, d.upper
        rng = np.random.default_rng(self.seed)
        geometric = geometric_variables(self.problem)
        draw = [slot for slot in d.slots if slot.variable in geometric] or list(d.slots)
        solutions = []
        for k in range(self.starts):
            guess = dict(options.initial or {})
            if k:
                for slot in draw:
                    i = d.index[slot]
                    guess[slot] = float(lower[i] + (upper[i] - lower[i]) * rng.random())
            solutions.append(self.inner.solve_with(replace(options, initial=guess, certify=False)))
        optimal = [s for s in solutions if s.status is Status.OPTIMAL] or solutions
        best = min(optimal, key=lambda s: s.objective if np.isfinite(s.objective) else np.inf)
        scale = SAME_OBJECTIVE * max(1.0, abs(best.objective))
        reached = sum(1 for s in optimal if s.status is best.status and abs(s.objective - best.objective) <= scale)
        if options.certify:
            best = self.inner.certify(best, options)
        return replace(best, stats=replace(best.stats, starts=(reached, self.starts), solve_time=sum(s.stats.solve_time for s in solutions)))

    def certify(self, solution: Solution, options: SolveOptions = SolveOptions()) -> Solution:
        return self.inner.certify(solution, options)


def core_method(problem: Problem, starts: int = 1, backend: str = "auto", designer: Designer | MinimaxDesigner | None = None) -> Plain | Minimax | MultiStart:
    """The innermost method of ``problem``: minimax when a spring is attached directly, else
    the designer (IPOPT or LP); wrapped in :class:`MultiStart` when ``starts`` > 1.
    ``designer``: a prebuilt designer of ``problem`` to use (it must be of the right kind)."""
    from .designer import Designer
    from .minimax import MinimaxDesigner, needs_minimax

    inner: Plain | Minimax
    if needs_minimax(problem):
        if backend not in ("auto", "ipopt"):
            raise ValueError(f"backend {backend!r}: real springs (directly attached, or over pulleys of radius > 0) are designed by IPOPT (minimax)")
        inner = Minimax(designer if designer is not None and not isinstance(designer, Designer) else MinimaxDesigner(problem))
    else:
        # an object with the designer's solve() is used as given (a study may wrap one)
        inner = Plain(designer if designer is not None and not isinstance(designer, MinimaxDesigner) else Designer(problem, backend=backend))
    return MultiStart(inner, starts, problem.settings.seed) if starts > 1 else inner
