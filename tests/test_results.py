"""Typed, immutable results per layer (issue 19, part 3).

Every design layer (designer certificate, multi-start, payload range, catalogue parts,
robust counterpart) returns a new :class:`Solution` and leaves the one its inner method
returned as it was; a layer whose word goes beyond the dense check adds a
:class:`Verdict` naming itself, and the final verdict (``DesignResult.verdict``, what
:func:`judge` returns) is what that layer said.

Each layer's inner method is wrapped in a :class:`Spy` that records every solution it
returns with a snapshot of its fields; after the outer solve every recorded solution must
still equal its snapshot, and the outer result must be none of them.
"""

from __future__ import annotations

import dataclasses
import math

import pytest

from builders import pendulum as plain_pendulum
from counterpoise.designer.methods import MultiStart, Plain, SolveOptions
from counterpoise.designer.solution import VERDICT_SOURCES, Solution, Verdict
from counterpoise.io.loader import load_problem
from counterpoise.pipeline import DesignResult, build_method, run
from counterpoise.solvers.base import Status
from counterpoise.verify.judge import judge, verdict
from counterpoise.robust.result import RobustReport
from counterpoise.selection.result import PartsReport


def _snapshot(solution: Solution) -> dict[str, object]:
    """Every field, with the values dict and scenario parameters copied (they are mutable)."""
    fields = {f.name: getattr(solution, f.name) for f in dataclasses.fields(solution)}
    fields["values"] = dict(solution.values)
    fields["scenario_parameters"] = {k: (g, dict(p)) for k, (g, p) in solution.scenario_parameters.items()}
    return fields


def _same(a: object, b: object) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a is b or a == b


class Spy:
    """An inner design method whose returned solutions are recorded (with a snapshot)."""

    def __init__(self, inner: object) -> None:
        self.inner = inner
        self.returned: list[tuple[Solution, dict[str, object]]] = []

    @classmethod
    def on(cls, method: object) -> "Spy":
        """Put a spy between ``method`` and its inner method."""
        spy = cls(method.inner)  # type: ignore[attr-defined]  # every wrapping layer has .inner
        method.inner = spy  # type: ignore[attr-defined]
        return spy

    def __getattr__(self, name: str) -> object:
        return getattr(self.inner, name)

    def solve_with(self, options: object) -> Solution:
        solution = self.inner.solve_with(options)
        self.returned.append((solution, _snapshot(solution)))
        return solution

    def solve(self, *args: object, **kwargs: object) -> Solution:
        return self.solve_with(SolveOptions(*args, **kwargs))

    def check_untouched(self, outer: Solution) -> None:
        assert self.returned, "the inner method was not called"
        for solution, before in self.returned:
            assert solution is not outer, "the layer returned its inner solution instead of a new one"
            now = _snapshot(solution)
            changed = [name for name in before if not _same(before[name], now[name])]
            assert not changed, f"the layer changed its inner solution: {changed}"


def _run_spied(problem: object, layer: str) -> tuple[DesignResult, Spy]:
    """``problem``'s design method (of type ``layer``) run with a spy on its inner method;
    the design is optimal and the layer left every inner solution as it was returned."""
    method = build_method(problem)
    if layer != "RealisationMethod" and type(method).__name__ == "RealisationMethod":
        method = method.inner  # the layers inside the realisation layer (its own: tests/test_realisation.py)
    assert type(method).__name__ == layer
    spy = Spy.on(method)
    result = run(method)
    assert result.optimal, result.message
    spy.check_untouched(result.solution)
    return result, spy


def _mutation_raises(solution: Solution) -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        solution.status = Status.FAILED
    with pytest.raises(dataclasses.FrozenInstanceError):
        solution.message = "changed"


# -- the innermost layer and multi-start ---------------------------------------------
def test_plain_design_is_frozen_and_judged_by_the_dense_check():
    """A plain pendulum: no layer judges it, so the verdict's source is the dense check."""
    method = build_method(plain_pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build())
    assert isinstance(method, Plain)
    result = run(method)
    assert result.optimal, result.message
    _mutation_raises(result.solution)
    # the dense check's verdict is the only one; the finished design has one status: the verdict's
    assert [v.source for v in result.solution.verdicts] == ["check"] and result.verdict is result.solution.verdict
    assert (result.solution.status, result.solution.message) == (result.status, result.message)
    assert (result.status, result.message) == judge(result.solution, result.verification)
    # DesignResult wraps the solution: what it holds is read through it, not copied
    assert result.problem is result.solution.problem
    assert result.payload is None and result.parts is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.verdict = Verdict(Status.FAILED, "x", "check")


def test_designer_certify_returns_a_new_solution():
    """``Designer.certify`` (what multi-start calls on its best start) sets the certificate
    gap on a new value; the solution given keeps its NaN (no gap computed yet)."""
    method = build_method(plain_pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build())
    assert isinstance(method, Plain)
    raw = method.solve(certify=False)
    before = _snapshot(raw)
    certified = method.certify(raw)
    assert certified is not raw
    assert math.isnan(raw.stats.certificate_gap)
    assert all(_same(before[name], value) for name, value in _snapshot(raw).items())
    assert not math.isnan(certified.stats.certificate_gap)


def test_multi_start_returns_a_new_solution_and_leaves_its_starts_alone():
    method = build_method(plain_pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build(), starts=3)
    assert isinstance(method, MultiStart)
    spy = Spy.on(method)
    best = method.solve()
    spy.check_untouched(best)
    assert len(spy.returned) == 3
    assert best.stats.starts[1] == 3
    assert all(s.stats.starts == (1, 1) for s, _ in spy.returned)  # each start's own value untouched
    assert best.stats.solve_time == pytest.approx(sum(s.stats.solve_time for s, _ in spy.returned))
    _mutation_raises(best)


