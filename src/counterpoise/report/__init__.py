"""The report layer: rows with units (:mod:`.rows`), files written atomically (:mod:`.files`),
DataFrame views (:mod:`.tables`)."""

from __future__ import annotations

from .files import atomic_write_text, csv_text, write_reports
from .rows import DESIGN_COLUMNS, SUMMARY_COLUMNS, VERIFICATION_COLUMNS, design_rows, status_text, summary_row, verification_rows
from .tables import design_table, summary_table, verification_table

__all__ = [
    "DESIGN_COLUMNS",
    "SUMMARY_COLUMNS",
    "VERIFICATION_COLUMNS",
    "atomic_write_text",
    "csv_text",
    "design_rows",
    "design_table",
    "status_text",
    "summary_row",
    "summary_table",
    "verification_rows",
    "verification_table",
    "write_reports",
]
