"""``counterpoise frames`` and ``counterpoise draw``: where everything is, at one configuration.

``--at NAME=VALUE`` sets a coordinate (or a design variable) for the table or the
drawing; the others stay at home (coordinates) and at their initial values (variables).
A closed loop's dependent coordinates are solved from the independent ones (never given).
Values need their unit, like in a problem file ("30 deg", "120 mm"); a bare number for an
angle is an error that says how to write it, as in a file.

``--design DIR`` shows a solved design: the folder ``solve`` wrote (``results/<problem>``),
whose ``design.csv`` gives the variables and the catalogue part of each slot. Spring forces
are then those of the chosen parts (or of the designed stiffness). Without it the table and
the drawing say that they show the file's initial values, and a spring that takes its part
from a catalogue slot has no force yet (no part is chosen before a solve).
"""

from __future__ import annotations

import csv
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import InputError, ProblemFileError
from ..mechanics.poses import Placed, assembled, default_values, place
from ..model.problem import Problem
from ..model.units import LENGTH, DisplayUnit, angle_hint, canonical_dimension, dimension_name, display_unit, is_angle_unit, parse_quantity


class AtError(ValueError):
    """A bad ``--at`` or ``--design`` item (the message names it)."""


@dataclass(frozen=True)
class Design:
    """The design shown: variables (SI), base-parameter values that the chosen parts set
    (each slot's rate, free length, initial tension, longest length), the parts (slot ->
    part number), and a line saying where it comes from."""

    variables: dict[str, float]
    parameters: dict[str, float] = field(default_factory=dict)
    parts: dict[str, str] = field(default_factory=dict)
    source: str = ""
    solved: bool = False


def initial_design(problem: Problem) -> Design:
    """The file's initial values (no solve)."""
    _, variables = default_values(problem)
    source = f"design: the file's initial values (not solved; give --design results/{problem.name} after a solve)"
    if problem.slots:
        source += "; springs of catalogue slots: no part chosen yet, no force"
    return Design(variables, source=source)


def read_design(problem: Problem, folder: Path) -> Design:
    """The design ``solve`` wrote into ``folder`` (its ``design.csv``): one line naming the
    folder and what is wrong when it is not a design of this problem."""
    where = f"--design {folder}"
    path = folder / "design.csv"
    if not path.is_file():
        raise AtError(f"{where}: no design.csv there (give the folder a solve wrote: results/{problem.name}, or DIR/{problem.name} after --out DIR)")
    status = folder / "status.txt"
    if status.is_file():
        first = _read_text(status, where).splitlines()[:1]
        named = first[0].partition(":")[2].strip() if first and first[0].startswith("problem:") else ""
        if named and named != problem.name:
            raise AtError(f"{where}: holds a design of problem '{named}', not of '{problem.name}'")
    rows = _read_rows(path, where)
    variables: dict[str, float] = {}
    per_setting: dict[str, dict[str, float]] = {}
    parts: dict[str, str] = {}
    setting = problem.setting(problem.scenarios[0].name)
    for i, row in enumerate(rows, start=1):
        kind, name = row.get("kind", ""), row.get("name", "")
        at = f"{where}: design.csv row {i} ({name})"
        if kind == "variable":
            if name not in problem.variable:
                raise AtError(f"{at}: the file has no variable '{name}' (a design of another version of the file?)")
            v = problem.variable[name]
            try:
                q = parse_quantity(f"{row.get('value', '')} {'' if row.get('unit') in (None, '', '1') else row['unit']}".strip())
            except InputError as exc:
                raise AtError(f"{at}: {exc}") from None
            if q.dimension != v.unit.dimension:
                raise AtError(f"{at}: expected {dimension_name(v.unit.dimension)}, got {dimension_name(q.dimension)}")
            scenario = row.get("scenario") or ""
            if scenario:
                per_setting.setdefault(name, {}).setdefault(scenario, q.si)
            else:
                variables[name] = q.si
        elif kind == "part":
            from ..report.files import cell_text

            slot = next((s for s in problem.slots if s.name == name), None)
            if slot is None:
                raise AtError(f"{at}: the file has no slot '{name}'")
            number = cell_text(row.get("value", ""))
            if number not in slot.catalogue.part_number:
                raise AtError(f"{at}: part '{number}' is not in catalogue {slot.catalogue.name} ({slot.catalogue.path})")
            parts[name] = number
    shown_at = ""
    for name, values in per_setting.items():
        if name in variables:
            continue
        if setting in values:
            variables[name] = values[setting]
        else:
            first_setting = next(iter(values))
            variables[name] = values[first_setting]
            shown_at = first_setting
    missing = [v.name for v in problem.variables if v.name not in variables]
    if missing:
        raise AtError(f"{where}: design.csv has no value of variable '{missing[0]}' (a design of another version of the file?)")
    unchosen = [s.name for s in problem.slots if s.name not in parts]
    if unchosen:
        raise AtError(f"{where}: design.csv names no part for slot '{unchosen[0]}' (the solve found none: see its status.txt)")
    parameters: dict[str, float] = {}
    if parts:
        from ..selection.direct import part_parameters

        rows_of = {s.name: s.catalogue.part_number.index(parts[s.name]) for s in problem.slots}
        parameters = part_parameters(problem, rows_of)
    source = f"design: {folder}"
    if parts:
        source += "; parts " + ", ".join(f"{k}: {v}" for k, v in parts.items())
    if shown_at:
        source += f"; variables set per scenario shown at {shown_at}"
    return Design(variables, parameters, parts, source, solved=True)


