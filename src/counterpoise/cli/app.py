"""The command line: ``counterpoise validate FILE...``, ``catalogue CSV...``, ``solve FILE...``,
``schedule FILE --payload MASS``, ``synthesise FILE``, ``study FILE --vary ...``, ``plot FILE|STUDY``, ``frames``
and ``draw``: one typer app, its output drawn by rich.

A thin layer: it parses options, calls the library and prints. The commands, their
arguments and options (types, defaults, help, checks) are declared once, in :mod:`.spec`;
:func:`command` gives each function below the typer signature of its entry there, and
runs the table's checks before it. A command is added as an entry in :mod:`.spec` and a
function here; what a long command does once its values are parsed is a plain function of
:mod:`.run` (``solve``, ``validate``, ``study``). The library is imported inside the
command functions, so ``counterpoise --help`` imports typer and rich only.

Exit status: 0 every problem solved to a verified optimum; 1 some problem is infeasible or
failed (its reports are still written when there is a design to report); 2 bad input (one
line per error, nothing written); 3 an internal error (one line; ``--debug`` shows the
traceback).
"""

from __future__ import annotations

import functools
import inspect
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Optional

import typer
from rich.console import Console, JustifyMethod
from rich.table import Table
from rich.text import Text

from . import run
from .run import INTERNAL_ERROR, UsageError  # noqa: F401 - INTERNAL_ERROR: the app's exit status of an internal error
from .spec import BY_NAME, DESCRIPTION, Param, invalid
from ..errors import CounterpoiseError, ProblemFileError, clip

if TYPE_CHECKING:
    from ..model.problem import Problem

#: help pages and usage errors in click's plain format: typer's rich format imports rich's
#: markdown and traceback modules (~0.2 s of CPU for a help page)
app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False, rich_markup_mode=None, help=DESCRIPTION)
#: stdout; wide enough in logs and CI (not a terminal) that names are not cut. No emoji:
#: a name such as ``a:smile:`` is printed as written.
out_console = Console(emoji=False)
if not out_console.is_terminal:
    out_console = Console(width=160, emoji=False)
err_console = Console(stderr=True, highlight=False, soft_wrap=True, emoji=False)

_TYPES: dict[str, type] = {"path": Path, "str": str, "int": int, "float": float, "flag": bool}


def typer_parameter(param: Param) -> inspect.Parameter:
    """``param`` of the table (:mod:`.spec`) as typer reads a command's parameter: its type
    annotated with a :func:`typer.Argument` or :func:`typer.Option`, and its default."""
    kind: Any = _TYPES[param.kind]
    if param.many:
        kind = list[kind]  # a runtime type built from the table
    if param.default is None:
        kind = Optional[kind]
    options: dict[str, Any] = {"help": param.help, "show_default": param.show_default}
    if param.metavar is not None:
        options["metavar"] = param.metavar
    info = typer.Option("/".join(param.flags), **options) if param.flags else typer.Argument(**options)
    default = inspect.Parameter.empty if param.required else default_value(param)
    return inspect.Parameter(param.dest, inspect.Parameter.KEYWORD_ONLY, default=default, annotation=Annotated[kind, info])


def default_value(param: Param) -> object:
    """The value a command function receives when ``param`` is not given (a path as a
    :class:`~pathlib.Path`)."""
    if param.kind == "path" and isinstance(param.default, str):
        return Path(param.default)
    return param.default


def command(body: Callable[..., None]) -> Callable[..., None]:
    """Register ``body`` as the command of its name, with the arguments and options of its
    entry in :data:`counterpoise.cli.spec.COMMANDS` (its parameters must be theirs, in
    order; a function taking ``**values`` gets them all). The table's checks
    (:func:`counterpoise.cli.spec.invalid`) run before ``body``: one line, exit 2."""
    entry = BY_NAME[body.__name__]
    own = [p for p in inspect.signature(body).parameters.values()]
    if [p.kind for p in own] != [inspect.Parameter.VAR_KEYWORD] and [p.name for p in own] != [p.dest for p in entry.params]:
        raise TypeError(f"{body.__name__}: parameters {[p.name for p in own]} are not the table's {[p.dest for p in entry.params]}")

    @functools.wraps(body)
    def checked(**values: Any) -> None:
        wrong = invalid(entry, values)
        if wrong is not None:
            _err_line(wrong)
            raise typer.Exit(2)
        body(**values)

    checked.__signature__ = inspect.Signature([typer_parameter(p) for p in entry.params])  # type: ignore[attr-defined]  # what typer reads
    app.command(entry.name, help=entry.help, short_help=entry.help)(checked)  # short_help: listed whole in --help
    return checked


def _overrides(items: list[str] | None) -> dict[str, object]:
    try:
        return run.overrides(items)
    except UsageError as exc:
        _err_line(str(exc))
        raise typer.Exit(2) from None


def _load_all(files: list[Path], overrides: Mapping[str, object], warnings: dict[str, tuple[str, ...]] | None = None) -> list[Problem]:
    problems = run.load_all(files, overrides, _err_line, warnings)
    if problems is None:
        raise typer.Exit(2)
    return problems


