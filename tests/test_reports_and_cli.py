"""Report files (columns, units, atomic writes) and the command line (exit status, output)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from conftest import PROBLEMS, run_cli, solved
from counterpoise.report import DESIGN_COLUMNS, SUMMARY_COLUMNS, write_reports

CLI = Path(sys.executable).with_name("counterpoise")


def test_design_and_summary_columns(tmp_path):
    folder = write_reports(solved("yasir2019_hybrid"), tmp_path)
    design = pd.read_csv(folder / "design.csv", keep_default_na=False)
    summary = pd.read_csv(folder / "summary.csv")
    assert list(design.columns) == [
        "name", "kind", "scenario", "value", "unit", "lower", "upper", "active_bound", "description"
    ] == DESIGN_COLUMNS
    assert list(summary.columns) == [
        "problem", "status", "objective", "added_mass_kg", "added_inertia_kg_m2", "max_residual_N_m",
        "max_gravity_torque_N_m", "residual_ratio", "residual_ratio_as_built", "spring_model", "checked_configurations", "iterations", "solve_time_s", "solver",
        "max_residual_N", "max_gravity_force_N", "certificate_gap_kg", "starts_reaching_best", "worst_scenario",
        "lower_bound_ratio", "parts", "certificate",
    ] == SUMMARY_COLUMNS
    # masses, a stiffness and a payload share at a fixed geometry: an LP, solved by Clarabel
    assert len(summary) == 1 and summary.loc[0, "status"] == "optimal" and summary.loc[0, "solver"] == "clarabel"
    # no max_force in the file: no constraint rows (a designed spring's limit is reported in springs.csv)
    assert set(design["kind"]) == {"variable", "quantity"}
    assert set(design["active_bound"]) <= {"", "lower", "upper"}
    # values are in the units the file wrote: k in N/mm with bounds 0.01 and 5
    k = design.set_index("name").loc["k"]
    assert k["unit"] == "N/mm" and float(k["lower"]) == 0.01 and float(k["upper"]) == 5
    # quantities have no bounds
    assert (design[design["kind"] == "quantity"]["lower"] == "").all()
    # no temporary files are left behind; the free-stiffness springs get springs.csv (their designed springs)
    assert sorted(p.name for p in folder.iterdir()) == ["build.csv", "design.csv", "springs.csv", "status.txt", "summary.csv", "verification.csv"]


def test_verification_table_one_row_per_condition(tmp_path):
    folder = write_reports(solved("yasir2019_counter_mass"), tmp_path)
    table = pd.read_csv(folder / "verification.csv")
    assert list(table["coordinate"]) == ["theta_a", "theta_b", "theta_c"]
    assert (table["configurations"] >= 10_000).all()
    assert (table["residual_ratio"] <= 1e-9).all()
    assert (table["unit"] == "N·m").all()


def test_atomic_write_keeps_old_file_when_writing_fails(tmp_path, monkeypatch):
    from counterpoise.report import files as report

    target = tmp_path / "x.csv"
    target.write_text("old")

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(report.os, "replace", boom)
    with pytest.raises(OSError):
        report.atomic_write_text(target, "new")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["x.csv"]  # the temporary file is removed


def test_cli_solve_exit_0_and_summary(tmp_path):
    """A real process (the console script, its start-up and exit status); the other
    command-line tests here run the entry point in process (``run_cli``)."""
    run = subprocess.run(
        [CLI, "solve", str(PROBLEMS / "yasir2019_counter_mass.toml"), "--out", str(tmp_path)],
        capture_output=True, text=True,
    )
    assert run.returncode == 0, run.stderr
    assert "yasir2019_counter_mass" in run.stdout and "optimal" in run.stdout
    assert (tmp_path / "yasir2019_counter_mass" / "summary.csv").exists()


def test_cli_set_override_changes_the_design(tmp_path):
    run = run_cli("solve", str(PROBLEMS / "yasir2019_counter_mass.toml"), "--out", str(tmp_path), "--set", "parameters.m_c=800 g")
    assert run.returncode == 0, run.stderr
    design = pd.read_csv(tmp_path / "yasir2019_counter_mass" / "design.csv").set_index("name")
    assert design.loc["M_c", "value"] == pytest.approx(800.0)  # M_c = m_c r_c / b_c with r_c = b_c


def test_cli_validate_ok():
    run = run_cli("validate", *sorted(map(str, PROBLEMS.glob("*.toml"))))
    assert run.returncode == 0, run.stderr
    assert run.stdout.count("ok  ") == len(list(PROBLEMS.glob("*.toml")))


def test_cli_bad_set_syntax_exit_2(tmp_path):
    run = run_cli("solve", str(PROBLEMS / "yasir2019_counter_mass.toml"), "--out", str(tmp_path), "--set", "novalue")
    assert run.returncode == 2
    assert run.stderr.strip() == "--set novalue: expected KEY=VALUE"
    assert not any(tmp_path.iterdir())


def test_cli_two_files_with_one_problem_name_exit_2(tmp_path):
    copy = tmp_path / "copy.toml"
    copy.write_text((PROBLEMS / "yasir2019_counter_mass.toml").read_text())
    out = tmp_path / "out"
    run = run_cli("solve", str(PROBLEMS / "yasir2019_counter_mass.toml"), str(copy), "--out", str(out))
    assert run.returncode == 2
    assert run.stderr.strip().startswith(f"{copy}: problem.name: 'yasir2019_counter_mass' is also the name of")
    assert not out.exists()


def test_energy_plot_does_not_magnify_rounding_noise():
    """Issue 24: a flat residual of 1e-15 filled its panel with zig-zags. The axis is kept at
    least ±tolerance × reference wide, so the noise stays a flat line."""
    import numpy as np

    from counterpoise.plots._mpl import pyplot
    from counterpoise.plots.energy import _floor_axis

    plt = pyplot()
    fig, ax = plt.subplots()
    noise = 1e-15 * np.sin(np.arange(50.0))
    ax.plot(noise)
    _floor_axis(ax, [noise], 1e-8 * 2.0)
    lo, hi = ax.get_ylim()
    assert lo <= -2e-8 and hi >= 2e-8
    fig2, ax2 = plt.subplots()
    big = np.linspace(-1, 1, 10)
    ax2.plot(big)
    before = ax2.get_ylim()
    _floor_axis(ax2, [big], 1e-8)  # a real curve keeps its own scale
    assert ax2.get_ylim() == before
    plt.close(fig)
    plt.close(fig2)


def test_a_slow_phase_says_so_while_it_runs_and_a_quick_one_stays_quiet():
    """Issue 24: solve printed nothing for 10-50 s on a catalogue or payload problem."""
    import time

    from counterpoise import progress

    lines: list[str] = []
    with progress.sink(lines.append):  # a sink that did not ask for timed notes (a log) gets none
        with progress.phase("slow", after=0.01):
            time.sleep(0.1)
    assert lines == []
    with progress.sink(lines.append, timed=True):
        with progress.phase("quick", after=0.5):
            pass
        assert lines == []
        with progress.phase("slow", after=0.05):
            time.sleep(0.3)
            assert lines == ["slow ..."]  # said while still running
    assert lines[0] == "slow ..." and lines[1].startswith("slow: done in ")


def test_a_value_within_the_bound_tolerance_is_reported_as_the_bound():
    """Issue 24: values on a bound showed as 2.34e-08 mm off it."""
    import dataclasses

    from conftest import solved
    from counterpoise.report.rows import design_rows

    result = solved("yasir2019_counter_mass")
    slot, value = next(iter(result.solution.values.items()))
    v = result.problem.variable[slot.variable]
    off = v.lower + 1e-9 * (v.upper - v.lower)  # within BOUND_TOLERANCE (1e-7 of the span)
    solution = dataclasses.replace(result.solution, values={**result.solution.values, slot: off})
    rows = design_rows(dataclasses.replace(result, solution=solution))
    row = next(r for r in rows if r["name"] == v.name and r["kind"] == "variable")
    assert row["value"] == v.unit.from_si(v.lower) and row["active_bound"] == "lower"