def _read_text(path: Path, where: str) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise AtError(f"{where}: cannot read {path.name}: {getattr(exc, 'strerror', None) or exc}") from None


def _read_rows(path: Path, where: str) -> list[dict[str, str]]:
    text = _read_text(path, where)
    reader = csv.DictReader(text.splitlines())
    needed = {"name", "kind", "scenario", "value", "unit"}
    if reader.fieldnames is None or not needed <= set(reader.fieldnames):
        raise AtError(f"{where}: design.csv lacks the columns {', '.join(sorted(needed - set(reader.fieldnames or [])))}")
    try:
        return list(reader)
    except csv.Error as exc:
        raise AtError(f"{where}: design.csv: {exc}") from None


def parse_at(problem: Problem, items: Sequence[str] | None, design: Design | None = None) -> tuple[dict[str, float], dict[str, float]]:
    """Coordinates and variables (SI) with the ``--at`` values applied (on top of ``design``'s
    variables, else the file's initial values)."""
    coordinates, variables = default_values(problem)
    if design is not None:
        variables.update(design.variables)
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
        if is_angle_unit(units[name].symbol) and not q.unit.symbol and q.si != 0:  # a bare 0 is 0 in any unit
            raise AtError(f"--at {item}: a bare number used as an angle ('{raw.strip()}' would be radians): {angle_hint(q.si)}")
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


def rows(problem: Problem, placed: list[Placed], unit: DisplayUnit, unset: set[str] | frozenset[str] = frozenset()) -> list[tuple[str, ...]]:
    """One row per placed thing; a spring in ``unset`` (a slot with no part chosen) has no force."""
    out = []
    for p in placed:
        xyz = [f"{unit.from_si(c):.9g}" for c in p.position]
        mass = f"{p.mass:.6g}" if p.kind in ("body", "counter_mass") else ""
        force = f"{p.force:.6g}" if p.kind == "spring" and p.name.rsplit(".", 1)[0] not in unset else ""
        out.append((p.kind, p.name, p.frame, *xyz, unit.symbol, mass, force))
    return out


def _design(problem: Problem, design_dir: Path | None) -> Design:
    return read_design(problem, design_dir) if design_dir is not None else initial_design(problem)


def placed_at(problem: Problem, at: Sequence[str] | None, design: Design) -> tuple[dict[str, float], list[Placed], set[str]]:
    """Coordinates, everything placed, and the springs with no force (slots, no part)."""
    from ..plots.mechanism import scenario_with, unset_slot_springs

    coordinates, variables = parse_at(problem, at, design)
    placed = place(problem, coordinates, variables, scenario_with(problem, design.parameters))
    return coordinates, placed, unset_slot_springs(problem, design.solved)


def frames_table(problem: Problem, at: Sequence[str] | None, as_csv: bool, console: object, design_dir: Path | None = None, err: Any = None) -> None:
    """Print the table (or CSV); the line saying which design it shows goes under the table's
    title, or to ``err`` (stderr) with ``--csv``, so that stdout stays one CSV table."""
    design = _design(problem, design_dir)
    coordinates, placed, unset = placed_at(problem, at, design)
    unit = length_unit(problem)
    table_rows = rows(problem, placed, unit, unset)
    if as_csv:
        (err or (lambda line: print(line, file=sys.stderr)))(design.source)
        from ..report.files import CsvWriter

        writer = CsvWriter(sys.stdout)
        writer.writerow(HEADER)
        writer.writerows(table_rows)
        return
    from rich.table import Table

    shown = ", ".join(f"{c.name} = {c.unit.from_si(coordinates[c.name]):.6g} {c.unit.symbol}".rstrip() for c in problem.coordinates)
    table = Table(title=f"{problem.name}: world positions ({unit.symbol}) at {shown}", caption=design.source, caption_justify="left")
    for col in HEADER:
        if col != "unit":
            table.add_column(col, justify="right" if col in ("x", "y", "z", "mass_kg", "force_N") else "left")
    for r in table_rows:
        table.add_row(*(v for i, v in enumerate(r) if HEADER[i] != "unit"))
    console.print(table)  # type: ignore[attr-defined]  # a rich Console, imported lazily


def draw(problem: Problem, at: Sequence[str] | None, out: Path, design_dir: Path | None = None) -> Any:
    """The drawing (:class:`counterpoise.plots.mechanism.Drawing`) of ``problem`` at ``at``."""
    from ..plots.mechanism import mechanism_drawing

    design = _design(problem, design_dir)
    coordinates, variables = parse_at(problem, at, design)
    title = f"{problem.name}: solved design" if design.solved else None
    return mechanism_drawing(problem, out / problem.name, variables, coordinates if at else None, title, design.parameters, design.source, design.solved)


def draw_files(problem: Problem, at: Sequence[str] | None, out: Path, design_dir: Path | None = None) -> list[Path]:
    return [draw(problem, at, out, design_dir).path]
