"""Plots of a study folder (``study.csv`` + ``study.json``): curves and a Pareto front.

``study.png``: the objective and every design variable (rows) against each varied key
(columns), in the CSV's display units; points that did not end ``optimal`` are marked
with a red cross on the objective row, and then a row of ``residual_ratio`` (every point,
log scale) shows how far from balance each point's closest design stays. Each column's
x range is the range of every point of the study (optimal or not), with matplotlib's
default 5 % margins. ``pareto.png`` (when an objective weight is varied): added mass
against added inertia of the optimal points, coloured by the weight.

``study.png`` is drawn in two parts (:class:`StudyFigure`): what does not depend on the
points' results (the figure, its axes in the fixed layout, the x axes, labels and grid) is
laid out and rasterized first, possibly while the study runs; then only what depends on
the results (the y axes, the curves, the legend, the title) is drawn over it, and the
canvas written as PNG. Every artist is drawn once.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ._mpl import DPI, pyplot, save, save_canvas

#: columns of ``study.csv`` that are not a design variable (the ``certificate`` column is text)
FIXED = {"point", "status", "objective_kg", "added_mass_kg", "added_inertia_kg_m2", "residual_ratio", "certificate", "certificate_gap_kg", "solve_time_s",
         "solver", "message"}
TEXT = ("status", "certificate", "solver", "message")

#: the fixed layout of ``study.png``, in inches: room left of the first column of axes for
#: its tick labels and y label, right of the last one, above the first row for the two-line
#: title (which starts TITLE_TOP below the top edge), below the last row for its tick
#: labels and x label; the axes of a column share their x axis and those of a row their y
#: axis (one variable per row), so only the outer ones are labelled, GAP_X and GAP_Y apart;
#: each axes is AXES_HEIGHT high. A layout computed from the drawn text (``tight_layout``,
#: ``bbox_inches="tight"``) draws the figure once more each; this one is set before the
#: only drawing.
LEFT, RIGHT, TOP, BOTTOM, TITLE_TOP = 1.0, 0.3, 0.8, 0.55, 0.1
GAP_X, GAP_Y, AXES_HEIGHT = 0.25, 0.15, 1.75

#: y tick objects made with each axes before its results are known (matplotlib makes them on
#: demand, ~1 ms each, when the axis is drawn: one per location of its locator, in its view
#: or next to it); those made here cost the helper's CPU while the study's points are
#: solved, those missing are made after them, when the study waits
Y_TICKS = 6


@dataclass(frozen=True)
class Layout:
    """What ``study.png`` looks like before the points' results are drawn: the varied
    headers (columns of axes), the rows (``objective_kg``, ``residual_ratio`` when a point
    is not optimal, then the design variables) and each column's x range (least and
    greatest varied value of every point; None without a finite value)."""

    varied: tuple[str, ...]
    ys: tuple[str, ...]
    xranges: tuple[tuple[float, float] | None, ...]


def varied_headers(meta: Mapping[str, Any]) -> list[str]:
    """The CSV headers of the varied keys of the study ``meta`` (``study.json``)."""
    return [f"{v['key']} [{v['unit'] or '1'}]" for v in meta["plan"]["vary"]]


def layout(meta: Mapping[str, Any], xs: Sequence[Sequence[float] | Any], residual: bool = False) -> Layout:
    """The :class:`Layout` of the study ``meta`` (``study.json``'s content) whose points
    have the varied values ``xs`` (one sequence per varied key, in ``meta``'s order, as
    ``study.csv`` holds them); ``residual``: a row of residual ratios (some point not optimal)."""
    varied = varied_headers(meta)
    variables = [c for c in meta["columns"] if c not in FIXED and c not in varied and c not in meta.get("text_columns", ())]
    ys = ["objective_kg"] + (["residual_ratio"] if residual else []) + variables
    ranges: list[tuple[float, float] | None] = []
    for x in xs:
        finite = np.asarray(x, dtype=float)
        finite = finite[np.isfinite(finite)]
        ranges.append((float(finite.min()), float(finite.max())) if finite.size else None)
    return Layout(tuple(varied), tuple(ys), tuple(ranges))


class StudyFigure:
    """``study.png`` of one :class:`Layout`, drawn up to the points' results: the figure
    (Agg canvas, not pyplot's) and its axes in the fixed layout, with their x range, x and y
    labels and grid, rasterized without the y axes, spines and title
    (:meth:`__init__`); :meth:`finish` draws the results over it and writes the PNG.
    Nothing in it depends on the results, so it can be made while the study runs (in a
    thread or another process); it is used once."""

    def __init__(self, layout: Layout) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.layout = layout
        self.used = False
        nrows, ncols = len(layout.ys), len(layout.varied)
        width, height = max(7.0, 5.0 * ncols + 1), TOP + BOTTOM + nrows * AXES_HEIGHT + (nrows - 1) * GAP_Y
        axes_width = (width - LEFT - RIGHT - (ncols - 1) * GAP_X) / ncols
        fig = Figure(figsize=(width, height), dpi=DPI)
        self.canvas = FigureCanvasAgg(fig)
        self.fig = fig
        self.axes = fig.subplots(nrows, ncols, squeeze=False, sharex="col", sharey="row", gridspec_kw={
            "left": LEFT / width, "right": 1 - RIGHT / width, "bottom": BOTTOM / height, "top": 1 - TOP / height,
            "wspace": GAP_X / axes_width, "hspace": GAP_Y / AXES_HEIGHT})
        self.title = fig.suptitle("", fontsize=11, y=1 - TITLE_TOP / height, va="top")
        for j, (x_name, xrange) in enumerate(zip(layout.varied, layout.xranges)):
            for i, y_name in enumerate(layout.ys):
                ax = self.axes[i, j]
                ax.set_xlabel(x_name)
                ax.set_ylabel(y_name.replace("objective_kg", "objective [kg]").replace("residual_ratio", "residual ratio"))
                ax.grid(alpha=0.3)
                if xrange is not None:  # as autoscaling would set it from every point
                    lo, hi = ax.xaxis.get_major_locator().nonsingular(*xrange)
                    margin = (hi - lo) * ax.margins()[0]
                    ax.set_xlim(lo - margin, hi + margin)
                ax.set_autoscalex_on(False)  # the x axis is drawn now: the curves must not move it
                ax.label_outer()  # tick labels and axis labels on the outer axes only (shared axes)
        # what the results decide is drawn by finish(): hidden from the first drawing
        self._later = [self.title] + [a for ax in self.axes.flat for a in (ax.yaxis, *ax.spines.values())]
        for artist in self._later:
            artist.set_visible(False)
        self.canvas.draw()
        for ax in self.axes.flat:
            ax.yaxis.get_major_ticks(Y_TICKS)

    def finish(self, meta: Mapping[str, Any], rows: Sequence[Mapping[str, str]], data: Mapping[str, Any], ok: Any, path: Path) -> None:
        """Draw the results (``data``: a float array per column of ``study.csv``, ``ok``: which
        points ended optimal) over the figure and write it to ``path``."""
        if self.used:
            raise RuntimeError("a StudyFigure is drawn once")
        self.used = True
        one_axis = len(self.layout.varied) == 1 and meta["plan"]["method"] == "grid"
        drawn: list[Any] = []
        for j, x_name in enumerate(self.layout.varied):
            x = data[x_name]
            order = np.argsort(x, kind="stable")
            for i, y_name in enumerate(self.layout.ys):
                ax = self.axes[i, j]
                y = data[y_name]
                sel = order[ok[order]]
                if y_name == "residual_ratio":  # every point: the closest design's residual, not only the optimal ones
                    sel = order[np.isfinite(y[order])]
                    if (y[sel] > 0).all() and sel.size:
                        ax.set_yscale("log")
                label = "every point" if y_name == "residual_ratio" else "optimal"
                # markers at the curves' zorder 2, over the x grid (drawn before the results)
                if one_axis:
                    ax.plot(x[sel], y[sel], marker="o" if len(rows) <= 200 else None, markersize=3, linewidth=1.5, color="tab:blue", label=label)
                elif i == 0:  # a scatter, for the legend's handle
                    ax.scatter(x[sel], y[sel], s=8, color="tab:blue", label=label, zorder=2)
                else:  # the same markers as a scatter of size 8 pt², a quarter of its cost to make (no legend here)
                    ax.plot(x[sel], y[sel], linestyle="none", marker="o", markersize=np.sqrt(8), markeredgewidth=1.0, color="tab:blue", label=label, zorder=2)
                if i > 0 and y_name != "residual_ratio" and (~ok).any():  # the closest designs of the points not optimal
                    bad = ~ok & np.isfinite(x) & np.isfinite(y)
                    ax.scatter(x[bad], y[bad], marker="x", s=14, color="0.5", label="closest design (not optimal)", zorder=2)
                if i == 0 and (~ok).any():
                    bad = ~ok & np.isfinite(x)
                    ax.scatter(x[bad], np.where(np.isfinite(y[bad]), y[bad], np.nanmin(y[sel]) if sel.size else 0.0), marker="x", color="red",
                               label=f"not optimal ({int((~ok).sum())})", zorder=2)
                if i == 0:
                    ax.legend(fontsize=8, loc="best")
                drawn.append(ax)
        self.title.set_text(f"{meta['problem']}: study of {', '.join(self.layout.varied)}\n{len(rows)} points ({meta['plan']['method']}), {int(ok.sum())} optimal")
        for artist in self._later:
            artist.set_visible(True)
        renderer = self.canvas.get_renderer()  # the one drawn on by __init__, same size and resolution
        later = set(self._later)
        for ax in drawn:
            ax.get_ylim()  # the y range autoscaled to the curves
            fresh = later | set(ax.lines) | set(ax.collections) | ({ax.legend_} if ax.legend_ is not None else set())
            # in the order Axes.draw draws them (by zorder, stable)
            for artist in sorted((a for a in ax.get_children() if a in fresh), key=lambda a: a.get_zorder()):
                artist.draw(renderer)
        self.title.draw(renderer)
        save_canvas(self.fig, path)


def load() -> None:
    """Import what :class:`StudyFigure` draws and writes with."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: F401
    from matplotlib.figure import Figure  # noqa: F401
    from PIL import PngImagePlugin  # noqa: F401


def prepare(meta: Mapping[str, Any], xs: Sequence[Sequence[float]]) -> StudyFigure:
    """The :class:`StudyFigure` of a study whose points all end optimal (the usual
    case: :func:`study_plots` makes another when they do not), drawn up to the results;
    its drawing imports matplotlib and fills its caches (the font...). ``meta``:
    ``study.json``'s content, ``xs``: each varied key's values, of which the layout reads
    the least and the greatest (:func:`layout`). For a thread or another process of a
    study's while its points are solved (:class:`counterpoise.studies.command.PlotPreload`,
    :mod:`counterpoise.plotter`)."""
    load()
    return StudyFigure(layout(meta, xs))


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return float("nan")


def study_plots(folder: str | Path, prepared: StudyFigure | None = None) -> list[Path]:
    """Write ``study.png`` (and ``pareto.png`` when a weight was varied) into ``folder``.

    ``prepared``: a :class:`StudyFigure` made for this study (:func:`prepare`), used when
    its layout is this study's, else a new one is made."""
    folder = Path(folder)
    meta = json.loads((folder / "study.json").read_text(encoding="utf-8"))
    with (folder / "study.csv").open(encoding="utf-8", newline="") as handle:
        rows = list(csv.DictReader(handle))
    columns = meta["columns"]
    varied = varied_headers(meta)
    ok = np.array([r["status"] == "optimal" for r in rows], dtype=bool)
    data = {c: np.array([_number(r.get(c, "")) for r in rows]) for c in columns if c not in TEXT and c not in meta.get("text_columns", ())}
    residual = bool((~ok).any()) and "residual_ratio" in data and bool(np.isfinite(data["residual_ratio"]).any())
    wanted = layout(meta, [data[x] for x in varied], residual)
    figure = prepared if prepared is not None and not prepared.used and prepared.layout == wanted else StudyFigure(wanted)
    paths = [folder / "study.png"]
    figure.finish(meta, rows, data, ok, paths[0])
    weights = [v for v in varied if v.startswith("objective.")]
    if weights:
        w = data[weights[0]]
        plt = pyplot()
        fig, ax = plt.subplots(figsize=(7, 5))
        sel = np.argsort(w, kind="stable")
        sel = sel[ok[sel]]
        inertia, mass = data["added_inertia_kg_m2"][sel], data["added_mass_kg"][sel]
        ax.plot(inertia, mass, color="0.6", linewidth=1, zorder=1)
        points = ax.scatter(inertia, mass, c=w[sel], cmap="viridis", s=28, zorder=2)
        fig.colorbar(points, ax=ax, label=weights[0])
        ax.set_xlabel("added inertia Σ M d² [kg·m²]")
        ax.set_ylabel("added mass Σ M [kg]")
        ax.set_title(f"{meta['problem']}: Pareto front of added mass and added inertia\n(each point: the optimum for one {weights[0]})", fontsize=11)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        paths.append(folder / "pareto.png")
        save(fig, paths[1])
    return paths
