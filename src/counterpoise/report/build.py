"""The build sheet, ``build.csv``: one row per physical item of a design (docs/build.md).

Kinds: ``spring_from`` and ``spring_to`` (a spring's anchor points), ``pulley`` (a pulley
mount's pulley, at the ``from`` point, with its cable), ``spring`` (the spring itself: rate,
part, length and force at home and over the workspace), ``counter_mass`` (mass and
position) and ``adjustment`` (a design variable the mechanism itself uses, or one set per
payload: its setting at home and its range).

Points are given in their own frame (``x_mm, y_mm, z_mm``) and in the world at home
(``world_*_mm``). Home is every coordinate at its home (closed loops assembled) in the home
scenario: the nominal payload's setting for a payload range, else the first scenario. The
workspace extremes of a spring are those of ``springs.csv`` for a catalogue part, else the
distances over the configurations the dense verification checked. The geometry of each
mount (cable length, installed length) comes from :mod:`counterpoise.mechanics.realisation`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import SupportsFloat

import numpy as np

from ..mechanics.energy import Mechanics
from ..mechanics.poses import assembled
from ..mechanics.realisation import DIRECT, Realisation, finite, realise_spring
from ..model import expr as ex
from ..model.mechanism import Point
from ..model.problem import Problem
from ..pipeline import DesignResult
from .rows import Row

BUILD_COLUMNS = [
    "item",
    "kind",
    "name",
    "frame",
    "x_mm",
    "y_mm",
    "z_mm",
    "world_x_mm",
    "world_y_mm",
    "world_z_mm",
    "value",
    "unit",
    "note",
    "subsystem",
    "part_number",
    "rate_N_per_mm",
    "free_length_mm",
    "initial_tension_N",
    "distance_home_mm",
    "distance_min_mm",
    "distance_max_mm",
    "cable_mm",
    "length_home_mm",
    "length_min_mm",
    "length_max_mm",
    "force_home_N",
    "force_min_N",
    "force_max_N",
    "range_min",
    "range_max",
]
#: build.csv keeps 12 significant digits (the other reports 10): the sheet alone rebuilds the
#: design's energy, and its residual ratio, to 1e-9 (tests/test_build_sheet.py)
BUILD_FLOAT_FORMAT = "%.12g"
MM = 1e3


def home_scenario(result: DesignResult) -> str:
    """The scenario home is taken in: the nominal payload's setting, else the first."""
    problem = result.problem
    if result.payload is not None:
        from ..payload.scenarios import payload_of, setting_name

        payload = payload_of(problem)
        nominal = setting_name(payload, payload.nominal)
        for s in problem.scenarios:
            if (s.setting or s.name) == nominal:
                return s.name
    return problem.scenarios[0].name


def home_mechanics(result: DesignResult, scenario: str | None = None) -> Mechanics:
    """The design's mechanics at home in ``scenario`` (default :func:`home_scenario`)."""
    problem = result.problem
    scenario = scenario or home_scenario(result)
    gravity, base = result.solution.scenario_parameters[scenario]
    coordinates = assembled(problem, {c.name: c.home for c in problem.coordinates})
    return Mechanics(problem, base, result.solution.variable_values(scenario), coordinates, gravity)


def _floats(values: Iterable[SupportsFloat]) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in values)
    return (x, y, z)


def _point_row(mech: Mechanics, kind: str, name: str, point: Point, subsystem: str | None) -> Row:
    local = _floats(mech.vector(point.position))
    world = _floats(mech.position(point))
    return {
        "kind": kind,
        "name": name,
        "frame": point.frame,
        "x_mm": local[0] * MM,
        "y_mm": local[1] * MM,
        "z_mm": local[2] * MM,
        "world_x_mm": world[0] * MM,
        "world_y_mm": world[1] * MM,
        "world_z_mm": world[2] * MM,
        "subsystem": subsystem or "",
    }


