"""Solve, verify and evaluate a problem: the result a report is written from.

:func:`build_method` builds a problem's design method once: the core method, wrapped by
every registered layer that the problem needs (:data:`counterpoise.registry.REGISTRY`,
:func:`counterpoise.designer.layers.build_stack`), innermost first::

    RealisationMethod      springs: realisation limits, wound rates      (realisation)
      PartsMethod          spring slots: a catalogue part per slot      (selection)
        RobustMethod       [robust]: robust counterpart (cvxpy), tuning   (robust)
          PayloadMethod    a payload range: samples, then a schedule     (payload)
            MultiStart     starts > 1: seeded random geometries          (designer.methods)
              Plain | Minimax  IPOPT or the LP path | real springs (minimax)

Each layer is present only when the problem needs it, and each takes the same options
(:class:`~counterpoise.designer.options.SolveOptions`: ``parameters``, ``bounds``,
``initial``), so every option acts on every kind of problem. :func:`run` solves a method,
verifies and judges the design and lets every layer finish it: the one wrapper that makes
a :class:`DesignResult`. :func:`design` is both in one call.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, TypeVar

from .designer.checks import Verification
from .designer.layers import build_stack, layers
from .designer.methods import DesignMethod, core_method
from .designer.options import SolveOptions
from .designer.quantities import QuantityValue, evaluate_quantities
from .designer.solution import Solution, Verdict
from .formulation.layout import Slot
from .model.problem import Problem
from .payload.result import PayloadDesign
from .realisation.result import BuildCheck, RealisationReport
from .selection.result import PartsReport
from .solvers.base import Status
from .verify.check import check as check_design
from .verify.judge import verdict

if TYPE_CHECKING:
    from .designer.designer import Designer
    from .designer.minimax import MinimaxDesigner
    from .payload import OperatorSettings
    from .realisation.asbuilt import AsBuilt
    from .springs.workspace import DesignedSpring

#: the options :func:`design` passes on to a method's ``solve``
SOLVE_OPTIONS = ("parameters", "bounds", "initial")

#: the type of an extra (:meth:`DesignResult.extra`)
E = TypeVar("E")


@dataclass(frozen=True)
class DesignResult:
    """A finished design: the outermost method's :class:`Solution`, verified
    (``solution.verification``) and judged (``solution.verdict``, whose status and message
    are the solution's own: one status), with what every layer added to it once final (its
    extras), and the report quantities. Everything else is read through the solution."""

    solution: Solution
    quantities: tuple[QuantityValue, ...] = ()

    def __post_init__(self) -> None:
        if self.solution.verification is None or self.solution.verdict is None:
            raise ValueError(f"{self.solution.problem.name}: a DesignResult holds a verified and judged design (see counterpoise.pipeline.run)")

    @property
    def problem(self) -> Problem:
        return self.solution.problem

    @property
    def verification(self) -> Verification:
        """The design's verification (the dense check, or a layer's own)."""
        verification = self.solution.verification
        if verification is None:  # pragma: no cover - refused by __post_init__
            raise ValueError("not verified")
        return verification

    @property
    def verdict(self) -> Verdict:
        """The final status and message, and who gave them (:func:`counterpoise.verify.judge.verdict`)."""
        final = self.solution.verdict
        if final is None:  # pragma: no cover - refused by __post_init__
            raise ValueError("not judged")
        return final

    @property
    def status(self) -> Status:
        return self.solution.status

    @property
    def message(self) -> str:
        return self.solution.message

    @property
    def optimal(self) -> bool:
        return self.status is Status.OPTIMAL

    def extra(self, kind: type[E]) -> E | None:
        """What a layer found of this design, by its type (:meth:`Solution.extra`)."""
        return self.solution.extra(kind)

    # -- the layers' results as they were read before they were extras (compatibility) ----
    @property
    def payload(self) -> PayloadDesign | None:
        """Payload problems: the schedule, samples and range (``extra(PayloadDesign)``)."""
        return self.extra(PayloadDesign)

    @property
    def parts(self) -> PartsReport | None:
        """Problems with spring slots: the chosen catalogue parts (``extra(PartsReport)``)."""
        return self.extra(PartsReport)

    @property
    def realisation(self) -> RealisationReport | None:
        """The realisation limits of the springs (``extra(RealisationReport)``; None: no springs)."""
        return self.extra(RealisationReport)

    @property
    def springs(self) -> tuple[DesignedSpring, ...]:
        """Free-stiffness springs: the helical spring designed for each (``extra(RealisationReport).springs``)."""
        report = self.extra(RealisationReport)
        return tuple(report.springs) if report is not None else ()

    @property
    def sheet(self) -> tuple[dict[str, Any], ...]:
        """The build sheet's rows (``extra(BuildCheck).sheet``; empty: nothing to build)."""
        built = self.extra(BuildCheck)
        return built.sheet if built is not None else ()

    @property
    def as_built(self) -> AsBuilt | None:
        """The balancer rebuilt from the sheet with real springs (``extra(BuildCheck).as_built``)."""
        built = self.extra(BuildCheck)
        return built.as_built if built is not None else None


