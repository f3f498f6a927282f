"""A kinematic sketch of the mechanism: ``mechanism.png``.

Links are lines between successive frame origins (a parent's origin to its child's),
joints small rings, the ground a hatched triangle; bodies are discs whose area grows
with the mass, counter-masses dark squares on thin lines from their frame's origin,
springs zigzags between their two anchors coloured by their force, a pulley-mounted
spring's pulley a ring at its ``from`` point (docs/catalogues.md: the string runs from
the pulley to the ``to`` point), the payload a star. A reference link (a frame with
``orientation``) is drawn as the parallelogram that realises it: its second bar, offset
along an axis of the frame whose orientation it keeps, and the brackets at its joints.
The configuration drawn bold is home (or the ``--at`` one); faint grey poses are the
corners of the coordinate ranges. A planar mechanism (every point moves in parallel
planes) is drawn in its plane of motion with "up" against gravity; only one that leaves
its plane gets three views (front, side, top).

**Spring forces tell the truth.** The force of a spring is k·d (or F0 + k·x for a
directly attached one) with the rate of the design drawn: a solved design's (its chosen
catalogue part, or its designed stiffness), or, before a solve, the file's initial values;
a spring that takes its part from a catalogue slot has no rate before a part is chosen,
and is drawn grey and labelled so. :class:`Drawing` returns every label's text and value
(the tests read them there).

**Labels never overlap** and stay inside their axes: each is placed, most important
first, at the free spot nearest to its point (a simple repel from the labels already
placed, the drawn points and lines, and the edges), with a thin leader line when it had
to move away.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..mechanics.poses import Placed, assembled, default_values, mechanics, place
from ..model.mechanism import GROUND
from ..model.problem import Problem, Scenario
from ..selection.result import PartsReport
from ._mpl import freeze_layout, pyplot, save

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
FONT = 7.0  # label font size (points)
#: label placement: distances (pixels at 100 dpi) and directions tried around a point
RADII = (3.0, 8.0, 14.0, 22.0, 32.0, 45.0, 60.0, 80.0, 105.0, 135.0, 170.0)
DIRECTIONS = 16
LEADER = 12.0  # a label further than this from its point gets a leader line (pixels)
#: what covering costs a label, in pixels of distance: a marker, 5 px of a line, another label's point
MARKER_COST, LINE_COST, ANCHOR_COST = 40.0, 6.0, 60.0
#: order in which labels are placed (first: most important)
PRIORITY = {"spring": 0, "counter_mass": 1, "payload": 2, "frame": 3}
STYLE = {"frame": "0.3", "counter_mass": "0.05", "spring": "0.15", "payload": "darkgreen"}
JOINT = {"marker": "o", "markersize": 7, "markerfacecolor": "white", "markeredgecolor": "0.15", "zorder": 6}
NO_PART = "0.55"  # colour of a spring whose catalogue part is not chosen yet
WIDTH = 0.1  # a parallelogram's width, drawn: this fraction of its first bar


@dataclass(frozen=True)
class Label:
    """One label as drawn: ``kind`` (spring, counter_mass, payload, frame), the things it
    names, their values (spring force in N, counter-mass in kg; None: no value), its text,
    the view it is in, the point it labels (data units of the view) and its box in figure
    pixels at 100 dpi (x0, y0, x1, y1)."""

    kind: str
    names: tuple[str, ...]
    values: tuple[float | None, ...]
    text: str
    view: str
    anchor: tuple[float, float]
    box: tuple[float, float, float, float]


@dataclass(frozen=True)
class Drawing:
    """What :func:`mechanism_drawing` drew: the file, its views, every spring's force at
    the drawn configuration (N; NaN: a slot spring with no part chosen yet), the labels,
    those that found no free spot (left out) and the axes' boxes (figure pixels)."""

    path: Path
    views: tuple[str, ...]
    forces: dict[str, float]
    labels: tuple[Label, ...]
    omitted: tuple[str, ...] = ()
    axes: tuple[tuple[float, float, float, float], ...] = field(default=())


def scenario_with(problem: Problem, parameters: Mapping[str, float] | None) -> Scenario:
    """The first scenario with these base-parameter values on top of its own (a solved
    design's chosen parts: each slot's rate, free length, initial tension...)."""
    sc = problem.scenarios[0]
    if not parameters:
        return sc
    return replace(sc, parameters={**sc.parameters, **parameters})


