"""Design layers as extensions of the core designer: the :class:`Layer` protocol, what a
layer's report hooks read (:class:`Result`) and give (rows, :class:`Table`), and
:func:`layers`, the registered layers (:data:`counterpoise.registry.REGISTRY`).

A layer is a package that wraps the core design method when a problem needs it and reports
what it found, with its own result type attached to the design as an extra
(:meth:`counterpoise.designer.solution.Solution.extra`). Compare cvxpy's reductions
(``accepts``, ``apply``, ``invert``): :meth:`Layer.accepts` says whether a problem needs the
layer, :meth:`Layer.wrap` builds its design method around the inner one, and the report
hooks read the finished design. Everything that loops over the layers (building a design
method, the verdict sources, the report files) loops over :func:`layers`, so a new layer is
its package and one line of the registry.

Each hook has a default in :class:`BaseLayer` (nothing to add); a layer overrides what it
needs. The hooks run for every design, whether or not the layer wrapped its method (the
springs of a paper's idealised design are reported though not enforced), and answer
nothing when the design holds nothing of theirs.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Protocol, TypeVar

from ..model.problem import Problem
from .. import registry
from ..solvers.base import Status
from .checks import Verification
from .methods import DesignMethod
from .solution import Solution

#: one row of a report file: column -> value (a missing value is None or NaN)
Row = dict[str, Any]

#: the type of an extra (:meth:`Result.extra`)
E = TypeVar("E")


@dataclass(frozen=True)
class Page:
    """How ``report.html`` shows a layer's file: a section ``title`` (its link ``anchor``)
    after the verification, in ``order`` among the layers' sections; the file's text as a
    table with ``caption``, or made into HTML by ``render`` (text -> HTML)."""

    anchor: str
    title: str
    caption: str = ""
    render: Callable[[str], str] | None = None
    order: int = 0


@dataclass(frozen=True)
class Table:
    """A CSV file a layer writes beside the design's reports: its rows, its columns, the
    ``printf`` format of its floats (None: the reports' own, 10 significant digits) and its
    section of ``report.html`` (None: written, not shown there)."""

    rows: Sequence[Row]
    columns: Sequence[str]
    float_format: str | None = None
    page: Page | None = None


class Result(Protocol):
    """What a layer's report hooks read of a finished design (the design, its problem, its
    verification and final verdict, the extras the layers attached);
    :class:`counterpoise.pipeline.DesignResult` is one."""

    @property
    def solution(self) -> Solution: ...

    @property
    def problem(self) -> Problem: ...

    @property
    def verification(self) -> Verification: ...

    @property
    def status(self) -> Status: ...

    @property
    def message(self) -> str: ...

    def extra(self, kind: type[E]) -> E | None: ...


class Layer(Protocol):
    """A design layer: how it wraps a design method, what it adds when a design is
    finished, and what it reports (see the module docstring)."""

    @property
    def name(self) -> str:
        """Its registry name: the ``source`` of its verdicts."""
        ...

    def accepts(self, problem: Problem) -> bool:
        """Whether ``problem`` needs this layer's design method."""
        ...

    def wrap(self, problem: Problem, inner: Callable[[Problem], DesignMethod]) -> DesignMethod:
        """This layer's design method for ``problem``; ``inner(p)`` builds the method of the
        layers inside this one for a problem ``p`` (``problem`` itself, a sampled one, one
        with added constraints), when the layer asks for it."""
        ...

    def finish(self, solution: Solution, quantities: bool) -> Solution:
        """The verified, judged design with what this layer adds once the design is final
        (a new value; ``solution`` itself when nothing). ``quantities``: False for a
        study's point, which reports neither quantities nor what is built from them."""
        ...

    def summary_cells(self, result: Result) -> Row:
        """This layer's cells of ``summary.csv`` (columns the summary does not list go last)."""
        ...

    def design_rows(self, result: Result, rows: list[Row]) -> list[Row]:
        """``design.csv``'s rows with this layer's: ``rows`` are those of the core and the
        layers inside this one; a layer adds rows, or marks the core's (a new list)."""
        ...

    def status_lines(self, result: Result) -> str:
        """``status.txt``'s lines on what this layer chose, after the design's own and before
        the problem's warnings (each ending in a newline)."""
        ...

    def status_notes(self, result: Result) -> str:
        """``status.txt``'s lines after the problem's warnings (each ending in a newline)."""
        ...

    def tables(self, result: Result) -> dict[str, Table]:
        """The files this layer writes (file name -> table); no two layers write one name."""
        ...


class BaseLayer:
    """A layer's defaults: no method of its own, nothing to add, nothing to report."""

    name = ""

    def accepts(self, problem: Problem) -> bool:
        return False

    def wrap(self, problem: Problem, inner: Callable[[Problem], DesignMethod]) -> DesignMethod:
        return inner(problem)

    def finish(self, solution: Solution, quantities: bool) -> Solution:
        return solution

    def summary_cells(self, result: Result) -> Row:
        return {}

    def design_rows(self, result: Result, rows: list[Row]) -> list[Row]:
        return rows

    def status_lines(self, result: Result) -> str:
        return ""

    def status_notes(self, result: Result) -> str:
        return ""

    def tables(self, result: Result) -> dict[str, Table]:
        return {}


@lru_cache(maxsize=None)
def layers() -> tuple[Layer, ...]:
    """The registered layers, innermost first: each entry's module imported (once) and its
    ``LAYER`` taken. A layer module imports only what its hooks read (its result records);
    its design method is imported when :meth:`Layer.wrap` builds one."""
    out: list[Layer] = []
    for entry in registry.REGISTRY:
        layer = importlib.import_module(entry.module).LAYER
        if layer.name != entry.name:
            raise ValueError(f"{entry.module}: its LAYER is named {layer.name!r}, the registry says {entry.name!r}")
        out.append(layer)
    return tuple(out)


def build_stack(problem: Problem, core: Callable[[Problem], DesignMethod], stack: Sequence[Layer] | None = None) -> DesignMethod:
    """The design method of ``problem``: ``core(problem)`` wrapped by every layer of
    ``stack`` (innermost first; default :func:`layers`) that accepts it. A layer's ``inner``
    builds the same stack, up to that layer, for another problem."""
    stack = tuple(layers() if stack is None else stack)

    def upto(k: int) -> Callable[[Problem], DesignMethod]:
        def build(p: Problem) -> DesignMethod:
            for i in range(k - 1, -1, -1):
                if stack[i].accepts(p):
                    return stack[i].wrap(p, upto(i))
            return core(p)

        return build

    return upto(len(stack))(problem)
