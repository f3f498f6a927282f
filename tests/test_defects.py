"""Regression tests for defects found by trying the tool as a new user (issue 5, section 1).

Bad problem files have their own manifest (``tests/test_bad_problems.py``); the tests here
cover what a bad file cannot: the command line (``--set``, internal errors), report fields
of odd but valid mechanisms, and the statements of the documentation about them.
"""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT, run_cli

from builders import OVERDETERMINED_TOML, counter_mass_toml, pendulum, pendulum_toml, toml_head
from counterpoise.designer import Designer
from counterpoise.errors import ProblemFileError, SolverError
from counterpoise.formulation import Slot
from counterpoise.io.loader import load_problem_text
from counterpoise.pipeline import design
from counterpoise.report import write_reports
from counterpoise.solvers import Status

GOOD = ROOT / "problems" / "yasir2019_counter_mass.toml"
CLI = Path(sys.executable).with_name("counterpoise")
BIG = "1" * 400


def _cli(*args: str, cwd: Path):  # noqa: ANN202 - conftest.CliRun
    """The command line, in process (conftest.run_cli)."""
    return run_cli(*args, cwd=cwd)


# --------------------------------------------------------------------------------------
# Tracebacks: every failure is one line with a documented exit status
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("setting", "key", "fragment"),
    [
        (f"parameters.r_a={BIG}", "parameters.r_a", "number too large (400 digits)"),
        (f"bodies.tip.mass=m_c * {BIG}", "bodies.tip.mass", "number too large in 'm_c * 111"),
        ("objective.mass_weight=inf", "objective.mass_weight", "must be a finite number, got inf"),
        ("objective.inertia_weight=0 kg", "objective.inertia_weight", "got a mass ('0 kg')"),
        (f"settings.max_iterations={BIG}", "settings.max_iterations", "less than or equal to 1000000"),
    ],
)
def test_set_with_bad_values_is_one_line_exit_2(setting, key, fragment, tmp_path):
    proc = _cli("solve", str(GOOD), "--out", str(tmp_path / "out"), "--set", setting, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"{GOOD}: {key}: "), lines[0]
    assert fragment in lines[0]
    assert len(lines[0]) <= len(f"{GOOD}: ") + 600
    assert list(tmp_path.iterdir()) == []


def test_bad_set_syntax_echo_is_clipped(tmp_path):
    proc = _cli("validate", str(GOOD), "--set", "x" * 10_000, cwd=tmp_path)
    assert proc.returncode == 2
    assert len(proc.stderr) < 300, len(proc.stderr)
    assert proc.stderr.strip().endswith("…: expected KEY=VALUE")


def test_internal_error_is_one_line_with_exit_status_3(monkeypatch, capsys, tmp_path):
    """An error that is no fault of the input: one line, status 3; ``--debug`` re-raises."""
    import counterpoise.pipeline
    from counterpoise.cli.app import INTERNAL_ERROR, main

    def broken(problem, designer=None, **options):
        raise RuntimeError("something " * 100)

    monkeypatch.setattr(counterpoise.pipeline, "design", broken)
    with pytest.raises(SystemExit) as info:
        main(["solve", str(GOOD), "--out", str(tmp_path / "out")])
    assert info.value.code == INTERNAL_ERROR == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("internal error: RuntimeError: something")
    assert "--debug" in err and len(err) < 400
    with pytest.raises(RuntimeError):
        main(["solve", str(GOOD), "--out", str(tmp_path / "out"), "--debug"])


def test_non_finite_residual_in_compression_is_a_solver_error():
    """A NaN region of the box narrower than the loader's samples ends as a SolverError
    (one line, exit 1 in the CLI), not as numpy's LinAlgError."""
    from counterpoise.formulation.compression import compress

    samples = np.ones((6, 4))
    samples[2, 1] = np.nan
    with pytest.raises(SolverError, match="not a finite number at some designs within the bounds"):
        compress(samples)


def test_nan_on_the_coordinate_box_is_rejected():
    """The box check covers coordinates too: an angle sqrt(q) is NaN for q < 0."""
    text = pendulum_toml(0.8, 0.3, (0.02, 1.0), 0.0).replace('angle = "q"', 'angle = "sqrt(q + pi) - sqrt(pi)"')
    load_problem_text(text)  # q in [-180, 180] deg: q + pi >= 0 everywhere
    with pytest.raises(ProblemFileError) as info:
        load_problem_text(text.replace("sqrt(q + pi)", "sqrt(q + 3 rad)"))  # a bare 3 added to q is an error of its own
    assert info.value.key == "frames.link.transforms.0.angle"
    assert "is not a finite number everywhere within the bounds: nan at q = -180 deg" in info.value.message


