"""Design methods compose: every option acts on every kind of problem (issue 13)."""

from __future__ import annotations

import pytest

from builders import counter_mass_toml, one_link_toml, payload_pendulum_toml
from conftest import ROOT, solved
from counterpoise.designer.methods import DesignMethod, Minimax, MultiStart, Plain
from counterpoise.errors import ProblemFileError
from counterpoise.formulation.layout import Slot
from counterpoise.io.loader import load_problem, load_problem_text
from counterpoise.pipeline import build_method, design, run
from counterpoise.solvers.base import Status
from counterpoise.designer.minimax import MinimaxDesign


PAYLOAD_PENDULUM = payload_pendulum_toml(
    "pendulum_payload_lever", "b", "0.05 m", "0.3 m", '["-b", 0, 0]', description="the counter-mass lever, set per payload: b(p) = (m + p) r / M"
)


def payload_pendulum():
    return load_problem_text(PAYLOAD_PENDULUM, "pendulum_payload_lever.toml")


def _value(result, name):
    return next(v for s, v in result.solution.values.items() if s.variable == name and s.scenario is None)


def test_methods_nest_by_content(tmp_path):
    """The problem decides the nesting: plain, multi-start, payload around them."""
    from builders import pendulum

    plain = build_method(pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build())
    assert isinstance(plain, Plain) and isinstance(plain, DesignMethod)
    assert isinstance(build_method(pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build(), starts=3), MultiStart)
    payload = build_method(payload_pendulum(), starts=2)
    assert type(payload).__name__ == "PayloadMethod"
    assert isinstance(payload.core(payload.search_problem_with()), MultiStart)


def test_starts_act_on_a_payload_range():
    """Before: starts was dropped for payload ranges (starts_reaching_best 1/1)."""
    result = design(payload_pendulum(), starts=3)
    assert result.status is Status.OPTIMAL, result.message
    assert result.solution.stats.starts[1] == 3
    assert result.payload is not None and result.payload.schedule.feasible


def test_solve_options_design_a_payload_range_over_its_range():
    """Before: any solve option designed a payload problem at its nominal payload only.
    With m = 1.5 kg the lever reaches 0.3 m at 1 kg: M = (1.5 + 1)·0.3/0.3 = 2.5 kg."""
    result = design(payload_pendulum(), parameters={"m": 1.5})
    assert result.status is Status.OPTIMAL, result.message
    assert result.payload is not None
    assert result.payload.checked == (0.0, 1.0)
    assert _value(result, "M") == pytest.approx(2.5, rel=1e-7)
    rows = result.payload.schedule.rows
    assert rows[0].values["b"] == pytest.approx(1.5 * 0.3 / 2.5, rel=1e-7)  # the schedule saw m = 1.5 kg too
    # bounds act on every sample and on the schedule: the lever at most 0.25 m needs
    # M = (1 + 1)·0.3/0.25 = 2.4 kg, and the schedule keeps b ≤ 0.25 m
    narrowed = design(payload_pendulum(), bounds={"b": (0.05, 0.25)}, initial={Slot("M", None): 2.9})
    assert narrowed.status is Status.OPTIMAL, narrowed.message
    assert _value(narrowed, "M") == pytest.approx(2.4, rel=1e-7)
    assert max(s.values["b"] for s in narrowed.payload.schedule.rows) == pytest.approx(0.25, rel=1e-9)
    with pytest.raises(ProblemFileError, match="parameters: 'tool' is the payload"):
        design(payload_pendulum(), parameters={"tool": 0.5})


def test_a_method_is_built_once_and_solved_many_times():
    method = build_method(payload_pendulum())
    first = run(method, parameters={"m": 1.5})
    second = run(method, parameters={"m": 0.5})
    assert _value(first, "M") == pytest.approx(2.5, rel=1e-7)
    assert _value(second, "M") == pytest.approx(1.5, rel=1e-7)
    assert len(method._built) == 1  # one sampled problem, one inner method


def test_starts_act_on_directly_attached_springs(tmp_path):
    from test_direct_springs import arm

    problem = arm(tmp_path, 'stiffness = "k"\nfree_length = "50 mm"\ninitial_tension = "2 N"\nmax_length = "0.6 m"')
    method = build_method(problem, starts=2)
    assert isinstance(method, MultiStart) and isinstance(method.inner, Minimax)
    result = run(method)
    assert result.status is Status.OPTIMAL, result.message
    assert result.solution.stats.starts[1] == 2


