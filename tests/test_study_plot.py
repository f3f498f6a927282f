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
        for ax in figure.axes[:, j]:
            assert ax.get_xlabel() == f"{key} [{unit}]"
            assert ax.get_xlim() == pytest.approx((min(x) - 0.05 * span, max(x) + 0.05 * span))
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


def test_the_study_command_plots_with_the_figure_prepared_from_its_plan(tmp_path, capsys, monkeypatch):
    """A --jobs 2 study prepares study.png from its plan while its points are solved (every
    point of the varied range is known from the plan: the prepared layout is the finished
    study's) and draws the results on that figure: one StudyFigure in all."""
    from conftest import PROBLEMS
    from counterpoise.cli.app import main

    made = []
    init = study_plot.StudyFigure.__init__
    monkeypatch.setattr(study_plot.StudyFigure, "__init__", lambda self, layout: made.append(self) or init(self, layout))
    file = str(PROBLEMS / "yasir2019_counter_mass.toml")
    with pytest.raises(SystemExit) as exit_:
        main(["study", file, "--vary", "m_c=300 g:500 g:4", "--out", str(tmp_path), "--jobs", "2", "--batch-size", "2"])
    assert exit_.value.code == 0 and "4 points run (4 optimal)" in capsys.readouterr().out
    [figure] = made
    assert figure.used and (tmp_path / "yasir2019_counter_mass-study" / "study.png").exists()