def unset_slot_springs(problem: Problem, parts_known: bool) -> set[str]:
    """Springs whose rate is a catalogue slot's placeholder (no part chosen): none when the
    design gives the parts."""
    return set() if parts_known else {s.name for s in problem.springs if s.slot is not None}


def design_drawing(result: "DesignResult", folder: str | Path) -> Drawing:
    """``mechanism.png`` of a solved design: its variables and the rates of its springs
    (the chosen parts, the designed stiffness) in its first scenario."""
    problem = result.problem
    scenario = problem.scenarios[0]
    variables = result.solution.variable_values(scenario.name)
    if not variables and problem.variables:
        variables = {v.name: v.initial for v in problem.variables}
    solved = result.solution.scenario_parameters.get(scenario.name)
    parameters = dict(solved[1]) if solved is not None else {}
    chosen = [s for s in problem.slots if s.name in parameters] if problem.slots else []
    parts_known = len(chosen) == len(problem.slots)
    parts = ""
    chosen_parts = result.extra(PartsReport)
    if chosen_parts is not None and problem.slots:
        parts = "; parts " + ", ".join(f"{s.name}: {s.catalogue.part_number[chosen_parts.chosen[s.name]]}" for s in problem.slots if s.name in chosen_parts.chosen)
    title = f"{problem.name}: {result.status.value} design"
    where = f"; shown in scenario {scenario.name}" if len(problem.scenarios) > 1 else ""
    note = f"spring forces from the design{parts}{where}" if problem.springs else where.lstrip("; ")
    return mechanism_drawing(problem, folder, variables, None, title, parameters, note, parts_known)


def design_mechanism_plot(result: "DesignResult", folder: str | Path) -> list[Path]:
    """``mechanism.png`` of a solved design (see :func:`design_drawing`)."""
    return [design_drawing(result, folder).path]


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
    if len(sv) < 3 or sv[-1] <= PLANAR * sv[0] * math.sqrt(len(moves)):
        return up, vt[-1] if len(sv) == 3 else np.cross(vt[0], vt[1] if len(sv) > 1 else _any_normal(vt[0]))
    return up, None


def _any_normal(v: np.ndarray) -> np.ndarray:
    return np.cross(v, np.eye(3)[int(np.argmin(np.abs(v)))])


