"""Studies (points, study files, resume, failures, engines), the convex path and plots."""

from __future__ import annotations

import csv
import dataclasses
import json
import time

import numpy as np
import pytest

from builders import pendulum
from conftest import PROBLEMS
from counterpoise.cli.app import main
from counterpoise.errors import ProblemFileError, SolverError
from counterpoise.io.loader import load_problem
from counterpoise.studies.runners import ProcessRunner, SerialRunner, StudyTask
from counterpoise.studies.spec import DEFAULT_SEED, plan_study
from counterpoise.studies.study import read_rows, run_study

DESIGN_COLUMNS = ("point", "status", "objective_kg", "added_mass_kg", "added_inertia_kg_m2", "M [kg]", "b [m]")


def _pendulum():
    # M b = m r balances; minimising M + w M b² = m r (1/b + w b) gives b = 1/sqrt(w) = 0.2 m (in [0.02, 1] m)
    return pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build()


def _design_values(folder):
    return [{c: r[c] for c in DESIGN_COLUMNS} for r in read_rows(folder / "study.csv")]


# -- points ------------------------------------------------------------------------------
def test_grid_is_the_product_of_the_ranges_in_si():
    plan = plan_study(_pendulum(), ["m=500 g:900 g:3", "inertia_weight=10 1/m^2:30 1/m^2:2"], "f")
    assert plan.method == "grid" and len(plan.points) == 6
    assert [p["m"] for p in plan.points] == pytest.approx([0.5, 0.5, 0.7, 0.7, 0.9, 0.9])  # first --vary outermost
    assert [p["objective.inertia_weight"] for p in plan.points] == pytest.approx([10, 30] * 3)
    assert [v.header for v in plan.varies] == ["m [g]", "objective.inertia_weight [1/m^2]"]


def test_latin_hypercube_has_one_point_per_stratum_and_a_recorded_default_seed():
    problem = _pendulum()
    plan = plan_study(problem, ["m=0.5 kg:0.9 kg", "b.upper=0.5 m:1 m"], "f", samples=20)
    assert plan.method == "lhs" and plan.seed == DEFAULT_SEED and plan.identity()["seed"] == DEFAULT_SEED
    m = np.array([p["m"] for p in plan.points])
    upper = np.array([p["b.upper"] for p in plan.points])
    # each of the 20 equal slices of each range holds exactly one sample
    assert sorted(np.floor((m - 0.5) / 0.4 * 20).astype(int)) == list(range(20))
    assert sorted(np.floor((upper - 0.5) / 0.5 * 20).astype(int)) == list(range(20))
    again = plan_study(problem, ["m=0.5 kg:0.9 kg", "b.upper=0.5 m:1 m"], "f", samples=20, seed=DEFAULT_SEED)
    other = plan_study(problem, ["m=0.5 kg:0.9 kg", "b.upper=0.5 m:1 m"], "f", samples=20, seed=7)
    assert again.points == plan.points and other.points != plan.points


@pytest.mark.parametrize(
    ("vary", "samples", "message"),
    [
        (["rr=1 m:2 m:3"], None, "unknown key (did you mean 'r'?)"),
        (["m=1 mm:2 mm:3"], None, "'1 mm' is a length, expected a mass"),
        (["m=1 kg:2 kg:0"], None, "N must be at least 1"),
        (["m=1 kg:2 kg:3"], 10, "gives N, but --samples draws the points"),
        (["M=1 kg:2 kg:3"], None, "is a design variable"),
        (["m=1:2:3"], None, "is dimensionless (an angle or a ratio), expected a mass"),
    ],
)
def test_bad_vary_is_one_line_naming_the_option(vary, samples, message):
    with pytest.raises(ProblemFileError) as err:
        plan_study(_pendulum(), vary, "pendulum.toml", samples=samples)
    assert str(err.value).startswith(f"pendulum.toml: --vary {vary[0].split('=')[0]}: ") and message in str(err.value)


