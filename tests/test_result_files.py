"""Result folders appear whole or not at all, and files follow the umask (issue 13, faults)."""

from __future__ import annotations

import os
import resource
import signal
import stat
import threading

import pytest

from conftest import PROBLEMS
from counterpoise.io.loader import load_problem
from counterpoise.pipeline import design
from counterpoise.report.files import report_texts, write_reports
from counterpoise.studies.spec import plan_study
from counterpoise.studies.study import run_study

FILE = PROBLEMS / "yasir2019_counter_mass.toml"


@pytest.fixture(scope="module")
def two_results():
    return [design(load_problem(FILE, {"parameters.m_c": f"{g} g"})) for g in (400, 800)]


@pytest.fixture
def umask_022():
    old = os.umask(0o022)
    yield
    os.umask(old)


def _mode(path):
    return stat.S_IMODE(path.stat().st_mode)


def test_reports_and_study_files_follow_the_umask(tmp_path, two_results, umask_022):
    folder = write_reports(two_results[0], tmp_path)
    assert _mode(folder) == 0o755
    assert {p.name: _mode(p) for p in folder.iterdir()} == {p.name: 0o644 for p in folder.iterdir()}
    problem = two_results[0].problem
    outcome = run_study(problem, plan_study(problem, ["r_a=130 mm:140 mm:2"], "f"), tmp_path)
    assert _mode(outcome.folder / "study.csv") == 0o644
    assert _mode(outcome.folder / "study.json") == 0o644


def test_a_full_disk_leaves_the_previous_folder_whole(tmp_path, two_results):
    first, second = two_results
    folder = write_reports(first, tmp_path)
    before = {p.name: p.read_text() for p in folder.iterdir()}
    sizes = sorted(len(t.encode()) for t in report_texts(second).values())
    limit = sizes[len(sizes) // 2]  # the smaller files fit, the larger ones do not: like a disk filling up
    old_handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, hard))
    try:
        with pytest.raises(OSError):
            write_reports(second, tmp_path)
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, old_handler)
    assert {p.name: p.read_text() for p in folder.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [folder.name]  # no temporary folder left


def test_concurrent_writers_each_leave_a_whole_folder(tmp_path, two_results):
    texts = [report_texts(r) for r in two_results]
    errors = []

    def writer(result):
        try:
            for _ in range(15):
                write_reports(result, tmp_path)
        except OSError as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=writer, args=(r,)) for r in two_results]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    folder = tmp_path / two_results[0].problem.name
    found = {p.name: p.read_text() for p in folder.iterdir()}
    assert found in texts
    assert sorted(p.name for p in tmp_path.iterdir()) == [folder.name]


def test_worst_configuration_names_its_coordinates(two_results):
    from counterpoise.report.rows import verification_rows

    rows = verification_rows(two_results[0])
    cells = rows[0]["worst_configuration"].split("; ")
    assert [c.split("=")[0] for c in cells] == ["theta_a", "theta_b", "theta_c"]
    assert all(c.endswith(" deg") for c in cells)


def test_the_energy_plot_legend_lists_the_unbalanced_curves_once(tmp_path, two_results, monkeypatch):
    from counterpoise.plots import energy as energy_module

    legends = []

    def keep(fig, path):
        legends.append([t.get_text() for legend in fig.legends for t in legend.get_texts()])
        energy_module.pyplot().close(fig)

    monkeypatch.setattr(energy_module, "save", keep)
    energy_module.energy_plot(two_results[0], tmp_path)
    assert sum("(unbalanced)" in text for text in legends[0]) == 1


def test_the_solve_table_shows_summary_csv_solve_time(tmp_path, capsys):
    import csv

    from counterpoise.cli.app import main

    with pytest.raises(SystemExit):
        main(["solve", str(FILE), "--out", str(tmp_path), "--wide"])
    out = capsys.readouterr().out
    summary = next(csv.DictReader((tmp_path / "yasir2019_counter_mass" / "summary.csv").open()))
    assert "solve (s)" in out and "total (s)" in out
    row = next(line for line in out.splitlines() if "yasir2019_counter_mass" in line and "optimal" in line)
    assert f"{float(summary['solve_time_s']):.3f}" in row


def test_the_default_summary_fits_80_columns_and_names_the_parts():
    """Issue 24: at 80 columns the table read "optim…", "probl…". The default shows fewer
    columns (--wide: all), folds rather than cuts, and names the chosen parts."""
    import io

    from rich.console import Console

    from counterpoise.cli.app import print_summary

    row = {
        "problem": "essomba2021_orientation_catalogue", "status": "optimal", "added_mass_kg": 0.0, "added_inertia_kg_m2": 0.0,
        "objective": 0.0, "residual_ratio": 1.2e-15, "checked_configurations": 10004, "solve_time_s": 0.1, "wall_s": 1.5,
        "parts": "spring_a: CP-EXT-0324; spring_b: CP-EXT-0111", "folder": "results/x", "message": "",
    }
    buffer = io.StringIO()
    print_summary([row], console=Console(file=buffer, width=80))
    text = buffer.getvalue()
    assert "…" not in text and max(len(line) for line in text.splitlines()) <= 80
    assert "optimal" in text and "CP-EXT-0324" in text and "configs" not in text
    wide = io.StringIO()
    print_summary([row], wide=True, console=Console(file=wide, width=200))
    assert "configs" in wide.getvalue() and "solve (s)" in wide.getvalue()


def test_the_summary_shows_the_balancer_as_built_and_says_ideal_springs():
    """The table's "as built" column is summary.csv's residual_ratio_as_built; a paper's
    idealised design (spring_model ideal) says so in its status cell."""
    import io

    from rich.console import Console

    from counterpoise.cli.app import print_summary

    row = {
        "problem": "yasir2019_hybrid", "status": "optimal", "added_mass_kg": 5.753, "added_inertia_kg_m2": 0.0, "objective": 5.753,
        "residual_ratio": 1.3e-15, "residual_ratio_as_built": 0.662, "spring_model": "ideal", "checked_configurations": 30024,
        "solve_time_s": 0.01, "wall_s": 0.5, "parts": "", "folder": "results/x", "message": "",
    }
    buffer = io.StringIO()
    print_summary([row], console=Console(file=buffer, width=80))
    text = buffer.getvalue()
    assert "as built" in text and "6.62e-01" in text and "optimal" in text and "(ideal)" in text
