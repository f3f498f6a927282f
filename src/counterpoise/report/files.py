"""Report files: CSV text from rows, written through a temporary file and a rename.

``results/<problem>/`` receives ``design.csv``, ``summary.csv``, ``verification.csv``,
``status.txt`` (see :mod:`.rows`), ``substitution.csv`` when the problem substitutes a body,
and ``schedule.csv`` for a payload range (:mod:`.schedule`). Floats are written with 10 significant digits; a missing
value (None, NaN) is an empty cell.

Every CSV the tool writes (these, ``study.csv``, ``frames --csv``) goes through
:class:`CsvWriter`: a text cell that a spreadsheet would run as a formula (one beginning
with ``=``, ``+``, ``-``, ``@``, a tab or a carriage return: a name, a description, a
catalogue's part number) is written with a leading single quote, as OWASP advises against
CSV injection; a number, negative ones included, stays a number.
"""

from __future__ import annotations

import csv
import errno
import io
import math
import os
import re
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import TextIO

from .. import unfinished
from ..filemodes import respect_umask
from ..designer.layers import Page, Row, layers
from ..pipeline import DesignResult
from .rows import (
    DESIGN_COLUMNS,
    SUBSTITUTION_COLUMNS,
    VERIFICATION_COLUMNS,
    design_rows,
    status_text,
    substitution_rows,
    summary_columns,
    summary_row,
    verification_rows,
)

FLOAT_FORMAT = "%.10g"
#: the first characters that make a spreadsheet read a cell as a formula (OWASP: CSV injection)
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
#: a number written as text (``-12.5``, ``1e-05``): a spreadsheet reads it as a number, not a formula
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


def _runs_as_formula(text: str) -> bool:
    return text.startswith(FORMULA_STARTS) and _NUMBER.fullmatch(text) is None


def spreadsheet_cell(value: object) -> object:
    """``value`` as a CSV cell no spreadsheet runs: a text beginning with one of
    :data:`FORMULA_STARTS` (and not a number) gets a leading ``'``; so does a text that is
    already such a text behind quotes (``'=x`` -> ``''=x``), so that :func:`cell_text`
    gives back exactly what was written. Numbers and other values are left as they are."""
    if isinstance(value, str) and _runs_as_formula(value.lstrip("'")):
        return "'" + value
    return value


def cell_text(cell: str) -> str:
    """The text :func:`spreadsheet_cell` was given, from the cell it wrote (a reader of our
    own CSV files: a part number read back from ``design.csv``)."""
    if cell.startswith("'") and _runs_as_formula(cell.lstrip("'")):
        return cell[1:]
    return cell


class CsvWriter:
    """``csv.writer`` (lines ending in a newline, ``\\n``) whose every cell goes through
    :func:`spreadsheet_cell`: the one way the tool writes CSV."""

    def __init__(self, handle: TextIO) -> None:
        self._writer = csv.writer(handle, lineterminator="\n")

    def writerow(self, cells: Iterable[object]) -> None:
        self._writer.writerow([spreadsheet_cell(c) for c in cells])

    def writerows(self, rows: Iterable[Iterable[object]]) -> None:
        for cells in rows:
            self.writerow(cells)


def _cell(value: object, float_format: str = FLOAT_FORMAT) -> object:
    if value is None:
        return ""
    if isinstance(value, float):
        return "" if math.isnan(value) else float_format % value
    return value


