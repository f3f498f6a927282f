"""What ``load`` and ``solve`` do, written once for the typer app (:mod:`.app`) and the
light path (:mod:`.light`): neither typer nor rich is imported here, and every message
goes through the caller's ``err`` (one line each)."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator, Mapping
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


def load_all(files: list[Path], overrides: Mapping[str, object], err: Err, warnings: dict[str, tuple[str, ...]] | None = None) -> list[Problem] | None:
    """Every file loaded and checked (closed loops assemble), or None after printing every
    error (the caller exits 2); a problem with nothing to balance gets a warning line.
    ``warnings``: filled with each problem's warnings (:func:`~counterpoise.formulation.assumptions.degeneracies`)
    by problem name (unique here), for :func:`solve_all` to pass on to the reports. The
    console script keeps each problem with what its checks found (:mod:`counterpoise.io.cache`)."""
    from ..errors import ProblemFileError
    from ..io.cache import load_checked  # the loader, or the console script's cache of loaded problems

    problems, errors = [], []
    found: dict[str, tuple[str, ...]] = {}
    seen: dict[str, Path] = {}
    for path in files:
        try:
            problem, problem_warnings = load_checked(path, overrides, checked)
        except ProblemFileError as exc:
            errors.append(str(exc))
            continue
        if problem.name in seen:
            errors.append(f"{path}: problem.name: '{problem.name}' is also the name of {seen[problem.name]} (both would write the report folder {problem.name})")
            continue
        seen[problem.name] = path
        found[problem.name] = problem_warnings
        problems.append(problem)
    if errors:
        for line in errors:
            err(line)
        return None
    for problem in problems:  # nothing to balance: say so, the design would be "optimal" anyway
        if warnings is not None:
            warnings[problem.name] = found[problem.name]
        for warning in found[problem.name]:
            err(f"{problem.path}: warning: {warning}")
    return problems


def checked(problem: Problem) -> tuple[str, ...]:
    """The checks of a loaded problem: closed loops close at home and assemble over the
    ranges (docs/loops.md; a :class:`~counterpoise.errors.ProblemFileError` otherwise),
    then its degeneracy warnings (:func:`~counterpoise.formulation.assumptions.degeneracies`).
    Both depend on the problem's content only, so the console script keeps the warnings
    with the loaded problem."""
    from ..formulation.assumptions import degeneracies
    from ..mechanics.closure import check_assembly

    check_assembly(problem)
    return tuple(degeneracies(problem))


def solve_all(
    problems: list[Problem],
    out: Path,
    plot: bool,
    starts: int,
    err: Err,
    html: bool = True,
    jobs: int = 1,
    check: str = "dense",
    warnings: Mapping[str, tuple[str, ...]] | None = None,
) -> tuple[list[dict[str, Any]], int]:
    """Design, verify and write every problem (``plot``: energy.png and mechanism.png in its
    folder before the folder appears; ``html``: report.html, the page of the folder, last);
    the summary rows and the worst exit status. ``check``: ``dense`` or ``auto`` (the exact
    certificate where it applies, :func:`counterpoise.verify.check.check`). ``warnings``:
    what :func:`load_all` found per problem name, written into status.txt as found (a
    problem missing from it is looked at by the report layer).

    ``jobs`` > 1 (``solve --jobs N``): the problems are solved on a local pool of that many
    worker processes (at most one per problem; :func:`counterpoise.studies.runners.process_pool`),
    each writing its own report folder. Their error lines and summary rows come back in the
    order of ``problems``, as in one process, and each design is the same as in one process.
    """
    if jobs > 1 and len(problems) > 1:
        outcomes: Iterable[tuple[dict[str, Any] | None, int]] = _pooled(problems, out, plot, starts, err, html, min(jobs, len(problems)), check, warnings)
    else:
        outcomes = (solve_one(problem, out, plot, starts, err, html, check, _found(warnings, problem)) for problem in problems)
    rows, worst = [], 0
    for row, status in outcomes:
        worst = max(worst, status)
        if row is not None:
            rows.append(row)
    return rows, worst


def _found(warnings: Mapping[str, tuple[str, ...]] | None, problem: Problem) -> tuple[str, ...] | None:
    return None if warnings is None else warnings.get(problem.name)


def solve_one(
    problem: Problem, out: Path, plot: bool, starts: int, err: Err, html: bool = True, check: str = "dense", warnings: tuple[str, ...] | None = None
) -> tuple[dict[str, Any] | None, int]:
    """Design, verify and write one problem (as :func:`solve_all`): its summary row (None
    when there is no design to report) and its exit status. ``warnings``: the problem's
    degeneracy warnings found at load (None: the report layer finds them)."""
    from ..errors import CounterpoiseError, ProblemFileError
    from ..nofollow import LinkRefused
    from ..pipeline import design
    from ..report.files import write_reports
    from ..report.rows import summary_row

    t0 = time.perf_counter()
    try:
        result = design(problem, starts=starts, check=check)
    except ProblemFileError as exc:  # an input limit met while designing (a part search too large): exit 2
        err(str(exc))
        return None, 2
    except CounterpoiseError as exc:
        err(f"{problem.path}: {exc}")
        return None, 1
    try:
        extra = None
        if plot:
            from ..plots import energy_plot
            from ..plots.mechanism import design_mechanism_plot

            def extra(folder: Path, result: Any = result) -> None:
                energy_plot(result, folder)
                design_mechanism_plot(result, folder)

        folder = write_reports(result, out, extra, html=html, warnings=warnings)
    except LinkRefused as exc:  # a link planted at the report folder: nothing written
        err(f"{problem.path}: --out: {exc}")
        return None, 2
    except OSError as exc:
        err(f"{problem.path}: cannot write reports to {out}: {exc.strerror or exc}")
        return None, 1
    row = summary_row(result)
    row["wall_s"] = time.perf_counter() - t0
    row["folder"] = str(folder)
    row["message"] = result.message
    return row, 0 if result.optimal else 1


def _solve_in_worker(
    problem: Problem, out: Path, plot: bool, starts: int, html: bool, check: str = "dense", warnings: tuple[str, ...] | None = None
) -> tuple[dict[str, Any] | None, int, list[str]]:
    """:func:`solve_one` in a pool worker: its error lines are sent back with its row."""
    lines: list[str] = []
    row, status = solve_one(problem, out, plot, starts, lines.append, html, check, warnings)
    return row, status, lines


def _pooled(
    problems: list[Problem],
    out: Path,
    plot: bool,
    starts: int,
    err: Err,
    html: bool,
    jobs: int,
    check: str = "dense",
    warnings: Mapping[str, tuple[str, ...]] | None = None,
) -> Iterator[tuple[dict[str, Any] | None, int]]:
    """:func:`solve_one` of every problem on a pool of ``jobs`` processes, in order."""
    from ..studies.runners import process_pool, stop_pool

    pool = process_pool(jobs)
    finished = False
    try:
        futures = [pool.submit(_solve_in_worker, problem, out, plot, starts, html, check, _found(warnings, problem)) for problem in problems]
        for future in futures:
            row, status, lines = future.result()
            for line in lines:
                err(line)
            yield row, status
        finished = True
    finally:  # interrupted or failed: the workers end now, none outlives the command
        stop_pool(pool, finished)
