"""The realisation layer's entry in the registry of layers (:mod:`counterpoise.registry`).

A problem with springs (not declared ideal) is designed by
:class:`~.method.RealisationMethod` around every other layer: within the realisation
limits of its springs, for the rates they are wound to. When the design is final
(:meth:`RealisationLayer.finish`), every design with springs or counter-masses gets its
build sheet and is rebuilt from it with real springs (:mod:`.sheet`, :mod:`.asbuilt`): a
design whose balancer misses its tolerance as built is ``not_balanced`` (source
``realisation``, :func:`judge_as_built`). The springs of a paper's idealised design
(``[settings] ideal_springs``) are not enforced: their limits are reported, and the verdict
of the ideal model stands with the as-built figure beside it. The reports add
``springs.csv`` (every spring: catalogue parts and designed springs), ``build.csv``, the
``residual_ratio_as_built`` of ``summary.csv`` and the lines of ``status.txt`` (:mod:`.report`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

from .. import progress
from ..designer.layers import BaseLayer, Result, Row, Table
from ..designer.methods import DesignMethod
from ..designer.minimax import minimax_of
from ..designer.solution import Solution, Verdict
from ..model.problem import Problem
from ..robust.result import RobustReport
from ..selection.result import PartsReport
from ..solvers.base import Status
from .report import SPRINGS_COLUMNS, designed_status, realisation_status, springs_rows
from .result import BuildCheck, RealisationReport

if TYPE_CHECKING:
    from .asbuilt import AsBuilt


class RealisationLayer(BaseLayer):
    name = "realisation"

    def accepts(self, problem: Problem) -> bool:
        return bool(problem.springs) and not problem.settings.ideal_springs

    def wrap(self, problem: Problem, inner: Callable[[Problem], DesignMethod]) -> DesignMethod:
        from .method import RealisationMethod

        return RealisationMethod(problem, inner)  # inner: the other layers, built again for a problem with realisation constraints

    def finish(self, solution: Solution, quantities: bool) -> Solution:
        """The springs' limits (when the layer's method did not measure them: ideal springs),
        the build sheet and the balancer as built, and the verdict as built."""
        problem = solution.problem
        if not quantities:
            return solution
        realised = solution.extra(RealisationReport)
        if realised is None and problem.springs:
            from .method import report_of

            realised = report_of(solution, ideal=problem.settings.ideal_springs)
            solution = solution.with_extra(realised)
        if not (problem.springs or problem.counter_masses):
            return solution
        from .asbuilt import check as check_as_built
        from .sheet import as_written, sheet_rows

        springs = realised.springs if realised is not None else ()
        with progress.phase(f"{problem.name}: checking the balancer as built"):
            sheet = tuple(as_written(sheet_rows(solution, springs, solution.extra(PartsReport))))  # the numbers build.csv holds
            built = BuildCheck(sheet, check_as_built(sheet))
        solution = solution.with_extra(built)
        if realised is not None and solution.verification is not None:  # what a point pulley's radius would cost (status.txt)
            from .radius import radius_notes

            solution = solution.with_extra(replace(realised, notes=(*realised.notes, *radius_notes(solution, solution.verification))))
        final = solution.verdict
        if final is None:  # pragma: no cover - run() judges every design before it is finished
            raise ValueError(f"{problem.name}: a design is finished once it is judged")
        as_built = judge_as_built(solution, final, built.as_built)
        if as_built is final:
            return solution
        if as_built.source == final.source:  # the same verdict with the as-built figure beside it (ideal springs)
            solution = replace(solution, verdicts=solution.verdicts[:-1])
        return solution.settled(as_built)

    def summary_cells(self, result: Result) -> Row:
        built = result.extra(BuildCheck)
        return {"residual_ratio_as_built": built.as_built.residual_ratio if built is not None else None}

    def status_lines(self, result: Result) -> str:
        return designed_status(result)

    def status_notes(self, result: Result) -> str:
        return realisation_status(result)

    def tables(self, result: Result) -> dict[str, Table]:
        from .sheet import COLUMNS, FLOAT_FORMAT

        tables: dict[str, Table] = {}
        report = result.extra(RealisationReport)
        if result.extra(PartsReport) is not None or (report is not None and report.springs):
            tables["springs.csv"] = Table(springs_rows(result), SPRINGS_COLUMNS)
        built = result.extra(BuildCheck)
        if built is not None and built.sheet:
            tables["build.csv"] = Table(list(built.sheet), COLUMNS, FLOAT_FORMAT)
        return tables


def judge_as_built(solution: Solution, final: Verdict, as_built: AsBuilt) -> Verdict:
    """The final verdict with the as-built check: an optimal design whose balancer, rebuilt
    from its build sheet with real springs, misses its tolerance (the verification
    tolerance; a minimax design's ``minimax_tolerance``; a robust design's worst case over
    its tolerances) is "not balanced" as built. A problem whose springs are declared ideal
    keeps the ideal model's verdict, the as-built figure beside it."""
    problem = solution.problem
    ratio = as_built.residual_ratio
    if problem.settings.ideal_springs:
        figure = f"{ratio:.3g}" if math.isfinite(ratio) else "not known (" + "; ".join(as_built.notes) + ")"
        return replace(final, message=f"{final.message}; IDEAL SPRINGS (a paper's idealised design): as built, the residual ratio is {figure}")
    if final.status is not Status.OPTIMAL:
        return final
    tolerance = problem.settings.minimax_tolerance if minimax_of(solution) is not None else problem.settings.verify_tolerance
    robust = solution.extra(RobustReport)
    if robust is not None:  # a robust design answers for its hardware with its worst case over the tolerances
        tolerance = max([tolerance, *(v for band in robust.bands.values() for v in band.values() if math.isfinite(v))])
    if math.isfinite(ratio) and ratio <= tolerance * (1 + 1e-9):
        return final
    why = "; ".join(as_built.notes) if as_built.notes else f"residual ratio {ratio:.3g} > {tolerance:.3g}"
    slack = ", ".join(f"{name} slack on {100 * share:.3g} % of the workspace" for name, share in as_built.slack.items() if share > 0)
    message = f"not balanced as built (rebuilt from build.csv with real springs): {why}" + (f"; {slack}" if slack else "")
    return Verdict(Status.NOT_BALANCED, message, "realisation")


LAYER = RealisationLayer()