def test_derived_parameter_may_use_pi():
    """Found by the loader fuzz: ``pi`` in a derived parameter raised KeyError."""
    text = pendulum_toml(0.8, 0.3, (0.02, 1.0), 0.0).replace('r = "0.3 m"', 'r0 = "0.3 m"\nr = "r0 * pi / pi"')
    result = design(load_problem_text(text))
    assert result.status is Status.OPTIMAL, result.message
    M, b = result.solution.values[Slot("M", None)], result.solution.values[Slot("b", None)]
    assert M * b == pytest.approx(0.8 * 0.3, rel=1e-9)  # m r = M b with r = 0.3 m


@pytest.mark.parametrize(
    ("old", "new", "status"),
    [
        # M fixed at 0: the pendulum cannot be balanced ('NLP is overconstrained')
        ('upper = "100.0 kg"', 'upper = "0 kg"', "balance cannot be met within the bounds"),
        # (mass_weight = 1e308, which overflowed the objective, is an input error now:
        # tests/bad_problems/mass_weight_too_large.toml)
    ],
)
def test_solver_warnings_do_not_reach_stderr(old, new, status, tmp_path):
    """Found by fuzzing whole designs: CasADi printed warnings on stderr, stray lines next
    to a status that already says what happened (exit 1, reports written)."""
    path = tmp_path / "p.toml"
    text = pendulum_toml(0.8, 0.3, (0.3, 0.3), 0.0)
    assert old in text
    path.write_text(text.replace(old, new))
    proc = _cli("solve", str(path), "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert proc.returncode == 1
    assert proc.stderr == ""
    assert status in (tmp_path / "out" / "pendulum" / "status.txt").read_text()


# --------------------------------------------------------------------------------------
# Report fields
# --------------------------------------------------------------------------------------

YAW_PITCH = """
[problem]
name = "yaw_pitch"
[gravity]
acceleration = "9.81 m/s^2"
direction = [0, 0, -1]
[parameters]
m = "1 kg"
l = "0.3 m"
b = "0.1 m"
[subsystems.arm]
coordinates.yaw = { range = ["-90 deg", "90 deg"] }
coordinates.pitch = { range = ["-60 deg", "60 deg"] }
[frames.base]
transforms = [{ rotate = "z", angle = "yaw" }]
[frames.link]
parent = "base"
transforms = [{ rotate = "y", angle = "pitch" }]
[bodies.tip]
frame = "link"
mass = "m"
com = ["l", 0, 0]
[variables.M]
lower = "0 kg"
upper = "10 kg"
[counter_masses.M]
frame = "link"
mass = "M"
position = ["-b", 0, 0]
"""


def test_zero_gravity_torque_coordinate_has_a_finite_ratio(tmp_path):
    """The yaw axis is parallel to gravity: no gravity torque on it at all. Its ratio is
    measured against the largest torque of the problem (the pitch's m g l = 2.943 N·m)
    and is finite in verification.csv (it was inf: 0/0 for the yaw)."""
    result = design(load_problem_text(YAW_PITCH))
    assert result.status is Status.OPTIMAL, result.message
    assert result.solution.values[Slot("M", None)] == pytest.approx(3.0, rel=1e-8)  # M b = m l
    rows = {r["coordinate"]: r for r in csv.DictReader((write_reports(result, tmp_path) / "verification.csv").open())}
    assert float(rows["yaw"]["max_gravity_torque"]) == 0.0
    assert float(rows["pitch"]["max_gravity_torque"]) == pytest.approx(1.0 * 9.81 * 0.3, rel=1e-6)
    for row in rows.values():
        assert math.isfinite(float(row["residual_ratio"])) and float(row["residual_ratio"]) <= 1e-9, row


SLIDER = toml_head("slider", 'm = "1 kg"') + """[subsystems.s]
coordinates.y = { range = ["0 mm", "100 mm"] }
[frames.carriage]
transforms = [{ translate = [0, "y", 0] }]
[bodies.load]
frame = "carriage"
mass = "m"
com = [0, 0, 0]
[variables.M]
lower = "0 kg"
upper = "10 kg"
""" + counter_mass_toml("[0, 0, 0]", name="M", frame="carriage")


def test_slider_infeasibility_speaks_of_force_in_newtons(tmp_path):
    """A vertical slider cannot be balanced by a mass riding on it: the residual is the
    load's weight m g = 9.81 N, a force, and the message must say so."""
    result = design(load_problem_text(SLIDER))
    assert result.status is Status.INFEASIBLE
    assert "residual up to 9.81 N (100 % of the largest unbalanced gravity force)" in result.message
    assert "torque" not in result.message and "N·m" not in result.message
    summary = next(csv.DictReader((write_reports(result, tmp_path) / "summary.csv").open()))
    assert summary["max_residual_N_m"] == "" and float(summary["max_residual_N"]) == pytest.approx(9.81)


def test_small_value_with_a_huge_span_is_not_at_a_bound():
    """m r = M b: 0.05 kg at 0.2 m balanced at b = 0.2 m needs M = 0.05 kg. With M in
    [0, 50 t] that is far from its lower bound (1e-6 of the span), so ``active_bound`` is
    empty. b sits on its upper bound, although IPOPT stops 1.1e-7 of the span inside it
    here (the scales of M and b differ by 2.5e5): the polish puts it there."""
    result = design(pendulum(0.05, 0.2, (0.02, 0.2), 0.0, mass_upper=50_000.0).build())
    assert result.status is Status.OPTIMAL, result.message
    assert result.solution.values[Slot("M", None)] == pytest.approx(0.05, rel=1e-6)
    from counterpoise.report.rows import design_rows

    sides = {r["name"]: r["active_bound"] for r in design_rows(result)}
    assert sides == {"M": "", "b": "upper"}
    assert result.solution.values[Slot("b", None)] == 0.2


# --------------------------------------------------------------------------------------
# Documentation statements
# --------------------------------------------------------------------------------------


def test_solve_time_counts_solver_calls_not_builds(monkeypatch):
    """README: ``solve_time_s`` is the time spent in solver calls; building a solver is not
    counted, also not the solvers the over-determined path builds during ``solve``."""
    from counterpoise.solvers import ipopt

    calls: list[float] = []
    builds: list[str] = []
    solve, init = ipopt.IpoptBackend.solve, ipopt.IpoptBackend.__init__

    def counting_solve(self, *args, **kwargs):
        out = solve(self, *args, **kwargs)
        calls.append(out.solve_time)
        return out

    def counting_init(self, nlp, options, label="design"):
        builds.append(label)
        init(self, nlp, options, label)

    monkeypatch.setattr(ipopt.IpoptBackend, "solve", counting_solve)
    monkeypatch.setattr(ipopt.IpoptBackend, "__init__", counting_init)
    text = OVERDETERMINED_TOML
    designer = Designer(load_problem_text(text))
    assert builds == ["design"]
    calls.clear()
    solution = designer.solve()
    assert solution.status is Status.OPTIMAL
    assert "design_reduced" in builds  # a solver is built inside solve() on this path
    assert len(calls) >= 2
    assert solution.stats.solve_time == pytest.approx(sum(calls), rel=1e-12)


def test_readme_states_the_display_unit_fallback():
    """The code falls back to ``upper``'s unit when ``lower`` is a bare number; the format
    reference must say so (it promised ``lower``'s unit only)."""
    problem = load_problem_text(pendulum_toml(0.8, 0.3, (0.02, 1.0), 0.0).replace('lower = "0 kg"', "lower = 0"))
    assert problem.variable["M"].unit.symbol == "kg"
    reference = (ROOT / "problems" / "README.md").read_text(encoding="utf-8")
    assert "or `upper`'s when `lower` is a bare number" in " ".join(reference.split())


def test_a_set_override_may_change_an_entry_not_create_one():
    """Review finding: ``--set parameters.m_cc=3 g`` (a typo for m_c) added an unused
    parameter and the solve went on with m_c unchanged."""
    from counterpoise.errors import ProblemFileError
    from counterpoise.io.loader import load_problem

    path = ROOT / "problems" / "yasir2019_counter_mass.toml"
    with pytest.raises(ProblemFileError, match=r"parameters.m_cc: the file has no parameters entry 'm_cc' to override \(did you mean 'm_c'\?\)"):
        load_problem(path, {"parameters.m_cc": "3 g"})
    assert {p.name: p.value for p in load_problem(path, {"parameters.m_c": "3 g"}).parameters}["m_c"] == pytest.approx(0.003)
    assert load_problem(path, {"settings.verify_samples": 2000}).settings.verify_samples == 2000  # a key of a plain table: allowed