def _check_out(out: Path) -> None:
    """``--out`` must be usable as a folder (one line and exit 2 before any work, else)."""
    wrong = run.out_error(out)
    if wrong is not None:
        _err_line(wrong)
        raise typer.Exit(2)


def _err_line(line: str) -> None:
    err_console.print(line, markup=False)


def _out_line(line: str) -> None:
    out_console.print(line, markup=False)


@command
def validate(**values: Any) -> None:
    raise typer.Exit(run.validate_command(_err_line, _out_line, **values))


@command
def catalogue(files: list[Path], columns: str, units: str | None) -> None:
    from ..catalogue import mapping_from, read_catalogue

    try:
        mapping = mapping_from(columns, units)
    except ValueError as exc:
        err_console.print(f"--columns/--units: {exc}", markup=False)
        raise typer.Exit(2) from None
    errors = 0
    for path in files:
        try:
            cat = read_catalogue(path, mapping)
        except ProblemFileError as exc:
            err_console.print(str(exc), markup=False)
            errors += 1
            continue
        a = cat.arrays
        out_console.print(
            f"ok  {cat.path}  ({len(cat)} parts; rate {a['rate'].min() / 1e3:.4g}-{a['rate'].max() / 1e3:.4g} N/mm, "
            f"free length {a['free_length'].min() * 1e3:.4g}-{a['free_length'].max() * 1e3:.4g} mm, "
            f"max load {a['max_load'].min():.4g}-{a['max_load'].max():.4g} N)",
            markup=False,
        )
    if errors:
        raise typer.Exit(2)


@command
def solve(**values: Any) -> None:
    raise typer.Exit(run.solve_command(_err_line, print_summary, **values))


#: ``schedule --payload`` beyond this multiple of the declared range's upper end is an
#: input error (a typo such as '1e200 g' kept IPOPT busy for minutes)
PAYLOAD_FACTOR = 100.0


@command
def schedule(file: Path, payload: str, set_: list[str] | None) -> None:
    from ..errors import InputError
    from ..model.units import MASS, canonical_dimension, dimension_name, parse_quantity

    problem = _load_all([file], _overrides(set_))[0]
    if not problem.payloads:
        err_console.print(f"{file}: payloads: no payload range declared (add a [payloads.<name>] table)", markup=False)
        raise typer.Exit(2)
    try:
        mass = parse_quantity(payload)
    except InputError as exc:
        err_console.print(f"{file}: --payload: {exc}", markup=False)
        raise typer.Exit(2) from None
    if mass.dimension != canonical_dimension(MASS):
        err_console.print(f"{file}: --payload: expected a mass, got {dimension_name(mass.dimension)} ('{payload}')", markup=False)
        raise typer.Exit(2)
    if mass.si < 0:
        err_console.print(f"{file}: --payload: a payload mass must not be negative ('{payload}')", markup=False)
        raise typer.Exit(2)
    declared = max(problem.payloads, key=lambda p: p.upper)
    if mass.si > PAYLOAD_FACTOR * max(declared.upper, declared.unit.to_si):
        err_console.print(
            f"{file}: --payload: '{clip(payload)}' is more than {PAYLOAD_FACTOR:g} times the upper end of the declared range "
            f"({declared.label(declared.lower)} to {declared.label(declared.upper)})",
            markup=False,
        )
        raise typer.Exit(2)
    from ..pipeline import operator_settings

    result = operator_settings(problem, mass.si)
    spec = result.design.payload
    if result.setting is None:
        out_console.print(f"{problem.name}: the design is {result.design.status.value}: {result.design.message}", markup=False)
        raise typer.Exit(1)
    if result.note:
        out_console.print(f"{problem.name}: {result.note}", markup=False, soft_wrap=True)
    if result.balanceable is not None:
        lo, hi = result.balanceable
        out_console.print(
            f"{problem.name}: payload {spec.label(mass.si)} is outside the balanceable range "
            f"{spec.label(lo)} to {spec.label(hi)} ({result.setting.message})",
            markup=False,
            soft_wrap=True,
        )
        raise typer.Exit(1)
    out_console.print(f"{problem.name}: settings for payload {spec.name} = {spec.label(mass.si)}", markup=False, soft_wrap=True)
    table = Table()
    for col in ("adjustment", "value", "unit"):
        table.add_column(col, justify="right" if col == "value" else "left")
    for v in problem.variables:
        if v.adjustable:
            table.add_row(v.name, f"{v.unit.from_si(result.setting.values[v.name]):.6g}", v.unit.label)
    out_console.print(table)
    out_console.print(f"residual ratio {result.setting.residual_ratio:.2e} (balanced in every working mode)", markup=False)


@command
def study(**values: Any) -> None:
    raise typer.Exit(run.study_command(_err_line, _out_line, err_console, **values))


@command
def synthesise(file: Path, out: Path, set_: list[str] | None, refine: bool, report: str) -> None:
    from .synthesis import run_synthesise

    raise typer.Exit(run_synthesise(file, out, _overrides(set_), refine, report == "html", _err_line, _out_line))