def workspace_distances(result: DesignResult) -> dict[str, tuple[float, float]]:
    """Per spring: the smallest and largest distance between its ends, in every scenario.

    Open chains: over the configurations ``springs.csv`` takes its extremes on (the dense
    sample of :func:`counterpoise.selection.geometry.sample_configurations`, seed + 11,
    drawn the same way without importing the selection layer:
    :func:`counterpoise.springs.workspace.sample`). Closed loops: over the
    assembled configurations the dense verification checked (its evaluators are cached:
    assembling a new sample would cost more than the rest of the page).
    """
    from ..springs.workspace import SEED_OFFSET
    from ..springs.workspace import sample as drawn
    from ..verify.check import evaluators

    problem = result.problem
    if not problem.springs:
        return {}
    settings = problem.settings
    by_scenario: dict[str, dict[str, np.ndarray]] = {}
    if problem.loops:
        for scenario, subsystem, evaluator in evaluators(result.solution):
            by_scenario.setdefault(scenario, {})[subsystem] = evaluator.q
    else:  # open chains: the draws of springs.csv's sample (kept on disk by counterpoise solve)
        sample = drawn(problem, {}, settings.verify_samples, settings.seed + SEED_OFFSET)
        by_scenario = {s.name: sample for s in problem.scenarios}
    out: dict[str, tuple[float, float]] = {}
    for scenario, q in by_scenario.items():
        gravity, base = result.solution.scenario_parameters[scenario]
        variables = result.solution.variable_values(scenario)
        for s in problem.springs:
            if s.subsystem is not None and s.subsystem in q:
                columns = q[s.subsystem]
                coordinates: dict[str, np.ndarray | float] = {c.name: columns[:, i] for i, c in enumerate(problem.subsystem_coordinates(s.subsystem))}
            else:  # fixed to ground at both ends: one configuration
                coordinates = {c.name: c.home for c in problem.coordinates}
            mech = Mechanics(problem, base, variables, coordinates, gravity)
            a, b = mech.position(s.ends[0]), mech.position(s.ends[1])
            d = np.sqrt(sum(np.asarray(x - y, dtype=float) ** 2 for x, y in zip(a, b)))
            lo, hi = float(np.min(d)), float(np.max(d))
            old = out.get(s.name)
            out[s.name] = (lo, hi) if old is None else (min(old[0], lo), max(old[1], hi))
    return out


def realisations(result: DesignResult, mech: Mechanics | None = None) -> dict[str, tuple[Realisation, str]]:
    """Per spring: its :class:`Realisation` and its part number ("" for a designed spring).

    A catalogue part takes its free length and initial tension from its catalogue row and
    its workspace extremes from ``springs.csv`` (:class:`~counterpoise.selection.parts.SpringUse`).
    """
    problem = result.problem
    mech = mech or home_mechanics(result)
    parts = result.parts
    uses = {u.spring: u for u in parts.springs} if parts is not None else {}
    slots = {s.name: s for s in problem.slots}
    need = [s.name for s in problem.springs if s.name not in uses]
    extremes = workspace_distances(result) if need else {}
    out: dict[str, tuple[Realisation, str]] = {}
    designed = {d.spring: d.design for d in getattr(result, "springs", ()) if d.design.ok}
    for s in problem.springs:
        l0 = f0 = math.nan
        part = ""
        if s.slot is not None and parts is not None and s.slot in parts.chosen:
            i = parts.chosen[s.slot]
            cat = slots[s.slot].catalogue
            l0, f0, part = float(cat.free_length[i]), float(cat.initial_tension[i]), str(cat.part_number[i])
        elif s.slot is None and s.direct is None and s.name in designed:
            # a pulley-mounted designed spring (docs/springs.md): its own free length and
            # initial tension place its fixed end; a direct mount keeps the file's
            l0, f0 = designed[s.name].free_length, designed[s.name].initial_tension
        use = uses.get(s.name)
        distances = (use.distance_min, use.distance_max) if use is not None else extremes[s.name]
        tuning = getattr(getattr(result.solution, "robust", None), "envelope", {}).get(s.name)
        if tuning is not None:  # [robust] tune: the cable serves every tuned corner (robust/limits.py)
            distances = (min(distances[0], tuning.distance_min), max(distances[1], tuning.distance_max))
        out[s.name] = (realise_spring(mech, s, distances, l0, f0), part)
    return out


def _names_in_mechanism(problem: Problem) -> set[str]:
    """Names the frames and bodies use (a design variable among them is an adjustment row)."""
    used: set[str] = set().union(*(f.names() for f in problem.frames))
    for b in problem.bodies:
        used |= ex.names(b.mass)
        for c in b.com.position:
            used |= ex.names(c)
    return used


