"""The build sheet, ``build.csv``: everything a workshop builds, and everything a checker needs
to rebuild the balancer as built (docs/build.md).

One row per item, in this order (``kind``):

- ``setting``: the dense sample the as-built check takes (``verify_samples``, ``seed``) and
  the tolerance it is judged by (``verify_tolerance``);
- ``gravity``: per scenario, the acceleration (``value``, m/s²) and its direction
  (``axis_*``); on a tilting base also ``upright`` rows (the untilted gravity) and ``tilt``
  rows (an axis of the base and its range of angles);
- ``coordinate`` (``dependent_coordinate`` for a loop's solved coordinate): its subsystem,
  home (``value``) and range, in ``unit`` (deg or mm);
- ``frame``, then its ``rotation`` and ``translation`` rows in order: pose(frame) =
  pose(parent) · T1 · T2 · …; a rotation about ``axis_*`` by ``angle_rad`` plus Σ c·q over
  its ``coefficients`` ("q1=1;q2=-1"); a translation by ``x_mm, y_mm, z_mm`` plus Σ c·q
  ("q=1000,0,0": mm per unit of q);
- ``loop`` and ``loop_b``: a closed loop's joint (``value``: revolute, spherical or
  prismatic), its point in frame a (and axis) and in frame b;
- ``body``: a given mass (``value``, kg) at its centre of mass in its frame;
- ``spring_from``, ``spring_to``, ``pulley`` and ``spring``: a spring's anchor points, its
  pulley (radius, clearance, axis, wrap, pin, lead and fixing directions) and the spring as
  made: its wound rate, design rate, free length, initial tension, cable, anchor and
  ``offset`` (its extension is x = path + offset, where path is the cable's length from
  where it meets the pulley to the link point, or the distance between the ends);
- ``counter_mass``: mass and point; ``adjustment``: a design variable the mechanism uses,
  or one set per payload, with its range.

Rows that differ between scenarios (a payload's mass, an adjustment's setting, a working
mode's gravity) are written once per scenario (``scenario`` names it); every other row has
an empty ``scenario`` and holds in all. Lengths in mm, forces in N, rates in N/mm, angles in
rad, masses in kg: 15 significant digits, so that the sheet alone rebuilds the design's
energy to ~1e-14 (:mod:`.asbuilt` does, and every shipped design is checked that way).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..mechanics import Mechanics
from ..mechanics.cable import fixing_local, lead_local
from ..model import expr as ex
from ..model.elements import ZeroFreeLengthSpring
from ..model.mechanism import Point, Rotation
from ..model.problem import Problem
from ..payload.result import PayloadDesign
from .limits import Extreme, checked_solution, tuned_envelope

Row = dict[str, Any]

COLUMNS = [
    "item", "kind", "name", "scenario", "frame", "parent", "subsystem",
    "x_mm", "y_mm", "z_mm", "world_x_mm", "world_y_mm", "world_z_mm",
    "axis_x", "axis_y", "axis_z", "angle_rad", "coefficients",
    "value", "unit", "range_min", "range_max",
    "part_number", "mount", "rate_N_per_mm", "design_rate_N_per_mm", "free_length_mm", "initial_tension_N", "offset_mm",
    "radius_mm", "clearance_mm", "wrap", "pin", "lead_x", "lead_y", "lead_z", "fixing_x", "fixing_y", "fixing_z", "slack_margin_mm",
    "distance_home_mm", "distance_min_mm", "distance_max_mm", "path_min_mm", "path_max_mm", "cable_mm", "anchor_mm",
    "length_home_mm", "length_min_mm", "length_max_mm", "force_home_N", "force_min_N", "force_max_N",
    "note",
]  # fmt: skip
#: build.csv keeps 15 significant digits (the other reports 10): a long chain amplifies rounding
FLOAT_FORMAT = "%.15g"
MM = 1e3
#: an expression counts as affine in the coordinates when a random point agrees to this (relative)
AFFINE_TOLERANCE = 1e-10


@dataclass(frozen=True)
class Made:
    """A spring as made, SI: its part number ("" when designed), wound rate, initial tension
    and free length (NaN when no spring can be made)."""

    part: str
    rate: float
    initial_tension: float
    free_length: float


def as_written(rows: Sequence[Row]) -> list[Row]:
    """``rows`` with every float rounded as ``build.csv`` writes it (:data:`FLOAT_FORMAT`):
    the as-built check of the sheet in memory is then the check of the file, to the bit."""
    return [{k: (float(FLOAT_FORMAT % v) if isinstance(v, float) and math.isfinite(v) else v) for k, v in row.items()} for row in rows]


def home_scenario(solution: Any) -> str:
    """The scenario home is taken in: the nominal payload's setting, else the first."""
    problem = solution.problem
    if solution.extra(PayloadDesign) is not None:
        from ..payload.scenarios import payload_of, setting_name

        payload = payload_of(problem)
        nominal = setting_name(payload, payload.nominal)
        for s in problem.scenarios:
            if (s.setting or s.name) == nominal:
                return str(s.name)
    return str(problem.scenarios[0].name)