def build_method(problem: Problem, starts: int = 1, backend: str = "auto", designer: "Designer | MinimaxDesigner | None" = None) -> DesignMethod:
    """The design method of ``problem`` (see the module docstring), built once.

    ``starts`` > 1: a seeded multi-start (seed ``settings.seed``) around the innermost
    solve, for every kind of problem. ``backend``: ``auto``, ``ipopt`` or ``clarabel``
    (see :class:`~counterpoise.designer.designer.Designer`). ``designer``: a prebuilt
    designer of ``problem`` for the innermost solve (of ``problem`` itself: not of a
    payload range's samples nor of a problem a layer derives).
    """
    if starts < 1:
        raise ValueError("starts must be at least 1")
    from . import progress

    def core(p: Problem) -> DesignMethod:
        return core_method(p, starts, backend, designer if p is problem else None)

    # building the balance conditions grows with the scenarios (a tilting base: 3ⁿ of
    # them): a build still running after a few seconds says so (progress.phase)
    scenarios = len(problem.scenarios)
    with progress.phase(f"{problem.name}: building the balance conditions of {scenarios} scenario{'s' if scenarios != 1 else ''}", after=progress.SLOW_PHASE_S):
        return build_stack(problem, core)


def run(
    method: DesignMethod,
    parameters: Mapping[str, float] | None = None,
    bounds: Mapping["Slot | str", tuple[float, float]] | None = None,
    initial: Mapping[Slot, float] | None = None,
    quantities: bool = True,
    check: str = "dense",
) -> DesignResult:
    """Solve ``method`` with these options, verify the design, judge it and let every layer
    finish it (the springs' build sheet and the balancer as built, :mod:`counterpoise.realisation`).
    ``quantities=False``: no report quantities and nothing built from them (a study, whose
    rows hold neither). ``check``: ``dense`` (the dense check) or ``auto`` (the exact
    certificate where it applies and proves balance, see :func:`counterpoise.verify.check.check`);
    a design method that verified its own design (a payload range, catalogue parts) keeps that."""
    from . import progress

    name = getattr(getattr(method, "problem", None), "name", "")
    what = getattr(method, "phase", "designing")
    with progress.phase(f"{name}: {what}" if name else what):
        solution = method.solve_with(SolveOptions(parameters, bounds, initial))
    verification = solution.verification
    if verification is None:
        with progress.phase(f"{solution.problem.name}: verifying on {solution.problem.settings.verify_samples:,} configurations per subsystem and scenario"):
            verification = check_design(solution, check)
        solution = replace(solution, verification=verification)
    values = evaluate_quantities(solution) if quantities else ()
    solution = solution.settled(verdict(solution, verification))
    for layer in layers():
        solution = layer.finish(solution, quantities)
    return DesignResult(solution, values)


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
