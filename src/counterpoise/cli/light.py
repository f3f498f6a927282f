"""The command line without typer and rich, for the two things run most: the top-level help
and ``counterpoise solve``. The standard library only at import.

- ``counterpoise`` and ``counterpoise --help`` are printed from :data:`COMMANDS`.
  ``tests/test_speed.py`` checks that :data:`COMMANDS` lists exactly the commands of the
  typer app (:mod:`.app`), with the same one-line help: a command added there must be
  added here too.
- ``counterpoise solve FILE... [--out DIR] [--set KEY=VALUE]... [--plot] [--starts N] [--report html|csv] [--check dense|auto] [--jobs N]``
  is parsed and run here (:func:`solve`), with the same output, messages and exit status
  as the typer app's ``solve``: importing typer and rich costs 0.1–0.15 s, a quarter of
  a whole solve. Anything this path does not fully understand is handed to the typer app
  unchanged (:func:`solve` returns None): another option or a misspelt one, ``--help``,
  a value that would be an error (``--starts 0``, ``--set`` without ``=``). Loading and
  solving are :mod:`.run`'s, shared with the app (a file that does not load: every
  error, one line each, exit 2). The summary
  table is printed by :func:`plain_table` when rich would print plain text (output not a
  terminal, width 160, nothing rich would re-interpret), else by rich itself.
  ``tests/test_speed.py`` runs both paths on the same commands and compares their output.
  **An option added to the app's ``solve`` must be added to :data:`SOLVE_OPTIONS` and to
  :func:`_run` to be served here; until then such a call simply goes to the app.**
"""

from __future__ import annotations

import os
import re
import sys
from typing import Any

#: Command name -> first line of its help, in the order the app registers them.
COMMANDS: dict[str, str] = {
    "validate": "Check problem files without solving them.",
    "catalogue": "Check spring catalogues (every row) and print their ranges (docs/catalogues.md).",
    "solve": "Solve problem files and write their reports.",
    "schedule": "Print the adjustments for one payload: what an operator sets at the table.",
    "study": "Solve a problem over a grid or a Latin hypercube of parameters, bounds or weights.",
    "plot": "Write plots: energy.png of a problem's design, or study.png/pareto.png of a study.",
    "frames": "Print the world position of every frame, centre of mass, counter-mass and spring end.",
    "draw": "Draw the mechanism (a kinematic sketch) at home and at the corners of its ranges.",
}

DESCRIPTION = "Design gravity balancers for mechanisms. Add --debug to see the traceback of an internal error."


def wants_top_level_help(args: list[str]) -> int | None:
    """The exit status when ``args`` ask for the top-level help (0 for ``--help``, 2 for
    no arguments at all, as the typer app does), else None."""
    if not args:
        return 2
    if args == ["--help"]:
        return 0
    return None


def top_level_help() -> str:
    width = max(len(name) for name in COMMANDS)
    lines = [
        "Usage: counterpoise [OPTIONS] COMMAND [ARGS]...",
        "",
        f"  {DESCRIPTION}",
        "",
        "Options:",
        "  --help  Show this message and exit.",
        "",
        "Commands:",
        *(f"  {name.ljust(width)}  {text}" for name, text in COMMANDS.items()),
        "",
        "Run 'counterpoise COMMAND --help' for the options of a command.",
        "",
    ]
    return "\n".join(lines)


# -- solve ---------------------------------------------------------------------------------

#: The app's ``solve`` options served here: name -> whether it takes a value.
SOLVE_OPTIONS: dict[str, bool] = {"--out": True, "--set": True, "--starts": True, "--plot": False, "--report": True, "--wide": False, "--check": True, "--jobs": True}

#: ``solve --report``: ``html`` (the default) writes report.html beside the CSV files, ``csv`` only those
REPORTS = ("html", "csv")
#: ``solve --check`` / ``study --check``: ``dense`` the dense random check; ``auto`` the exact
#: certificate where the residual is a trigonometric polynomial and it proves balance, else
#: the dense check (as :data:`counterpoise.verify.check.CHECKS`; kept here: no import at start)
CHECK_MODES = ("auto", "dense")

#: Exit status of an internal error (as :data:`counterpoise.cli.app.INTERNAL_ERROR`).
INTERNAL_ERROR = 3

#: Width of the summary when stdout is not a terminal (as the app's console).
PLAIN_WIDTH = 160

#: rich replaces ``:name:`` by an emoji even with markup off; text like this goes to rich.
_EMOJI_LIKE = re.compile(r":\S*?:")
_INT = re.compile(r"-?[0-9]+")

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


def summary_columns(rows: list[dict[str, Any]], wide: bool = False) -> list[int]:
    """Indices of the summary columns to show: all with ``wide``, else the default ones;
    the parts column only when some problem has parts."""
    keep = [j for j, (_, _, default) in enumerate(SUMMARY_COLUMNS_ALL) if wide or default]
    if not any(r.get("parts") for r in rows):
        keep = [j for j in keep if SUMMARY_COLUMNS_ALL[j][0] != "parts"]
    return keep


class SolveArgs:
    """The arguments of one ``solve`` call (a plain class: ``dataclasses`` costs ~10 ms
    to import, which ``--help`` would pay)."""

    __slots__ = ("files", "out", "sets", "plot", "starts", "debug", "report", "wide", "check", "jobs")

    def __init__(
        self,
        files: tuple[str, ...],
        out: str = "results",
        sets: tuple[str, ...] = (),
        plot: bool = False,
        starts: int = 1,
        debug: bool = False,
        report: str = "html",
        wide: bool = False,
        check: str = "dense",
        jobs: int = 1,
    ) -> None:
        self.files, self.out, self.sets, self.plot, self.starts, self.debug, self.report, self.wide = files, out, sets, plot, starts, debug, report, wide
        self.check, self.jobs = check, jobs

    def __eq__(self, other: object) -> bool:
        return isinstance(other, SolveArgs) and all(getattr(self, k) == getattr(other, k) for k in self.__slots__)

    def __repr__(self) -> str:
        return "SolveArgs(" + ", ".join(f"{k}={getattr(self, k)!r}" for k in self.__slots__) + ")"


