"""What makes studies faster keeps their results: the study file written once per row, and
matplotlib imported and warmed up while the workers run."""

from __future__ import annotations

import sys

import pytest

from conftest import PROBLEMS
from counterpoise.cli.app import main
from counterpoise.studies.command import PlotPreload
from counterpoise.studies.study import read_rows


def _cli(args, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(args)
    return exit_.value.code, capsys.readouterr()


def test_plot_preload_warms_matplotlib_once_and_only_when_enabled(monkeypatch):
    from counterpoise.plots import study as study_plot

    calls = []
    monkeypatch.setattr(study_plot, "prepare", lambda: calls.append(1))
    off = PlotPreload(False)
    off.start()
    off.join()
    assert off._thread is None and calls == []
    on = PlotPreload(True)
    on.start()
    first = on._thread
    on.start()  # a second batch: no second thread
    on.join()
    assert on._thread is first and not first.is_alive()
    assert calls == [1]


def test_the_plot_warm_up_draws_without_pyplot_and_writes_nothing(tmp_path, monkeypatch):
    """prepare() imports matplotlib and draws a figure in memory: no file, no pyplot figure."""
    from counterpoise.plots.study import prepare

    monkeypatch.chdir(tmp_path)
    had_pyplot = "matplotlib.pyplot" in sys.modules  # another test may have imported it
    prepare()
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