def csv_text(rows: Iterable[Row], columns: Sequence[str], float_format: str = FLOAT_FORMAT) -> str:
    """CSV text with a header line; cells in ``columns`` order."""
    buffer = io.StringIO()
    writer = CsvWriter(buffer)
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_cell(row.get(c), float_format) for c in columns])
    return buffer.getvalue()


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename (mode from the umask)."""
    import tempfile

    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as handle:
            handle.write(text)
        respect_umask(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


#: attempts at moving a finished folder into place while other runs do the same
SWAP_ATTEMPTS = 20


def atomic_folder(folder: Path, fill: Callable[[Path], None]) -> Path:
    """Make ``folder`` whole or not at all: ``fill(temp)`` writes every file into a temporary
    folder beside it, which then replaces ``folder`` by renames. What was there stays until
    the new folder is complete; if ``fill`` fails (a full disk), it stays as it was. Two runs
    writing the same folder at once each leave a whole folder, the last one to finish wins.
    A symbolic link at ``folder`` is refused (:class:`~counterpoise.nofollow.LinkRefused`),
    before anything is written.
    """
    import shutil  # here, not at import (with bz2 and lzma): only a written folder needs them
    import tempfile

    from ..nofollow import refuse_link

    refuse_link(folder)  # a planted link: refused (LinkRefused), as a study's folders are
    folder.parent.mkdir(parents=True, exist_ok=True)
    temp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".new", dir=folder.parent))
    unfinished.begin(temp)  # an ended pool worker removes it (counterpoise.unfinished)
    try:
        fill(temp)
        respect_umask(temp, directory=True)
        for _ in range(SWAP_ATTEMPTS):
            old = None
            if folder.exists():
                # not registered with counterpoise.unfinished: between the two renames it holds
                # the previous whole folder, which an ended worker must not delete
                old = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".old", dir=folder.parent))
                try:
                    os.replace(folder, old / folder.name)
                except FileNotFoundError:  # another run moved it first
                    pass
            try:
                os.rename(temp, folder)
            except OSError as exc:
                if exc.errno not in (errno.ENOTEMPTY, errno.EEXIST):
                    raise
                continue  # another run put its folder there in between: move it aside again
            finally:
                if old is not None:
                    shutil.rmtree(old, ignore_errors=True)
            return folder
        raise OSError(errno.EBUSY, f"other runs keep replacing {folder}")
    except BaseException:
        shutil.rmtree(temp, ignore_errors=True)
        raise
    finally:
        unfinished.end(temp)


def report_texts(result: DesignResult, warnings: Sequence[str] | None = None) -> dict[str, str]:
    """File name -> text of every report of ``result`` (see :func:`report_files`)."""
    return report_files(result, warnings)[0]


def report_files(result: DesignResult, warnings: Sequence[str] | None = None) -> tuple[dict[str, str], list[tuple[str, Page]]]:
    """(File name -> text of every report of ``result``, the sections ``report.html`` gives
    the layers' files): ``design.csv``, ``summary.csv``,
    ``verification.csv``, ``status.txt``, ``substitution.csv`` when the problem substitutes a
    body, and the files of the registered layers (:func:`counterpoise.designer.layers.layers`,
    innermost first: a payload range's ``schedule.csv``; a ``[robust]`` design's
    ``tolerance.csv``, ``tuning_corners.csv`` and ``tuning.csv``; catalogue parts'
    ``tolerance.csv``; ``springs.csv`` and ``build.csv`` of a design with springs or
    counter-masses). Each layer adds its rows to ``design.csv``, its cells to ``summary.csv``
    (a column the summary does not list goes last) and its lines to ``status.txt``: what it
    chose after the design's own lines, what it found after the problem's warnings.

    ``warnings``: the problem's degeneracy warnings as already found
    (:func:`~counterpoise.formulation.assumptions.degeneracies`; the CLI finds them at load);
    None: the problem's, as :func:`~counterpoise.formulation.assumptions.problem_warnings`
    found them (once per problem)."""
    stack = layers()
    summary = summary_row(result)
    status = status_text(result)
    for layer in stack:
        status = _lines(status, layer.status_lines(result))
    if warnings is None:  # not given: the problem's own, found once per problem (formulation.assumptions)
        from ..formulation.assumptions import problem_warnings

        warnings = problem_warnings(result.problem)
    status = _lines(status, "".join(f"warning: {w}\n" for w in warnings))
    for layer in stack:
        status = _lines(status, layer.status_notes(result))
    texts = {
        "design.csv": csv_text(design_rows(result), DESIGN_COLUMNS),
        "summary.csv": csv_text([summary], summary_columns(summary)),
        "verification.csv": csv_text(verification_rows(result), VERIFICATION_COLUMNS),
        "status.txt": status if status.endswith("\n") else status + "\n",  # a text file ends with a newline, whichever layer wrote its last line
    }
    if result.problem.substitutions:
        texts["substitution.csv"] = csv_text(substitution_rows(result), SUBSTITUTION_COLUMNS)
    pages: list[tuple[str, Page]] = []
    for layer in stack:
        for name, table in layer.tables(result).items():
            if name in texts:
                raise ValueError(f"{name}: written twice (layer {layer.name} and another): a file has one writer")
            texts[name] = csv_text(table.rows, table.columns, table.float_format or FLOAT_FORMAT)
            if table.page is not None:
                pages.append((name, table.page))
    return texts, pages


def _lines(text: str, more: str) -> str:
    """``text`` with the lines ``more`` after it, each layer's starting on a line of its own."""
    if not more:
        return text
    return (text if not text or text.endswith("\n") else text + "\n") + more


def write_reports(
    result: DesignResult, out_dir: str | Path, extra: Callable[[Path], object] | None = None, html: bool = False, warnings: Sequence[str] | None = None
) -> Path:
    """Write every report of ``result`` into ``out_dir/<problem name>/``; returns that folder.

    The folder appears whole or not at all (:func:`atomic_folder`): it replaces what was
    there (reports of an earlier run included) only once every file is written.
    ``extra(folder)`` writes more files into it first (the CLI's ``--plot``). ``html``: then
    ``report.html``, the page of every file and plot in the folder (:mod:`.html`).
    ``warnings``: the degeneracy warnings already found (see :func:`report_texts`).
    """
    texts, pages = report_files(result, warnings)  # built before anything is written

    def fill(temp: Path) -> None:
        for name, text in texts.items():
            with (temp / name).open("w", encoding="utf-8", newline="") as handle:
                handle.write(text)
        if extra is not None:
            extra(temp)
        if html:
            from .html import IMAGES, report_html

            images = {name: (temp / name).read_bytes() for name, *_ in IMAGES if (temp / name).is_file()}
            page = report_html(result.problem.name, result.problem.title, result.status.value, texts, images, pages)
            with (temp / "report.html").open("w", encoding="utf-8", newline="") as handle:
                handle.write(page)

    return atomic_folder(Path(out_dir) / result.problem.name, fill)
