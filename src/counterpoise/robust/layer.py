"""The robust layer's entry in the registry of layers (:mod:`counterpoise.registry`).

A problem with a ``[robust]`` table is designed by :class:`~.method.RobustMethod` around its
ordinary method; the design carries its :class:`~.result.RobustReport`, and the reports add
the counterpart's design rows, ``tolerance.csv``, the tuning's ``tuning_corners.csv`` and
``tuning.csv``, and the robust lines of ``status.txt`` (:mod:`.report`). Nothing of the
counterpart (cvxpy, the minimax NLP) is imported until a method is built.
"""

from __future__ import annotations

from collections.abc import Callable

from ..designer.layers import BaseLayer, Page, Result, Row, Table
from ..designer.methods import DesignMethod
from ..model.problem import Problem
from .result import RobustReport


class RobustLayer(BaseLayer):
    name = "robust"

    def accepts(self, problem: Problem) -> bool:
        return problem.robust is not None

    def wrap(self, problem: Problem, inner: Callable[[Problem], DesignMethod]) -> DesignMethod:
        from .method import RobustMethod

        return RobustMethod(problem, inner(problem))

    # the report's module is imported only for a design that has something to report
    def design_rows(self, result: Result, rows: list[Row]) -> list[Row]:
        if result.extra(RobustReport) is None:
            return rows
        from . import report

        return rows + report.design_rows(result)

    def status_notes(self, result: Result) -> str:
        if result.extra(RobustReport) is None:
            return ""
        from . import report

        return report.status_lines(result) + report.law_status_lines(result)

    def tables(self, result: Result) -> dict[str, Table]:
        if result.extra(RobustReport) is None:
            return {}
        from . import report

        tables = {"tolerance.csv": Table(report.tolerance_rows(result), report.TOLERANCE_COLUMNS, page=Page("tolerance", "Tolerance", report.TOLERANCE_CAPTION, order=10))}
        if result.problem.robust is not None and result.problem.robust.tune:
            tables["tuning_corners.csv"] = Table(report.tuning_rows(result), report.tuning_columns(result))
            procedure = report.procedure_rows(result)
            if procedure:
                tables["tuning.csv"] = Table(procedure, report.PROCEDURE_COLUMNS, page=Page("tuning", "Tuning procedure", render=report.procedure_html, order=11))
        return tables


LAYER = RobustLayer()