def mechanics_at(solution: Any, scenario: str, coordinates: Mapping[str, Any] | None = None) -> Mechanics:
    """The design's mechanics in ``scenario`` at ``coordinates`` (default: every home)."""
    from ..mechanics.poses import assembled

    problem: Problem = solution.problem
    gravity, base = solution.scenario_parameters[scenario]
    if coordinates is None:
        coordinates = assembled(problem, {c.name: c.home for c in problem.coordinates})
    return Mechanics(problem, base, solution.variable_values(scenario), coordinates, gravity)


def _f(value: Any) -> float:
    return float(np.asarray(value, dtype=float).reshape(-1)[0])


def _vector(mech: Mechanics, trees: Sequence[ex.Expr]) -> tuple[float, float, float]:
    x, y, z = (_f(mech.value(t)) for t in trees)
    return (x, y, z)


def affine(mech: Mechanics, tree: ex.Expr, coordinates: Sequence[str]) -> tuple[float, dict[str, float]]:
    """(constant, {coordinate: coefficient}) of ``tree`` at ``mech``'s parameters and
    variables, affine in the coordinates it uses; ValueError when it is not affine."""
    used = [c for c in coordinates if c in ex.names(tree)]
    zero = {c: 0.0 for c in coordinates}
    base = _f(mech.moved(zero).value(tree))
    out = {}
    for c in used:
        out[c] = _f(mech.moved({**zero, c: 1.0}).value(tree)) - base
    if used:
        rng = np.random.default_rng(len(used))
        point = {c: float(v) for c, v in zip(used, rng.uniform(-2.0, 2.0, len(used)))}
        got = _f(mech.moved({**zero, **point}).value(tree))
        want = base + sum(out[c] * point[c] for c in used)
        if abs(got - want) > AFFINE_TOLERANCE * max(1.0, abs(want), abs(base)):
            raise ValueError(f"'{tree}' is not affine in the coordinates")
    return base, {c: v for c, v in out.items() if v != 0.0}


def coefficients_text(coefficients: Mapping[str, float] | Mapping[str, tuple[float, ...]]) -> str:
    parts = []
    for name, c in coefficients.items():
        parts.append(f"{name}={','.join(f'{v:.12g}' for v in c)}" if isinstance(c, tuple) else f"{name}={c:.12g}")
    return ";".join(parts)


def _point_row(mech: Mechanics, kind: str, name: str, point: Point, subsystem: str | None) -> Row:
    local = _vector(mech, point.position)
    world = tuple(_f(v) for v in mech.position(point))
    return {
        "kind": kind, "name": name, "frame": point.frame, "subsystem": subsystem or "",
        "x_mm": local[0] * MM, "y_mm": local[1] * MM, "z_mm": local[2] * MM,
        "world_x_mm": world[0] * MM, "world_y_mm": world[1] * MM, "world_z_mm": world[2] * MM,
    }  # fmt: skip


