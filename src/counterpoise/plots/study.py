"""Plots of a study folder (``study.csv`` + ``study.json``): curves and a Pareto front.

``study.png``: the objective and every design variable (rows) against each varied key
(columns), in the CSV's display units; points that did not end ``optimal`` are marked
with a red cross on the objective row, and then a row of ``residual_ratio`` (every point,
log scale) shows how far from balance each point's closest design stays. ``pareto.png`` (when an objective weight is
varied): added mass against added inertia of the optimal points, coloured by the weight.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np

from ._mpl import pyplot, save

#: columns of ``study.csv`` that are not a design variable (the ``certificate`` column is text)
FIXED = {"point", "status", "objective_kg", "added_mass_kg", "added_inertia_kg_m2", "residual_ratio", "certificate", "certificate_gap_kg", "solve_time_s",
         "solver", "message"}
TEXT = ("status", "certificate", "solver", "message")

#: the fixed layout of ``study.png``, in inches: room left of each column of axes for its
#: tick labels and y label, right of the last one, above the first row for the two-line
#: title (which starts TITLE_TOP below the top edge), below each row for its tick labels
#: and x label. A layout computed from the drawn text (``tight_layout``, ``bbox_inches=
#: "tight"``) draws the figure once more each; this one is set before the only drawing.
LEFT, RIGHT, TOP, BOTTOM, TITLE_TOP = 1.0, 0.3, 0.8, 0.55, 0.1


def _grid(nrows: int, ncols: int) -> tuple[Any, Any]:
    """A figure of ``nrows`` × ``ncols`` axes in the fixed layout (Agg canvas, not pyplot's)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    width, height = max(7.0, 5.0 * ncols + 1), 2.3 * nrows + 1.2
    axes_width = (width - LEFT - RIGHT - (ncols - 1) * LEFT) / ncols
    axes_height = (height - TOP - BOTTOM - (nrows - 1) * BOTTOM) / nrows
    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=False, gridspec_kw={
        "left": LEFT / width, "right": 1 - RIGHT / width, "bottom": BOTTOM / height, "top": 1 - TOP / height,
        "wspace": LEFT / axes_width, "hspace": BOTTOM / axes_height})
    return fig, axes


def prepare() -> None:
    """Import what :func:`study_plots` draws with and draw a small figure of the same kind,
    written nowhere: the font is loaded and matplotlib's caches are filled, so the plot
    after a study costs its own drawing only. For a thread of the study's process while
    pool workers solve the points (:class:`counterpoise.studies.command.PlotPreload`)."""
    from PIL import PngImagePlugin  # noqa: F401 - imported for the PNG writer

    fig, axes = _grid(1, 1)
    ax = axes[0, 0]
    ax.plot([0.0, 1.0], [0.0, 1.0], color="tab:blue", label="optimal")
    ax.set_xlabel("x [1]")
    ax.set_ylabel("y [1]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.suptitle("study\npoints", fontsize=11)
    fig.canvas.draw()


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return float("nan")


def study_plots(folder: str | Path) -> list[Path]:
    """Write ``study.png`` (and ``pareto.png`` when a weight was varied) into ``folder``."""
    folder = Path(folder)
    meta = json.loads((folder / "study.json").read_text(encoding="utf-8"))
    with (folder / "study.csv").open(encoding="utf-8", newline="") as handle:
        rows = list(csv.DictReader(handle))
    columns = meta["columns"]
    varied = [f"{v['key']} [{v['unit'] or '1'}]" for v in meta["plan"]["vary"]]
    variables = [c for c in columns if c not in FIXED and c not in varied]
    ok = np.array([r["status"] == "optimal" for r in rows], dtype=bool)
    data = {c: np.array([_number(r.get(c, "")) for r in rows]) for c in columns if c not in TEXT}
    residual = (~ok).any() and "residual_ratio" in data and bool(np.isfinite(data["residual_ratio"]).any())
    ys = ["objective_kg"] + (["residual_ratio"] if residual else []) + variables
    fig, axes = _grid(len(ys), len(varied))
    one_axis = len(varied) == 1 and meta["plan"]["method"] == "grid"
    for j, x_name in enumerate(varied):
        x = data[x_name]
        order = np.argsort(x, kind="stable")
        for i, y_name in enumerate(ys):
            ax = axes[i, j]
            y = data[y_name]
            sel = order[ok[order]]
            if y_name == "residual_ratio":  # every point: the closest design's residual, not only the optimal ones
                sel = order[np.isfinite(y[order])]
                if (y[sel] > 0).all() and sel.size:
                    ax.set_yscale("log")
            label = "every point" if y_name == "residual_ratio" else "optimal"
            if one_axis:
                ax.plot(x[sel], y[sel], marker="o" if len(rows) <= 200 else None, markersize=3, linewidth=1.5, color="tab:blue", label=label)
            else:
                ax.scatter(x[sel], y[sel], s=8, color="tab:blue", label=label)
            if i > 0 and y_name != "residual_ratio" and (~ok).any():  # the closest designs of the points not optimal
                bad = ~ok & np.isfinite(x) & np.isfinite(y)
                ax.scatter(x[bad], y[bad], marker="x", s=14, color="0.5", label="closest design (not optimal)")
            if i == 0 and (~ok).any():
                bad = ~ok & np.isfinite(x)
                ax.scatter(x[bad], np.where(np.isfinite(y[bad]), y[bad], np.nanmin(y[sel]) if sel.size else 0.0), marker="x", color="red",
                           label=f"not optimal ({int((~ok).sum())})")
            ax.set_xlabel(x_name)
            ax.set_ylabel(y_name.replace("objective_kg", "objective [kg]").replace("residual_ratio", "residual ratio"))
            ax.grid(alpha=0.3)
            if i == 0:
                ax.legend(fontsize=8, loc="best")
    fig.suptitle(f"{meta['problem']}: study of {', '.join(varied)}\n{len(rows)} points ({meta['plan']['method']}), {int(ok.sum())} optimal",
                 fontsize=11, y=1 - TITLE_TOP / fig.get_figheight(), va="top")
    paths = [folder / "study.png"]
    save(fig, paths[0], crop=False)  # laid out by _grid: drawn once
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