class _Defer(Exception):
    """This call is for the typer app (raised before anything was written)."""


def parse_solve(args: list[str]) -> SolveArgs | None:
    """``solve`` arguments as the app would read them, or None when the app should."""
    if args[:1] != ["solve"]:
        return None
    debug = "--debug" in args
    if args.count("--debug") > 1:
        return None
    rest = list(args[1:])
    if debug:
        rest.remove("--debug")  # as the app: the first occurrence, wherever it is
    files: list[str] = []
    values: dict[str, list[str]] = {name: [] for name, takes in SOLVE_OPTIONS.items() if takes}
    flags: set[str] = set()
    i = 0
    while i < len(rest):
        token = rest[i]
        i += 1
        if token == "--":
            files += rest[i:]
            break
        if token == "-":
            return None
        if not token.startswith("-"):
            files.append(token)
            continue
        name, eq, value = token.partition("=")
        if name not in SOLVE_OPTIONS:
            return None  # --help, an option of the app not served here, a typo
        if not SOLVE_OPTIONS[name]:
            if eq or name in flags:
                return None
            flags.add(name)
            continue
        if not eq:
            if i >= len(rest) or rest[i].startswith("-"):
                return None
            value = rest[i]
            i += 1
        values[name].append(value)
    if not files or any(len(values[name]) > 1 for name in ("--out", "--starts", "--report", "--check", "--jobs")):
        return None
    check = values["--check"][0] if values["--check"] else "dense"
    if check not in CHECK_MODES:
        return None  # the app says what is wrong
    report = values["--report"][0] if values["--report"] else "html"
    if report not in REPORTS:
        return None  # the app says what is wrong
    starts = values["--starts"][0] if values["--starts"] else "1"
    if not _INT.fullmatch(starts) or int(starts) < 1:
        return None
    jobs = values["--jobs"][0] if values["--jobs"] else "1"
    if not _INT.fullmatch(jobs) or int(jobs) < 1:
        return None
    out = values["--out"][0] if values["--out"] else "results"
    if not out:
        return None
    return SolveArgs(tuple(files), out, tuple(values["--set"]), "--plot" in flags, int(starts), debug, report, "--wide" in flags, check, int(jobs))


def solve(args: list[str], pause_gc: bool = False) -> int | None:
    """Run ``counterpoise solve`` here; its exit status, or None for the typer app.

    ``pause_gc`` (for a process that ends right after, as the console script's does): no
    cyclic garbage collection while the library is imported and the files are loaded,
    then :func:`gc.freeze` on everything allocated so far (modules, classes, the problems:
    nothing of it is garbage) before the design work starts. Imports allocate ~95,000
    tracked objects, which otherwise cost ~140 young and one full collection for nothing.
    """
    parsed = parse_solve(args)
    if parsed is None:
        return None
    import gc

    paused = pause_gc and gc.isenabled()
    if paused:
        gc.disable()
    try:
        import warnings

        from .. import progress

        with warnings.catch_warnings(), progress.sink(_err, timed=progress.wants_timed_notes(sys.stderr)):  # as the app: progress lines on stderr,
            if not parsed.debug:  # and no library warning (with its source path) unless --debug
                warnings.simplefilter("ignore")
            return _run(parsed, paused)
    except _Defer:
        return None
    except KeyboardInterrupt:
        _err("interrupted")
        return 130
    except Exception as exc:  # noqa: BLE001 - as the app: one line, never a traceback
        if parsed.debug:
            raise
        _err(f"internal error: {type(exc).__name__}: {_short(exc)} (run with --debug for the traceback)")
        return INTERNAL_ERROR
    finally:
        if paused:
            gc.enable()


def overrides(items: tuple[str, ...]) -> dict[str, object] | None:
    """``--set`` items as the app reads them, or None when one is malformed."""
    out: dict[str, object] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            return None
        try:
            out[key.strip()] = coerce(value.strip())
        except ValueError:
            return None  # the app says what is wrong
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


def _run(a: SolveArgs, paused_gc: bool = False) -> int:
    from pathlib import Path

    from .run import load_all, out_error, solve_all

    sets = overrides(a.sets)
    if sets is None:
        raise _Defer
    warnings: dict[str, tuple[str, ...]] = {}  # found at load, written into status.txt as found
    problems = load_all([Path(f) for f in a.files], sets, _err, warnings)
    if problems is None:
        return 2
    wrong = out_error(Path(a.out))
    if wrong is not None:
        _err(wrong)
        return 2
    if paused_gc:
        import gc

        gc.freeze()
        gc.enable()
    rows, worst = solve_all(problems, Path(a.out), a.plot, a.starts, _err, html=a.report == "html", jobs=a.jobs, check=a.check, warnings=warnings)
    print_summary(rows, a.wide)
    return worst


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
    return text.isprintable() and not _EMOJI_LIKE.search(text) and (text.isascii() or not ascii_only)


def _err(line: str) -> None:
    """One line on stderr, as the app's error console prints it."""
    if _plain(line, ascii_only=False):
        sys.stderr.write(line + "\n")
        sys.stderr.flush()
        return
    from rich.console import Console

    Console(stderr=True, highlight=False, soft_wrap=True).print(line, markup=False)


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