def _mechanism_rows(problem: Problem, mech: Mechanics, scenario: Any) -> list[Row]:
    """Gravity, coordinates, frames and their transforms, loops and bodies in ``scenario``."""
    rows: list[Row] = []
    g = scenario.gravity
    rows.append({"kind": "gravity", "name": "gravity", "value": g.acceleration, "unit": "m/s^2", "axis_x": g.direction[0], "axis_y": g.direction[1], "axis_z": g.direction[2],
                 "coefficients": ";".join(f"{a:.12g}" for a in scenario.tilt), "note": "gravity (on a tilting base: at the tilt angles of coefficients)"})
    if scenario.upright is not None:
        u = scenario.upright
        rows.append({"kind": "upright", "name": "gravity", "value": u.acceleration, "unit": "m/s^2", "axis_x": u.direction[0], "axis_y": u.direction[1], "axis_z": u.direction[2],
                     "note": "gravity of the untilted base"})
    names = [c.name for c in problem.coordinates]
    for c in problem.coordinates:
        unit = "deg" if c.unit.dimension == "" else "mm"
        scale = 180.0 / math.pi if unit == "deg" else MM
        rows.append({"kind": "dependent_coordinate" if c.dependent else "coordinate", "name": c.name, "subsystem": c.subsystem, "value": c.home * scale, "unit": unit,
                     "range_min": c.lower * scale, "range_max": c.upper * scale, "note": c.description})
    for f in problem.frames:
        rows.append({"kind": "frame", "name": f.name, "parent": f.parent or "ground", "subsystem": f.subsystem or "", "note": f.description})
        for t in f.transforms:
            if isinstance(t, Rotation):
                axis = _vector(mech, t.axis)
                norm = math.sqrt(sum(a * a for a in axis))
                constant, coeffs = affine(mech, t.angle, names)
                rows.append({"kind": "rotation", "name": f.name, "axis_x": axis[0] / norm, "axis_y": axis[1] / norm, "axis_z": axis[2] / norm,
                             "angle_rad": constant + 0.0, "coefficients": coefficients_text(coeffs)})
            else:
                parts = [affine(mech, v, names) for v in t.vector]
                used = sorted({n for _, c in parts for n in c}, key=names.index)
                shifts = {n: tuple(parts[i][1].get(n, 0.0) * MM for i in range(3)) for n in used}
                rows.append({"kind": "translation", "name": f.name, "x_mm": parts[0][0] * MM, "y_mm": parts[1][0] * MM, "z_mm": parts[2][0] * MM,
                             "coefficients": coefficients_text(shifts)})
    for loop in problem.loops:
        a = _point_row(mech, "loop", loop.name, loop.a, loop.subsystem)
        a.update(value=loop.joint, note=loop.description)
        if loop.axis is not None:
            a.update(zip(("axis_x", "axis_y", "axis_z"), _vector(mech, loop.axis)))
        b = _point_row(mech, "loop_b", loop.name, loop.b, loop.subsystem)
        if loop.axis_b is not None:
            b.update(zip(("axis_x", "axis_y", "axis_z"), _vector(mech, loop.axis_b)))
        rows += [a, b]
    for body in problem.bodies:
        r = _point_row(mech, "body", body.name, body.com, body.subsystem)
        r.update(value=_f(mech.value(body.mass)), unit="kg", note=body.description)
        rows.append(r)
    return rows


def made_springs(solution: Any, designed: Sequence[Any], parts: Any) -> dict[str, Made]:
    """Per spring: the part or designed spring that is made (a direct mount without a part:
    the file's free length and initial tension)."""
    problem: Problem = solution.problem
    out: dict[str, Made] = {}
    designs = {d.spring: d.design for d in designed if d.scenario == "all"}
    designs.update({d.spring: d.design for d in designed if d.spring not in designs})
    slots = {s.name: s for s in problem.slots}
    mech = mechanics_at(solution, home_scenario(solution))
    for s in problem.springs:
        if s.slot is not None and parts is not None and s.slot in parts.chosen:
            i = parts.chosen[s.slot]
            cat = slots[s.slot].catalogue
            out[s.name] = Made(str(cat.part_number[i]), float(cat.rate[i]), float(cat.initial_tension[i]), float(cat.free_length[i]))
        elif s.name in designs:
            d = designs[s.name]
            if not d.ok and s.direct is None and math.isfinite(d.needed_distance):
                d = slack_spring(d)  # what would be wound, though its cable goes slack: the sheet shows it
            rate = float(d.rate) if d.ok else _f(mech.value(s.stiffness))
            if s.direct is not None:
                out[s.name] = Made("", rate, _f(mech.value(s.direct.initial_tension)), _f(mech.value(s.direct.free_length)))
            else:
                out[s.name] = Made("", rate, float(d.initial_tension) if d.ok else math.nan, float(d.free_length) if d.ok else math.nan)
        elif s.direct is not None:
            out[s.name] = Made("", _f(mech.value(s.stiffness)), _f(mech.value(s.direct.initial_tension)), _f(mech.value(s.direct.free_length)))
        else:
            out[s.name] = Made("", _f(mech.value(s.stiffness)), math.nan, math.nan)
    return out


