"""What ``load`` and ``solve`` do, written once for the typer app (:mod:`.app`) and the
light path (:mod:`.light`): neither typer nor rich is imported here, and every message
goes through the caller's ``err`` (one line each)."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..model.problem import Problem

Err = Callable[[str], None]


def out_error(out: Path) -> str | None:
    """What is wrong with ``--out`` as a folder to write into (it is created if missing), as
    one line, or None: a regular file, a symbolic link to nothing, or a file on its path."""
    import os

    for where in (out, *out.parents):
        if where.is_symlink() and not where.exists():
            what = "" if where == out else f" (on the path of '{out}')"
            return f"--out: '{where}'{what} is a symbolic link to '{os.readlink(where)}', which does not exist: create that folder, or give another --out"
        if where.exists():
            if not where.is_dir():
                what = "" if where == out else f" (on the path of '{out}')"
                return f"--out: '{where}'{what} is a file, not a folder: give a folder (it is created if missing)"
            return None
    return None


def load_all(files: list[Path], overrides: Mapping[str, object], err: Err) -> list[Problem] | None:
    """Every file loaded and checked (closed loops assemble), or None after printing every
    error (the caller exits 2); a problem with nothing to balance gets a warning line."""
    from ..errors import ProblemFileError
    from ..io.loader import load_problem
    from ..mechanics.closure import check_assembly

    problems, errors = [], []
    seen: dict[str, Path] = {}
    for path in files:
        try:
            problem = load_problem(path, overrides)
            check_assembly(problem)  # closed loops: closes at home, assembles over the ranges (docs/loops.md)
        except ProblemFileError as exc:
            errors.append(str(exc))
            continue
        if problem.name in seen:
            errors.append(f"{path}: problem.name: '{problem.name}' is also the name of {seen[problem.name]} (both would write the report folder {problem.name})")
            continue
        seen[problem.name] = path
        problems.append(problem)
    if errors:
        for line in errors:
            err(line)
        return None
    from ..formulation.assumptions import degeneracies

    for problem in problems:  # nothing to balance: say so, the design would be "optimal" anyway
        for warning in degeneracies(problem):
            err(f"{problem.path}: warning: {warning}")
    return problems


def solve_all(
    problems: list[Problem], out: Path, plot: bool, starts: int, err: Err, html: bool = True, check: str = "dense"
) -> tuple[list[dict[str, Any]], int]:
    """Design, verify and write every problem (``plot``: energy.png and mechanism.png in its
    folder before the folder appears; ``html``: report.html, the page of the folder, last);
    the summary rows and the worst exit status. ``check``: ``dense`` or ``auto`` (the exact
    certificate where it applies, :func:`counterpoise.verify.check.check`)."""
    from ..errors import CounterpoiseError, ProblemFileError
    from ..pipeline import design
    from ..report.files import write_reports
    from ..report.rows import summary_row

    rows, worst = [], 0
    for problem in problems:
        t0 = time.perf_counter()
        try:
            result = design(problem, starts=starts, check=check)
        except ProblemFileError as exc:  # an input limit met while designing (a part search too large): exit 2
            err(str(exc))
            worst = max(worst, 2)
            continue
        except CounterpoiseError as exc:
            err(f"{problem.path}: {exc}")
            worst = max(worst, 1)
            continue
        try:
            extra = None
            if plot:
                from ..plots import energy_plot
                from ..plots.mechanism import design_mechanism_plot

                def extra(folder: Path, result: Any = result) -> None:
                    energy_plot(result, folder)
                    design_mechanism_plot(result, folder)

            folder = write_reports(result, out, extra, html=html)
        except OSError as exc:
            err(f"{problem.path}: cannot write reports to {out}: {exc.strerror or exc}")
            worst = max(worst, 1)
            continue
        row = summary_row(result)
        row["wall_s"] = time.perf_counter() - t0
        row["folder"] = str(folder)
        row["message"] = result.message
        rows.append(row)
        if not result.optimal:
            worst = max(worst, 1)
    return rows, worst
