"""The report rows as pandas DataFrames, for notebooks and scripts (pandas is imported here only)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..pipeline import DesignResult
from .rows import DESIGN_COLUMNS, SUMMARY_COLUMNS, VERIFICATION_COLUMNS, design_rows, summary_columns, summary_row, verification_rows

if TYPE_CHECKING:
    import pandas as pd


def design_table(result: DesignResult) -> "pd.DataFrame":
    import pandas as pd

    return pd.DataFrame(design_rows(result), columns=DESIGN_COLUMNS)


def summary_table(results: list[DesignResult]) -> "pd.DataFrame":
    import pandas as pd

    rows = [summary_row(r) for r in results]
    columns = list(dict.fromkeys(c for row in rows for c in summary_columns(row))) or SUMMARY_COLUMNS
    return pd.DataFrame(rows, columns=columns)


def verification_table(result: DesignResult) -> "pd.DataFrame":
    import pandas as pd

    return pd.DataFrame(verification_rows(result), columns=VERIFICATION_COLUMNS)
