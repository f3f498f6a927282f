"""Inputs that must be rejected at load time, and results that must survive odd designs."""

from __future__ import annotations

import math

import pytest

from builders import pendulum, pendulum_toml
from counterpoise.pipeline import design
from counterpoise.errors import ProblemFileError
from counterpoise.io.loader import load_problem_text
from counterpoise.designer import Designer
from counterpoise.formulation import Slot
from counterpoise.solvers import Status


def load_error(text: str) -> ProblemFileError:
    with pytest.raises(ProblemFileError) as info:
        load_problem_text(text, "p.toml")
    return info.value


BASE = pendulum_toml(0.8, 0.3, (0.02, 1.0), 0.0)


def test_a_point_may_not_move_with_a_coordinate():
    """A point is fixed in its frame; motion belongs in a frame (or it would escape the balance)."""
    err = load_error(BASE.replace('com = ["r", 0, 0]', 'com = ["r*cos(q)", 0, 0]'))
    assert err.key == "bodies.tip.com.0"
    assert "unknown name 'q'" in err.message


def test_rotation_axis_as_expression_is_normalised_everywhere():
    """A tilt written as an expression gives the same design as the literal axis."""
    text = BASE.replace('[parameters]', '[parameters]\nk = 2').replace('rotate = "z"', 'rotate = [0, 0, "k"]')
    result = design(load_problem_text(text))
    reference = design(load_problem_text(BASE))
    assert result.status is Status.OPTIMAL, result.message
    assert result.solution.values[Slot("M", None)] == pytest.approx(reference.solution.values[Slot("M", None)], rel=1e-9)
    assert result.solution.added_inertia == pytest.approx(reference.solution.added_inertia, rel=1e-9)


def test_zero_rotation_axis():
    err = load_error(BASE.replace('[parameters]', '[parameters]\nk = 0').replace('rotate = "z"', 'rotate = [0, 0, "k"]'))
    assert err.key == "frames.link.transforms.0.rotate"
    assert "zero vector" in err.message


@pytest.mark.parametrize(
    ("scenario", "fragment"),
    [
        ('parameters = { m = "-3 kg" }', "a mass bodies.tip.mass = 'm' is negative in this scenario"),
        ('parameters = { c = -1 }', "parameter 'm2' is not a finite number in this scenario"),
    ],
)
def test_scenario_values_are_checked(scenario, fragment):
    text = BASE.replace('[parameters]', '[parameters]\nc = 1\nm2 = "sqrt(c) * m"') + f"\n[scenarios.bad]\n{scenario}\n"
    err = load_error(text)
    assert err.key == "scenarios.bad"
    assert fragment in err.message


def test_negative_seed():
    err = load_error(BASE + "\n[settings]\nseed = -1\n")
    assert err.key == "settings.seed"


def test_display_unit_falls_back_to_upper_when_lower_is_a_bare_zero():
    problem = load_problem_text(BASE.replace('lower = "0 kg"', "lower = 0"))
    assert problem.variable["M"].unit.symbol == "kg"


def test_unevaluable_report_quantity_is_nan_not_a_crash(tmp_path):
    from counterpoise.report import write_reports

    text = BASE + '\n[report.ratio]\nexpression = "m / (M - M)"\n'
    result = design(load_problem_text(text))
    assert result.status is Status.OPTIMAL
    assert math.isnan(result.quantities[0].value)
    folder = write_reports(result, tmp_path)
    assert "ratio,quantity,,,1" in (folder / "design.csv").read_text()


def test_resolve_with_new_parameters_reuses_the_solver():
    """A study changes parameters without rebuilding: m r = M b must follow the new m."""
    problem = pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build()
    designer = Designer(problem)
    solver = designer.backend.solver
    for m in (0.5, 1.0, 2.0):
        solution = designer.solve(parameters={"m": m})
        assert designer.backend.solver is solver
        M, b = solution.values[Slot("M", None)], solution.values[Slot("b", None)]
        assert M * b == pytest.approx(m * 0.3, rel=1e-9)
        assert b == pytest.approx(0.2, rel=1e-7)  # 1/sqrt(w) does not depend on m
        assert solution.scenario_parameters["nominal"][1]["m"] == m
