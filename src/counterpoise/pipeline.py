"""Solve, verify and evaluate a problem: the result a report is written from.

:func:`build_method` builds a problem's design method once, nested by the problem's
content (:mod:`counterpoise.designer.methods`)::

    RealisationMethod      springs: realisation limits, wound rates      (realisation.method)
    PartsMethod            spring slots: a catalogue part per slot      (selection.method)
      PayloadMethod        a payload range: samples, then a schedule     (payload.method)
        MultiStart         starts > 1: seeded random geometries          (designer.methods)
          Plain | Minimax  IPOPT or the LP path | directly attached springs
    RobustMethod           [robust]: robust counterpart (cvxpy), tuning   (robust.method)

Each layer is present only when the problem needs it, and each takes the same options
(``parameters``, ``bounds``, ``initial``), so every option acts on every kind of problem.
:func:`run` solves a method, verifies and judges the design: the one wrapper that makes a
:class:`DesignResult`. :func:`design` is both in one call.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from .designer.designer import Designer
from .designer.methods import DesignMethod, core_method
from .designer.minimax import has_direct_springs, minimax_of
from .designer.quantities import QuantityValue, evaluate_quantities
from .designer.solution import Solution, Verdict
from .formulation.layout import Slot
from .model.problem import Problem
from .solvers.base import Status
from .verify.check import check as check_design
from .designer.checks import Verification
from .payload.result import PayloadDesign
from .robust.result import RobustReport
from .selection.result import PartsReport
from .verify.judge import verdict

if TYPE_CHECKING:
    from .designer.minimax import MinimaxDesigner
    from .payload import OperatorSettings
    from .realisation.asbuilt import AsBuilt
    from .realisation.method import RealisationReport
    from .springs.workspace import DesignedSpring

#: the options :func:`design` passes on to a method's ``solve``
SOLVE_OPTIONS = ("parameters", "bounds", "initial")


@dataclass(frozen=True)
class DesignResult:
    """The outermost method's :class:`Solution`, wrapped with what :func:`run` adds: its
    dense verification, the final verdict, report quantities and designed springs. What
    the solution holds (problem, payload design, parts) is read through it."""

    solution: Solution
    verification: Verification
    #: the final status and message, and who gave them (:func:`counterpoise.verify.judge.verdict`)
    verdict: Verdict
    quantities: tuple[QuantityValue, ...] = ()
    #: free-stiffness springs: the helical spring designed for each (:mod:`counterpoise.springs`)
    springs: "tuple[DesignedSpring, ...]" = ()
    #: the realisation limits of the springs (:mod:`counterpoise.realisation`; None: no springs)
    realisation: "RealisationReport | None" = None
    #: the build sheet's rows (``build.csv``, :mod:`counterpoise.realisation.sheet`; empty: nothing to build)
    sheet: tuple[dict[str, Any], ...] = ()
    #: the balancer rebuilt from the sheet with real springs (:mod:`counterpoise.realisation.asbuilt`)
    as_built: "AsBuilt | None" = None

    @property
    def problem(self) -> Problem:
        return self.solution.problem

    @property
    def status(self) -> Status:
        return self.verdict.status

    @property
    def message(self) -> str:
        return self.verdict.message

    @property
    def payload(self) -> "PayloadDesign | None":
        """Payload problems: the schedule, samples and range."""
        return self.solution.extra(PayloadDesign)

    @property
    def parts(self) -> "PartsReport | None":
        """Problems with spring slots: the chosen catalogue parts."""
        return self.solution.extra(PartsReport)

    @property
    def optimal(self) -> bool:
        return self.status is Status.OPTIMAL


def build_method(problem: Problem, starts: int = 1, backend: str = "auto", designer: "Designer | MinimaxDesigner | None" = None) -> DesignMethod:
    """The design method of ``problem`` (see the module docstring), built once.

    ``starts`` > 1: a seeded multi-start (seed ``settings.seed``) around the innermost
    solve, for every kind of problem. ``backend``: ``auto``, ``ipopt`` or ``clarabel``
    (see :class:`~counterpoise.designer.designer.Designer`). ``designer``: a prebuilt
    designer of ``problem`` for the innermost solve (plain problems without a payload range).
    """
    if starts < 1:
        raise ValueError("starts must be at least 1")
    from . import progress

    # building the balance conditions grows with the scenarios (a tilting base: 3ⁿ of
    # them): a build still running after a few seconds says so (progress.phase)
    scenarios = len(problem.scenarios)
    with progress.phase(f"{problem.name}: building the balance conditions of {scenarios} scenario{'s' if scenarios != 1 else ''}", after=progress.SLOW_PHASE_S):
        inner = _build_method(problem, starts, backend, designer)
        if not problem.springs or problem.settings.ideal_springs:
            return inner
        from .realisation.method import RealisationMethod

        return RealisationMethod(problem, lambda augmented: _build_method(augmented, starts, backend, None), inner)


def _build_method(problem: Problem, starts: int, backend: str, designer: "Designer | MinimaxDesigner | None") -> DesignMethod:
    """Every layer of :func:`build_method` but the realisation layer."""
    direct = has_direct_springs(problem)
    method: DesignMethod
    if problem.payloads:
        from .payload.method import PayloadMethod

        method = PayloadMethod(problem, lambda sampled: core_method(sampled, starts, backend))
    else:
        method = core_method(problem, starts, backend, designer)
    if problem.robust is not None:
        from .robust import RobustMethod

        method = RobustMethod(problem, method)
    if problem.slots:
        from .selection.method import PartsMethod

        method = PartsMethod(problem, method, direct)
    return method


def run(
    method: DesignMethod,
    parameters: Mapping[str, float] | None = None,
    bounds: Mapping["Slot | str", tuple[float, float]] | None = None,
    initial: Mapping[Slot, float] | None = None,
    quantities: bool = True,
    check: str = "dense",
) -> DesignResult:
    """Solve ``method`` with these options, verify the design, judge it and design a helical
    spring for each free-stiffness spring. ``quantities=False``: no report quantities and no
    designed springs (a study, whose rows hold neither). ``check``: ``dense`` (the dense
    check) or ``auto`` (the exact certificate where it applies and proves balance, see
    :func:`counterpoise.verify.check.check`); a design method that verified its own design
    (a payload range, catalogue parts) keeps that."""
    from . import progress

    name = getattr(getattr(method, "problem", None), "name", "")
    what = getattr(method, "phase", "designing")
    with progress.phase(f"{name}: {what}" if name else what):
        solution = method.solve(parameters, bounds, initial)
    if solution.verification is not None:
        verification = solution.verification
    else:
        with progress.phase(f"{solution.problem.name}: verifying on {solution.problem.settings.verify_samples:,} configurations per subsystem and scenario"):
            verification = check_design(solution, check)
    final = verdict(solution, verification)
    values = evaluate_quantities(solution) if quantities else ()
    from .realisation.method import RealisationReport, report_of

    realised = solution.extra(RealisationReport)
    if realised is None and quantities and solution.problem.springs:
        realised = report_of(solution, ideal=solution.problem.settings.ideal_springs)
    springs: tuple[DesignedSpring, ...] = realised.springs if realised is not None and quantities else ()
    sheet: tuple[dict[str, Any], ...] = ()
    as_built = None
    if quantities and (solution.problem.springs or solution.problem.counter_masses):
        from .realisation.asbuilt import check as check_as_built
        from .realisation.sheet import as_written, sheet_rows

        with progress.phase(f"{solution.problem.name}: checking the balancer as built"):
            sheet = tuple(as_written(sheet_rows(solution, springs, solution.extra(PartsReport))))  # the numbers build.csv holds
            as_built = check_as_built(sheet)
        final = judge_as_built(solution, final, as_built)
    return DesignResult(solution, verification, final, values, springs, realised, sheet, as_built)


def judge_as_built(solution: Solution, final: Verdict, as_built: "AsBuilt") -> Verdict:
    """The final verdict with the as-built check: an optimal design whose balancer, rebuilt
    from its build sheet with real springs, misses its tolerance (the verification
    tolerance; a minimax design's ``minimax_tolerance``) is "not balanced" as built. A
    problem whose springs are declared ideal keeps the ideal model's verdict, the as-built
    figure beside it."""
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


def design(problem: Problem, designer: "Designer | MinimaxDesigner | None" = None, starts: int = 1, check: str = "dense", **solve_options: Any) -> DesignResult:
    """Solve ``problem`` (with a prebuilt ``designer`` if given), verify it, evaluate reports.

    ``solve_options``: ``parameters``, ``bounds``, ``initial`` (see :func:`run`); any other
    name is an error. They act on every kind of problem: a payload range is designed over
    its whole range with them, a problem with slots searches its parts with them.
    ``starts`` > 1: a seeded multi-start over the free geometry (seed ``settings.seed``).
    To solve one problem many times, build its method once (:func:`build_method`) and
    call :func:`run`.
    """
    unknown = sorted(set(solve_options) - set(SOLVE_OPTIONS))
    if unknown:
        raise TypeError(f"design() got an unexpected option {unknown[0]!r} (expected {', '.join(SOLVE_OPTIONS)})")
    return run(build_method(problem, starts, designer=designer), check=check, **solve_options)


def operator_settings(problem: Problem, mass: float, method: DesignMethod | None = None) -> "OperatorSettings":
    """What ``counterpoise schedule`` prints: the design of ``problem`` for its range (through
    its design method, so parts and every other layer take part), then its adjustments
    for payload ``mass`` (kg)."""
    from .payload import settings_for

    solution = (method or build_method(problem)).solve()
    return settings_for(problem, mass, solution.extra(PayloadDesign))