def slack_spring(made: Any) -> Any:
    """The spring a pulley mount would be wound as when the slack rule alone refuses every
    candidate (its ends come closer than any windable F0/k): the lightest that keeps every
    other rule, its initial tension the middle of its band. Its cable goes slack near the
    shortest distance; the as-built check measures what that costs."""
    from dataclasses import replace as replaced

    from ..springs.design import design

    need = made.requirement
    return design(replaced(need, force_min=need.force_max), made.material, made.envelope, made.rate_tolerance, made.min_safety_factor)


def _spring_rows(problem: Problem, mech: Mechanics, s: ZeroFreeLengthSpring, made: Made, found: Mapping[str, Extreme], tuned: Any = None) -> list[Row]:
    """The rows of spring ``s`` in one scenario: anchor points, pulley and the spring as made
    (``tuned``: a [robust] design's envelope of the spring over its tuned corners)."""
    from ..mechanics.cable import spring_quantities

    k = made.rate
    design_rate = _f(mech.value(s.stiffness))
    home = {q: _f(v) for q, v in spring_quantities(mech, s).items()}
    a = _point_row(mech, "spring_from", f"{s.name}.from", s.ends[0], s.subsystem)
    b = _point_row(mech, "spring_to", f"{s.name}.to", s.ends[1], s.subsystem)
    d_lo, d_hi = min(found["length"].low, home["length"]), max(found["length"].high, home["length"])
    p_lo, p_hi = min(found["path"].low, home["path"]), max(found["path"].high, home["path"])
    if tuned is not None:  # [robust] tune: the cable serves every tuned corner (counterpoise.robust.limits)
        wraps = home["path"] - home["length"]  # a pin's constant wraps; 0 for a point pulley or a direct mount
        d_lo, d_hi = min(d_lo, tuned.distance_min), max(d_hi, tuned.distance_max)
        p_lo, p_hi = min(p_lo, tuned.distance_min + wraps), max(p_hi, tuned.distance_max + wraps)
    f0, l0 = made.initial_tension, made.free_length
    spring: Row = {
        "kind": "spring", "name": s.name, "subsystem": s.subsystem or "", "part_number": made.part,
        "rate_N_per_mm": k / MM, "design_rate_N_per_mm": design_rate / MM, "free_length_mm": l0 * MM, "initial_tension_N": f0,
        "slack_margin_mm": s.slack_margin * MM, "distance_home_mm": home["length"] * MM, "distance_min_mm": d_lo * MM, "distance_max_mm": d_hi * MM,
        "path_min_mm": p_lo * MM, "path_max_mm": p_hi * MM,
    }  # fmt: skip
    rows = [a, b]
    p = s.pulley
    if s.direct is not None or p is None:
        m = s.direct
        cable = _f(mech.value(m.cable)) if m is not None else 0.0
        offset = -cable - l0
        a["note"] = f"spring {s.name}: fixed end (attached directly)"
        b["note"] = f"spring {s.name}: through a {cable * MM:.4g} mm cable to this point"
        spring.update(mount="direct", cable_mm=cable * MM, offset_mm=offset * MM)
    else:
        # the design model pulls k·d (a point pulley or a pin) or k·(ℓ − ℓ*): the anchor is
        # set so that the part made, F0 + k·x with x = path + offset, pulls the same
        if p.exact or p.zero_length is None:
            zero = home["path"] - home["length"]  # a pin's constant wraps r(θp + θb); 0 for a point pulley
        else:
            zero = _f(mech.env[p.zero_length])
        offset = -zero - f0 / k
        cable = p_hi + p.clearance
        anchor = offset + cable + l0
        pulley = {key: a[key] for key in ("frame", "subsystem", "x_mm", "y_mm", "z_mm", "world_x_mm", "world_y_mm", "world_z_mm")}
        pulley.update(
            kind="pulley", name=f"{s.name}.pulley", axis_x=p.axis[0], axis_y=p.axis[1], axis_z=p.axis[2],
            radius_mm=p.radius * MM, clearance_mm=p.clearance * MM, wrap="ccw" if p.sense > 0 else "cw", pin="true" if p.pin else "false", cable_mm=cable * MM,
        )  # fmt: skip
        if p.radius > 0.0:  # where the spring lies behind the pulley (a point pulley: anywhere)
            lead = [_f(c) for c in lead_local(mech, s)]
            norm = math.sqrt(sum(c * c for c in lead))
            pulley.update(lead_x=lead[0] / norm, lead_y=lead[1] / norm, lead_z=lead[2] / norm)
        if p.pin and p.radius > 0.0:
            fixing = [_f(c) for c in fixing_local(mech, s)]
            fnorm = math.sqrt(sum(c * c for c in fixing))
            pulley.update(fixing_x=fixing[0] / fnorm, fixing_y=fixing[1] / fnorm, fixing_z=fixing[2] / fnorm)
        what = f"a pulley of radius {p.radius * MM:.4g} mm" if p.radius > 0 else "a pulley (its radius neglected)"
        a["note"] = f"spring {s.name}: the axis of {what}"
        b["note"] = f"spring {s.name}: " + (f"a pin of radius {p.radius * MM:.4g} mm, the cable wrapped onto it" if p.pin and p.radius > 0 else "the cable's end (link point)")
        pulley["note"] = (
            f"cable {cable * MM:.4g} mm from the spring's end over this pulley to {s.name}.to (the longest path {p_hi * MM:.4g} mm + clearance "
            f"{p.clearance * MM:.4g} mm); the spring lies behind the pulley along the lead direction, its fixed end {anchor * MM:.4g} mm from "
            f"where the cable meets the pulley" if math.isfinite(anchor) else "the spring's free length and initial tension are not known: no spring can be made"
        )
        spring.update(mount="pulley", cable_mm=cable * MM, anchor_mm=anchor * MM, offset_mm=offset * MM)
        rows.append(pulley)
    lengths = [path + offset + l0 for path in (home["path"], p_lo, p_hi)]
    forces = [f0 + k * (length - l0) for length in lengths]
    spring.update(
        length_home_mm=lengths[0] * MM, length_min_mm=lengths[1] * MM, length_max_mm=lengths[2] * MM,
        force_home_N=forces[0], force_min_N=forces[1], force_max_N=forces[2], value=k / MM, unit="N/mm",
        note=(f"part {made.part}" if made.part else "designed spring") + f" ({spring['mount']} mount): wound {k / MM:.6g} N/mm"
        + (f" (designed for {design_rate / MM:.6g})" if abs(k / design_rate - 1) > 1e-12 else "")
        + (f", free length {l0 * MM:.4g} mm, initial tension {f0:.4g} N" if math.isfinite(l0) else ", no spring can be made"),
    )  # fmt: skip
    rows.append(spring)
    return rows