# -- payload range ---------------------------------------------------------------------
def test_payload_layer_wraps_the_sample_design_and_its_verdict_is_the_schedules():
    from test_methods import payload_pendulum

    method = build_method(payload_pendulum())
    assert type(method).__name__ == "PayloadMethod"
    spies: list[Spy] = []
    build = method._core

    def spied(sampled):
        spies.append(Spy(build(sampled)))
        return spies[-1]

    method._core = spied
    result = run(method)
    assert result.optimal, result.message
    for spy in spies:
        spy.check_untouched(result.solution)
    assert result.verdict.source == "payload"
    outcome = result.payload
    assert outcome is not None
    assert (result.status, result.message) == (outcome.status, outcome.message)  # what the layer said
    assert result.verdict is result.solution.verdict
    assert outcome.solution.verdict is None  # the sample design itself carries no verdict
    _mutation_raises(result.solution)


# -- catalogue parts -------------------------------------------------------------------
def test_parts_layer_wraps_its_inner_design_and_its_verdict_names_the_part(tmp_path):
    """The catalogue pendulum of test_catalogue: one part GOOD (k = 200 N/m, b = 0.1 m) and
    m g r = 2 N·m, balanced by h = 2 / (200 · 0.1) = 0.1 m."""
    from test_catalogue import pendulum

    problem = pendulum(tmp_path, ["GOOD,200,0.05,1,50,0.3,0.01,0.001,x"], 2.0 / (9.81 * 0.2))
    result, spy = _run_spied(problem, "PartsMethod")
    assert result.verdict.source == "parts"
    assert "; parts " in result.message and result.message.endswith(": GOOD")  # the layer's own line
    assert result.parts is not None and result.parts is result.solution.extra(PartsReport)
    assert all(s.extra(PartsReport) is None for s, _ in spy.returned)  # the inner design knows no parts
    _mutation_raises(result.solution)


# -- robust ----------------------------------------------------------------------------
def test_robust_layer_wraps_the_nominal_design_and_its_verdict_is_the_counterparts(tmp_path):
    """The robust pendulum of test_robust, ``limit`` mode: the counterpart (not the dense
    check of the nominal) gives the verdict; the nominal design is left as the inner
    method returned it (no robust report, no verdict)."""
    from test_robust import _pendulum

    problem = load_problem(_pendulum(tmp_path, "limit", 'mode = "limit"\nlimit = 0.04\ntolerances.rate = "10 %"'))
    result, spy = _run_spied(problem, "RobustMethod")
    assert result.verdict.source == "robust"
    assert result.solution.extra(RobustReport) is not None
    assert all(s.extra(RobustReport) is None and s.verdict is None for s, _ in spy.returned)
    assert "worst-case residual ratio" in result.message


# -- the judge -------------------------------------------------------------------------
def test_judge_takes_the_outermost_layers_verdict_as_it_stands():
    method = build_method(plain_pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build())
    result = run(method)
    inner = method.solve()  # as the method returned it: no verdict yet
    said = inner.judged(Status.INFEASIBLE, "inner layer", "payload").judged(Status.FAILED, "outer layer", "parts")
    assert [v.source for v in said.verdicts] == ["payload", "parts"]  # innermost first
    assert judge(said, result.verification) == (Status.FAILED, "outer layer")
    assert verdict(said, result.verification) is said.verdicts[-1]
    assert inner.verdicts == ()  # judged() left the solution it was called on alone
    assert said.status is Status.OPTIMAL  # a layer's verdict leaves what the solver said
    final = dataclasses.replace(said, verification=result.verification).settled(verdict(said, result.verification))
    rewrapped = DesignResult(final)
    assert (rewrapped.status, rewrapped.message) == (Status.FAILED, "outer layer") == (final.status, final.message)
    assert final.verdicts == said.verdicts  # the outermost verdict is not stacked twice
    with pytest.raises(ValueError, match="verified and judged"):
        DesignResult(said)  # a result holds a finished design


def test_a_verdict_names_a_known_source():
    assert "check" in VERDICT_SOURCES and "parts" in VERDICT_SOURCES
    with pytest.raises(ValueError, match="verdict source 'somewhere'"):
        Verdict(Status.OPTIMAL, "x", "somewhere")


# -- the innermost layers' own verdicts --------------------------------------------------
def test_constraints_verdict_names_its_layer():
    """test_constraints' housing: b ≤ 0.3 m needs M ≥ 2/3 kg, so a cap of 0.5 kg on the added
    mass conflicts; the balance alone holds, and the constraints' layer says infeasible."""
    from test_constraints import housing

    from counterpoise.pipeline import design

    result = design(housing(heavy={"expression": "added_mass()", "upper": "0.5 kg"}).build())
    assert result.status is Status.INFEASIBLE
    assert result.verdict.source == "constraints"
    assert [v.source for v in result.solution.verdicts] == ["constraints"]
    assert result.message == result.solution.verdict.message and "cannot all hold" in result.message


def test_minimax_design_is_judged_by_the_minimax_rule(tmp_path):
    """A directly attached spring (test_direct_springs' arm): no layer gives a verdict of its
    own, the minimax rule reports the dense ratio as is."""
    from test_direct_springs import arm

    result = run(build_method(arm(tmp_path, 'stiffness = "k"\nfree_length = "50 mm"\ninitial_tension = "2 N"\nmax_length = "0.6 m"')))
    assert result.optimal, result.message
    assert [v.source for v in result.solution.verdicts] == ["minimax"] and result.verdict.source == "minimax"
    assert "dense check: worst residual ratio" in result.message