def _views(up: np.ndarray, normal: np.ndarray | None) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(title, horizontal axis, vertical axis) of each view."""
    if normal is not None:
        normal = normal / np.linalg.norm(normal)
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


def _zigzag(a: np.ndarray, b: np.ndarray, turns: int = 6, amplitude: float | None = None) -> np.ndarray:
    """A zigzag from ``a`` to ``b`` (straight ends); its half-width is 6 % of its length,
    at most ``amplitude``."""
    d = b - a
    length = float(np.linalg.norm(d))
    if length == 0:
        return np.vstack([a, b])
    n = np.array([-d[1], d[0]]) / length
    t = np.linspace(0.12, 0.88, 2 * turns + 1)
    half = 0.06 * length if amplitude is None else min(0.06 * length, amplitude)
    amp = half * np.array([0 if i in (0, 2 * turns) else (1 if i % 2 else -1) for i in range(2 * turns + 1)])
    mid = a + np.outer(t, d) + np.outer(amp, n)
    return np.vstack([a, mid, b])


def _fmt_force(force: float) -> str:
    """Four significant digits: a label is then within 0.05 % of the value it shows."""
    return f"{force:.4g} N"


def mechanism_plot(
    problem: Problem,
    folder: str | Path,
    variables: Mapping[str, float] | None = None,
    coordinates: Mapping[str, float] | None = None,
    title: str | None = None,
    parameters: Mapping[str, float] | None = None,
    note: str | None = None,
    parts_known: bool = False,
) -> list[Path]:
    """Write ``mechanism.png`` into ``folder`` (see :func:`mechanism_drawing`)."""
    return [mechanism_drawing(problem, folder, variables, coordinates, title, parameters, note, parts_known).path]


def mechanism_drawing(
    problem: Problem,
    folder: str | Path,
    variables: Mapping[str, float] | None = None,
    coordinates: Mapping[str, float] | None = None,
    title: str | None = None,
    parameters: Mapping[str, float] | None = None,
    note: str | None = None,
    parts_known: bool = False,
) -> Drawing:
    """Write ``mechanism.png`` into ``folder``: the mechanism at ``coordinates`` (home if
    None), bold, and faint at the corners of the ranges, for design ``variables`` and
    base-parameter values ``parameters`` (a solved design's chosen parts; with
    ``parts_known`` False, springs of catalogue slots have no rate and are drawn grey).
    ``note``: a line under the title (None: "the file's initial values")."""
    plt = pyplot()
    from matplotlib import colormaps, colors
    from matplotlib.lines import Line2D

    _, initial = default_values(problem)
    design = {**initial, **(variables or {})}
    scenario = scenario_with(problem, parameters)
    unset = unset_slot_springs(problem, parts_known)
    main, ghosts = _poses(problem, coordinates)
    placed_main = place(problem, main, design, scenario)
    placed_ghosts = [place(problem, g, design, scenario) for g in ghosts]
    cloud = lambda items: np.array([p.position for p in items])  # noqa: E731
    up, normal = _basis(problem, [cloud(placed_main)] + [cloud(g) for g in placed_ghosts])
    views = _views(up, normal)
    unit_scale, unit = _length_scale(placed_main)
    forces = {p.name.rsplit(".", 1)[0]: (math.nan if p.name.rsplit(".", 1)[0] in unset else p.force) for p in placed_main if p.kind == "spring"}
    known = [f for f in forces.values() if math.isfinite(f)]
    norm = colors.Normalize(vmin=0.0, vmax=max(known) if known and max(known) > 0 else 1.0)
    cmap = colormaps["plasma"]
    masses = [p.mass for p in placed_main if p.kind in ("body", "counter_mass")]
    heaviest = max(masses) if masses and max(masses) > 0 else 1.0
    payloads = {p.name for p in problem.payloads}
    joint_frames = _joint_frames(problem)
    joints = _joint_positions(problem, joint_frames, main, design, scenario)
    closing = _loop_segments(problem, main, design, scenario)
    brackets = _parallelograms(problem, main, design, scenario, joints, normal)
    extent = np.ptp(cloud(placed_main + [p for g in placed_ghosts for p in g]), axis=0).max() / unit_scale

    ghost_joints = [_joint_positions(problem, joint_frames, g, design, scenario) for g in ghosts]
    ghost_loops = [_loop_segments(problem, g, design, scenario) for g in ghosts]
    width = 7.5 if len(views) == 1 else 15.0
    fig, axes = plt.subplots(1, len(views), figsize=(width, 6.4), squeeze=False, layout="constrained")
    requests: list[_Request] = []
    obstacles: dict[Any, _Obstacles] = {}
    for ax, (view, h, v) in zip(axes[0], views):

        def xy(p: Any, h: np.ndarray = h, v: np.ndarray = v) -> np.ndarray:
            q = np.asarray(p, dtype=float)
            return np.array([q @ h, q @ v]) / unit_scale

        obs = obstacles[ax] = _Obstacles()
        pen = _Pen(ax)
        for i, items in enumerate(placed_ghosts):
            _draw(ax, problem, items, xy, ghost=True, joints=ghost_joints[i], closing=ghost_loops[i], pen=pen)
        _draw(
            ax, problem, placed_main, xy, ghost=False, joints=joints, closing=closing, cmap=cmap, norm=norm, heaviest=heaviest,
            payloads=payloads, unset=unset, brackets=brackets, extent=extent, view=view, requests=requests, obstacles=obs, pen=pen,
        )
        pen.flush()
        ax.set_aspect("equal", adjustable="datalim")
        ax.margins(0.12)  # room for the largest markers (a counter-mass square is ~32 px wide) and labels at the edge
        ax.grid(alpha=0.25)
        ax.set_xlabel(f"{_axis_name(h)} [{unit}]")
        ax.set_ylabel(f"{_axis_name(v)} [{unit}]")
        ax.set_title(view, fontsize=10)
    if known:
        sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
        fig.colorbar(sm, ax=axes[0].tolist(), shrink=0.7, label="spring force [N]")
    handles = [
        Line2D([], [], color="0.15", linewidth=2.5, label="link (frame to frame)"),
        Line2D([], [], marker="o", markerfacecolor="white", markeredgecolor="0.15", linestyle="none", label="joint"),
        Line2D([], [], marker="^", color="0.4", linewidth=5, markersize=9, label="ground, fixed frames"),
        Line2D([], [], marker="o", color="tab:blue", alpha=0.6, linestyle="none", markersize=10, label="body (area ∝ mass)"),
    ]
    if brackets:
        handles.append(Line2D([], [], color="tab:purple", linewidth=1.4, linestyle="--", label="parallelogram (reference link)"))
    if problem.counter_masses:
        handles.append(Line2D([], [], marker="s", color="0.1", linestyle="none", markersize=9, label="counter-mass (area ∝ mass)"))
    if problem.springs:
        handles.append(Line2D([], [], color=cmap(0.6), linewidth=1.5, label="spring (colour: force)"))
    if any(s.direct is None for s in problem.springs):
        handles.append(Line2D([], [], marker="o", markerfacecolor="white", markeredgecolor=cmap(0.6), markeredgewidth=1.6, markersize=9, linestyle="none", label="pulley (spring's from end)"))
    if unset & {s.name for s in problem.springs}:
        handles.append(Line2D([], [], color=NO_PART, linewidth=1.5, label="spring, part not chosen yet"))
    if payloads:
        handles.append(Line2D([], [], marker="*", color="tab:green", linestyle="none", markersize=14, label="payload"))
    handles.append(Line2D([], [], color="0.6", alpha=0.5, linewidth=1.5, label="corners of the ranges"))
    fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 4), fontsize=8, frameon=False)
    at = ", ".join(f"{c.name} = {c.unit.from_si(main[c.name]):.4g} {c.unit.symbol}".rstrip() for c in problem.coordinates)
    lines = [title or problem.name, _wrap(f"{'home' if coordinates is None else 'at'}: {at}", 110 if len(views) == 1 else 220)]
    lines.append(note if note is not None else "design: the file's initial values (not solved)")
    fig.suptitle("\n".join(line for line in lines if line), fontsize=10)
    labels, omitted, boxes = _place_labels(fig, list(axes[0]), requests, obstacles)
    path = Path(folder) / "mechanism.png"
    save(fig, path, crop=False)  # laid out and frozen by _place_labels: one draw
    return Drawing(path, tuple(v[0] for v in views), forces, tuple(labels), tuple(omitted), tuple(boxes))


def _wrap(text: str, width: int) -> str:
    """``text`` broken after commas into lines of at most ``width`` characters."""
    out, line = [], ""
    for piece in text.split(", "):
        candidate = f"{line}, {piece}" if line else piece
        if line and len(candidate) > width:
            out.append(line + ",")
            line = piece
        else:
            line = candidate
    return "\n".join([*out, line])


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


def _joint_positions(
    problem: Problem, joints: dict[str, int], coordinates: Mapping[str, float], variables: Mapping[str, float], scenario: Scenario | None = None
) -> dict[str, Any]:
    mech = mechanics(problem, coordinates, variables, scenario)
    return {name: [float(c) for c in mech.pose(name, upto=i)[1]] for name, i in joints.items()}


def _loop_segments(problem: Problem, coordinates: Mapping[str, float], variables: Mapping[str, float], scenario: Scenario | None = None) -> list[tuple[Any, ...]]:
    """Each closed loop's two half-links (frame a's origin to point a, frame b's origin to
    point b) and the joint that closes it, in world coordinates."""
    if not problem.loops:
        return []
    mech = mechanics(problem, coordinates, variables, scenario)
    world = lambda v: np.array([float(np.ravel(c)[0]) for c in v])  # noqa: E731
    return [(world(mech.pose(loop.a.frame)[1]), world(mech.position(loop.a)), world(mech.pose(loop.b.frame)[1]), world(mech.position(loop.b))) for loop in problem.loops]


def _chain(problem: Problem, name: str) -> list[str]:
    """``name`` and its ancestors, ``name`` first, ground last."""
    out = [name]
    while out[-1] != GROUND:
        parent = problem.frame[out[-1]].parent
        out.append(parent if parent is not None else GROUND)
    return out


def _parallelograms(
    problem: Problem,
    coordinates: Mapping[str, float],
    variables: Mapping[str, float],
    scenario: Scenario,
    joints: Mapping[str, Any],
    normal: np.ndarray | None,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The parallelogram of each reference link (a frame with ``orientation``), world
    coordinates: (joints, offset). ``joints``: the joints of the chain from the frame whose
    axes it keeps to the reference link's origin (ancestor side first); ``offset``: where the
    second bar runs, a fixed vector in the kept frame's axes (the one of its axes most across
    the first bar, in the plane of motion when there is one), :data:`WIDTH` of the first bar
    long, on the side away from the springs."""
    out: list[tuple[np.ndarray, np.ndarray]] = []
    mech: Any = None
    springs: list[np.ndarray] = []
    for f in problem.frames:
        if f.orientation is None or f.subsystem is None:
            continue
        if mech is None:
            mech = mechanics(problem, coordinates, variables, scenario)
            springs = [0.5 * (np.array([float(c) for c in mech.position(s.ends[0])]) + np.array([float(c) for c in mech.position(s.ends[1])])) for s in problem.springs]
        kept = set(_chain(problem, f.orientation))
        path = []
        for name in _chain(problem, f.name):
            if name in kept:
                break
            path.append(name)
        points = [np.asarray(joints[n], dtype=float) for n in reversed(path) if n in joints]
        points.append(np.array([float(c) for c in mech.pose(f.name)[1]]))
        distinct = [points[0]]
        for p in points[1:]:
            if np.linalg.norm(p - distinct[-1]) > 1e-9:
                distinct.append(p)
        if len(distinct) < 2:
            continue
        bar = distinct[1] - distinct[0]
        length = float(np.linalg.norm(bar))
        rot = np.array([[float(c) for c in row] for row in mech.pose(f.orientation)[0]])
        axes = [rot[:, i] for i in range(3)]
        if normal is not None:
            axes = [a for a in axes if abs(float(a @ normal)) < 1e-6] or axes
        across = max(axes, key=lambda a: float(np.linalg.norm(np.cross(a, bar / length))))
        offset = WIDTH * length * across
        middle = 0.5 * (distinct[0] + distinct[1])
        if springs:  # the side away from the springs, to keep them readable
            offset *= 1.0 if min(np.linalg.norm(middle + offset - s) for s in springs) >= min(np.linalg.norm(middle - offset - s) for s in springs) else -1.0
        out.append((np.array(distinct), offset))
    return out