def sheet_rows(solution: Any, designed: Sequence[Any] = (), parts: Any = None, found: Mapping[tuple[str, str], Mapping[str, Extreme]] | None = None) -> list[Row]:
    """The rows of ``build.csv`` for ``solution`` (see the module docstring); ``designed``:
    its designed springs, ``parts``: its catalogue parts, ``found``: the springs' extremes
    over the workspace (:func:`~.limits.extremes`, computed when not given)."""
    from .limits import extremes

    problem: Problem = solution.problem
    found = extremes(solution) if found is None else found
    made = made_springs(solution, designed, parts)
    settings = problem.settings
    head: list[Row] = [
        {"kind": "setting", "name": "verify_samples", "value": settings.verify_samples, "note": "random configurations per subsystem and scenario of the as-built check"},
        {"kind": "setting", "name": "seed", "value": settings.seed, "note": "their seed"},
        {"kind": "setting", "name": "verify_tolerance", "value": settings.verify_tolerance, "note": "the largest residual ratio that counts as balanced"},
    ]
    for t in problem.tilts:
        head.append({"kind": "tilt", "name": t.description or "tilt", "axis_x": t.axis[0], "axis_y": t.axis[1], "axis_z": t.axis[2], "range_min": t.lower, "range_max": t.upper,
                     "unit": "rad", "note": "a tilt of the base about this axis, over this range"})
    checked = checked_solution(solution)
    tuned = tuned_envelope(solution)
    per_scenario: dict[str, list[Row]] = {}
    for scenario in problem.scenarios:
        mech = mechanics_at(solution, scenario.name)
        rows = _mechanism_rows(problem, mech, scenario)
        for s in problem.springs:
            if not made[s.name].rate > 0.0 or _unused(found, s.name):  # stiffness 0: the design leaves it out
                continue
            extremes_of = _spring_extremes(found, s.name, scenario.name, checked)
            rows += _spring_rows(problem, mech, s, made[s.name], extremes_of, tuned.get(s.name))
        for c in problem.counter_masses:
            row = _point_row(mech, "counter_mass", c.name, c.position, c.subsystem)
            mass = _f(mech.value(c.mass))
            row.update(value=mass, unit="kg", note=f"{mass:.4g} kg in frame {c.position.frame}")
            rows.append(row)
        per_scenario[scenario.name] = rows
    rows = head + _collapse(problem, per_scenario) + _adjustments(solution)
    for i, row in enumerate(rows, start=1):
        row["item"] = i
    return rows