@command
def plot(file: Path, out: Path, set_: list[str] | None) -> None:
    if file.is_dir() or file.suffix == ".csv":
        from ..plots import study_plots

        folder = file if file.is_dir() else file.parent
        if not (folder / "study.json").exists() or not (folder / "study.csv").exists():
            err_console.print(f"{file}: file: not a study (expected study.csv and study.json in {folder})", markup=False)
            raise typer.Exit(2)
        paths = study_plots(folder)
    else:
        from ..pipeline import design
        from ..plots import energy_plot

        problem = _load_all([file], _overrides(set_))[0]
        _check_out(out)
        try:
            paths = energy_plot(design(problem), out / problem.name)
        except (CounterpoiseError, OSError) as exc:
            err_console.print(f"{problem.path}: {exc}", markup=False)
            raise typer.Exit(1) from None
    for path in paths:
        out_console.print(f"wrote {path}", markup=False)


@command
def frames(file: Path, at: list[str] | None, csv: bool, set_: list[str] | None, design: Path | None) -> None:
    from .mechanism import AtError, frames_table

    problem = _load_all([file], _overrides(set_))[0]
    try:
        frames_table(problem, at, csv, out_console, design, _err_line)
    except AtError as exc:
        err_console.print(f"{file}: {exc}", markup=False)
        raise typer.Exit(2) from None


@command
def draw(file: Path, at: list[str] | None, out: Path, set_: list[str] | None, design: Path | None) -> None:
    from .mechanism import AtError, draw_files

    problem = _load_all([file], _overrides(set_))[0]
    _check_out(out)
    try:
        paths = draw_files(problem, at, out, design)
    except AtError as exc:
        err_console.print(f"{file}: {exc}", markup=False)
        raise typer.Exit(2) from None
    except OSError as exc:
        err_console.print(f"{problem.path}: cannot write the drawing to {out}: {exc.strerror or exc}", markup=False)
        raise typer.Exit(1) from None
    for path in paths:
        out_console.print(f"wrote {path}", markup=False)


#: The summary table of ``solve``: header and justification of each column. ``--wide``
#: shows them all; by default only those marked True, so the table fits 80 columns.
SUMMARY_TITLE = "counterpoise: designs"
SUMMARY_COLUMNS: tuple[tuple[str, JustifyMethod, bool], ...] = (
    ("problem", "left", True),
    ("status", "left", True),
    ("added mass (kg)", "right", True),
    ("added inertia (kg m²)", "right", False),
    ("objective", "right", False),
    ("residual ratio", "right", True),
    ("as built", "right", True),  # summary.csv's residual_ratio_as_built: the balancer rebuilt from build.csv with real springs
    ("configs", "right", False),
    ("solve (s)", "right", False),  # summary.csv's solve_time_s: time inside the solver calls
    ("total (s)", "right", False),  # design, verification and reports of this problem
    ("parts", "left", True),  # the chosen catalogue parts (empty column left out)
)


def print_summary(rows: list[dict[str, Any]], wide: bool = False, console: Console | None = None) -> None:
    """The summary table of ``solve`` (one row per design; ``wide``: every column, else the
    default ones, and the parts column only when some problem has parts), then the message
    of each design that is not optimal and where the reports are, on ``console`` (default:
    stdout). No design, no table (every problem's failure was already said on stderr)."""
    if not rows:
        return
    console = out_console if console is None else console
    keep = [j for j, (name, _, default) in enumerate(SUMMARY_COLUMNS) if (wide or default) and (name != "parts" or any(r.get("parts") for r in rows))]
    table = Table(title=SUMMARY_TITLE)
    for j in keep:
        name, justify, _ = SUMMARY_COLUMNS[j]
        table.add_column(name, justify=justify, overflow="fold")
    for r in rows:
        built = r.get("residual_ratio_as_built")
        cells = [
            str(r["problem"]),
            str(r["status"]) + (" (ideal)" if r.get("spring_model") == "ideal" else ""),  # a paper's idealised springs, said so
            f"{r['added_mass_kg']:.6g}",
            f"{r['added_inertia_kg_m2']:.6g}",
            f"{r['objective']:.6g}",
            f"{r['residual_ratio']:.2e}",
            f"{built:.2e}" if isinstance(built, float) and built == built else "",
            str(r["checked_configurations"]),
            f"{r['solve_time_s']:.3f}",
            f"{r['wall_s']:.3f}",
            str(r.get("parts") or ""),
        ]
        shown = [Text(cells[j]) for j in keep]
        shown[1].stylize("green" if r["status"] == "optimal" else "red")
        table.add_row(*shown)
    console.print(table)
    for r in rows:
        if r["status"] != "optimal":
            console.print(f"{r['problem']}: {r['message']}", markup=False, emoji=False)
    console.print(f"reports in {Path(rows[0]['folder']).parent}/<problem>/", markup=False, emoji=False)


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point: every failure ends as one line and an exit status."""
    args = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in args
    if debug:
        args.remove("--debug")
    # the app exits by itself (0/1/2 as documented, 2 for usage errors); a failure is one line
    code = run.guarded(_err_line, debug, lambda: app(args=args, prog_name="counterpoise"))
    if code is not None:
        sys.exit(code)
