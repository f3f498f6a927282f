"""``counterpoise frames`` and ``counterpoise draw``: where everything is, at one configuration.

``--at NAME=VALUE`` sets a coordinate (or a design variable) for the table or the
drawing; the others stay at home (coordinates) and at their initial values (variables).
A closed loop's dependent coordinates are solved from the independent ones (never given).
Values need their unit, like in a problem file ("30 deg", "120 mm").
"""

from __future__ import annotations

import csv
import sys
from collections.abc import Sequence
from pathlib import Path

from ..errors import InputError, ProblemFileError
from ..mechanics.poses import Placed, assembled, default_values, place
from ..model.problem import Problem
from ..model.units import LENGTH, DisplayUnit, canonical_dimension, dimension_name, display_unit, parse_quantity


class AtError(ValueError):
    """A bad ``--at`` item (the message names it)."""


def parse_at(problem: Problem, items: Sequence[str] | None) -> tuple[dict[str, float], dict[str, float]]:
    """Coordinates and variables (SI) with the ``--at`` values applied."""
    coordinates, variables = default_values(problem)
    units = {c.name: c.unit for c in problem.coordinates} | {v.name: v.unit for v in problem.variables}
    for item in items or []:
        name, sep, raw = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise AtError(f"--at {item}: expected NAME=VALUE, e.g. 'elbow_joint=30 deg'")
        if name not in units:
            raise AtError(f"--at {item}: '{name}' is neither a coordinate nor a design variable (coordinates: {', '.join(coordinates)})")
        if name in coordinates and problem.coordinate[name].dependent:
            raise AtError(f"--at {item}: '{name}' is a dependent coordinate of a closed loop: it is solved from the independent ones, give those")
        try:
            q = parse_quantity(raw.strip())
        except InputError as exc:
            raise AtError(f"--at {item}: {exc}") from None
        if q.dimension != units[name].dimension:
            raise AtError(f"--at {item}: expected {dimension_name(units[name].dimension)}, got {dimension_name(q.dimension)}")
        (coordinates if name in coordinates else variables)[name] = q.si
    try:
        return assembled(problem, coordinates), variables
    except ProblemFileError as exc:
        raise AtError(f"--at: {exc}") from None


def length_unit(problem: Problem) -> DisplayUnit:
    """The file's length unit: that of its first length parameter, variable or coordinate (else m)."""
    length = canonical_dimension(LENGTH)
    for unit in [p.unit for p in problem.parameters] + [v.unit for v in problem.variables] + [c.unit for c in problem.coordinates]:
        if unit.dimension == length and unit.symbol:
            return unit
    return display_unit("m")


HEADER = ("kind", "name", "frame", "x", "y", "z", "unit", "mass_kg", "force_N")


def rows(problem: Problem, placed: list[Placed], unit: DisplayUnit) -> list[tuple[str, ...]]:
    out = []
    for p in placed:
        xyz = [f"{unit.from_si(c):.9g}" for c in p.position]
        mass = f"{p.mass:.6g}" if p.kind in ("body", "counter_mass") else ""
        force = f"{p.force:.6g}" if p.kind == "spring" else ""
        out.append((p.kind, p.name, p.frame, *xyz, unit.symbol, mass, force))
    return out


def frames_table(problem: Problem, at: Sequence[str] | None, as_csv: bool, console: object) -> None:
    coordinates, variables = parse_at(problem, at)
    unit = length_unit(problem)
    table_rows = rows(problem, place(problem, coordinates, variables), unit)
    if as_csv:
        writer = csv.writer(sys.stdout, lineterminator="\n")
        writer.writerow(HEADER)
        writer.writerows(table_rows)
        return
    from rich.table import Table

    shown = ", ".join(f"{c.name} = {c.unit.from_si(coordinates[c.name]):.6g} {c.unit.symbol}".rstrip() for c in problem.coordinates)
    table = Table(title=f"{problem.name}: world positions ({unit.symbol}) at {shown}")
    for col in HEADER:
        if col != "unit":
            table.add_column(col, justify="right" if col in ("x", "y", "z", "mass_kg", "force_N") else "left")
    for r in table_rows:
        table.add_row(*(v for i, v in enumerate(r) if HEADER[i] != "unit"))
    console.print(table)  # type: ignore[attr-defined]


def draw_files(problem: Problem, at: Sequence[str] | None, out: Path) -> list[Path]:
    from ..plots.mechanism import mechanism_plot

    coordinates, variables = parse_at(problem, at)
    return mechanism_plot(problem, out / problem.name, variables, coordinates if at else None)