# -- study files, resume, failures ---------------------------------------------------------
def test_study_file_has_display_units_and_resume_runs_only_missing_points(tmp_path):
    problem = _pendulum()
    plan = plan_study(problem, ["m=500 g:900 g:5"], "f")
    full = run_study(problem, plan, tmp_path / "a", batch_size=2)
    rows = read_rows(full.folder / "study.csv")
    assert full.counts == {"optimal": 5} and [r["m [g]"] for r in rows] == ["500", "600", "700", "800", "900"]
    assert [float(r["b [m]"]) for r in rows] == pytest.approx([0.2] * 5, rel=1e-7)
    assert [float(r["M [kg]"]) for r in rows] == pytest.approx([m * 0.3 / 0.2 for m in (0.5, 0.6, 0.7, 0.8, 0.9)], rel=1e-7)
    meta = json.loads((full.folder / "study.json").read_text())
    assert meta["plan"]["vary"][0]["key"] == "m" and meta["points"] == 5

    # an interrupted study: the file keeps points 0 and 3 only
    partial = tmp_path / "b"
    run_study(problem, plan, partial, batch_size=2)
    path = partial / "pendulum-study" / "study.csv"
    kept = [r for r in read_rows(path) if r["point"] in ("0", "3")]
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(kept)
    resumed = run_study(problem, plan, partial, resume=True, batch_size=2)
    assert resumed.skipped == 2 and resumed.run == 3
    assert [r["point"] for r in read_rows(path)] == ["0", "1", "2", "3", "4"]
    assert [r["M [kg]"] for r in read_rows(path)] == [r["M [kg]"] for r in rows]

    other = plan_study(problem, ["m=500 g:900 g:6"], "f")
    with pytest.raises(ProblemFileError, match="--resume"):
        run_study(problem, other, partial, resume=True)


def test_a_study_of_catalogue_parts_names_each_slots_part_rate_and_force(tmp_path):
    """Issue 32: study.csv of a catalogue problem had no part, rate or force column, so a
    grip point jumping between points had nothing to say why. Each slot now has its chosen
    part, the part's rate and its springs' largest working force; the first point (the
    file's own m_head, solved cold) is the solve's design: its springs.csv has the same
    part, rate and largest force."""
    from conftest import solved
    from counterpoise.report.files import report_texts

    problem = load_problem(PROBLEMS / "lamp_catalogue.toml")
    plan = plan_study(problem, ["m_head=450 g:500 g:2"], "f")
    outcome = run_study(problem, plan, tmp_path, SerialRunner(), batch_size=1)
    rows = read_rows(outcome.folder / "study.csv")
    meta = json.loads((outcome.folder / "study.json").read_text(encoding="utf-8"))
    assert meta["text_columns"] == ["lower_spring part", "upper_spring part"]
    springs = list(csv.DictReader(report_texts(solved("lamp_catalogue"))["springs.csv"].splitlines()))
    for slot in ("lower_spring", "upper_spring"):
        used = [r for r in springs if r["slot"] == slot]
        assert rows[0][f"{slot} part"] == used[0]["part_number"]
        assert float(rows[0][f"{slot} rate [N/mm]"]) == pytest.approx(float(used[0]["rate_N_per_mm"]), rel=1e-6)
        assert float(rows[0][f"{slot} max force [N]"]) == pytest.approx(max(float(r["max_force_N"]) for r in used), rel=1e-6)
        assert rows[1][f"{slot} part"].startswith("CP-EXT-") and float(rows[1][f"{slot} max force [N]"]) > 0


class _Flaky:
    """A designer that raises at m = 0.6 kg and hangs at m = 0.7 kg (for the failure test)."""

    def __init__(self, designer):
        self.designer = designer
        self.problem = designer.problem

    def solve(self, parameters=None, **kwargs):
        if parameters and parameters.get("m") == pytest.approx(0.6):
            raise SolverError("deliberate failure")
        if parameters and parameters.get("m") == pytest.approx(0.7):
            time.sleep(60)  # stopped by the per-point time limit
        return self.designer.solve(parameters=parameters, **kwargs)


@dataclasses.dataclass(frozen=True)
class _FlakyTask(StudyTask):
    def designer(self, problem=None):
        return _Flaky(super().designer(problem))


def test_a_point_that_raises_and_one_that_hangs_are_recorded_and_the_study_goes_on(tmp_path):
    problem = _pendulum()
    plan = plan_study(problem, ["m=500 g:900 g:5"], "f")
    task = _FlakyTask(problem, time_limit=0.2)
    outcome = run_study(problem, plan, tmp_path, SerialRunner(), task=task, batch_size=5)
    rows = read_rows(outcome.folder / "study.csv")
    assert [r["status"] for r in rows] == ["optimal", "error", "timeout", "optimal", "optimal"]
    assert "deliberate failure" in rows[1]["message"] and "time limit" in rows[2]["message"]
    assert rows[1]["M [kg]"] == "" and float(rows[3]["M [kg]"]) == pytest.approx(0.8 * 0.3 / 0.2, rel=1e-7)


def test_the_solver_time_limit_marks_a_point_as_timeout(tmp_path):
    # a wall-time limit far below one IPOPT iteration: IPOPT stops with Maximum_WallTime_Exceeded
    problem = _pendulum()
    plan = plan_study(problem, ["m=500 g:600 g:2"], "f")
    outcome = run_study(problem, plan, tmp_path, task=StudyTask(problem, time_limit=1e-9))
    assert {r["status"] for r in read_rows(outcome.folder / "study.csv")} == {"timeout"}


