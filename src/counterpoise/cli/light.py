"""The fast path of the command line: ``counterpoise solve``, ``validate`` and ``study``
without typer (and ``solve`` and ``validate`` without rich), and what both paths share
(reading ``--set``, running ``solve``, ``validate`` and ``study``, printing the summary).

- ``counterpoise solve ...`` and ``validate ...`` are parsed here by an :mod:`argparse`
  parser derived from the command's entry in :data:`counterpoise.cli.spec.COMMANDS`
  (:func:`parse`), checked by that table's rules (:func:`counterpoise.cli.spec.invalid`)
  and run by :func:`run_solve` / :func:`run_validate`, the very functions the typer app's
  commands call: importing typer and rich costs ~0.2 s of CPU, a fifth of a whole solve.
  A call the derived parser does not accept (``--help``, an unknown or misspelt option, a
  value of the wrong type, a missing file argument) is handed to the typer app unchanged
  (:func:`run` returns None), which prints its usage message. Loading and solving are
  :mod:`.run`'s.
- The summary table is printed by :func:`plain_table` when rich would print plain text
  (output not a terminal, width 160, nothing rich would re-interpret), else by rich itself
  (:func:`print_summary`; the app always prints it through rich, :func:`rich_summary`).

An option is added in :mod:`.spec` only (and, for ``solve`` and ``validate``, as a keyword
of :func:`run_solve` / :func:`run_validate`): both parsers are derived from it.
"""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..errors import clip
from .spec import BY_NAME, Command, invalid

if TYPE_CHECKING:
    import argparse
    from pathlib import Path

    from ..model.problem import Problem

#: Commands the fast path runs (every other one goes to the typer app).
FAST = ("solve", "validate", "study")

#: exit status of an interrupted study: 128 + the signal number, as shells report it
EXIT_SIGINT, EXIT_SIGTERM = 130, 143

#: Exit status of an internal error, on both paths (:func:`guarded`).
INTERNAL_ERROR = 3

#: Width of the summary when stdout is not a terminal (as the app's console).
PLAIN_WIDTH = 160

#: rich replaces ``:name:`` by an emoji even with markup off; text like this goes to rich.
_EMOJI_LIKE = r":\S*?:"

#: The summary table: header and justification of each column (as the app's). ``--wide``
#: shows them all; by default only those marked True, so the table fits 80 columns.
SUMMARY_TITLE = "counterpoise: designs"
SUMMARY_COLUMNS_ALL: tuple[tuple[str, str, bool], ...] = (
    ("problem", "left", True),
    ("status", "left", True),
    ("added mass (kg)", "right", True),
    ("added inertia (kg m²)", "right", False),
    ("objective", "right", False),
    ("residual ratio", "right", True),
    ("configs", "right", False),
    ("solve (s)", "right", False),  # summary.csv's solve_time_s: time inside the solver calls
    ("total (s)", "right", True),  # design, verification and reports of this problem
    ("parts", "left", True),  # the chosen catalogue parts (empty column left out)
)
SUMMARY_COLUMNS: tuple[tuple[str, str], ...] = tuple((name, how) for name, how, _ in SUMMARY_COLUMNS_ALL)

Err = Callable[[str], None]
Summary = Callable[[list[dict[str, Any]], bool], None]


class UsageError(Exception):
    """A command-line value that is wrong: its one line (the command exits 2, nothing written)."""


def summary_columns(rows: list[dict[str, Any]], wide: bool = False) -> list[int]:
    """Indices of the summary columns to show: all with ``wide``, else the default ones;
    the parts column only when some problem has parts."""
    keep = [j for j, (_, _, default) in enumerate(SUMMARY_COLUMNS_ALL) if wide or default]
    if not any(r.get("parts") for r in rows):
        keep = [j for j in keep if SUMMARY_COLUMNS_ALL[j][0] != "parts"]
    return keep


# -- the parser derived from the table -------------------------------------------------------


