"""A kinematic sketch of the mechanism: ``mechanism.png``.

Links are lines between successive frame origins (a parent's origin to its child's),
joints small rings, the ground a hatched triangle; bodies are discs whose area grows
with the mass, counter-masses dark squares on thin lines from their frame's origin,
springs zigzags coloured by their force, the payload a star. The configuration drawn
bold is home (or the ``--at`` one); faint grey poses are the corners of the coordinate
ranges. A planar mechanism (every point moves in parallel planes) is drawn in its plane
of motion with "up" against gravity; otherwise as three views (front, side, top).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..mechanics.poses import Placed, assembled, default_values, place
from ..model.mechanism import GROUND
from ..model.problem import Problem
from ._mpl import pyplot, save

if TYPE_CHECKING:
    from ..pipeline import DesignResult

#: a mechanism is planar when its points' displacements leave this fraction (of the
#: largest displacement) out of one plane
PLANAR = 1e-9
#: at most this many corners of one subsystem's range box are drawn (else its axis extremes)
MAX_CORNERS = 8
#: at most this many faint poses in all
MAX_GHOSTS = 24
MARKER_MIN, MARKER_SPAN = 25.0, 500.0  # marker areas (points²) of the lightest and heaviest mass


def design_mechanism_plot(result: "DesignResult", folder: str | Path) -> list[Path]:
    """``mechanism.png`` of a solved design (the design's variables, first scenario)."""
    problem = result.problem
    scenario = problem.scenarios[0]
    variables = result.solution.variable_values(scenario.name)
    if not variables and problem.variables:
        variables = {v.name: v.initial for v in problem.variables}
    title = f"{problem.name}: {result.status.value} design"
    return mechanism_plot(problem, folder, variables, None, title)


def _poses(problem: Problem, chosen: Mapping[str, float] | None) -> tuple[dict[str, float], list[dict[str, float]]]:
    home, _ = default_values(problem)
    main = dict(chosen) if chosen is not None else home
    ghosts: list[dict[str, float]] = []
    for sub in problem.subsystems:
        coords = [problem.coordinate[n] for n in sub.coordinates if not problem.coordinate[n].dependent]
        ends = [_range_poses(c) for c in coords]
        if math.prod(len(e) for e in ends) <= MAX_CORNERS:
            corners = itertools.product(*ends)
            ghosts += [{**main, **{c.name: v for c, v in zip(coords, corner)}} for corner in corners]
        else:
            ghosts += [{**main, c.name: v} for c, values in zip(coords, ends) for v in values]
    if len(ghosts) > MAX_GHOSTS:
        step = len(ghosts) / MAX_GHOSTS
        ghosts = [ghosts[int(i * step)] for i in range(MAX_GHOSTS)]
    return assembled(problem, main), [assembled(problem, g) for g in ghosts]  # closed loops: every pose assembled


def _range_poses(c: Any) -> tuple[float, ...]:
    """The values a coordinate is drawn at besides home: its range's ends, or three points
    of a full turn (whose ends are one and the same pose)."""
    span = c.upper - c.lower
    if c.unit.dimension == "" and span >= 2 * math.pi * (1 - 1e-9):
        return tuple(c.lower + span * k / 4 for k in (1, 2, 3))
    return (c.lower, c.upper)


def _basis(problem: Problem, clouds: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray | None]:
    """(up, plane normal or None): up against gravity; the normal of the plane of motion."""
    g = np.array(problem.scenarios[0].gravity.direction, dtype=float)
    up = -g / np.linalg.norm(g) if np.linalg.norm(g) > 0 else np.array([0.0, 0.0, 1.0])
    moves = np.vstack([c - clouds[0] for c in clouds[1:]]) if len(clouds) > 1 else np.zeros((1, 3))
    scale = np.abs(moves).max()
    if scale == 0:
        return up, None
    _, sv, vt = np.linalg.svd(moves, full_matrices=False)
    if sv[-1] <= PLANAR * sv[0] * math.sqrt(len(moves)):
        return up, vt[-1]
    return up, None


def _views(up: np.ndarray, normal: np.ndarray | None) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(title, horizontal axis, vertical axis) of each view."""
    if normal is not None:
        vertical = up - normal * float(up @ normal)
        if np.linalg.norm(vertical) < 1e-6:  # gravity normal to the plane: any axes of the plane
            vertical = np.cross(normal, np.eye(3)[int(np.argmin(np.abs(normal)))])
        vertical /= np.linalg.norm(vertical)
        horizontal = np.cross(vertical, normal)
        if horizontal[int(np.argmax(np.abs(horizontal)))] < 0:  # along a positive world axis
            horizontal = -horizontal
        return [("plane of motion", horizontal, vertical)]
    axis = np.eye(3)[int(np.argmin(np.abs(np.eye(3) @ up)))]
    h1 = axis - up * float(axis @ up)
    h1 /= np.linalg.norm(h1)
    h2 = np.cross(up, h1)
    return [("front", h1, up), ("side", h2, up), ("top", h1, h2)]


def _axis_name(v: np.ndarray) -> str:
    names = "xyz"
    parts = [f"{'-' if c < 0 else '+'}{'' if abs(abs(c) - 1) < 1e-9 else f'{abs(c):.2g}'}{names[i]}" for i, c in enumerate(v) if abs(c) > 1e-9]
    return " ".join(parts).lstrip("+")


def _zigzag(a: np.ndarray, b: np.ndarray, turns: int = 6) -> np.ndarray:
    d = b - a
    length = float(np.linalg.norm(d))
    if length == 0:
        return np.vstack([a, b])
    n = np.array([-d[1], d[0]]) / length
    t = np.linspace(0.12, 0.88, 2 * turns + 1)
    amp = 0.06 * length * np.array([0 if i in (0, 2 * turns) else (1 if i % 2 else -1) for i in range(2 * turns + 1)])
    mid = a + np.outer(t, d) + np.outer(amp, n)
    return np.vstack([a, mid, b])


def mechanism_plot(
    problem: Problem,
    folder: str | Path,
    variables: Mapping[str, float] | None = None,
    coordinates: Mapping[str, float] | None = None,
    title: str | None = None,
) -> list[Path]:
    """Write ``mechanism.png`` into ``folder``: the mechanism at ``coordinates`` (home if
    None), bold, and faint at the corners of the ranges, for design ``variables``."""
    plt = pyplot()
    from matplotlib import colormaps, colors
    from matplotlib.lines import Line2D

    _, initial = default_values(problem)
    design = {**initial, **(variables or {})}
    main, ghosts = _poses(problem, coordinates)
    placed_main = place(problem, main, design)
    placed_ghosts = [place(problem, g, design) for g in ghosts]
    cloud = lambda items: np.array([p.position for p in items])  # noqa: E731
    up, normal = _basis(problem, [cloud(placed_main)] + [cloud(g) for g in placed_ghosts])
    views = _views(up, normal)
    unit_scale, unit = _length_scale(placed_main)
    forces = [p.force for p in placed_main if p.kind == "spring"]
    norm = colors.Normalize(vmin=0.0, vmax=max(forces) if forces and max(forces) > 0 else 1.0)
    cmap = colormaps["plasma"]
    masses = [p.mass for p in placed_main if p.kind in ("body", "counter_mass")]
    heaviest = max(masses) if masses and max(masses) > 0 else 1.0
    payloads = {p.name for p in problem.payloads}
    joints = _joint_positions(problem, _joint_frames(problem), main, design)
    closing = _loop_segments(problem, main, design)

    width = 7.5 if len(views) == 1 else 15.0
    fig, axes = plt.subplots(1, len(views), figsize=(width, 6.2), squeeze=False, layout="constrained")
    for ax, (view, h, v) in zip(axes[0], views):

        def xy(p: Any) -> np.ndarray:
            q = np.asarray(p, dtype=float)
            return np.array([q @ h, q @ v]) / unit_scale

        for items, pose in zip(placed_ghosts, ghosts):
            _draw(ax, problem, items, xy, ghost=True, joints=joints, closing=_loop_segments(problem, pose, design))
        _draw(ax, problem, placed_main, xy, ghost=False, joints=joints, closing=closing, cmap=cmap, norm=norm, heaviest=heaviest, payloads=payloads)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.25)
        ax.set_xlabel(f"{_axis_name(h)} [{unit}]")
        ax.set_ylabel(f"{_axis_name(v)} [{unit}]")
        ax.set_title(view, fontsize=10)
    if forces:
        sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
        fig.colorbar(sm, ax=axes[0].tolist(), shrink=0.7, label="spring force [N]")
    handles = [
        Line2D([], [], color="0.15", linewidth=2.5, label="link (frame to frame)"),
        Line2D([], [], marker="o", markerfacecolor="white", markeredgecolor="0.15", linestyle="none", label="joint"),
        Line2D([], [], marker="^", color="0.4", linewidth=5, markersize=9, label="ground, fixed frames"),
        Line2D([], [], marker="o", color="tab:blue", alpha=0.6, linestyle="none", markersize=10, label="body (area ∝ mass)"),
    ]
    if problem.counter_masses:
        handles.append(Line2D([], [], marker="s", color="0.1", linestyle="none", markersize=9, label="counter-mass (area ∝ mass)"))
    if problem.springs:
        handles.append(Line2D([], [], color=cmap(0.6), linewidth=1.5, label="spring (colour: force)"))
    if payloads:
        handles.append(Line2D([], [], marker="*", color="tab:green", linestyle="none", markersize=14, label="payload"))
    handles.append(Line2D([], [], color="0.6", alpha=0.5, linewidth=1.5, label="corners of the ranges"))
    fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 4), fontsize=8, frameon=False)
    at = ", ".join(f"{c.name} = {c.unit.from_si(main[c.name]):.4g} {c.unit.symbol}".rstrip() for c in problem.coordinates)
    fig.suptitle(f"{title or problem.name}\n{'home' if coordinates is None else 'at'}: {at}", fontsize=10)
    path = Path(folder) / "mechanism.png"
    save(fig, path)
    return [path]


def _length_scale(placed: list[Placed]) -> tuple[float, str]:
    extent = max((abs(c) for p in placed for c in p.position), default=1.0)
    return (1e-3, "mm") if extent < 2.0 else (1.0, "m")


def _joint_frames(problem: Problem) -> dict[str, int]:
    """Frames whose own transforms move with a coordinate -> index of the first such
    transform: the joint (drawn as a ring) sits where the frame's chain is just before it."""
    from ..model import expr as ex
    from ..model.mechanism import Rotation

    coordinates = {c.name for c in problem.coordinates}
    out: dict[str, int] = {}
    for f in problem.frames:
        for i, t in enumerate(f.transforms):
            trees = [t.angle] if isinstance(t, Rotation) else list(t.vector)
            if any(ex.names(tree) & coordinates for tree in trees):
                out[f.name] = i
                break
    return out


def _joint_positions(problem: Problem, joints: dict[str, int], coordinates: Mapping[str, float], variables: Mapping[str, float]) -> dict[str, Any]:
    from ..mechanics.poses import mechanics

    mech = mechanics(problem, coordinates, variables)
    return {name: [float(c) for c in mech.pose(name, upto=i)[1]] for name, i in joints.items()}


def _loop_segments(problem: Problem, coordinates: Mapping[str, float], variables: Mapping[str, float]) -> list[tuple[Any, ...]]:
    """Each closed loop's two half-links (frame a's origin to point a, frame b's origin to
    point b) and the joint that closes it, in world coordinates."""
    if not problem.loops:
        return []
    from ..mechanics.poses import mechanics

    mech = mechanics(problem, coordinates, variables)
    world = lambda v: np.array([float(np.ravel(c)[0]) for c in v])  # noqa: E731
    return [(world(mech.pose(loop.a.frame)[1]), world(mech.position(loop.a)), world(mech.pose(loop.b.frame)[1]), world(mech.position(loop.b))) for loop in problem.loops]


def _draw(
    ax: Any, problem: Problem, placed: list[Placed], xy: Any, ghost: bool, joints: Mapping[str, Any], closing: Any = (), **style: Any
) -> None:
    frames = {p.name: p for p in placed if p.kind == "frame"}
    origin = np.zeros(3)
    link_color, alpha, z = ("0.6", 0.35, 1) if ghost else ("0.15", 1.0, 3)
    for oa, pa_, ob, pb_ in closing:  # the links of a closed loop, to the joint where it was opened
        for o, p in ((oa, pa_), (ob, pb_)):
            q0, q1 = xy(o), xy(p)
            ax.plot([q0[0], q1[0]], [q0[1], q1[1]], color=link_color, linewidth=2.5 if not ghost else 1.5, alpha=alpha, zorder=z, solid_capstyle="round")
        if not ghost:
            j = xy(pa_)
            ax.plot(*j, marker="o", markersize=7, markerfacecolor="white", markeredgecolor="0.15", zorder=6, linestyle="none")
    for f in problem.frames:
        a = frames[f.parent].position if f.parent in frames else origin
        b = frames[f.name].position
        pa, pb = xy(a), xy(b)
        fixed = f.subsystem is None
        if fixed and ghost:
            continue
        width = 5.0 if fixed else (2.5 if not ghost else 1.5)
        ax.plot([pa[0], pb[0]], [pa[1], pb[1]], color="0.75" if fixed else link_color, linewidth=width, alpha=alpha, zorder=z - (1 if fixed else 0), solid_capstyle="round")
        if f.orientation is not None and not ghost:  # a reference link keeping another frame's axes
            ax.plot(*pb, marker="D", markersize=5, color="tab:purple", zorder=z + 2, linestyle="none")
    for p in placed:
        if p.kind in ("body", "counter_mass"):
            pf, pc = xy(frames[p.frame].position if p.frame in frames else origin), xy(p.position)
            width = 0.9 if p.kind == "body" else 1.6
            ax.plot([pf[0], pc[0]], [pf[1], pc[1]], color=link_color, linewidth=width, alpha=alpha * 0.8, zorder=z - 1)
    if ghost:  # the corner poses: links and small faint masses, no labels
        for p in placed:
            if p.kind in ("body", "counter_mass"):
                ax.plot(*xy(p.position), marker="o" if p.kind == "body" else "s", markersize=3.5, color="0.55", alpha=0.45, zorder=1, linestyle="none")
        return
    cmap, norm, heaviest, payloads = style["cmap"], style["norm"], style["heaviest"], style["payloads"]
    ground = xy(origin)
    ax.plot(*ground, marker="^", markersize=14, color="0.4", zorder=2, linestyle="none")
    for f in problem.frames:
        if f.subsystem is None and f.parent == GROUND:
            g = xy(frames[f.name].position)
            ax.plot(*g, marker="^", markersize=10, color="0.4", zorder=2, linestyle="none")
    for position in joints.values():
        j = xy(position)
        ax.plot(*j, marker="o", markersize=7, markerfacecolor="white", markeredgecolor="0.15", zorder=6, linestyle="none")
    labels: dict[tuple[str, float, float], list[str]] = {}

    def label(kind: str, q: np.ndarray, text: str) -> None:
        labels.setdefault((kind, round(float(q[0]), 1), round(float(q[1]), 1)), []).append(text)

    for name, p in frames.items():
        label("frame", xy(p.position), name)
    for p in placed:
        q = xy(p.position)
        size = MARKER_MIN + MARKER_SPAN * p.mass / heaviest
        if p.kind == "body" and p.name in payloads:
            ax.scatter(*q, s=max(size, 160), marker="*", color="tab:green", zorder=7, edgecolors="darkgreen")
            label("payload", q, p.name)
        elif p.kind == "body":
            ax.scatter(*q, s=size, color="tab:blue", alpha=0.55, zorder=5, edgecolors="tab:blue")
        elif p.kind == "counter_mass":
            ax.scatter(*q, s=size, marker="s", color="0.1", zorder=7)
            label("counter_mass", q, f"{p.name} {p.mass:.3g} kg")
    ends = [p for p in placed if p.kind == "spring"]
    for a, b in zip(ends[::2], ends[1::2]):
        line = _zigzag(xy(a.position), xy(b.position))
        ax.plot(line[:, 0], line[:, 1], color=cmap(norm(a.force)), linewidth=1.6, zorder=6)
        for e in (a, b):
            ax.plot(*xy(e.position), marker="o", markersize=3, color=cmap(norm(a.force)), zorder=6, linestyle="none")
        label("spring", 0.5 * (xy(a.position) + xy(b.position)), f"{a.name.rsplit('.', 1)[0]} {a.force:.3g} N")
    offsets = {"frame": ((6, 6), "0.3"), "counter_mass": ((7, -11), "0.05"), "spring": ((5, 3), "0.2"), "payload": ((6, -10), "darkgreen")}
    for (kind, x, y), texts in labels.items():
        text = ", ".join(texts[:3]) + (f" (+{len(texts) - 3})" if len(texts) > 3 else "")
        offset, color = offsets[kind]
        ax.annotate(text, (x, y), textcoords="offset points", xytext=offset, fontsize=6.5, color=color, zorder=8)