class _Pen:
    """Segments and markers batched by style: one artist per style, not one per item (a
    drawing has hundreds of them, and each artist costs as much as a hundred segments)."""

    def __init__(self, ax: Any) -> None:
        self.ax = ax
        self.lines: dict[tuple[Any, ...], list[Any]] = {}
        self.marks: dict[tuple[Any, ...], list[Any]] = {}

    def line(self, q0: np.ndarray, q1: np.ndarray, **style: Any) -> None:
        self.lines.setdefault(tuple(sorted(style.items())), []).append([tuple(q0), tuple(q1)])

    def mark(self, q: np.ndarray, **style: Any) -> None:
        self.marks.setdefault(tuple(sorted(style.items())), []).append(tuple(q))

    def flush(self) -> None:
        from matplotlib.collections import LineCollection

        for key, segments in self.lines.items():
            s = dict(key)
            self.ax.add_collection(
                LineCollection(segments, colors=s["color"], linewidths=s["linewidth"], alpha=s.get("alpha"), zorder=s["zorder"],
                               capstyle=s.get("capstyle", "butt"), linestyles=s.get("linestyle", "solid"))
            )
        for key, points in self.marks.items():
            q = np.array(points)
            self.ax.plot(q[:, 0], q[:, 1], linestyle="none", **dict(key))
        self.lines.clear()
        self.marks.clear()