def convert(kind: str, value: object) -> object:
    """A default or parsed string as typer hands it to a command (a path as :class:`Path`)."""
    if kind == "path" and isinstance(value, str):
        from pathlib import Path

        return Path(value)
    return value


def parser(command: Command) -> argparse.ArgumentParser:
    """An :mod:`argparse` parser of ``command``'s arguments and options, derived from its
    entry in :data:`~counterpoise.cli.spec.COMMANDS`. It raises :class:`argparse.ArgumentError`
    (or :class:`_Defer`) on anything it does not accept, and prints no help of its own
    (``--help`` is not an option here: such a call goes to the typer app)."""
    import argparse

    class Parser(argparse.ArgumentParser):
        def error(self, message: str) -> Any:  # argparse's errors that ignore exit_on_error
            raise _Defer(message)

    class Formatter(argparse.HelpFormatter):
        """argparse's formatter at a fixed width: it asks :mod:`shutil` for the terminal's
        (importing it, ~4 ms) whenever an argument is added, and nothing this parser
        formats is ever printed (help and usage errors are the typer app's)."""

        def __init__(self, prog: str, indent_increment: int = 2, max_help_position: int = 24, width: int | None = None) -> None:
            super().__init__(prog, indent_increment, max_help_position, PLAIN_WIDTH if width is None else width)

    types: dict[str, Callable[[str], Any]] = {"int": _number(_INT, int), "float": _number(_FLOAT, float)}
    p = Parser(
        prog=f"counterpoise {command.name}",
        description=command.help,
        add_help=False,
        allow_abbrev=False,
        exit_on_error=False,
        formatter_class=Formatter,
    )
    for param in command.params:
        text = param.help.replace("%", "%%")  # argparse formats help with %
        if not param.flags:
            p.add_argument(param.dest, nargs="+" if param.many else None, help=text, metavar=param.metavar)
        elif param.kind == "flag":
            p.add_argument(param.flags[0], dest=param.dest, action="store_const", const=True, default=param.default, help=text)
            for negative in param.flags[1:]:
                p.add_argument(negative, dest=param.dest, action="store_const", const=False, help=text)
        else:
            p.add_argument(
                *param.flags,
                dest=param.dest,
                type=types.get(param.kind, str),
                action="append" if param.many else "store",
                default=None if param.required else param.default,
                required=param.required,
                help=text,
                metavar=param.metavar,
            )
    return p


#: Numbers the fast path reads; anything else (' 3', '3_0', '1e3' for an int, 'inf'...) goes
#: to the typer app, which reads it its own way or says what is wrong. (The patterns of this
#: module are compiled on first use, by ``re``'s cache: a solve without a number reads none.)
_INT = r"[-+]?[0-9]+"
_FLOAT = r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?"


def _number(pattern: str, kind: Callable[[str], object]) -> Callable[[str], object]:
    def read(text: str) -> object:
        if not re.fullmatch(pattern, text):
            raise ValueError(text)  # argparse: an ArgumentError, the call goes to the app
        return kind(text)

    return read


class _Defer(Exception):
    """This call is for the typer app (raised before anything was written)."""


def parse(args: list[str]) -> tuple[Command, dict[str, Any]] | None:
    """``args`` (a command and its arguments, ``--debug`` taken out) parsed as the typer app
    parses them: the command and the values its function receives, keyed by
    :attr:`~counterpoise.cli.spec.Param.dest`; None when the typer app should read them (a
    command not served here, or anything the derived parser does not accept)."""
    if not args or args[0] not in FAST:
        return None
    import argparse

    command = BY_NAME[args[0]]
    rest = args[1:]
    try:
        namespace = parser(command).parse_intermixed_args(rest)
    except (_Defer, argparse.ArgumentError):
        return None
    values: dict[str, Any] = {}
    for param in command.params:
        value = getattr(namespace, param.dest)
        values[param.dest] = [convert(param.kind, v) for v in value] if isinstance(value, list) else convert(param.kind, value)
    # argparse reads '-1' or '-x y' before '--' as an argument; click as an unknown option
    after = len(rest) - rest.index("--") - 1 if "--" in rest else 0
    given = [str(v) for p in command.params if not p.flags for v in (values[p.dest] if p.many else [values[p.dest]])]
    if any(v.startswith("-") and v != "-" for v in given[: len(given) - after]):
        return None
    return command, values