def build_rows(result: DesignResult) -> list[Row]:
    """The rows of ``build.csv`` (see the module docstring)."""
    problem = result.problem
    mech = home_mechanics(result)
    rows: list[Row] = []
    made = realisations(result, mech)
    for s in problem.springs:
        r, part = made[s.name]
        a = _point_row(mech, "spring_from", f"{s.name}.from", s.ends[0], s.subsystem)
        b = _point_row(mech, "spring_to", f"{s.name}.to", s.ends[1], s.subsystem)
        if r.mount == DIRECT:
            a["note"] = f"spring {s.name}: fixed end (attached directly)"
            b["note"] = f"spring {s.name}: through a {r.cable * MM:.4g} mm cable to this point"
            rows += [a, b]
        else:
            a["note"] = f"spring {s.name}: the pulley's axis is here"
            b["note"] = f"spring {s.name}: the cable's end (link point)"
            pulley = {k: a[k] for k in a if k not in ("kind", "name", "note")}
            behind = f"{r.cable_behind_home * MM:.4g} mm of it behind the pulley at home"
            anchor = (
                f"; the spring's fixed end {r.anchor_distance * MM:.4g} mm behind the pulley along the cable"
                if not math.isnan(r.anchor_distance)
                else "; the spring's fixed end: free length and initial tension not known yet (a designed spring)"
            )
            pulley.update(
                kind="pulley",
                name=f"{s.name}.pulley",
                value=r.cable * MM,
                unit="mm",
                cable_mm=r.cable * MM,
                note=f"cable from the spring's end over this pulley to {s.name}.to: {r.cable * MM:.4g} mm, {behind}{anchor}",
            )
            rows += [a, b, pulley]
        installed = f"installed length at home {r.length_home * MM:.4g} mm, " if not math.isnan(r.length_home) else ""
        rows.append(
            {
                "kind": "spring",
                "name": s.name,
                "value": r.rate / MM,
                "unit": "N/mm",
                "note": f"{'part ' + part if part else 'designed spring'} ({r.mount} mount): {installed}force at home {r.force_home:.4g} N"
                + ("; free length and initial tension to be chosen (force k·d)" if math.isnan(r.free_length) else ""),
                "subsystem": s.subsystem or "",
                "part_number": part,
                "rate_N_per_mm": r.rate / MM,
                "free_length_mm": finite(r.free_length * MM),
                "initial_tension_N": finite(r.initial_tension),
                "distance_home_mm": r.distance_home * MM,
                "distance_min_mm": r.distance_min * MM,
                "distance_max_mm": r.distance_max * MM,
                "cable_mm": r.cable * MM,
                "length_home_mm": finite(r.length_home * MM),
                "length_min_mm": finite(r.length_min * MM),
                "length_max_mm": finite(r.length_max * MM),
                "force_home_N": r.force_home,
                "force_min_N": r.force_min,
                "force_max_N": r.force_max,
            }
        )
    for c in problem.counter_masses:
        row = _point_row(mech, "counter_mass", c.name, c.position, c.subsystem)
        mass = float(mech.value(c.mass))
        row.update(value=mass, unit="kg", note=f"{mass:.4g} kg in frame {c.position.frame}")
        rows.append(row)
    rows += adjustment_rows(result, mech)
    for i, row in enumerate(rows, start=1):
        row["item"] = i
    return rows


def adjustment_rows(result: DesignResult, mech: Mechanics) -> list[Row]:
    """A design variable the frames or bodies use, or one set per payload (adjustable): its
    setting at home and its range (over the payload schedule, or every scenario's setting)."""
    problem = result.problem
    used = _names_in_mechanism(problem)
    settings: dict[str, list[float]] = {}
    for slot, value in result.solution.values.items():
        settings.setdefault(slot.variable, []).append(value)
    schedule = result.payload.schedule if result.payload is not None else None
    if schedule is not None:
        for row in schedule.rows:
            for name, value in row.values.items():
                settings.setdefault(name, []).append(value)
    rows: list[Row] = []
    for v in problem.variables:
        if not (v.adjustable or v.name in used) or v.name not in mech.env:
            continue
        home = float(mech.env[v.name])
        values = settings.get(v.name, [home]) + [home]
        u = v.unit
        label = "" if u.label in ("", "1") else f" {u.label}"
        what = "set per payload" if v.adjustable else "a dimension of the mechanism set by the design"
        rows.append(
            {
                "kind": "adjustment",
                "name": v.name,
                "value": u.from_si(home),
                "unit": u.label,
                "range_min": u.from_si(min(values)),
                "range_max": u.from_si(max(values)),
                "note": f"{what}: {u.from_si(home):.6g}{label} at home" + (f"; {v.description}" if v.description else ""),
            }
        )
    return rows


def spring_realisations(result: DesignResult) -> Mapping[str, Realisation]:
    """Each spring's realisation at home (for a drawing or a page)."""
    return {name: r for name, (r, _) in realisations(result).items()}