def test_starts_and_parameters_act_on_slots(tmp_path):
    """Before: starts was dropped for problems with slots, and a parameter given to a slot
    problem did not reach its part search."""
    from test_catalogue import pendulum

    good = "GOOD,200,0.05,1,50,0.3,0.01,0.001,x"
    problem = pendulum(tmp_path, [good], 2.0 / (9.81 * 0.2))
    result = design(problem, starts=2)
    assert result.status is Status.OPTIMAL, result.message
    assert result.solution.stats.starts[1] == 2
    # m g r = k b h: a 10 % heavier m moves h to 1.1 × (2 N·m / (200 N/m · 0.1 m))
    heavier = design(problem, parameters={"m": 1.1 * 2.0 / (9.81 * 0.2)})
    assert heavier.status is Status.OPTIMAL, heavier.message
    assert _value(heavier, "h") == pytest.approx(1.1 * 0.1, rel=1e-7)
    with pytest.raises(ProblemFileError, match="parameters: 's' is set by the catalogue part"):
        design(problem, parameters={"s": 150.0})


def test_woo2019_hybrid_catalogue_part_holds_over_the_payload_range(tmp_path):
    """Acceptance: slots and a payload range compose. One shipped part for the spring, the
    schedule feasible from 0 to 122 g, and springs.csv shows the part within its limits
    at every payload of the schedule."""
    import csv
    import io

    from counterpoise.report.files import report_texts

    result = solved("woo2019_hybrid_catalogue")  # shared with test_report_html
    assert result.status is Status.OPTIMAL, result.message
    assert result.payload.schedule.feasible and result.payload.checked == pytest.approx((0.0, 0.122))
    assert result.parts.fits
    rows = list(csv.DictReader(io.StringIO(report_texts(result)["springs.csv"])))
    springs = [r for r in rows if r["kind"] == "spring" and r["scenario"] != "all"]
    plan = result.payload.schedule
    assert len(springs) == len(plan.rows) + len(plan.between)
    assert {r["scenario"] for r in springs} >= {"added_0g", "added_61g", "added_122g"}
    for r in springs:
        assert min(float(r["margin_slack_mm"]), float(r["margin_length_mm"]), float(r["margin_load_N"])) >= 0, r
    # one summary row (issue 24): the extremes over every payload, the smallest margins
    (summary,) = [r for r in rows if r["kind"] == "spring" and r["scenario"] == "all"]
    assert float(summary["max_force_N"]) == max(float(r["max_force_N"]) for r in springs)
    assert float(summary["min_distance_mm"]) == min(float(r["min_distance_mm"]) for r in springs)
    assert float(summary["margin_load_N"]) == min(float(r["margin_load_N"]) for r in springs)


TWO_TOOLS = one_link_toml(
    "two_tools",
    'm_tool = "1 kg"\nr = "0.2 m"\nb = "0.1 m"\ne = "0.1 m"\nk = "1000 N/m"',
    """
[variables.M]
lower = "0 kg"
upper = "0.5 kg"
description = "counter-mass shared by both tools"
[variables.a]
lower = "10 mm"
upper = "60 mm"
initial = "30 mm"
adjustable = true
description = "spring base height, set per tool"
""" + counter_mass_toml('["-b", 0, 0]') + """[springs.s]
stiffness = "k"
from = { frame = "ground", point = [0, "a", 0] }
to = { frame = "link", point = ["e", 0, 0] }
[scenarios.light]
parameters = { m_tool = "1 kg" }
[scenarios.heavy]
parameters = { m_tool = "5 kg" }
[objective]
mass_weight = 1
""",
    joint_range=("-90 deg", "90 deg"),
    body="tool",
    mass="m_tool",
)


def test_infeasible_modes_polish_the_modes_that_can_be_met():
    """Balance needs (m r − M b) g = k a e. heavy (5 kg) needs a ≥ 93 mm > 60 mm: unmet.
    light (1 kg) is met by its own a = (0.2 − 0.1 M)·9.81/100 for every M ≤ 0.5 kg. Before:
    the closest design left a@light 0.2 mm off and the message named both modes."""
    result = design(load_problem_text(TWO_TOOLS, "two_tools.toml"))
    assert result.status is Status.INFEASIBLE
    assert "'heavy'" in result.message and "'light'" not in result.message
    assert "a@heavy at its upper bound 60 mm" in result.message
    values = {(s.variable, s.scenario): v for s, v in result.solution.values.items()}
    m = values[("M", None)]
    assert values[("a", "light")] == pytest.approx((0.2 - 0.1 * m) * 9.81 / 100, rel=1e-9)
    light = [c for c in result.verification.checks if c.scenario == "light"]
    assert light and all(result.verification.ratio(c) <= 1e-9 for c in light)


