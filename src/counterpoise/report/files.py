"""Report files: CSV text from rows, written through a temporary file and a rename.

``results/<problem>/`` receives ``design.csv``, ``summary.csv``, ``verification.csv``,
``status.txt`` (see :mod:`.rows`), ``substitution.csv`` when the problem substitutes a body,
and ``schedule.csv`` for a payload range (:mod:`.schedule`). Floats are written with 10 significant digits; a missing
value (None, NaN) is an empty cell.
"""

from __future__ import annotations

import csv
import io
import math
import os
import tempfile
from collections.abc import Iterable, Sequence
from pathlib import Path

from ..pipeline import DesignResult
from . import parts
from .rows import (
    DESIGN_COLUMNS,
    SUBSTITUTION_COLUMNS,
    SUMMARY_COLUMNS,
    VERIFICATION_COLUMNS,
    Row,
    design_rows,
    status_text,
    substitution_rows,
    summary_row,
    verification_rows,
)

FLOAT_FORMAT = "%.10g"


def _cell(value: object) -> object:
    if value is None:
        return ""
    if isinstance(value, float):
        return "" if math.isnan(value) else FLOAT_FORMAT % value
    return value


def csv_text(rows: Iterable[Row], columns: Sequence[str]) -> str:
    """CSV text with a header line; cells in ``columns`` order."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_cell(row.get(c)) for c in columns])
    return buffer.getvalue()


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def report_texts(result: DesignResult) -> dict[str, str]:
    """File name -> text of every report of ``result`` (substitution.csv only when the
    problem substitutes a body; payload problems add ``schedule.csv``; problems with
    catalogue parts ``springs.csv`` and ``tolerance.csv``)."""
    texts = {
        "design.csv": csv_text(design_rows(result) + parts.part_design_rows(result), DESIGN_COLUMNS),
        "summary.csv": csv_text([summary_row(result)], SUMMARY_COLUMNS),
        "verification.csv": csv_text(verification_rows(result), VERIFICATION_COLUMNS),
        "status.txt": status_text(result) + parts.parts_status(result),
    }
    from ..formulation.assumptions import degeneracies

    texts["status.txt"] += "".join(f"warning: {w}\n" for w in degeneracies(result.problem))
    if result.problem.substitutions:
        texts["substitution.csv"] = csv_text(substitution_rows(result), SUBSTITUTION_COLUMNS)
    if result.payload is not None:
        from .schedule import payload_status_lines, schedule_columns, schedule_rows

        texts["status.txt"] += payload_status_lines(result)
        if result.payload.schedule is not None:
            texts["schedule.csv"] = csv_text(schedule_rows(result), schedule_columns(result))
    if result.parts is not None:
        texts["springs.csv"] = csv_text(parts.springs_rows(result), parts.SPRINGS_COLUMNS)
        texts["tolerance.csv"] = csv_text(parts.tolerance_rows(result), parts.TOLERANCE_COLUMNS)
    return texts


def write_reports(result: DesignResult, out_dir: str | Path) -> Path:
    """Write every report of ``result`` into ``out_dir/<problem name>/``; returns that folder.

    All texts are built before the first file is written, so a failure while building
    leaves the folder as it was.
    """
    folder = Path(out_dir) / result.problem.name
    for name, text in report_texts(result).items():
        atomic_write_text(folder / name, text)
    return folder