@dataclass
class _Request:
    """A label to place: kind, the things it names, their values and what follows each name
    (" 31.04 N"), colour, the axes and view it belongs to and the point it labels (data units)."""

    kind: str
    names: list[str]
    values: list[float | None]
    suffixes: list[str]
    color: str
    ax: Any
    view: str
    anchor: np.ndarray


@dataclass
class _Obstacles:
    """What a label should not cover, in data units: points (with a radius in points) and
    segments."""

    points: list[tuple[np.ndarray, float]] = field(default_factory=list)
    segments: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)


def _draw(
    ax: Any, problem: Problem, placed: list[Placed], xy: Any, ghost: bool, joints: Mapping[str, Any], closing: Any = (), **style: Any
) -> None:
    frames = {p.name: p for p in placed if p.kind == "frame"}
    origin = np.zeros(3)
    link_color, alpha, z = ("0.6", 0.35, 1) if ghost else ("0.15", 1.0, 3)
    obs: _Obstacles = style.get("obstacles") or _Obstacles()
    pen: _Pen = style["pen"]

    def segment(q0: np.ndarray, q1: np.ndarray) -> None:
        if not ghost:
            obs.segments.append((q0, q1))

    for oa, pa_, ob, pb_ in closing:  # the links of a closed loop, to the joint where it was opened
        for o, p in ((oa, pa_), (ob, pb_)):
            q0, q1 = xy(o), xy(p)
            pen.line(q0, q1, color=link_color, linewidth=2.5 if not ghost else 1.5, alpha=alpha, zorder=z, capstyle="round")
            segment(q0, q1)
        if not ghost:
            j = xy(pa_)
            pen.mark(j, **JOINT)
            obs.points.append((j, 4.0))
    for f in problem.frames:  # parent's origin to the joint: the parent's; joint to origin: the frame's
        a = frames[f.parent].position if f.parent in frames else origin
        b = frames[f.name].position
        parent_fixed = f.parent in (None, GROUND) or problem.frame[f.parent].subsystem is None
        pieces = [(a, joints[f.name], parent_fixed), (joints[f.name], b, False)] if f.name in joints else [(a, b, f.subsystem is None)]
        for start, end, fixed in pieces:
            pa, pb = xy(start), xy(end)
            if (fixed and ghost) or np.allclose(pa, pb, rtol=0.0, atol=1e-12):
                continue
            width = 5.0 if fixed else (2.5 if not ghost else 1.5)
            pen.line(pa, pb, color="0.75" if fixed else link_color, linewidth=width, alpha=alpha, zorder=z - (1 if fixed else 0), capstyle="round")
            segment(pa, pb)
    for p in placed:
        if p.kind in ("body", "counter_mass"):
            pf, pc = xy(frames[p.frame].position if p.frame in frames else origin), xy(p.position)
            width = 0.9 if p.kind == "body" else 1.6
            pen.line(pf, pc, color=link_color, linewidth=width, alpha=alpha * 0.8, zorder=z - 1)
            segment(pf, pc)
    if ghost:  # the corner poses: links and small faint masses, no labels
        for p in placed:
            if p.kind in ("body", "counter_mass"):
                pen.mark(xy(p.position), marker="o" if p.kind == "body" else "s", markersize=3.5, color="0.55", alpha=0.45, zorder=1)
        return
    cmap, norm, heaviest, payloads, unset = style["cmap"], style["norm"], style["heaviest"], style["payloads"], style["unset"]
    view, requests = style["view"], style["requests"]
    for points, offset in style["brackets"]:  # parallelograms: the second bar and the brackets at the joints
        main_bar = np.array([xy(p) for p in points])
        second = np.array([xy(p + offset) for p in points])
        for q0, q1 in zip(second[:-1], second[1:]):
            pen.line(q0, q1, color="tab:purple", linewidth=1.4, linestyle="--", zorder=z, alpha=0.9)
        for q0, q1 in zip(main_bar, second):
            pen.line(q0, q1, color="tab:purple", linewidth=2.2, zorder=z + 1, capstyle="round")
            segment(q0, q1)
        for q0, q1 in zip(second[:-1], second[1:]):
            segment(q0, q1)
    ground = xy(origin)
    pen.mark(ground, marker="^", markersize=14, color="0.4", zorder=2)
    obs.points.append((ground, 7.0))
    for f in problem.frames:
        if f.subsystem is None and f.parent in (GROUND, None):
            g = xy(frames[f.name].position)
            pen.mark(g, marker="^", markersize=10, color="0.4", zorder=2)
            obs.points.append((g, 5.0))
    for position in joints.values():
        j = xy(position)
        pen.mark(j, **JOINT)
        obs.points.append((j, 4.0))
    merged: dict[tuple[str, float, float], _Request] = {}

    def label(kind: str, q: np.ndarray, name: str, value: float | None, suffix: str = "") -> None:
        key = (kind, round(float(q[0]), 1), round(float(q[1]), 1))
        if key not in merged:
            merged[key] = _Request(kind, [], [], [], STYLE[kind], ax, view, np.asarray(q, dtype=float))
        merged[key].names.append(name)
        merged[key].values.append(value)
        merged[key].suffixes.append(suffix)

    for name, p in frames.items():
        label("frame", xy(p.position), name, None)
    for p in placed:
        q = xy(p.position)
        size = MARKER_MIN + MARKER_SPAN * p.mass / heaviest
        if p.kind == "body" and p.name in payloads:
            ax.scatter(*q, s=max(size, 160), marker="*", color="tab:green", zorder=7, edgecolors="darkgreen")
            label("payload", q, p.name, p.mass)
            obs.points.append((q, math.sqrt(max(size, 160)) / 2))
        elif p.kind == "body":
            ax.scatter(*q, s=size, color="tab:blue", alpha=0.55, zorder=5, edgecolors="tab:blue")
            obs.points.append((q, math.sqrt(size) / 2))
        elif p.kind == "counter_mass":
            ax.scatter(*q, s=size, marker="s", color="0.1", zorder=7)
            label("counter_mass", q, p.name, p.mass, f" {p.mass:.4g} kg")
            obs.points.append((q, math.sqrt(size) / 2))
    springs = {s.name: s for s in problem.springs}
    ends = [p for p in placed if p.kind == "spring"]
    amplitude = 0.025 * style["extent"]
    for ea, eb in zip(ends[::2], ends[1::2]):
        name = ea.name.rsplit(".", 1)[0]
        pa, pb = xy(ea.position), xy(eb.position)
        chosen = name not in unset
        color = cmap(norm(ea.force)) if chosen else NO_PART
        line = _zigzag(pa, pb, amplitude=amplitude)
        ax.plot(line[:, 0], line[:, 1], color=color, linewidth=1.6, zorder=6)
        obs.segments.append((pa, pb))
        pen.mark(pb, marker="o", markersize=3, color=color, zorder=6)
        if springs[name].direct is None:  # the pulley at the from point, the string running to the to point
            pen.mark(pa, marker="o", markersize=9, markerfacecolor="white", markeredgecolor=color, markeredgewidth=1.6, zorder=7)
            pen.mark(pa, marker="o", markersize=2, color=color, zorder=8)
            obs.points.append((pa, 5.0))
        else:
            pen.mark(pa, marker="o", markersize=3, color=color, zorder=6)
        label("spring", 0.5 * (pa + pb), name, ea.force if chosen else None, f" {_fmt_force(ea.force)}" if chosen else ": part not chosen")
    requests.extend(merged.values())


