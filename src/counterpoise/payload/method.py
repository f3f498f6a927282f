"""The payload-range design method: an inner method solved on sampled payloads, then a schedule.

:class:`PayloadMethod` wraps the method of each sampled problem (one scenario per working
mode and payload sample, :mod:`.scenarios`) and returns the shared design with its
schedule (:func:`.design.design_payloads`): a new solution with the
:class:`~.result.PayloadDesign` as its extra and whose verdict (source ``payload``) its status and message. Options act
on the whole range: ``parameters`` on every sample and on every schedule payload,
``bounds`` on every sample (adjustments within their travel), ``initial`` on every sample.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from ..designer.methods import DesignMethod
from ..designer.options import SolveOptions
from ..designer.solution import Solution
from ..model.problem import Problem
from .design import design_payloads
from .result import PayloadDesign
from .schedule import Adjusters
from .scenarios import payload_of, sampled_problem


#: a set of payload samples: (scenario name, its parameters sorted), per scenario
SampleKey = tuple[tuple[str, tuple[tuple[str, float], ...]], ...]


class PayloadMethod(DesignMethod):
    """Design for a payload range around ``core(sampled problem)``, built once per sample set."""

    #: what a solve is doing, for the progress line of a slow one (:func:`counterpoise.progress.phase`)
    phase = "designing for the payload range"

    def __init__(self, problem: Problem, core: Callable[[Problem], DesignMethod]) -> None:
        self._problem = problem
        self._core = core
        self._built: dict[SampleKey, DesignMethod] = {}
        #: the schedules' adjustment methods, built once per content (:class:`.schedule.Adjusters`)
        self._adjusters = Adjusters()

    @property
    def problem(self) -> Problem:
        return self._problem

    def core(self, sampled: Problem) -> DesignMethod:
        """The inner method of a sampled problem (built once per set of samples)."""
        key: SampleKey = tuple((s.name, tuple(sorted(s.parameters.items()))) for s in sampled.scenarios)  # the exact masses
        if key not in self._built:
            self._built[key] = self._core(sampled)
        return self._built[key]

    def search_problem_with(self, extra: tuple[float, ...] = ()) -> Problem:
        """What a part search sees: the problem on the range's end points, its nominal and
        the ``extra`` payloads (kg) where a part was found outside its limits."""
        p = payload_of(self.problem)
        return sampled_problem(self.problem, (p.lower, p.nominal, p.upper, *extra)).problem

    def scheduled(self, solution: Solution) -> Solution | None:
        outcome = solution.extra(PayloadDesign)
        return outcome.schedule_solution() if outcome is not None and outcome.schedule is not None else None

    def sample_of(self, solution: Solution, scenario: str) -> float | None:
        outcome = solution.extra(PayloadDesign)
        return outcome.mass_of(scenario) if outcome is not None else None

    def design(self, options: SolveOptions = SolveOptions()) -> PayloadDesign:
        """The design for the range with these options (the :class:`PayloadDesign` itself)."""
        return design_payloads(self.problem, self.core, options.parameters, options.bounds, options.initial, options.certify, self._adjusters)

    def solve_with(self, options: SolveOptions) -> Solution:
        outcome = self.design(options)
        return replace(outcome.solution, verification=outcome.verification).with_extra(outcome).judged(outcome.status, outcome.message, "payload")

    def __repr__(self) -> str:
        return f"PayloadMethod({self.problem.name})"