# -- engines -------------------------------------------------------------------------------
def test_every_engine_writes_the_same_design_values(tmp_path):
    pytest.importorskip("distributed")
    from counterpoise.studies.cluster import DaskRunner

    problem = _pendulum()
    plan = plan_study(problem, ["m=500 g:900 g:3", "inertia_weight=16 1/m^2:36 1/m^2:2"], "f")
    serial = run_study(problem, plan, tmp_path / "serial", SerialRunner(), batch_size=2)
    pooled = run_study(problem, plan, tmp_path / "pool", ProcessRunner(2), batch_size=2)
    dask = run_study(problem, plan, tmp_path / "dask", DaskRunner("local", 1), batch_size=2)
    reference = _design_values(serial.folder)
    assert all(r["status"] == "optimal" for r in reference)
    assert _design_values(pooled.folder) == reference
    assert _design_values(dask.folder) == reference
    # b = 1/sqrt(w): 0.25 m and 1/6 m
    assert [float(r["b [m]"]) for r in reference] == pytest.approx([0.25, 1 / 6] * 3, rel=1e-7)


# -- convex path ---------------------------------------------------------------------------
def test_the_lp_path_matches_ipopt_on_a_fixed_geometry_seed_problem():
    from counterpoise.designer.designer import Designer

    problem = load_problem(PROBLEMS / "yasir2019_hybrid.toml")
    lp, nlp = Designer(problem).solve(), Designer(problem, backend="ipopt").solve()
    assert lp.stats.solver == "clarabel" and nlp.stats.solver == "ipopt"
    for slot, value in nlp.values.items():
        assert lp.values[slot] == pytest.approx(value, rel=1e-8, abs=1e-8 * problem.variable[slot.variable].upper)
    assert lp.objective == pytest.approx(nlp.objective, rel=1e-8)


def test_certificate_gap_is_zero_at_the_optimum_and_not_after_a_solve_stopped_early():
    from counterpoise.designer.designer import Designer

    problem = load_problem(PROBLEMS / "yasir2019_free_extensions.toml")
    full = Designer(problem).solve()
    early = Designer(problem, {"max_iter": 3}).solve()
    assert full.stats.solver == "ipopt" and abs(full.stats.certificate_gap) < 1e-9
    # after 3 iterations the masses do not balance the geometry IPOPT stopped at: the LP's differ
    assert early.stats.solver_status == "Maximum_Iterations_Exceeded" and abs(early.stats.certificate_gap) > 1e-4


def test_multistart_reports_how_many_starts_reached_the_best():
    from counterpoise.pipeline import design

    result = design(load_problem(PROBLEMS / "yasir2019_free_extensions.toml", {"objective.inertia_weight": "200 1/m^2"}), starts=4)
    reached, run = result.solution.stats.starts
    assert run == 4 and 1 <= reached <= 4 and result.optimal
    assert result.solution.values[next(s for s in result.solution.values if s.variable == "b_b")] == pytest.approx(200**-0.5, rel=1e-6)


# -- plots ---------------------------------------------------------------------------------
def _png(path):
    data = path.read_bytes()
    return data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000


def test_energy_and_study_plots_are_written(tmp_path):
    from conftest import solved
    from counterpoise.plots import energy_plot, study_plots

    (path,) = energy_plot(solved("yasir2019_counter_mass"), tmp_path / "design")
    assert path.name == "energy.png" and _png(path)
    problem = _pendulum()
    plan = plan_study(problem, ["inertia_weight=4 1/m^2:100 1/m^2:6"], "f")
    outcome = run_study(problem, plan, tmp_path)
    paths = study_plots(outcome.folder)
    assert [p.name for p in paths] == ["study.png", "pareto.png"] and all(_png(p) for p in paths)


# -- command line --------------------------------------------------------------------------
def _cli(args, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(args)
    return exit_.value.code, capsys.readouterr()


def test_study_command_writes_csv_and_plots(tmp_path, capsys):
    file = str(PROBLEMS / "yasir2019_counter_mass.toml")
    code, out = _cli(["study", file, "--vary", "m_c=300 g:500 g:3", "--out", str(tmp_path), "--jobs", "1"], capsys)
    folder = tmp_path / "yasir2019_counter_mass-study"
    assert code == 0 and "3 points run (3 optimal)" in out.out
    assert sorted(p.name for p in folder.iterdir()) == ["study.csv", "study.json", "study.png"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--vary", "nope=1 g:2 g:3"], "--vary nope: unknown key"),
        (["--vary", "m_c=1 mm:2 mm:3"], "--vary m_c: '1 mm' is a length, expected a mass"),
        (["--vary", "m_c=1 g:2 g:0"], "--vary m_c: N must be at least 1"),
        (["--vary", "m_c=1 g:2 g:3", "--samples", "5"], "--vary m_c: gives N"),
        (["--vary", "m_c=1 g:2 g:3", "--scheduler", "tcp://127.0.0.1:9", "--scheduler-timeout", "1"], "--scheduler: cannot reach the Dask scheduler at tcp://127.0.0.1:9"),
    ],
)
def test_bad_study_options_exit_2_with_one_line_and_write_nothing(tmp_path, capsys, args, message):
    file = str(PROBLEMS / "yasir2019_counter_mass.toml")
    code, out = _cli(["study", file, "--out", str(tmp_path), *args], capsys)
    lines = out.err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith(f"{file}: {message}"), out.err
    if "scheduler" in message:
        assert "dask scheduler" in lines[0]  # how to start one
    assert not any(tmp_path.iterdir())