def _place_labels(fig: Any, axes: list[Any], requests: list[_Request], obstacles: Mapping[Any, _Obstacles]) -> tuple[list[Label], list[str], list[tuple[float, float, float, float]]]:
    """Place every label at the free spot nearest to its point (see the module docstring);
    returns the labels, those left out (frame names that found no free spot) and the axes'
    boxes. The layout is fixed first (:func:`~._mpl.freeze_layout`: laid out as a draw would,
    then frozen), so that pixels here are the pixels of the saved picture, up to its
    resolution."""
    fig.set_dpi(100)
    renderer = freeze_layout(fig, axes)
    frames = {ax: np.array(ax.get_window_extent(renderer).extents) for ax in axes}
    placed: list[np.ndarray] = []
    labels: list[Label] = []
    omitted: list[str] = []
    pts = {ax: _obstacle_points(ax, obstacles.get(ax, _Obstacles())) for ax in axes}
    anchors = {ax: np.array([ax.transData.transform(r.anchor) for r in requests if r.ax is ax]).reshape(-1, 2) for ax in axes}
    angles = np.arange(DIRECTIONS) * 2 * np.pi / DIRECTIONS + np.pi / 4  # up-right first
    dirs = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    for r in sorted(requests, key=lambda r: PRIORITY[r.kind]):
        text = _text(r)
        ax = r.ax
        artist = ax.annotate(text, r.anchor, xytext=r.anchor, textcoords="data", fontsize=FONT, color=r.color, zorder=9, annotation_clip=False,
                             ha="left", va="bottom", bbox={"boxstyle": "square,pad=0.1", "facecolor": "white", "edgecolor": "none", "alpha": 0.7})
        ext = artist.get_window_extent(renderer)
        w, h = ext.width + 2.0, ext.height + 2.0
        p = ax.transData.transform(r.anchor)
        best = _best_spot(p, w, h, dirs, frames[ax], placed, pts[ax], anchors[ax])
        if best is None and r.kind == "frame":  # a frame's name may go; a value may not
            artist.remove()
            omitted.append(text)
            continue
        box, distance = best if best is not None else (np.array([p[0], p[1], p[0] + w, p[1] + h]), 0.0)  # nowhere free: at its point
        artist.set_position(tuple(ax.transData.inverted().transform((box[0] + 1.0, box[1] + 1.0))))
        if distance > LEADER:
            ax.annotate("", r.anchor, xytext=ax.transData.inverted().transform(_nearest_on_box(box, p)), textcoords="data", annotation_clip=False, zorder=8,
                        arrowprops={"arrowstyle": "-", "color": r.color, "linewidth": 0.5, "shrinkA": 0, "shrinkB": 2, "alpha": 0.8})
        placed.append(box)
        labels.append(Label(r.kind, tuple(r.names), tuple(r.values), text, r.view, (float(r.anchor[0]), float(r.anchor[1])), tuple(float(c) for c in box)))  # type: ignore[arg-type]  # a box is four floats
    return labels, omitted, [tuple(float(c) for c in frames[ax]) for ax in axes]  # type: ignore[misc]  # a box is four floats


