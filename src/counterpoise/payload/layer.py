"""The payload layer's entry in the registry of layers (:mod:`counterpoise.registry`).

A problem with a ``[payloads]`` range is designed over its samples, then scheduled
(:class:`~.method.PayloadMethod`); the design carries its :class:`~.result.PayloadDesign`,
and the reports add ``schedule.csv`` and the range's lines of ``status.txt``
(:mod:`.report`). An adjustment pinned to its nominal at the nominal payload is not on an
active bound in ``design.csv``.
"""

from __future__ import annotations

from collections.abc import Callable

from ..designer.layers import BaseLayer, Page, Result, Row, Table
from ..designer.methods import DesignMethod
from ..formulation.layout import Slot
from ..model.problem import Problem
from .result import PayloadDesign


class PayloadLayer(BaseLayer):
    name = "payload"

    def accepts(self, problem: Problem) -> bool:
        return bool(problem.payloads)

    def wrap(self, problem: Problem, inner: Callable[[Problem], DesignMethod]) -> DesignMethod:
        from .method import PayloadMethod

        return PayloadMethod(problem, inner)  # the inner method of each sampled problem

    def design_rows(self, result: Result, rows: list[Row]) -> list[Row]:
        outcome = result.extra(PayloadDesign)
        if outcome is None:
            return rows
        # an adjustment fixed to its nominal at the nominal payload is not on an active bound
        return [{**row, "active_bound": ""} if row["kind"] == "variable" and outcome.pinned(Slot(row["name"], row["scenario"] or None)) else row for row in rows]

    def status_notes(self, result: Result) -> str:
        if result.extra(PayloadDesign) is None:
            return ""
        from .report import payload_status_lines

        return payload_status_lines(result)

    def tables(self, result: Result) -> dict[str, Table]:
        outcome = result.extra(PayloadDesign)
        if outcome is None or outcome.schedule is None:
            return {}
        from .report import schedule_columns, schedule_rows

        page = Page("schedule", "Payload schedule", "schedule.csv: the adjustments per payload", order=20)
        return {"schedule.csv": Table(schedule_rows(result), schedule_columns(result), page=page)}


LAYER = PayloadLayer()