def test_plot_command_redraws_a_study_and_rejects_other_folders(tmp_path, capsys):
    problem = _pendulum()
    outcome = run_study(problem, plan_study(problem, ["m=500 g:900 g:3"], "f"), tmp_path)
    code, out = _cli(["plot", str(outcome.folder / "study.csv")], capsys)
    assert code in (0, None) and "study.png" in out.out and not (outcome.folder / "pareto.png").exists()
    code, out = _cli(["plot", str(tmp_path)], capsys)
    assert code == 2 and out.err.strip().endswith(f"not a study (expected study.csv and study.json in {tmp_path})")


def test_bounds_and_weights_vary_per_point():
    from counterpoise.studies.runners import solve_batch

    # the optimum b = 1/sqrt(w) is cut off by an upper bound below it: b = min(1/sqrt(w), upper)
    task = StudyTask(_pendulum())
    points = [{"b.upper": 0.1}, {"b.upper": 0.3}, {"objective.inertia_weight": 100.0}, {"objective.inertia_weight": 100.0, "b.upper": 0.05}]
    results = solve_batch(task, points)
    assert [r.status for r in results] == ["optimal"] * 4
    assert [r.values["b"] for r in results] == pytest.approx([0.1, 0.2, 0.1, 0.05], rel=1e-7)
    assert [r.values["M"] for r in results] == pytest.approx([0.8 * 0.3 / b for b in (0.1, 0.2, 0.1, 0.05)], rel=1e-7)


def test_solve_with_plot_and_starts(tmp_path, capsys):
    code, _ = _cli(["solve", str(PROBLEMS / "yasir2019_free_extensions.toml"), "--out", str(tmp_path), "--plot", "--starts", "3"], capsys)
    folder = tmp_path / "yasir2019_free_extensions"
    (summary,) = read_rows(folder / "summary.csv")
    assert code == 0 and _png(folder / "energy.png")
    assert summary["starts_reaching_best"].endswith("/3") and abs(float(summary["certificate_gap_kg"])) < 1e-9
    code, out = _cli(["solve", str(PROBLEMS / "yasir2019_free_extensions.toml"), "--out", str(tmp_path / "x"), "--starts", "0"], capsys)
    assert code == 2 and out.err.strip() == "--starts: must be at least 1, got 0" and not (tmp_path / "x").exists()


class _Interrupted:
    """A runner that is interrupted (Ctrl-C) after its first batch."""

    def map_batches(self, task, batches):
        from counterpoise.studies.runners import solve_batch

        yield solve_batch(task, batches[0])
        raise KeyboardInterrupt


def test_an_interrupted_study_keeps_its_finished_batches(tmp_path):
    problem = _pendulum()
    plan = plan_study(problem, ["m=500 g:900 g:5"], "f")
    with pytest.raises(KeyboardInterrupt):
        run_study(problem, plan, tmp_path, _Interrupted(), batch_size=2, flush_seconds=3600)
    assert [r["point"] for r in read_rows(tmp_path / "pendulum-study" / "study.csv")] == ["0", "1"]


def test_a_bare_zero_in_vary_is_zero_in_the_ranges_unit(tmp_path, capsys):
    """docs/studies.md: START and STOP carry units, a bare 0 is allowed (issue 24: it was refused)."""
    from counterpoise.cli import main

    with pytest.raises(SystemExit) as exited:
        main(["study", str(PROBLEMS / "yasir2019_counter_mass.toml"), "--vary", "m_c=0:500 g:3", "--out", str(tmp_path), "--jobs", "1"])
    assert exited.value.code == 0, capsys.readouterr().err
    rows = (tmp_path / "yasir2019_counter_mass-study" / "study.csv").read_text(encoding="utf-8").splitlines()
    assert [r.split(",")[1] for r in rows[1:]] == ["0", "250", "500"]