def _text(r: _Request) -> str:
    """Names with the same value share it: "left, right, middle 31.04 N"; a frame label
    shows at most three names."""
    groups: dict[str, list[str]] = {}
    for name, suffix in zip(r.names, r.suffixes):
        groups.setdefault(suffix, []).append(name)
    if r.kind == "frame" and len(r.names) > 3:
        return ", ".join(r.names[:3]) + f" (+{len(r.names) - 3})"
    return ", ".join(", ".join(names) + suffix for suffix, names in groups.items())


def _obstacle_points(ax: Any, obs: _Obstacles) -> np.ndarray:
    """The obstacles as (x, y, radius, cost) in pixels: points, and segments sampled every 5 px."""
    rows = []
    for q, radius in obs.points:
        x, y = ax.transData.transform(q)
        rows.append((x, y, radius * 100 / 72, MARKER_COST))  # points -> pixels at 100 dpi
    for q0, q1 in obs.segments:
        a, b = ax.transData.transform(q0), ax.transData.transform(q1)
        n = max(2, int(np.linalg.norm(b - a) / 5.0) + 1)
        for t in np.linspace(0.0, 1.0, n):
            x, y = a + t * (b - a)
            rows.append((x, y, 1.5, LINE_COST))
    return np.array(rows, dtype=float).reshape(-1, 4)


