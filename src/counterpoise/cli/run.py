"""What the commands do once typer has parsed their values: a plain function per command
that :mod:`.app` calls (``solve``, ``validate``, ``study``), and the steps they share
(reading ``--set``, loading and checking files, solving and writing each problem). Neither
typer nor rich is imported here (only a study's progress bar imports rich's console), and
every message goes through the caller's ``err`` (one line each)."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import clip

if TYPE_CHECKING:
    from ..model.problem import Problem

Err = Callable[[str], None]
#: prints the summary rows of ``solve`` (``wide``: every column)
Summary = Callable[[list[dict[str, Any]], bool], None]

#: Exit status of an internal error (:func:`guarded`).
INTERNAL_ERROR = 3

#: exit status of an interrupted study: 128 + the signal number, as shells report it
EXIT_SIGINT, EXIT_SIGTERM = 130, 143


class UsageError(Exception):
    """A command-line value that is wrong: its one line (the command exits 2, nothing written)."""


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
    from ..formulation.assumptions import problem_warnings
    from ..mechanics.closure import check_assembly

    check_assembly(problem)
    return problem_warnings(problem)


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


# -- the commands ----------------------------------------------------------------------------


def guarded(err: Err, debug: bool, body: Callable[[], int | None]) -> int | None:
    """``body()`` as every command runs (the typer app, :func:`counterpoise.cli.app.main`): progress lines
    on ``err``, no library warning (with its source path) unless ``debug``; Ctrl-C is one
    line and status 130, any other failure one line and :data:`INTERNAL_ERROR` (the
    traceback with ``debug``). What ``body`` returns, or raises as SystemExit, stands."""
    import warnings

    from .. import progress

    try:
        with warnings.catch_warnings(), progress.sink(err, timed=progress.wants_timed_notes(sys.stderr)):
            if not debug:
                warnings.simplefilter("ignore")
            return body()
    except KeyboardInterrupt:
        err("interrupted")
        return 130
    except Exception as exc:  # noqa: BLE001 - the last line of defence: one line, never a traceback
        if debug:
            raise
        err(f"internal error: {type(exc).__name__}: {_short(exc)} (run with --debug for the traceback)")
        return INTERNAL_ERROR


def _load(
    files: list[Path], set_: list[str] | None, out: Path, err: Err, warnings: dict[str, tuple[str, ...]] | None = None
) -> tuple[list[Problem], dict[str, object]] | None:
    """What ``solve`` and ``study`` do before their work: read the ``--set`` values, load
    and check every file, check the output folder; the problems and the values set, or
    None after one line on ``err`` per error (the command exits 2)."""
    try:
        sets = overrides(set_)
    except UsageError as exc:
        err(str(exc))
        return None
    problems = load_all(list(files), sets, err, warnings)
    if problems is None:
        return None
    wrong = out_error(out)
    if wrong is not None:
        err(wrong)
        return None
    return problems, sets


def solve_command(
    err: Err,
    summary: Summary,
    *,
    files: list[Path],
    out: Path,
    set_: list[str] | None,
    plot: bool,
    starts: int,
    report: str,
    wide: bool,
    check: str,
    jobs: int,
) -> int:
    """``counterpoise solve`` once its values are parsed and checked: load every file,
    design, verify and write each, print the summary through ``summary``; the exit status.
    Every message goes through ``err`` (one line each)."""
    if len(files) > 1:
        from ..io.cache import keep_no_built

        keep_no_built()  # built designers and evaluators are kept for a solve of one file only
    warnings: dict[str, tuple[str, ...]] = {}  # found at load, written into status.txt as found
    found = _load(files, set_, out, err, warnings)
    if found is None:
        return 2
    problems, _ = found
    rows, worst = solve_all(problems, out, plot, starts, err, html=report == "html", jobs=jobs, check=check, warnings=warnings)
    summary(rows, wide)
    return worst


def validate_command(err: Err, out: Err, *, files: list[Path], set_: list[str] | None) -> int:
    """``counterpoise validate`` once its values are parsed: load and check every file, one
    ``ok`` line each on ``out``; the exit status (2: some file does not load, every error
    said on ``err``)."""
    try:
        sets = overrides(set_)
    except UsageError as exc:
        err(str(exc))
        return 2
    problems = load_all(list(files), sets, err)
    if problems is None:
        return 2
    for p in problems:
        out(
            f"ok  {p.path}  ({p.name}: {len(p.subsystems)} subsystem(s), {len(p.coordinates)} coordinate(s), "
            f"{len(p.variables)} variable(s), {len(p.scenarios)} scenario(s))"
        )
    return 0


def study_command(
    err: Err,
    said: Err,
    console: Any,
    *,
    file: Path,
    vary: list[str],
    samples: int | None,
    method: str | None,
    seed: int | None,
    out: Path,
    jobs: int | None,
    scheduler: str | None,
    scheduler_timeout: float,
    resume: bool,
    time_limit: float | None,
    batch_size: int,
    plot: bool,
    set_: list[str] | None,
    check: str,
) -> int:
    """``counterpoise study`` once its values are parsed and checked: load the file, run the
    study (its progress bar drawn on ``console``, a rich console on stderr), say where it is
    on ``said``; the exit status (2 bad input, 1 the study cannot be written, 130/143
    interrupted by Ctrl-C/SIGTERM with the finished points kept, else 0 whatever the
    points' statuses)."""
    import numpy  # noqa: F401 - both processes need it: imported once, before the fork

    from ..plotter import PlotProcess

    plotter = PlotProcess.fork_if_useful(plot, jobs, scheduler)  # draws the plot; imports matplotlib while this process loads
    from ..errors import ProblemFileError
    from ..studies.command import StudyOptions, run_study_command

    found = None
    try:
        found = _load([file], set_, out, err)
    finally:  # run_study_command ends the helper from here on
        if plotter is not None and found is None:
            plotter.close()
    if found is None:
        return 2
    (problem,), sets = found
    options = StudyOptions(tuple(vary), samples, method, seed, out, jobs, scheduler, scheduler_timeout, resume, time_limit, batch_size, plot,
                           overrides=tuple(sets.items()), check=check)
    try:
        outcome = run_study_command(problem, options, console, plotter)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: workers stopped, finished batches kept
        return _study_interrupted(err, problem, out, exc)
    except ProblemFileError as exc:
        err(str(exc))
        return 2
    except OSError as exc:
        err(f"{problem.path}: cannot write the study to {out}: {exc.strerror or exc}")
        return 1
    counts = ", ".join(f"{n} {s}" for s, n in sorted(outcome.counts.items()))
    skipped = f", {outcome.skipped} already done" if outcome.skipped else ""
    said(f"{problem.name}: {outcome.run} points run ({counts or 'none'}){skipped} in {outcome.wall_time:.1f} s; study in {outcome.folder}/")
    return 0


def _study_interrupted(err: Err, problem: Problem, out: Path, exc: KeyboardInterrupt) -> int:
    from ..studies.command import StudyTerminated
    from ..studies.study import study_folder, study_in_progress

    folder = study_in_progress(problem, out)
    kept = study_folder(problem, out)
    earlier = f" (the earlier study in {kept} is kept until this one completes)" if folder != kept else ""
    what = "terminated" if isinstance(exc, StudyTerminated) else "interrupted"
    err(f"{problem.path}: {what}; the finished points are in {folder / 'study.csv'}{earlier}; run the same command with --resume to continue")
    return EXIT_SIGTERM if isinstance(exc, StudyTerminated) else EXIT_SIGINT


def overrides(items: list[str] | tuple[str, ...] | None) -> dict[str, object]:
    """``--set`` items as the problem loader takes them; :class:`UsageError` (its one line)
    when one is not KEY=VALUE or its value cannot be read."""
    out: dict[str, object] = {}
    for item in items or ():
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UsageError(f"--set {clip(item)}: expected KEY=VALUE")
        try:
            out[key.strip()] = coerce(value.strip())
        except ValueError as exc:
            raise UsageError(f"--set {clip(key.strip())}: {clip(str(exc))}") from None
    return out


def coerce(value: str) -> object:
    """Numbers and booleans on the command line become TOML numbers and booleans; an array
    or inline table (``[0, 0, -1]``, ``{ range = [...] }``) is read as TOML, so an array is
    set whole (``--set 'gravity.direction=[0, 0, -1]'``); :class:`ValueError` when it is
    not valid TOML. One entry of an array is set by its index: ``KEY.0=VALUE``."""
    if value in ("true", "false"):
        return value == "true"
    if value[:1] in ("[", "{"):
        if sys.version_info >= (3, 11):
            import tomllib  # the standard library from Python 3.11
        else:  # pragma: no cover
            import tomli as tomllib
        try:
            return tomllib.loads(f"value = {value}")["value"]
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"cannot read '{value}' as a TOML {'array' if value[0] == '[' else 'inline table'}: {exc}") from None
    for kind in (int, float):
        try:
            return kind(value)
        except ValueError:
            pass
    return value


def _short(exc: BaseException, limit: int = 300) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= limit else text[: limit - 1] + "…"
