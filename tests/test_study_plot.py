"""study.png drawn in two parts (issue 19): the figure up to the results first (possibly
while the study runs, :class:`counterpoise.plots.study.StudyFigure`), then what the results
decide over it. The picture is the one a single whole drawing of the finished figure gives,
pixel for pixel; a study's preloaded figure is used when its layout is the study's.

The study folders here are written by hand (``study.json`` + ``study.csv``, as a study
writes them): the plot reads nothing else, and no point needs solving.
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from counterpoise.plots import study as study_plot

FIXED_AFTER = ["status", "objective_kg", "added_mass_kg", "added_inertia_kg_m2"]
FIXED_END = ["residual_ratio", "certificate", "certificate_gap_kg", "solve_time_s", "solver", "message"]


def _study(folder, method, vary, values, statuses):
    """A study folder of points ``values`` (one tuple of varied values per point) with
    ``statuses``: objective 1 + Σ values / 1000, one design variable M [g] = 2 × the first
    value; a point not optimal keeps a residual ratio of 0.1 (1e-9 when optimal) and its closest design."""
    headers = [f"{key} [{unit}]" for key, unit in vary]
    columns = ["point", *headers, *FIXED_AFTER, "M [g]", *FIXED_END]
    meta = {"problem": "p", "plan": {"method": method, "vary": [{"key": k, "unit": u} for k, u in vary]}, "columns": columns}
    folder.mkdir()
    (folder / "study.json").write_text(json.dumps(meta), encoding="utf-8")
    with (folder / "study.csv").open("w", encoding="utf-8", newline="") as handle:
        out = csv.DictWriter(handle, columns)
        out.writeheader()
        for i, (xs, status) in enumerate(zip(values, statuses)):
            row = dict(zip(headers, map(str, xs)), point=i, status=status, objective_kg=1 + sum(xs) / 1000, added_mass_kg=1, added_inertia_kg_m2=0.1,
                       residual_ratio=1e-9 if status == "optimal" else 0.1, certificate="exact", certificate_gap_kg=0, solve_time_s=0.01, solver="ipopt",
                       message="")
            row["M [g]"] = 2 * xs[0]
            out.writerow(row)
    return meta, [[float(x[j]) for x in values] for j in range(len(vary))]


def _pixels(path):
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"))


def _whole_drawing(fig):
    """The figure drawn again as a whole, as savefig would draw it."""
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3]


GRID = [(300.0 + 20 * i,) for i in range(11)]
LHS = [(200.0 + 17 * ((7 * i) % 12), 170.0 + 4 * ((5 * i) % 12)) for i in range(12)]


@pytest.mark.parametrize(
    ("method", "vary", "values", "failed"),
    [
        ("grid", [("m_c", "g")], GRID, ()),  # curves
        ("grid", [("m_c", "g")], GRID, (3, 7)),  # red crosses, grey crosses and a residual row (log scale)
        ("lhs", [("m_pay", "g"), ("r_b", "mm")], LHS, (0,)),  # two columns of scatter plots
        ("grid", [("m_c", "g")], [(1e6 + 3 * i,) for i in range(11)], ()),  # tick labels with an offset (+1e6)
        ("grid", [("m_c", "g")], [(2e-7 * i,) for i in range(5)], ()),  # with an order of magnitude (1e-6)
    ],
)
def test_the_picture_is_the_whole_drawing_of_the_finished_figure(tmp_path, monkeypatch, method, vary, values, failed):
    made = []
    init = study_plot.StudyFigure.__init__
    monkeypatch.setattr(study_plot.StudyFigure, "__init__", lambda self, layout: made.append(self) or init(self, layout))
    _study(tmp_path / "s", method, vary, values, ["infeasible" if i in failed else "optimal" for i in range(len(values))])
    [path] = study_plot.study_plots(tmp_path / "s")
    [figure] = made
    assert path.name == "study.png" and (_pixels(path) == _whole_drawing(figure.fig)).all()
    assert [ax.get_ylabel() for ax in figure.axes[:, 0]] == ["objective [kg]", *(["residual ratio"] if failed else []), "M [g]"]
    for j, (key, unit) in enumerate(vary):  # each column spans every point, optimal or not, with 5 % margins
        x = [v[j] for v in values]
        span = max(x) - min(x)
        # the column shares its x axis: labelled under its last row only
        assert [ax.get_xlabel() for ax in figure.axes[:, j]] == [""] * (len(figure.axes) - 1) + [f"{key} [{unit}]"]
        for ax in figure.axes[:, j]:
            assert ax.get_xlim() == pytest.approx((min(x) - 0.05 * span, max(x) + 0.05 * span))
    for row in figure.axes:  # a row (one variable) shares its y axis: labelled left of its first column only
        assert all(ax.get_ylabel() == "" for ax in row[1:]) and row[0].get_ylabel()
    if failed:
        assert figure.axes[1, 0].get_yscale() == "log"
        assert figure.title.get_text().endswith(f"{len(values)} points ({method}), {len(values) - len(failed)} optimal")


def test_a_prepared_figure_is_used_when_its_layout_is_the_studys(tmp_path):
    """prepare() from the study's plan (every point optimal): used by the plot of that study,
    and not for a study of another layout (here a point failed: one row more), which gets a
    figure of its own."""
    meta, xs = _study(tmp_path / "ok", "grid", [("m_c", "g")], GRID, ["optimal"] * len(GRID))
    prepared = study_plot.prepare(meta, xs)
    assert not prepared.used
    study_plot.study_plots(tmp_path / "ok", prepared)
    assert prepared.used  # the figure drawn, once: a second use is refused
    with pytest.raises(RuntimeError, match="drawn once"):
        prepared.finish(meta, [], {}, np.array([]), tmp_path / "x.png")
    meta, xs = _study(tmp_path / "failed", "grid", [("m_c", "g")], GRID, ["optimal"] * 10 + ["infeasible"])
    prepared = study_plot.prepare(meta, xs)
    study_plot.study_plots(tmp_path / "failed", prepared)
    assert not prepared.used and _pixels(tmp_path / "failed" / "study.png").shape[0] > _pixels(tmp_path / "ok" / "study.png").shape[0]


@pytest.fixture
def forking(monkeypatch):
    """The plot helper is forked as on the command line: a test run may have left threads
    of its own (a Dask client's), for which the command would prepare the plot in a
    thread instead (:meth:`counterpoise.plotter.PlotProcess.fork_if_useful`)."""
    import multiprocessing

    from counterpoise import plotter

    if "fork" not in multiprocessing.get_all_start_methods():
        pytest.skip("the helper is forked")
    monkeypatch.setattr(plotter, "active_count", lambda: 1)


def _study_command(tmp_path, capsys, *extra):
    from conftest import PROBLEMS
    from counterpoise.cli.app import main

    file = str(PROBLEMS / "yasir2019_counter_mass.toml")
    with pytest.raises(SystemExit) as exit_:
        main(["study", file, "--vary", "m_c=300 g:500 g:4", "--out", str(tmp_path), "--batch-size", "2", *extra])
    return exit_.value.code, capsys.readouterr()


def _logged(monkeypatch, log, name):
    """Each call of StudyFigure.``name`` writes its process id to ``log`` (from a forked
    process too)."""
    import os

    method = getattr(study_plot.StudyFigure, name)

    def logged(self, *args):
        with open(log, "a", encoding="utf-8") as handle:
            handle.write(f"{name} {os.getpid()}\n")
        return method(self, *args)

    monkeypatch.setattr(study_plot.StudyFigure, name, logged)


def test_a_pool_study_plots_in_a_helper_process_on_the_figure_prepared_from_its_plan(tmp_path, capsys, monkeypatch, forking):
    """A --jobs 2 study forks a helper that prepares study.png from the plan while the points
    are solved (the varied range is known from the plan: the prepared layout is the
    finished study's) and then draws the results on it: one StudyFigure in all, made and
    finished in the helper; the study's process draws nothing and no helper is left."""
    import multiprocessing
    import os

    log = tmp_path / "figures.txt"
    _logged(monkeypatch, log, "__init__")
    _logged(monkeypatch, log, "finish")
    code, printed = _study_command(tmp_path, capsys, "--jobs", "2")
    assert code == 0 and "4 points run (4 optimal)" in printed.out and printed.err.count("\n") <= 1
    [(made, pid), (finished, same)] = [line.split() for line in log.read_text(encoding="utf-8").splitlines()]
    assert (made, finished) == ("__init__", "finish") and pid == same != str(os.getpid())
    assert _pixels(tmp_path / "yasir2019_counter_mass-study" / "study.png").shape[2] == 3
    assert multiprocessing.active_children() == []


def test_a_helper_that_fails_leaves_the_plot_to_the_study(tmp_path, capsys, monkeypatch, forking):
    """The helper's plot fails (here: writing it): the study's process draws it instead, and
    the helper printed nothing."""
    import os

    parent = os.getpid()
    finish = study_plot.StudyFigure.finish

    failed = tmp_path / "failed.txt"

    def failing_in_the_helper(self, *args):
        if os.getpid() != parent:
            failed.write_text("helper", encoding="utf-8")
            raise OSError("disk full")
        return finish(self, *args)

    monkeypatch.setattr(study_plot.StudyFigure, "finish", failing_in_the_helper)
    code, printed = _study_command(tmp_path / "out", capsys, "--jobs", "2")
    assert code == 0 and "disk full" not in printed.err and failed.read_text(encoding="utf-8") == "helper"
    assert (tmp_path / "out" / "yasir2019_counter_mass-study" / "study.png").exists()


def test_a_study_refused_ends_its_helper(tmp_path, capsys, forking):
    """A study that stops before its points (here: --resume of another plan) leaves no helper
    process behind."""
    import multiprocessing

    assert _study_command(tmp_path, capsys, "--jobs", "1", "--no-plot")[0] == 0
    from conftest import PROBLEMS
    from counterpoise.cli.app import main

    with pytest.raises(SystemExit) as exit_:
        main(["study", str(PROBLEMS / "yasir2019_counter_mass.toml"), "--vary", "m_c=300 g:400 g:4", "--out", str(tmp_path), "--jobs", "2", "--resume"])
    assert exit_.value.code == 2 and "--resume" in capsys.readouterr().err
    assert multiprocessing.active_children() == []


@pytest.mark.skipif(not __import__("pathlib").Path("/proc").exists(), reason="reads /proc")
def test_ctrl_c_ends_the_plot_helper_with_the_workers(tmp_path):
    """Ctrl-C during a plotted pool study (a real process: signals): exit 130, one line, and
    neither the pool workers nor the plot helper (three children) outlive the study."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    from conftest import PROBLEMS, ROOT
    from test_faults import START_WAIT_S, _children

    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    args = [sys.executable, "-c", "from counterpoise.cli import main; main()", "study", str(PROBLEMS / "yasir2019_hybrid.toml"),
            "--vary", "m_endo=400 g:1000 g:100000", "--jobs", "2", "--out", str(tmp_path)]
    process = subprocess.Popen(  # SIGINT as a terminal's Ctrl-C meets it (see test_faults), in a process group of its own
        args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + START_WAIT_S
        while len(children := _children(process.pid)) < 3 and time.monotonic() < deadline and process.poll() is None:
            time.sleep(0.2)
        assert len(children) == 3
        time.sleep(1.0)
        os.killpg(process.pid, signal.SIGINT)  # Ctrl-C: to the whole group, helper and workers too
        _, err = process.communicate(timeout=START_WAIT_S)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 130 and "Traceback" not in err
    assert "interrupted" in err.strip().splitlines()[-1]
    time.sleep(0.5)
    assert [p for p in children if Path(f"/proc/{p}").exists() and "Z" not in (Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()[0])] == []


def test_a_file_that_does_not_load_ends_the_helper_forked_before_it(tmp_path, capsys, forking):
    """The helper is forked before the file is loaded: a file that does not load is still one
    line, exit 2, nothing written, and no helper left."""
    import multiprocessing

    from counterpoise.cli.app import main

    with pytest.raises(SystemExit) as exit_:
        main(["study", str(tmp_path / "missing.toml"), "--vary", "m=1 g:2 g:3", "--out", str(tmp_path / "out"), "--jobs", "2"])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and len(err.strip().splitlines()) == 1 and "missing.toml" in err
    assert not (tmp_path / "out").exists() and multiprocessing.active_children() == []


def test_markers_of_a_line_draw_the_pixels_of_a_scatter_of_the_same_size():
    """study.png draws the points of its rows below the objective (no legend there) as a
    Line2D of markers, a quarter of a scatter's cost to make: the same pixels as the
    scatter of size 8 pt² (marker size √8 pt, edge 1 pt, edge colour the face's) it
    replaces, here 200 points of a 4 × 3 in figure."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    x, y = np.random.default_rng(0).uniform(0, 1, (2, 200))
    drawn = []
    for scatter in (True, False):
        fig = Figure(figsize=(4, 3), dpi=study_plot.DPI)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        if scatter:
            ax.scatter(x, y, s=8, color="tab:blue", zorder=2)
        else:
            ax.plot(x, y, linestyle="none", marker="o", markersize=np.sqrt(8), markeredgewidth=1.0, color="tab:blue", zorder=2)
        fig.canvas.draw()
        drawn.append(np.asarray(fig.canvas.buffer_rgba()).copy())
    assert (drawn[0] == drawn[1]).all()


def test_the_layout_sent_to_the_helper_does_not_grow_with_the_points():
    """plot_inputs sends each varied key's least and greatest value (what the layout reads
    of them), not every point's: a 10,000-point study's message to the plot helper is the
    size of a 2-point one's (a large one blocked the study until the helper, still
    importing matplotlib, read it)."""
    from conftest import PROBLEMS
    from counterpoise.io.loader import load_problem
    from counterpoise.studies.command import plot_inputs
    from counterpoise.studies.spec import plan_study

    problem = load_problem(PROBLEMS / "yasir2019_hybrid.toml")
    _, xs = plot_inputs(problem, plan_study(problem, ["m_endo=400 g:1000 g:10000"], "f"))
    assert xs == [[400.0, 1000.0]]