def _best_spot(
    p: np.ndarray, w: float, h: float, dirs: np.ndarray, frame: np.ndarray, placed: list[np.ndarray], pts: np.ndarray, anchors: np.ndarray
) -> tuple[np.ndarray, float] | None:
    """The free box (x0, y0, x1, y1) of size w × h nearest to ``p``, fully inside ``frame``
    and overlapping no ``placed`` box, covering as few obstacle points and other labels'
    points as it can; with its distance from ``p``. None: no free box."""
    radii = np.array(RADII)
    r = np.repeat(radii, len(dirs))
    d = np.tile(dirs, (len(radii), 1))
    centre = p + d * (r[:, None] + np.abs(d) * np.array([w / 2, h / 2]))  # the box's near side r from p
    boxes = np.concatenate([centre - [w / 2, h / 2], centre + [w / 2, h / 2]], axis=1)
    inside = (boxes[:, 0] >= frame[0] + 2) & (boxes[:, 1] >= frame[1] + 2) & (boxes[:, 2] <= frame[2] - 2) & (boxes[:, 3] <= frame[3] - 2)
    free = inside.copy()
    if placed:
        others = np.array(placed)
        overlap = (boxes[:, None, 0] < others[None, :, 2]) & (boxes[:, None, 2] > others[None, :, 0]) & (boxes[:, None, 1] < others[None, :, 3]) & (boxes[:, None, 3] > others[None, :, 1])
        free &= ~overlap.any(axis=1)
    if not free.any():
        return None
    cost = r.astype(float) + 0.5 * (np.arange(len(r)) % len(dirs))  # nearer first, then up-right first
    if len(pts):
        hit = (pts[None, :, 0] + pts[None, :, 2] > boxes[:, None, 0]) & (pts[None, :, 0] - pts[None, :, 2] < boxes[:, None, 2])
        hit &= (pts[None, :, 1] + pts[None, :, 2] > boxes[:, None, 1]) & (pts[None, :, 1] - pts[None, :, 2] < boxes[:, None, 3])
        cost += (hit * pts[None, :, 3]).sum(axis=1)
    if len(anchors):  # other labels' points (its own lies outside every candidate)
        near = (anchors[None, :, 0] > boxes[:, None, 0] - 3) & (anchors[None, :, 0] < boxes[:, None, 2] + 3)
        near &= (anchors[None, :, 1] > boxes[:, None, 1] - 3) & (anchors[None, :, 1] < boxes[:, None, 3] + 3)
        cost += ANCHOR_COST * near.sum(axis=1)
    cost[~free] = np.inf
    i = int(np.argmin(cost))
    return boxes[i], float(r[i])


def _nearest_on_box(box: np.ndarray, p: np.ndarray) -> np.ndarray:
    return np.array([min(max(p[0], box[0]), box[2]), min(max(p[1], box[1]), box[3])])