# -- running solve and validate (both paths) ---------------------------------------------------------------


def run(args: list[str], pause_gc: bool = False) -> int | None:
    """Run ``counterpoise ARGS`` here when the fast path serves it (:data:`FAST`): its exit
    status, or None for the typer app.

    ``pause_gc`` (for a process that ends right after, as the console script's does): no
    cyclic garbage collection while the library is imported and the files are loaded,
    then :func:`gc.freeze` on everything allocated so far (modules, classes, the problems:
    nothing of it is garbage) before the design work starts. Imports allocate ~95,000
    tracked objects, which otherwise cost ~140 young and one full collection for nothing.
    """
    if not args or args[0] not in FAST:
        return None
    debug = "--debug" in args
    rest = list(args)
    if debug:
        rest.remove("--debug")  # as the app: the first occurrence, wherever it is
    parsed = parse(rest)
    if parsed is None:
        return None
    command, values = parsed
    wrong = invalid(command, values)
    if wrong is not None:
        _err(wrong)
        return 2
    import gc

    paused = pause_gc and gc.isenabled()
    if paused:
        gc.disable()

    def loaded() -> None:
        if paused:
            gc.freeze()
            gc.enable()

    def body() -> int:
        if command.name == "validate":
            return run_validate(_err, _out, **values)
        if command.name == "study":
            return run_study(_err, _out, loaded=loaded, **values)
        return run_solve(_err, print_summary, loaded=loaded, **values)

    try:
        return guarded(_err, debug, body)
    finally:
        if paused:
            gc.enable()