def _spring_extremes(found: Mapping[tuple[str, str], Mapping[str, Extreme]], spring: str, scenario: str, checked: Any) -> Mapping[str, Extreme]:
    """A spring's extremes in ``scenario``; a payload design's over its schedule's scenarios
    (the sheet's scenarios are the design's samples, the limits its schedule's)."""
    if (spring, scenario) in found:
        return found[(spring, scenario)]
    mine = [v for (name, _), v in found.items() if name == spring]
    out = {}
    for q in mine[0]:
        lows = [m[q] for m in mine]
        lo = min(lows, key=lambda e: e.low)
        hi = max(lows, key=lambda e: e.high)
        out[q] = Extreme(lo.low, hi.high, lo.at_low, hi.at_high)
    return out


def _unused(found: Mapping[tuple[str, str], Mapping[str, Extreme]], spring: str) -> bool:
    """Whether the spring pulls nothing anywhere (its largest force below NEGLIGIBLE_FORCE)."""
    from ..springs.design import NEGLIGIBLE_FORCE

    forces = [abs(v["force"].high) for (name, _), v in found.items() if name == spring]
    return bool(forces) and max(forces) < NEGLIGIBLE_FORCE


def _key(row: Row) -> tuple[Any, ...]:
    return tuple((k, row[k]) for k in sorted(row) if k not in ("item", "scenario"))


def _collapse(problem: Problem, per_scenario: Mapping[str, list[Row]]) -> list[Row]:
    """One row for an item that is the same in every scenario (``scenario`` empty), one per
    scenario where it differs; in the first scenario's order."""
    names = list(per_scenario)
    first = per_scenario[names[0]]
    out: list[Row] = []
    for i, row in enumerate(first):
        same = all(len(per_scenario[n]) > i and _key(per_scenario[n][i]) == _key(row) for n in names[1:])
        if same:
            out.append({**row, "scenario": ""})
        else:
            out += [{**per_scenario[n][i], "scenario": n} for n in names]
    return out


def _adjustments(solution: Any) -> list[Row]:
    """A design variable the frames or bodies use, or one set per payload: its setting at
    home and its range (over the payload schedule, or every scenario's setting)."""
    problem: Problem = solution.problem
    used: set[str] = set().union(*(f.names() for f in problem.frames))
    for body in problem.bodies:
        used |= ex.names(body.mass)
        for c in body.com.position:
            used |= ex.names(c)
    mech = mechanics_at(solution, home_scenario(solution))
    settings: dict[str, list[float]] = {}
    for slot, value in solution.values.items():
        settings.setdefault(slot.variable, []).append(value)
    outcome = solution.extra(PayloadDesign)
    schedule = outcome.schedule if outcome is not None else None
    if schedule is not None:
        for srow in schedule.rows:
            for name, value in srow.values.items():
                settings.setdefault(name, []).append(value)
    rows: list[Row] = []
    for v in problem.variables:
        if not (v.adjustable or v.name in used) or v.name not in mech.env:
            continue
        home = _f(mech.env[v.name])
        values = settings.get(v.name, [home]) + [home]
        u = v.unit
        label = "" if u.label in ("", "1") else f" {u.label}"
        what = "set per payload" if v.adjustable else "a dimension of the mechanism set by the design"
        rows.append({"kind": "adjustment", "name": v.name, "scenario": "", "value": u.from_si(home), "unit": u.label, "range_min": u.from_si(min(values)),
                     "range_max": u.from_si(max(values)), "note": f"{what}: {u.from_si(home):.6g}{label} at home" + (f"; {v.description}" if v.description else "")})
    return rows