def _pendulum_with(old: str, new: str):
    assert old in PAYLOAD_PENDULUM
    return load_problem_text(PAYLOAD_PENDULUM.replace(old, new), "pendulum_payload_lever.toml")


def test_max_payload_range_and_schedule_report_the_same_two_ends():
    """Declared 0.5-1 kg: M = 2 kg puts b = (1 + p)·0.3/2 in [0.05, 0.3] m for p in [0, 1] kg
    (b = 0.15 m at 0 kg, inside its bounds). Before: max_payload_range widened upward only
    (0.5 kg to 1 kg) while schedule answered 0 kg to 1 kg."""
    from counterpoise.pipeline import operator_settings

    problem = _pendulum_with('range = ["0 kg", "1 kg"]', 'range = ["0.5 kg", "1 kg"]')
    text = 'objective = "max_payload_range"\n' + PAYLOAD_PENDULUM.replace('range = ["0 kg", "1 kg"]', 'range = ["0.5 kg", "1 kg"]')
    widest = design(load_problem_text(text, "widest.toml"))
    assert widest.status is Status.OPTIMAL, widest.message
    w = widest.payload.widest
    assert (w.lower, w.upper) == pytest.approx((0.0, _value(widest, "M") - 1.0), abs=1e-6)
    heavy = operator_settings(problem, 1.5)
    assert heavy.balanceable == pytest.approx((0.0, 1.0), abs=1e-6)
    light = operator_settings(problem, 0.2)
    assert light.setting.feasible and "0.2 kg lies outside the declared range 0.5 kg to 1 kg" in light.note


def test_range_too_wide_says_what_is_balanceable_and_reports_a_design_balanced_at_the_nominal():
    """M ≤ 2 kg and b ≤ 0.3 m balance (1 + p)·0.3 ≤ 2·0.3 only up to p = 1 kg of the 3 kg declared."""
    text = PAYLOAD_PENDULUM.replace('range = ["0 kg", "1 kg"]', 'range = ["0 kg", "3 kg"]').replace('upper = "20 kg"', 'upper = "2 kg"')
    result = design(load_problem_text(text, "wide.toml"))
    assert result.status is Status.INFEASIBLE
    assert "balanceable from 0 kg to" in result.message and "b reaches its upper limit 0.3 m at" in result.message
    w = result.payload.widest
    assert (w.lower, w.upper) == pytest.approx((0.0, 1.0), abs=1e-3)
    nominal = next(c for c in result.verification.checks if c.scenario == "tool_0kg")
    assert result.verification.ratio(nominal) <= 1e-9  # the design reported is balanced at the nominal


def test_directly_attached_spring_with_a_payload_range_and_starts(tmp_path):
    """Minimax inside a payload design inside... all composed: the spring base height y set
    per payload, two starts on every sample design; before, the schedule's adjustment
    solver demanded exact balance conditions and the design stopped with an error."""
    from test_direct_springs import ARM

    spring = 'stiffness = "k"\nfree_length = "50 mm"\ninitial_tension = "2 N"\nmax_length = "0.6 m"'
    extra = '[payloads.tool]\nframe = "link"\nposition = ["r", 0, 0]\nrange = ["0 kg", "0.2 kg"]\n'
    text = ARM.format(spring=spring, extra=extra, stiffness_parameter='k = "200 N/m"')
    text = text.replace('initial = "0.2 m"\n', 'initial = "0.2 m"\nadjustable = true\n', 1)
    result = design(load_problem_text(text, "direct_payload.toml"), starts=2)
    assert result.status is Status.OPTIMAL, result.message
    assert result.solution.stats.starts[1] == 2 and result.solution.extra(MinimaxDesign) is not None
    plan = result.payload.schedule
    assert plan.feasible and plan.rows[-1].payload == pytest.approx(0.2)
    heights = [s.values["y"] for s in plan.rows]
    assert heights[-1] > heights[0]  # a heavier payload needs a higher spring base
