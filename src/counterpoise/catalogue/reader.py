"""Read a spring catalogue CSV through a column mapping and validate every row.

Every error is a :class:`CatalogueError`, one line naming the file, the row and the
column: ``parts.csv: row 3 (line 4), column stiffness: the rate must be positive, got -5``.
Rows are numbered from 1 (the first row after the header); the line counts the header.
"""

from __future__ import annotations

import csv
import math
import statistics
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..progress import counter

from ..errors import ProblemFileError
from ..model.parts import Catalogue
from .columns import (
    DERIVED,
    DERIVED_PLAUSIBLE,
    DERIVED_TEXT,
    DERIVED_TYPICAL,
    FIELDS,
    PLAUSIBLE,
    PLAUSIBLE_TEXT,
    TYPICAL,
    UNIT_SYSTEMS,
    ColumnMapping,
    mapping_from,
)

#: the name that stands for the catalogue shipped with the package
SHIPPED = "shipped"


class CatalogueError(ProblemFileError):
    """A catalogue file is unreadable or one of its rows is invalid (file, row, column)."""

    def __init__(self, file: str, where: str, message: str) -> None:
        super().__init__(file, where, message)


class CatalogueUnitsError(CatalogueError):
    """The values of a catalogue are not plausible for springs in the unit system it is
    read with (see :data:`~.columns.PLAUSIBLE`)."""


def shipped_catalogue_path() -> Path:
    """The extension-spring catalogue shipped as package data (docs/spring-catalogue.md)."""
    from importlib import resources

    return Path(str(resources.files("counterpoise").joinpath("data/extension_springs.csv")))


