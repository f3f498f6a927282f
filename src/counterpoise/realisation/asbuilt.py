"""The as-built check: the balancer rebuilt from its build sheet alone, with real springs.

:func:`rebuild` reads the rows of ``build.csv`` (:mod:`.sheet`; in memory, or read back from
the file by :func:`read`) into problems of the mechanism as built: numbers only, no
variables, every spring a real one (:class:`~counterpoise.model.elements.BuiltSpring`):
its wound rate, initial tension and free length, its anchor set by the sheet's offset, its
cable over a pulley of the sheet's radius (onto a pin where the sheet says so). It pulls
F0 + k·x while x = path + offset > 0 and nothing below (its coils close, the cable goes
slack). :func:`check` samples that balancer as densely as the design's own verification
(the sheet's ``verify_samples`` and ``seed``) and gives its residual ratio: what the
hardware the sheet specifies balances, as opposed to the ideal model the design was
solved in.

Scenarios that share every row but gravity (working modes, tilts) are one problem; those
whose masses or settings differ (the payloads of a range) are one problem each, and the
residual ratio is taken over all of them against one reference (:mod:`counterpoise.designer.checks`).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..model import expr as ex
from ..model.elements import BuiltSpring, CounterMass, Pulley, ZeroFreeLengthSpring
from ..model.loops import Loop
from ..model.mechanism import GROUND, Body, Coordinate, Frame, Point, Rotation, Subsystem, Translation
from ..model.problem import Gravity, Objective, Problem, Scenario, Settings
from ..model.tilt import Tilt
from ..model.units import display_unit
from ..designer.checks import Verification

Row = Mapping[str, Any]
MM = 1e-3
#: the scenario of a sheet whose rows name none
NOMINAL = "nominal"


@dataclass(frozen=True)
class AsBuilt:
    """The balancer as built: its residual ratio (NaN when it cannot be built), the dense
    verification it comes from, and per spring the share of checked configurations where
    it is slack."""

    residual_ratio: float
    verification: Verification | None
    slack: Mapping[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    @property
    def balanced(self) -> bool:
        return self.verification is not None and self.verification.balanced


def read(text: str) -> list[dict[str, str]]:
    """The rows of a ``build.csv`` text."""
    return list(csv.DictReader(io.StringIO(text)))


def _num(row: Row, key: str, scale: float = 1.0) -> float:
    v = row.get(key, "")
    if v is None or v == "":
        return math.nan
    return float(v) * scale


#: what a spreadsheet would run: a text cell starting so was written behind a ``'``
_FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def _text(row: Row, key: str) -> str:
    v = row.get(key, "")
    text = "" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v)
    if text.startswith("'") and text[1:].lstrip("'").startswith(_FORMULA_STARTS):
        return text[1:]  # the CSV writer's guard against formulas (counterpoise.report.files.spreadsheet_cell)
    return text


def _vec(row: Row, prefix: str, suffix: str = "", scale: float = 1.0) -> tuple[float, float, float]:
    x, y, z = (_num(row, f"{prefix}{c}{suffix}", scale) for c in "xyz")
    return (x, y, z)


def _point(row: Row) -> Point:
    x, y, z = _vec(row, "", "_mm", MM)
    return Point(_text(row, "frame") or GROUND, (ex.Num(x), ex.Num(y), ex.Num(z)))


def _affine(constant: float, coefficients: str, component: int | None = None) -> ex.Expr:
    """constant + Σ c·q over ``coefficients`` ("q1=1;q2=-1", or "q=1000,0,0" per component)."""
    tree: ex.Expr = ex.Num(constant)
    for part in filter(None, coefficients.split(";")):
        name, _, values = part.partition("=")
        numbers = [float(v) for v in values.split(",")]
        c = numbers[component] if component is not None else numbers[0]
        if c != 0.0:
            tree = ex.BinOp("+", tree, ex.BinOp("*", ex.Num(c), ex.Name(name)))
    return tree


def scenarios_of(rows: Sequence[Row]) -> list[str]:
    """The scenarios a sheet names, in order (one, :data:`NOMINAL`, when it names none)."""
    names: list[str] = []
    for r in rows:
        s = _text(r, "scenario")
        if s and s not in names:
            names.append(s)
    return names or [NOMINAL]


def rebuild(rows: Sequence[Row]) -> list[Problem]:
    """The mechanism as built, from the sheet's rows alone: one problem per group of
    scenarios that share every row but gravity (see the module docstring)."""
    names = scenarios_of(rows)
    groups: dict[tuple[Any, ...], list[str]] = {}
    for s in names:
        mine = tuple(tuple(sorted((k, str(v)) for k, v in r.items() if k != "item")) for r in rows if _text(r, "scenario") == s and _text(r, "kind") not in ("gravity", "upright"))
        groups.setdefault(mine, []).append(s)
    return [_problem(rows, members) for members in groups.values()]


def _problem(rows: Sequence[Row], members: Sequence[str]) -> Problem:
    first = members[0]
    mine = [r for r in rows if _text(r, "scenario") in ("", first)]
    settings = {_text(r, "name"): _num(r, "value") for r in mine if _text(r, "kind") == "setting"}
    coordinates: list[Coordinate] = []
    subsystems: dict[str, list[str]] = {}
    frames: dict[str, tuple[str, str, list[Any], str]] = {}
    loops_a: dict[str, Row] = {}
    loops_b: dict[str, Row] = {}
    bodies: list[Body] = []
    masses: list[CounterMass] = []
    points: dict[str, Row] = {}
    pulleys: dict[str, Row] = {}
    springs: list[Row] = []
    tilts: list[Tilt] = []
    for r in mine:
        kind, name = _text(r, "kind"), _text(r, "name")
        sub = _text(r, "subsystem") or None
        if kind in ("coordinate", "dependent_coordinate"):
            unit = display_unit(_text(r, "unit"))
            coordinates.append(Coordinate(name, sub or "", _num(r, "range_min", unit.to_si), _num(r, "range_max", unit.to_si), _num(r, "value", unit.to_si), unit,
                                          _text(r, "note"), kind == "dependent_coordinate"))
            subsystems.setdefault(sub or "", []).append(name)
        elif kind == "frame":
            frames[name] = (name, _text(r, "parent") or GROUND, [], sub or "")
        elif kind == "rotation":
            axis = _vec(r, "axis_")
            frames[name][2].append(Rotation((ex.Num(axis[0]), ex.Num(axis[1]), ex.Num(axis[2])), _affine(_num(r, "angle_rad"), _text(r, "coefficients"))))
        elif kind == "translation":
            x, y, z = _vec(r, "", "_mm", MM)
            shift = _text(r, "coefficients")
            scaled = ";".join(f"{p.partition('=')[0]}={','.join(str(float(v) * MM) for v in p.partition('=')[2].split(','))}" for p in filter(None, shift.split(";")))
            frames[name][2].append(Translation((_affine(x, scaled, 0), _affine(y, scaled, 1), _affine(z, scaled, 2))))
        elif kind == "loop":
            loops_a[name] = r
        elif kind == "loop_b":
            loops_b[name] = r
        elif kind == "body":
            bodies.append(Body(name, ex.Num(_num(r, "value")), _point(r), sub))
        elif kind == "counter_mass":
            masses.append(CounterMass(name, ex.Num(_num(r, "value") * display_unit(_text(r, "unit") or "kg").to_si), _point(r), None, sub))
        elif kind in ("spring_from", "spring_to"):
            points[name] = r
        elif kind == "pulley":
            pulleys[name.removesuffix(".pulley")] = r
        elif kind == "spring":
            springs.append(r)
        elif kind == "tilt":
            axis = _vec(r, "axis_")
            tilts.append(Tilt(axis, _num(r, "range_min"), _num(r, "range_max"), name))
    built = [_spring(r, points, pulleys) for r in springs]
    loops = []
    for name, a in loops_a.items():
        b = loops_b[name]
        axis = _vec(a, "axis_")
        axis_b = _vec(b, "axis_")
        loops.append(Loop(name, _text(a, "value"), _point(a), _point(b), None if math.isnan(axis[0]) else _nums(axis), _text(a, "subsystem"), "",
                          None if math.isnan(axis_b[0]) else _nums(axis_b)))
    scenarios = []
    for s in members:
        g = next(r for r in rows if _text(r, "kind") == "gravity" and _text(r, "scenario") in ("", s))
        upright = next((r for r in rows if _text(r, "kind") == "upright" and _text(r, "scenario") in ("", s)), None)
        angles = tuple(float(v) for v in _text(g, "coefficients").split(";") if v)
        scenarios.append(Scenario(s, Gravity(_num(g, "value"), _vec(g, "axis_")), {}, tilt=angles,
                                  upright=Gravity(_num(upright, "value"), _vec(upright, "axis_")) if upright is not None else None))
    frame_objects = tuple(Frame(n, parent, tuple(transforms), sub or None) for n, parent, transforms, sub in frames.values())
    return Problem(
        name="as_built",
        title="the balancer as built (build.csv)",
        source="build.csv",
        description="",
        path="build.csv",
        parameters=(),
        variables=(),
        subsystems=tuple(Subsystem(n, tuple(c)) for n, c in subsystems.items()),
        coordinates=tuple(coordinates),
        frames=frame_objects,
        bodies=tuple(bodies),
        counter_masses=tuple(masses),
        springs=tuple(built),
        scenarios=tuple(scenarios),
        objective=Objective(),
        report=(),
        settings=Settings(
            verify_samples=int(settings.get("verify_samples", Settings.verify_samples)),
            verify_tolerance=settings.get("verify_tolerance", Settings.verify_tolerance),
            seed=int(settings.get("seed", Settings.seed)),
        ),
        loops=tuple(loops),
        tilts=tuple(tilts),
    )


def _nums(v: tuple[float, float, float]) -> tuple[ex.Expr, ex.Expr, ex.Expr]:
    return (ex.Num(v[0]), ex.Num(v[1]), ex.Num(v[2]))


def _spring(r: Row, points: Mapping[str, Row], pulleys: Mapping[str, Row]) -> ZeroFreeLengthSpring:
    name = _text(r, "name")
    a, b = _point(points[f"{name}.from"]), _point(points[f"{name}.to"])
    k = _num(r, "rate_N_per_mm", 1e3)
    built = BuiltSpring(ex.Num(k), ex.Num(_num(r, "initial_tension_N")), ex.Num(_num(r, "free_length_mm", MM)), ex.Num(_num(r, "offset_mm", MM)))
    pulley = None
    p = pulleys.get(name)
    if p is not None:
        lead = _vec(p, "lead_")
        fixing = _vec(p, "fixing_")
        pulley = Pulley(
            radius=_num(p, "radius_mm", MM),
            clearance=_num(p, "clearance_mm", MM),
            axis=_vec(p, "axis_"),
            sense=1 if _text(p, "wrap") != "cw" else -1,
            pin=_text(p, "pin").lower() == "true",
            lead=None if math.isnan(lead[0]) else lead,
            fixing=None if math.isnan(fixing[0]) else fixing,
        )
    return ZeroFreeLengthSpring(name, ex.Num(k), (a, b), _text(r, "subsystem") or None, pulley=pulley, slack_margin=_num(r, "slack_margin_mm", MM), built=built)


def check(rows: Sequence[Row]) -> AsBuilt:
    """The as-built residual ratio of the sheet ``rows`` (see the module docstring)."""
    from ..designer.solution import Solution
    from ..solvers.base import Status
    from ..verify.check import check as dense

    notes = tuple(
        f"spring {_text(r, 'name')}: no spring can be made (its free length and initial tension are unknown)"
        for r in rows
        if _text(r, "kind") == "spring" and not (math.isfinite(_num(r, "free_length_mm")) and math.isfinite(_num(r, "initial_tension_N")) and math.isfinite(_num(r, "offset_mm")))
    )
    if notes:
        return AsBuilt(math.nan, None, {}, tuple(dict.fromkeys(notes)))
    checks = []
    tolerance = 0.0
    slack: dict[str, float] = {}
    for problem in rebuild(rows):
        scenario_parameters: dict[str, tuple[tuple[float, float, float], dict[str, float]]] = {s.name: (s.gravity.vector, {}) for s in problem.scenarios}
        solution = Solution(problem, Status.OPTIMAL, "as built", {}, 0.0, 0.0, 0.0, scenario_parameters=scenario_parameters)
        v = dense(solution, "dense")
        checks += list(v.checks)
        tolerance = v.tolerance
        for name, share in slack_shares(problem).items():
            slack[name] = max(slack.get(name, 0.0), share)
    verification = Verification(tuple(checks), tolerance)
    return AsBuilt(verification.residual_ratio, verification, slack)


def slack_shares(problem: Problem) -> dict[str, float]:
    """Per spring of an as-built ``problem``: the share of its subsystem's sampled
    configurations (the dense check's count and seed) where it is slack (x < 0)."""
    from ..mechanics import Mechanics
    from ..springs.workspace import SEED_OFFSET, sample

    settings = problem.settings
    q = sample(problem, {}, settings.verify_samples, settings.seed + SEED_OFFSET)
    out: dict[str, float] = {}
    for s in problem.springs:
        if s.built is None:
            continue
        coords: dict[str, Any] = {c.name: c.home for c in problem.coordinates}
        if s.subsystem is not None:
            rows = q[s.subsystem]
            coords.update({c.name: rows[:, i] for i, c in enumerate(problem.subsystem_coordinates(s.subsystem))})
        mech = Mechanics(problem, {}, {}, coords, problem.scenarios[0].gravity.vector)
        x = np.asarray(mech.spring_path(s), dtype=float) + float(mech.value(s.built.offset))
        out[s.name] = float(np.mean(x < 0.0))
    return out
