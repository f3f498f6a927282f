"""What makes studies faster keeps their results: the study file written once per row, and
matplotlib imported and warmed up while the workers run."""

from __future__ import annotations

import dataclasses
import sys

import pytest

from conftest import PROBLEMS, fresh_python
from counterpoise.cli.app import main
from counterpoise.io.loader import load_problem
from counterpoise.studies.command import PlotPreload
from counterpoise.studies.study import read_rows


def _cli(args, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(args)
    return exit_.value.code, capsys.readouterr()


def test_plot_preload_warms_matplotlib_once_and_only_when_enabled(monkeypatch):
    from counterpoise.plots import study as study_plot

    calls = []
    monkeypatch.setattr(study_plot, "prepare", lambda *args: calls.append(args) or "figure")
    off = PlotPreload(False)
    off.start()
    off.join()
    assert off._thread is None and calls == [] and off.figure is None
    on = PlotPreload(True, {"problem": "p"}, [[1.0]])
    on.start()
    first = on._thread
    on.start()  # a second batch: no second thread
    on.join()
    assert on._thread is first and not first.is_alive()
    assert calls == [({"problem": "p"}, [[1.0]])] and on.figure == "figure"


def test_the_plot_warm_up_draws_without_pyplot_and_writes_nothing(tmp_path, monkeypatch):
    """prepare() imports matplotlib and draws a figure in memory: no file, no pyplot figure."""
    from counterpoise.plots.study import prepare

    monkeypatch.chdir(tmp_path)
    had_pyplot = "matplotlib.pyplot" in sys.modules  # another test may have imported it
    prepare({"problem": "p", "plan": {"method": "grid", "vary": [{"key": "x", "unit": ""}]}, "columns": ["point", "x [1]", "objective_kg"]}, [[0.0, 1.0]])
    assert "matplotlib.figure" in sys.modules and list(tmp_path.iterdir()) == []
    assert had_pyplot or "matplotlib.pyplot" not in sys.modules


def test_pool_study_with_plot_matches_the_serial_study(tmp_path, capsys):
    """--jobs 2 (the preload runs while the pool works) writes the plot and the same rows
    as --jobs 1 (the same batches, so the same values, timings apart)."""
    file = str(PROBLEMS / "yasir2019_counter_mass.toml")
    folders = {}
    for jobs in ("1", "2"):
        out = tmp_path / jobs
        code, printed = _cli(["study", file, "--vary", "m_c=300 g:500 g:5", "--out", str(out), "--jobs", jobs, "--batch-size", "2"], capsys)
        assert code == 0 and "5 points run (5 optimal)" in printed.out
        folders[jobs] = out / "yasir2019_counter_mass-study"
        assert sorted(p.name for p in folders[jobs].iterdir()) == ["study.csv", "study.json", "study.png"]
    serial, pooled = (read_rows(folders[j] / "study.csv") for j in ("1", "2"))
    for row in serial + pooled:
        row.pop("solve_time_s")
    assert serial == pooled


def test_pool_workers_inherit_the_method_built_before_the_fork(tmp_path, capsys, monkeypatch):
    """A --jobs 2 study builds its designer once, in the study's process, before the pool
    forks (each worker built its own before); a weight study still builds in the workers."""
    import multiprocessing
    import os

    from counterpoise.designer import designer as designer_module
    from counterpoise.studies import runners

    if multiprocessing.get_start_method() != "fork":
        pytest.skip("the method is built before the fork only for a fork pool")
    log = tmp_path / "built.txt"
    original = designer_module.Designer.__init__

    def counting(self, *args, **kwargs):
        with open(log, "a", encoding="utf-8") as handle:  # the forked workers write here too
            handle.write(f"{os.getpid()}\n")
        original(self, *args, **kwargs)

    monkeypatch.setattr(designer_module.Designer, "__init__", counting)
    monkeypatch.delattr(runners._WORKER, "methods", raising=False)  # none kept from another test
    file = str(PROBLEMS / "yasir2019_counter_mass.toml")
    code, printed = _cli(["study", file, "--vary", "m_c=300 g:500 g:6", "--out", str(tmp_path / "mass"), "--jobs", "2", "--batch-size", "2", "--no-plot"], capsys)
    assert code == 0 and "6 points run (6 optimal)" in printed.out
    assert log.read_text(encoding="utf-8").split() == [str(os.getpid())]  # one build, here
    log.unlink()
    code, printed = _cli(["study", file, "--vary", "inertia_weight=0 1/m^2:10 1/m^2:2", "--out", str(tmp_path / "weight"), "--jobs", "2", "--batch-size", "1", "--no-plot"], capsys)
    assert code == 0
    assert str(os.getpid()) not in log.read_text(encoding="utf-8").split()  # built per weight in the workers


def test_vary_in_the_files_unit_is_read_as_pint_reads_it_without_pint(monkeypatch):
    """``m_c=300 g:500 g:3`` on a file that writes m_c in g takes the file's unit: the same
    values and unit as pint gives (300 g and 500 g: 0.3 kg and 0.5 kg), with the unit
    registry never asked. Another unit (kg here) still goes through pint."""
    from counterpoise.model import units
    from counterpoise.studies import spec

    problem = load_problem(PROBLEMS / "yasir2019_counter_mass.toml")
    start, stop = units.parse_quantity("300 g"), units.parse_quantity("500 g")  # pint's reading

    def no_pint(*args: object) -> None:
        raise AssertionError("pint asked for a unit the file already resolved")

    monkeypatch.setattr(units, "ureg", no_pint)
    monkeypatch.setattr(units, "display_unit", no_pint)
    monkeypatch.setattr(spec, "parse_quantity", no_pint)
    fast = spec.parse_vary(problem, "m_c=300 g:500 g:3", "f")
    assert (fast.start, fast.stop, fast.unit) == (start.si, stop.si, start.unit) == (start.si, 0.5, stop.unit)
    assert fast.header == "m_c [g]" and fast.count == 3
    with pytest.raises(AssertionError, match="pint asked"):
        spec.parse_vary(problem, "m_c=0.3 kg:0.5 kg:3", "f")


def test_the_study_plot_draws_the_objective_and_each_design_variable_once_laid_out(tmp_path, capsys, monkeypatch):
    """study.png of a one-key grid: one row for the objective and one per design variable of
    yasir2019_counter_mass (M_a, M_b, M_c), none for the text column ``certificate``; the
    figure is drawn once (what the results decide is drawn over that drawing, and the canvas
    written as it is: no second drawing to save or crop it)."""
    from matplotlib.figure import Figure

    from counterpoise.plots import study as study_plot

    file = str(PROBLEMS / "yasir2019_counter_mass.toml")
    code, _ = _cli(["study", file, "--vary", "m_c=300 g:500 g:3", "--out", str(tmp_path), "--jobs", "1", "--no-plot"], capsys)
    assert code == 0
    saved, draws = [], []
    monkeypatch.setattr(study_plot, "save_canvas", lambda fig, path: saved.append((fig, path)))
    draw = Figure.draw
    monkeypatch.setattr(Figure, "draw", lambda self, renderer: draws.append(self) or draw(self, renderer))
    study_plot.study_plots(tmp_path / "yasir2019_counter_mass-study")
    [(fig, path)] = saved
    assert path.name == "study.png" and draws == [fig]
    assert [ax.get_ylabel() for ax in fig.axes] == ["objective [kg]", "M_a [g]", "M_b [g]", "M_c [g]"]
    assert [ax.get_xlabel() for ax in fig.axes] == ["", "", "", "m_c [g]"]  # one shared x axis, labelled under the last row


def test_a_study_without_plot_imports_no_matplotlib(tmp_path):
    """``counterpoise study --no-plot`` in a fresh process: matplotlib is never imported
    (no plot helper, no preload); the study is written."""
    code = (
        "import sys\n"
        "from counterpoise.cli import main\n"
        f"try:\n    main(['study', {str(PROBLEMS / 'yasir2019_counter_mass.toml')!r}, '--vary', 'm_c=300 g:500 g:2', '--jobs', '1', '--no-plot',"
        f" '--out', {str(tmp_path)!r}])\n"
        "except SystemExit as e:\n    code = e.code\n"
        "print(code, sorted(m for m in ('matplotlib',) if m in sys.modules))\n"
    )
    stdout = fresh_python(code)
    assert stdout.strip().splitlines()[-1] == "0 []"
    assert "2 points run (2 optimal)" in stdout
    assert len(read_rows(tmp_path / "yasir2019_counter_mass-study" / "study.csv")) == 2