def read_catalogue(
    path: str | Path,
    mapping: ColumnMapping | None = None,
    name: str = "",
    rate_tolerance: float = math.nan,
    initial_tension_tolerance: float = math.nan,
) -> Catalogue:
    """Read and validate ``path`` (the shipped catalogue for :data:`SHIPPED`).

    ``rate_tolerance`` and ``initial_tension_tolerance`` fill those fields where the file
    has no column for them (NaN: unknown).
    """
    mapping = mapping or mapping_from(None)
    if str(path) == SHIPPED:
        path = shipped_catalogue_path()
    label = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise CatalogueError(label, "file", f"cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise CatalogueError(label, "file", "not UTF-8 text") from None
    rows = _csv_rows(label, text.splitlines())
    if not rows or not any(cell.strip() for cell in rows[0]):
        raise CatalogueError(label, "header", "the file is empty: expected a header line of column names")
    header = [h.strip() for h in rows[0]]
    twice = sorted({h for h in header if h and header.count(h) > 1}, key=header.index)
    if twice:
        where = ", ".join(str(i + 1) for i, h in enumerate(header) if h == twice[0])
        raise CatalogueError(label, "header", f"column '{twice[0]}' appears twice (columns {where}): which one holds the values is ambiguous; rename or remove one")
    index: dict[str, int] = {}
    for field, column in mapping.columns:
        if column in header:
            index[field] = header.index(column)
        elif field not in mapping.optional_columns:
            raise CatalogueError(label, "header", f"missing column '{column}' (for {field.replace('_', ' ')}); columns are {', '.join(header)}")
    values: dict[str, list[Any]] = {f: [] for f in (
        "part_number", "material", "rate", "free_length", "initial_tension", "max_load", "max_length",
        "outer_diameter", "wire_diameter", "mass", "price", "rate_tolerance", "initial_tension_tolerance",
    )}
    seen: dict[str, int] = {}
    number = 0
    tick = counter(f"reading catalogue {label}: rows", len(rows) - 1)
    for line, cells in enumerate(rows[1:], start=2):
        tick(line - 1)
        if not any(c.strip() for c in cells):
            continue  # blank line
        number += 1
        if len(cells) != len(header):
            raise CatalogueError(label, f"row {number} (line {line})", f"expected {len(header)} cells, got {len(cells)}")
        row = _row(label, number, line, cells, index, mapping, header)
        part = row["part_number"]
        if part in seen:
            raise CatalogueError(label, _where(number, line, header[index["part_number"]]), f"duplicate part number '{part}' (also row {seen[part]})")
        seen[part] = number
        if math.isnan(row["rate_tolerance"]):
            row["rate_tolerance"] = rate_tolerance
        if math.isnan(row["initial_tension_tolerance"]):
            row["initial_tension_tolerance"] = initial_tension_tolerance
        for key in values:
            values[key].append(row[key])
    if not number:
        raise CatalogueError(label, "file", "the catalogue has no parts")
    check_plausible(label, values, mapping, header, index)
    return Catalogue(name or Path(label).stem, label, currency="", **{k: tuple(v) for k, v in values.items()})


def check_plausible(label: str, values: dict[str, list[Any]], mapping: ColumnMapping, header: list[str], index: dict[str, int]) -> None:
    """The median of each column must be plausible for an extension spring
    (:data:`~.columns.PLAUSIBLE`); if not, the file is probably in other units: the unit
    systems that make every median plausible are named."""
    medians = {}
    for field in PLAUSIBLE:
        known = [v for v in values.get(field, []) if not math.isnan(v)]
        if known:
            medians[field] = statistics.median(known)
    derived = {}  # the ratios of DERIVED, row by row (SI as read): they need no optional column
    for field, (top, bottom, power) in DERIVED.items():
        ratios = [a / b**power for a, b in zip(values[top], values[bottom]) if b > 0 and math.isfinite(a / b**power)]
        if ratios:
            derived[field] = statistics.median(ratios)

    def to(units: str, f: str) -> float:  # factor from SI as read to SI read in ``units``
        return UNIT_SYSTEMS[units].get(FIELDS[f], (1.0, ""))[0] / mapping.factor(f)

    def read_as(units: str) -> dict[str, float]:
        out = {f: m * to(units, f) for f, m in medians.items()}
        out.update({f: m * to(units, DERIVED[f][0]) / to(units, DERIVED[f][1]) ** DERIVED[f][2] for f, m in derived.items()})
        return out

    def band(f: str) -> tuple[float, float]:
        return PLAUSIBLE[f] if f in PLAUSIBLE else DERIVED_PLAUSIBLE[f]

    def outside(units: str) -> list[str]:
        return [f for f, m in read_as(units).items() if not band(f)[0] <= m <= band(f)[1]]

    def distance(units: str) -> float:
        return sum(abs(math.log(m / {**TYPICAL, **DERIVED_TYPICAL}[f])) for f, m in read_as(units).items() if m > 0)

    def show(f: str) -> str:
        if f in derived:
            what, text = DERIVED_TEXT[f]
            return f"{what} (columns {header[index[DERIVED[f][0]]]}, {header[index[DERIVED[f][1]]]}): median {derived[f] / 1e6:.3g} N/mm² (expected {text})"
        return f"column {header[index[f]]}: median {medians[f] / mapping.factor(f):.4g} {mapping.unit_name(f)} (expected {PLAUSIBLE_TEXT[f]})"

    wrong = outside(mapping.units)
    if not wrong:
        _check_springs_exist(label, values, mapping, header, index, to, lambda u: not outside(u), distance)
        return
    shown = "; ".join(show(f) for f in wrong[:2])
    fits = sorted((u for u in UNIT_SYSTEMS if u != mapping.units and not outside(u)), key=distance)
    hint = f'; the values are most plausible in {fits[0]} units: set units = "{fits[0]}"' if fits else "; check the unit system (units = ...) and the columns"
    raise CatalogueUnitsError(label, "units", f"not plausible for extension springs read in {mapping.units} units: {shown}{hint}")


def _check_springs_exist(
    label: str,
    values: dict[str, list[Any]],
    mapping: ColumnMapping,
    header: list[str],
    index: dict[str, int],
    to: Callable[[str, str], float],
    in_bands: Callable[[str], bool],
    distance: Callable[[str], float],
) -> None:
    """The median part must be a possible steel extension spring in the file's units
    (:func:`.physics.implausibility`: its rate and free length leave room for a wire that
    carries its loads) when it is one in other units (where every band holds too): then the
    file is refused, naming those units. Catches a file of weak springs in lbf and inch read
    as N-mm, whose medians all lie in their bands. Parts that are springs in no unit system
    (made up for a test, a paper's idealised rates) are left to the part limits."""
    import numpy as np

    from .physics import implausibility, sample

    rows = sample(len(values["rate"]))

    def median(units: str) -> float:
        column = {f: np.array([values[f][i] for i in rows], dtype=float) * to(units, f) for f in ("rate", "free_length", "initial_tension", "max_load")}
        return float(np.median(implausibility(column["rate"], column["free_length"], column["initial_tension"], column["max_load"])))

    declared = median(mapping.units)
    if not declared > 1:
        return
    fits = sorted((u for u in UNIT_SYSTEMS if u != mapping.units and in_bands(u) and median(u) <= 1), key=distance)
    if not fits:  # no unit system makes them springs: made-up parts (a test's), not a unit mistake
        return
    hint = f'; the values are most plausible in {fits[0]} units: set units = "{fits[0]}"'
    name = {f: header[index[f]] for f in ("rate", "free_length", "max_load", "initial_tension")}
    raise CatalogueUnitsError(
        label,
        "units",
        f"not plausible for extension springs read in {mapping.units} units: no steel spring of these rates and free lengths (columns "
        f"{name['rate']}, {name['free_length']}) carries these max loads and initial tensions (columns {name['max_load']}, "
        f"{name['initial_tension']}): the median part asks {declared:.3g} times the most it could{hint}",
    )


def _csv_rows(label: str, lines: list[str]) -> list[list[str]]:
    """The CSV rows of ``lines``; a malformed line (a field longer than the csv module's
    limit, :func:`csv.field_size_limit`) is a :class:`CatalogueError` naming its row and column."""
    rows: list[list[str]] = []
    reader = csv.reader(lines)
    while True:
        try:
            cells = next(reader)
        except StopIteration:
            return rows
        except csv.Error as exc:
            line = reader.line_num
            header = [h.strip() for h in rows[0]] if rows else []
            where = "header" if line == 1 else f"row {sum(1 for r in rows[1:] if any(c.strip() for c in r)) + 1} (line {line})"
            column = _long_field(lines[line - 1]) if 0 < line <= len(lines) else None
            if column is not None:
                name = header[column] if column < len(header) and header[column] else f"{column + 1}"
                where += f", column {name}"
                message = f"a field of {_field_length(lines[line - 1], column):,} characters; at most {csv.field_size_limit():,} are read"
            else:
                message = f"not valid CSV: {exc}"
            raise CatalogueError(label, where, message) from None
        rows.append(cells)


def _fields(line: str) -> list[str]:
    """The raw fields of one CSV line (quotes kept), split at commas outside quotes: enough to
    say which one is too long where the csv module refuses the line."""
    fields, start, quoted = [], 0, False
    for i, char in enumerate(line):
        if char == '"':
            quoted = not quoted
        elif char == "," and not quoted:
            fields.append(line[start:i])
            start = i + 1
    fields.append(line[start:])
    return fields


def _long_field(line: str) -> int | None:
    """The index of the first field of ``line`` longer than the csv module's limit."""
    limit = csv.field_size_limit()
    return next((i for i, f in enumerate(_fields(line)) if len(f) > limit), None)


def _field_length(line: str, column: int) -> int:
    """The length of a field of ``line`` without its quotes (``"a""b"`` is ``a"b``)."""
    field = _fields(line)[column].strip()
    if len(field) >= 2 and field[0] == field[-1] == '"':
        field = field[1:-1].replace('""', '"')
    return len(field)


def _where(number: int, line: int, column: str) -> str:
    return f"row {number} (line {line}), column {column}"


def _row(label: str, number: int, line: int, cells: list[str], index: dict[str, int], mapping: ColumnMapping, header: list[str]) -> dict[str, Any]:
    def cell(field: str) -> str | None:
        return cells[index[field]].strip() if field in index else None

    def fail(field: str, message: str) -> CatalogueError:
        return CatalogueError(label, _where(number, line, header[index[field]]), message)

    def number_of(field: str, required: bool) -> float:
        raw = cell(field)
        if raw is None or raw == "":
            if required and field in index:
                raise fail(field, "missing value")
            return math.nan
        try:
            value = float(raw)
        except ValueError:
            raise fail(field, f"expected a number, got '{raw}'") from None
        if not math.isfinite(value):
            raise fail(field, f"the value must be finite, got '{raw}'")
        return value * mapping.factor(field)

    part = cell("part_number") or ""
    if not part:
        raise fail("part_number", "missing part number")
    out: dict[str, Any] = {"part_number": part, "material": cell("material") or ""}
    for field in ("rate", "free_length", "initial_tension", "max_load", "max_length"):
        out[field] = number_of(field, required=True)
    for field in ("outer_diameter", "wire_diameter", "mass", "price", "package_quantity", "rate_tolerance", "initial_tension_tolerance"):
        out[field] = number_of(field, required=False)
    unit = mapping.unit_name
    if not out["rate"] > 0:
        raise fail("rate", f"the rate must be positive, got {cell('rate')} {unit('rate')}")
    if not out["free_length"] > 0:
        raise fail("free_length", f"the free length must be positive, got {cell('free_length')} {unit('free_length')}")
    if out["initial_tension"] < 0:
        raise fail("initial_tension", f"the initial tension must not be negative, got {cell('initial_tension')} {unit('initial_tension')}")
    if not out["max_load"] > out["initial_tension"]:
        raise fail("max_load", f"the maximum load {cell('max_load')} {unit('max_load')} must be above the initial tension {cell('initial_tension')} {unit('initial_tension')}")
    if not out["max_length"] > out["free_length"]:
        raise fail("max_length", f"the maximum length {cell('max_length')} {unit('max_length')} must be above the free length {cell('free_length')} {unit('free_length')}")
    for field in ("outer_diameter", "wire_diameter", "mass", "price"):
        if out[field] < 0:
            raise fail(field, f"must not be negative, got {cell(field)}")
    quantity = out.pop("package_quantity")
    if not math.isnan(quantity):
        if not (quantity >= 1 and float(quantity).is_integer()):
            raise fail("package_quantity", f"expected a whole number of springs per package, got {cell('package_quantity')}")
        out["price"] = out["price"] / quantity
    for field in ("rate_tolerance", "initial_tension_tolerance"):
        if not math.isnan(out[field]) and not 0 <= out[field] <= 1:
            raise fail(field, f"a tolerance is a fraction between 0 and 1 (0.1 = ±10 %), got {cell(field)}")
    return out