def guarded(err: Err, debug: bool, body: Callable[[], int | None]) -> int | None:
    """``body()`` as every command runs (the fast path and the typer app): progress lines
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
    files: list[Path],
    set_: list[str] | None,
    out: Path,
    err: Err,
    loaded: Callable[[], None] | None,
    warnings: dict[str, tuple[str, ...]] | None = None,
) -> "tuple[list[Problem], dict[str, object]] | None":
    """What ``solve`` and ``study`` do before their work: read the ``--set`` values, load
    and check every file, check the output folder, then call ``loaded``; the problems and
    the values set, or None after one line on ``err`` per error (the command exits 2)."""
    from .run import load_all, out_error

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
    if loaded is not None:
        loaded()
    return problems, sets


def run_solve(
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
    loaded: Callable[[], None] | None = None,
) -> int:
    """``counterpoise solve`` once its values are parsed and checked (by either path): load
    every file, design, verify and write each, print the summary; the exit status. Every
    message goes through ``err`` (one line each); ``loaded`` is called once every file has
    loaded, before the design work."""
    from .run import solve_all

    if len(files) > 1:
        from ..io.cache import keep_no_built

        keep_no_built()  # built designers and evaluators are kept for a solve of one file only
    warnings: dict[str, tuple[str, ...]] = {}  # found at load, written into status.txt as found
    found = _load(files, set_, out, err, loaded, warnings)
    if found is None:
        return 2
    problems, _ = found
    rows, worst = solve_all(problems, out, plot, starts, err, html=report == "html", jobs=jobs, check=check, warnings=warnings)
    summary(rows, wide)
    return worst


def run_validate(err: Err, out: Err, *, files: list[Path], set_: list[str] | None) -> int:
    """``counterpoise validate`` once its values are parsed (by either path): load and check
    every file, one ``ok`` line each on ``out``; the exit status (2: some file does not load,
    every error said on ``err``)."""
    from .run import load_all

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


def run_study(
    err: Err,
    said: Err,
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
    loaded: Callable[[], None] | None = None,
) -> int:
    """``counterpoise study`` once its values are parsed and checked (by either path): load
    the file, run the study (its progress bar drawn by rich on stderr), say where it is on
    ``said``; the exit status (2 bad input, 1 the study cannot be written, 130/143
    interrupted by Ctrl-C/SIGTERM with the finished points kept, else 0 whatever the
    points' statuses). ``loaded`` is called once the file has loaded."""
    import numpy  # noqa: F401 - both processes need it: imported once, before the fork

    from ..plotter import PlotProcess

    plotter = PlotProcess.fork_if_useful(plot, jobs, scheduler)  # draws the plot; imports matplotlib while this process loads
    from rich.console import Console

    from ..errors import ProblemFileError
    from ..studies.command import StudyOptions, run_study_command
    found = None
    try:
        found = _load([file], set_, out, err, loaded)
    finally:  # run_study_command ends the helper from here on
        if plotter is not None and found is None:
            plotter.close()
    if found is None:
        return 2
    (problem,), sets = found
    options = StudyOptions(tuple(vary), samples, method, seed, out, jobs, scheduler, scheduler_timeout, resume, time_limit, batch_size, plot,
                           overrides=tuple(sets.items()), check=check)
    try:
        outcome = run_study_command(problem, options, Console(stderr=True, highlight=False, soft_wrap=True), plotter)
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


# -- output --------------------------------------------------------------------------------


def rich_is_terminal(stream: Any, environ: Any = os.environ) -> bool:
    """Whether rich would treat ``stream`` as a terminal (its rules, in its order)."""
    tty_compatible = environ.get("TTY_COMPATIBLE", "")
    if tty_compatible in ("0", "1"):
        return tty_compatible == "1"
    force_color = environ.get("FORCE_COLOR")
    if force_color is not None:
        return force_color != ""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


def _plain(text: str, ascii_only: bool) -> bool:
    """Whether rich prints ``text`` unchanged (no control characters, nothing emoji-like;
    ASCII when its width must be known)."""
    return text.isprintable() and not re.search(_EMOJI_LIKE, text) and (text.isascii() or not ascii_only)


def _err(line: str) -> None:
    """One line on stderr, as the app's error console prints it."""
    if _plain(line, ascii_only=False):
        sys.stderr.write(line + "\n")
        sys.stderr.flush()
        return
    from rich.console import Console

    Console(stderr=True, highlight=False, soft_wrap=True).print(line, markup=False)


def _out(line: str) -> None:
    """One line on stdout, as the app's console prints it: plain when rich would print
    exactly that (not a terminal, at most its 160 columns, nothing it re-interprets)."""
    utf = (getattr(sys.stdout, "encoding", None) or "").lower().startswith("utf")
    if utf and not rich_is_terminal(sys.stdout) and len(line) <= PLAIN_WIDTH and _plain(line, ascii_only=True) and "[" not in line:
        sys.stdout.write(line + "\n")
        sys.stdout.flush()
        return
    from rich.console import Console

    console = Console()
    if not console.is_terminal:
        console = Console(width=PLAIN_WIDTH)
    console.print(line, markup=False)


def summary_cells(row: dict[str, Any], columns: list[int] | None = None) -> list[str]:
    """One summary row's cells (of ``columns``, default all), as the app formats them."""
    cells = [
        str(row["problem"]),
        str(row["status"]),
        f"{row['added_mass_kg']:.6g}",
        f"{row['added_inertia_kg_m2']:.6g}",
        f"{row['objective']:.6g}",
        f"{row['residual_ratio']:.2e}",
        str(row["checked_configurations"]),
        f"{row['solve_time_s']:.3f}",
        f"{row['wall_s']:.3f}",
        str(row.get("parts") or ""),
    ]
    return cells if columns is None else [cells[j] for j in columns]


def summary_lines(rows: list[dict[str, Any]]) -> list[str]:
    """The lines printed after the table: the message of each design that is not optimal,
    then where the reports are."""
    lines = [f"{r['problem']}: {r['message']}" for r in rows if r["status"] != "optimal"]
    if rows:
        from pathlib import Path

        lines.append(f"reports in {Path(rows[0]['folder']).parent}/<problem>/")
    return lines


def plain_table(title: str, columns: tuple[tuple[str, str], ...], rows: list[list[str]], width: int) -> str | None:
    """The table as rich draws it (heavy head, one space of padding, title centred) on a
    console ``width`` wide without colour, or None when rich would draw it differently
    (no rows, too wide, or text that rich would re-interpret or measure otherwise)."""
    headers = [name for name, _ in columns]
    cells = [c for row in rows for c in row]
    if not rows or not all(_plain(c, ascii_only=True) and "[" not in c for c in cells):
        return None
    if not all(_plain(h.replace("²", ""), ascii_only=True) for h in [*headers, title]):
        return None
    inner = [max(len(headers[j]), *(len(row[j]) for row in rows)) for j in range(len(columns))]
    total = sum(inner) + 3 * len(inner) + 1
    if total > width or len(title) > total:
        return None

    def line(texts: list[str], edge: str, sep: str) -> str:
        parts = [f" {t.rjust(w) if how == 'right' else t.ljust(w)} " for t, w, (_, how) in zip(texts, inner, columns)]
        return edge + sep.join(parts) + edge

    def rule(left: str, fill: str, sep: str, right: str) -> str:
        return left + sep.join(fill * (w + 2) for w in inner) + right

    pad = total - len(title)
    out = [" " * (pad // 2) + title + " " * (pad - pad // 2), rule("┏", "━", "┳", "┓"), line(headers, "┃", "┃"), rule("┡", "━", "╇", "┩")]
    out += [line(row, "│", "│") for row in rows]
    out.append(rule("└", "─", "┴", "┘"))
    return "\n".join(out) + "\n"


def print_summary(rows: list[dict[str, Any]], wide: bool = False) -> None:
    """The summary table and lines on stdout: plain text when rich would print exactly
    that, else through rich (a terminal: colours and its width). No design, no table (every
    problem's failure was already said on stderr)."""
    if not rows:
        return
    table = None
    lines = summary_lines(rows)
    utf = (getattr(sys.stdout, "encoding", None) or "").lower().startswith("utf")  # else rich draws an ASCII box
    if utf and not rich_is_terminal(sys.stdout) and all(_plain(t, ascii_only=True) and len(t) <= PLAIN_WIDTH for t in lines):
        keep = summary_columns(rows, wide)
        table = plain_table(SUMMARY_TITLE, tuple(SUMMARY_COLUMNS[j] for j in keep), [summary_cells(r, keep) for r in rows], PLAIN_WIDTH)
    if table is not None:
        sys.stdout.write(table + "".join(t + "\n" for t in lines))
        sys.stdout.flush()
        return
    rich_summary(rows, wide=wide)


def rich_summary(rows: list[dict[str, Any]], console: Any = None, wide: bool = False) -> None:
    """The summary through rich, as the app prints it."""
    from rich.console import Console
    from rich.table import Table

    if console is None:
        console = Console()
        if not console.is_terminal:
            console = Console(width=PLAIN_WIDTH)
    table = Table(title=SUMMARY_TITLE, show_lines=False)
    keep = summary_columns(rows, wide)
    for j in keep:
        col, justify = SUMMARY_COLUMNS[j]
        table.add_column(col, justify=justify, overflow="fold")  # type: ignore[arg-type]  # SUMMARY_COLUMNS holds rich's justify names
    for r in rows:
        cells = summary_cells(r, keep)
        style = "green" if r["status"] == "optimal" else "red"
        cells[1] = f"[{style}]{cells[1]}[/{style}]"
        table.add_row(*cells)
    console.print(table)
    for text in summary_lines(rows):
        console.print(text, markup=False)


def _short(exc: BaseException, limit: int = 300) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= limit else text[: limit - 1] + "…"
