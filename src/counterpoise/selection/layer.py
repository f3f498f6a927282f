"""The parts layer's entry in the registry of layers (:mod:`counterpoise.registry`).

A problem with spring slots is designed by :class:`~.method.PartsMethod`: a catalogue part
per slot, then the inner method for it; the design carries its
:class:`~.result.PartsReport`, and the reports add a ``part`` row per slot to
``design.csv``, the parts and the search's lower bound to ``summary.csv``, the search's
account to ``status.txt`` and the tolerance band's ``tolerance.csv`` (:mod:`.report`; the
parts' rows of ``springs.csv`` are written with the designed springs by the realisation
layer). Nothing of the search is imported until a method is built.
"""

from __future__ import annotations

from collections.abc import Callable

from ..designer.layers import BaseLayer, Page, Result, Row, Table
from ..designer.methods import DesignMethod
from ..model.problem import Problem
from .result import PartsReport


class PartsLayer(BaseLayer):
    name = "parts"

    def accepts(self, problem: Problem) -> bool:
        return bool(problem.slots)

    def wrap(self, problem: Problem, inner: Callable[[Problem], DesignMethod]) -> DesignMethod:
        from ..designer.minimax import has_direct_springs
        from .method import PartsMethod

        return PartsMethod(problem, inner(problem), has_direct_springs(problem))

    def summary_cells(self, result: Result) -> Row:
        parts = result.extra(PartsReport)
        if parts is None:
            return {}
        from .report import chosen_parts

        return {"lower_bound_ratio": parts.search.lower_bound_ratio, "parts": chosen_parts(result)}

    # the report's module is imported only for a design that has parts to report
    def design_rows(self, result: Result, rows: list[Row]) -> list[Row]:
        if result.extra(PartsReport) is None:
            return rows
        from .report import part_design_rows

        return rows + part_design_rows(result)

    def status_lines(self, result: Result) -> str:
        if result.extra(PartsReport) is None:
            return ""
        from .report import parts_status

        return parts_status(result)

    def tables(self, result: Result) -> dict[str, Table]:
        if result.extra(PartsReport) is None or result.problem.robust is not None:
            return {}  # with [robust] its tolerance.csv is the worst case over the parts' tolerances
        from .report import TOLERANCE_COLUMNS, tolerance_rows

        caption = "tolerance.csv: the residual ratio with the parts' rates and initial tensions at the ends of their tolerance bands"
        return {"tolerance.csv": Table(tolerance_rows(result), TOLERANCE_COLUMNS, page=Page("tolerance", "Tolerance", caption, order=10))}


LAYER = PartsLayer()
