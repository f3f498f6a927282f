"""Command line: ``counterpoise validate FILE...``, ``counterpoise catalogue CSV...``,
``counterpoise solve FILE...``, ``counterpoise schedule FILE --payload MASS``,
``counterpoise study FILE --vary ...`` and ``counterpoise plot FILE|STUDY``.

A thin layer: it parses options, calls the library and prints. Exit status: 0 every
problem solved to a verified optimum; 1 some problem is infeasible or failed (its reports
are still written when there is a design to report); 2 bad input (one line per error,
nothing written); 3 an internal error (one line; ``--debug`` shows the traceback).
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Optional

import typer
from rich.console import Console
from rich.table import Table

from .. import progress
from .light import INTERNAL_ERROR, _short, coerce
from ..errors import CounterpoiseError, ProblemFileError, clip

if TYPE_CHECKING:
    from ..model.problem import Problem

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Design gravity balancers for mechanisms. Add --debug to see the traceback of an internal error.",
)
out_console = Console()
if not out_console.is_terminal:  # logs and CI: wide enough that names are not cut
    out_console = Console(width=160)
err_console = Console(stderr=True, highlight=False, soft_wrap=True)

FilesArg = Annotated[list[Path], typer.Argument(help="Problem files (TOML).", show_default=False)]
SetOpt = Annotated[
    Optional[list[str]],
    typer.Option("--set", help="Override a key before validation, e.g. --set 'parameters.r_a=140 mm' (repeatable)."),
]


def _overrides(items: list[str] | None) -> dict[str, object]:
    out: dict[str, object] = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            err_console.print(f"--set {clip(item)}: expected KEY=VALUE", markup=False)
            raise typer.Exit(2)
        try:
            out[key.strip()] = _coerce(value.strip())
        except ValueError as exc:
            err_console.print(f"--set {clip(key.strip())}: {clip(str(exc))}", markup=False)
            raise typer.Exit(2) from None
    return out


_coerce = coerce  # one reading of --set values for both paths (.light)


def _load_all(files: list[Path], overrides: Mapping[str, object], warnings: dict[str, tuple[str, ...]] | None = None) -> list[Problem]:
    from .run import load_all

    problems = load_all(files, overrides, _err_line, warnings)
    if problems is None:
        raise typer.Exit(2)
    return problems


def _check_out(out: Path) -> None:
    """``--out`` must be usable as a folder (one line and exit 2 before any work, else)."""
    from .run import out_error

    wrong = out_error(out)
    if wrong is not None:
        _err_line(wrong)
        raise typer.Exit(2)


def _err_line(line: str) -> None:
    err_console.print(line, markup=False)


@app.command()
def validate(files: FilesArg, set_: SetOpt = None) -> None:
    """Check problem files without solving them."""
    problems = _load_all(files, _overrides(set_))
    for p in problems:
        n_var = len(p.variables)
        out_console.print(
            f"ok  {p.path}  ({p.name}: {len(p.subsystems)} subsystem(s), {len(p.coordinates)} coordinate(s), "
            f"{n_var} variable(s), {len(p.scenarios)} scenario(s))",
            markup=False,
        )


@app.command()
def catalogue(
    files: Annotated[list[Path], typer.Argument(help="Catalogue files (CSV), or 'shipped'.", show_default=False)],
    columns: Annotated[str, typer.Option("--columns", help="Column preset: counterpoise, vendor or vendor_inch.")] = "counterpoise",
    units: Annotated[Optional[str], typer.Option("--units", help="Unit system: SI, N-mm or inch (default: the preset's).")] = None,
) -> None:
    """Check spring catalogues (every row) and print their ranges (docs/catalogues.md)."""
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


@app.command()
def solve(
    files: FilesArg,
    out: Annotated[Path, typer.Option("--out", help="Folder for the reports (one subfolder per problem).")] = Path("results"),
    set_: SetOpt = None,
    plot: Annotated[bool, typer.Option("--plot", help="Also write energy.png (energies and residual torque) and mechanism.png (the mechanism with its design) next to the reports.")] = False,
    starts: Annotated[int, typer.Option("--starts", help="Seeded multi-start over the free geometry: number of starts.")] = 1,
    report: Annotated[
        str, typer.Option("--report", help="html: also write report.html, one self-contained page of the design (docs/build.md); csv: the CSV files only.")
    ] = "html",
    wide: Annotated[bool, typer.Option("--wide", help="Show every column of the summary (inertia, objective, configurations, solve time).")] = False,
    check: Annotated[
        str,
        typer.Option("--check", help="dense: the dense random check (default); auto: the exact certificate where the residual is a trigonometric polynomial and it proves balance, else dense (docs/studies.md)."),
    ] = "dense",
    jobs: Annotated[int, typer.Option("--jobs", help="Worker processes solving the problems (1 = in this process); one summary, in the files' order.")] = 1,
) -> None:
    """Solve problem files and write their reports."""
    from .light import CHECK_MODES, REPORTS
    from .run import solve_all

    if starts < 1:
        err_console.print(f"--starts: must be at least 1, got {starts}", markup=False)
        raise typer.Exit(2)
    if jobs < 1:
        err_console.print(f"--jobs: must be at least 1, got {jobs}", markup=False)
        raise typer.Exit(2)
    if report not in REPORTS:
        err_console.print(f"--report: expected one of {', '.join(REPORTS)}, got '{report}'", markup=False)
        raise typer.Exit(2)
    if check not in CHECK_MODES:
        err_console.print(f"--check: expected one of {', '.join(CHECK_MODES)}, got '{check}'", markup=False)
        raise typer.Exit(2)
    warnings: dict[str, tuple[str, ...]] = {}  # found at load, written into status.txt as found
    problems = _load_all(files, _overrides(set_), warnings)
    _check_out(out)
    rows, worst = solve_all(problems, out, plot, starts, _err_line, html=report == "html", jobs=jobs, check=check, warnings=warnings)
    _print_summary(rows, wide)
    raise typer.Exit(worst)


#: ``schedule --payload`` beyond this multiple of the declared range's upper end is an
#: input error (a typo such as '1e200 g' kept IPOPT busy for minutes)
PAYLOAD_FACTOR = 100.0


@app.command()
def schedule(
    file: Annotated[Path, typer.Argument(help="Problem file with a payload range.", show_default=False)],
    payload: Annotated[str, typer.Option("--payload", help="Payload mass to print the settings for, e.g. '31 g'.", show_default=False)],
    set_: SetOpt = None,
) -> None:
    """Print the adjustments for one payload: what an operator sets at the table."""
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


@app.command()
def study(
    file: Annotated[Path, typer.Argument(help="Problem file (TOML).", show_default=False)],
    vary: Annotated[list[str], typer.Option("--vary", help="NAME=START:STOP:N (grid) or NAME=START:STOP (with --samples), with units, e.g. 'm_endo=500 g:900 g:41'.")],
    samples: Annotated[Optional[int], typer.Option("--samples", help="Number of Latin-hypercube samples.")] = None,
    method: Annotated[Optional[str], typer.Option("--method", help="grid or lhs (default: lhs with --samples, else grid).")] = None,
    seed: Annotated[Optional[int], typer.Option("--seed", help="Seed of the Latin hypercube (the default is written in study.json).")] = None,
    out: Annotated[Path, typer.Option("--out", help="Folder for <problem>-study/.")] = Path("results"),
    jobs: Annotated[Optional[int], typer.Option("--jobs", help="Worker processes (default: the number of cores; 1 = in this process).")] = None,
    scheduler: Annotated[Optional[str], typer.Option("--scheduler", help="tcp://HOST:PORT of a Dask scheduler, or local for a Dask LocalCluster.")] = None,
    scheduler_timeout: Annotated[float, typer.Option("--scheduler-timeout", help="Seconds to wait for the Dask scheduler.")] = 10.0,
    resume: Annotated[bool, typer.Option("--resume", help="Skip the points already in study.csv.")] = False,
    time_limit: Annotated[Optional[float], typer.Option("--time-limit", help="Seconds per point; a point past it is recorded as timeout.")] = None,
    batch_size: Annotated[int, typer.Option("--batch-size", help="Points per batch (one task of a worker).")] = 16,
    plot: Annotated[bool, typer.Option("--plot/--no-plot", help="Write study.png (and pareto.png when a weight is varied).")] = True,
    set_: SetOpt = None,
    check: Annotated[
        str,
        typer.Option("--check", help="auto: each point by the exact certificate where the residual is a trigonometric polynomial and it proves balance, else the dense check (default); dense: the dense random check always."),
    ] = "auto",
) -> None:
    """Solve a problem over a grid or a Latin hypercube of parameters, bounds or weights."""
    from ..studies.command import StudyOptions, run_study_command
    from .light import CHECK_MODES

    if check not in CHECK_MODES:
        err_console.print(f"--check: expected one of {', '.join(CHECK_MODES)}, got '{check}'", markup=False)
        raise typer.Exit(2)
    overrides = _overrides(set_)
    problem = _load_all([file], overrides)[0]
    _check_out(out)
    options = StudyOptions(tuple(vary), samples, method, seed, out, jobs, scheduler, scheduler_timeout, resume, time_limit, batch_size, plot,
                           overrides=tuple(overrides.items()), check=check)
    try:
        outcome = run_study_command(problem, options, err_console)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: workers stopped, finished batches kept
        _study_interrupted(problem, out, exc)
    except ProblemFileError as exc:
        err_console.print(str(exc), markup=False)
        raise typer.Exit(2) from None
    except OSError as exc:
        err_console.print(f"{problem.path}: cannot write the study to {out}: {exc.strerror or exc}", markup=False)
        raise typer.Exit(1) from None
    counts = ", ".join(f"{n} {s}" for s, n in sorted(outcome.counts.items()))
    skipped = f", {outcome.skipped} already done" if outcome.skipped else ""
    out_console.print(f"{problem.name}: {outcome.run} points run ({counts or 'none'}){skipped} in {outcome.wall_time:.1f} s; study in {outcome.folder}/", markup=False)


#: exit status of an interrupted study: 128 + the signal number, as shells report it
EXIT_SIGINT, EXIT_SIGTERM = 130, 143


def _study_interrupted(problem: Problem, out: Path, exc: KeyboardInterrupt) -> None:
    from ..studies.command import StudyTerminated
    from ..studies.study import study_folder, study_in_progress

    folder = study_in_progress(problem, out)
    kept = study_folder(problem, out)
    earlier = f" (the earlier study in {kept} is kept until this one completes)" if folder != kept else ""
    what = "terminated" if isinstance(exc, StudyTerminated) else "interrupted"
    err_console.print(
        f"{problem.path}: {what}; the finished points are in {folder / 'study.csv'}{earlier}; "
        "run the same command with --resume to continue",
        markup=False,
    )
    raise typer.Exit(EXIT_SIGTERM if isinstance(exc, StudyTerminated) else EXIT_SIGINT)


@app.command()
def plot(
    file: Annotated[Path, typer.Argument(help="A problem file (solve it, plot its energies), or a study folder or its study.csv.", show_default=False)],
    out: Annotated[Path, typer.Option("--out", help="Folder for <problem>/energy.png (problem files).")] = Path("results"),
    set_: SetOpt = None,
) -> None:
    """Write plots: energy.png of a problem's design, or study.png/pareto.png of a study."""
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


AtOpt = Annotated[
    Optional[list[str]],
    typer.Option("--at", help="A coordinate (or design variable) and its value with a unit, e.g. --at 'elbow_joint=30 deg' (repeatable); the others stay at home."),
]


DesignOpt = Annotated[
    Optional[Path],
    typer.Option(
        "--design",
        help="A solved design: the folder solve wrote (results/<problem>). Its variables and chosen parts are shown, "
        "with the parts' spring forces; without it, the file's initial values.",
        show_default=False,
    ),
]


@app.command()
def frames(
    file: Annotated[Path, typer.Argument(help="Problem file (TOML).", show_default=False)],
    at: AtOpt = None,
    csv: Annotated[bool, typer.Option("--csv", help="Print CSV instead of a table.")] = False,
    set_: SetOpt = None,
    design: DesignOpt = None,
) -> None:
    """Print the world position of every frame, centre of mass, counter-mass and spring end."""
    from .mechanism import AtError, frames_table

    problem = _load_all([file], _overrides(set_))[0]
    try:
        frames_table(problem, at, csv, out_console, design, _err_line)
    except AtError as exc:
        err_console.print(f"{file}: {exc}", markup=False)
        raise typer.Exit(2) from None


@app.command()
def draw(
    file: Annotated[Path, typer.Argument(help="Problem file (TOML).", show_default=False)],
    at: AtOpt = None,
    out: Annotated[Path, typer.Option("--out", help="Folder for <problem>/mechanism.png.")] = Path("results"),
    set_: SetOpt = None,
    design: DesignOpt = None,
) -> None:
    """Draw the mechanism (a kinematic sketch) at home and at the corners of its ranges."""
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


def _print_summary(rows: list[dict], wide: bool = False) -> None:
    from .light import rich_summary

    if rows:  # no design, no table (every problem's failure was already said on stderr)
        rich_summary(rows, out_console, wide=wide)  # one table for both paths (see .light)




def main(argv: list[str] | None = None) -> None:
    """Console-script entry point: every failure ends as one line and an exit status."""
    args = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in args
    if debug:
        args.remove("--debug")
    try:
        with warnings.catch_warnings(), progress.sink(lambda line: err_console.print(line, markup=False), timed=progress.wants_timed_notes(sys.stderr)):
            if not debug:  # a library's warning (with its source path) is no message for a user
                warnings.simplefilter("ignore")
            app(args=args, prog_name="counterpoise")  # exits by itself: 0/1/2 as documented, 2 for usage errors
    except KeyboardInterrupt:
        err_console.print("interrupted", markup=False)
        sys.exit(130)
    except Exception as exc:  # noqa: BLE001 - the last line of defence: one line, never a traceback
        if debug:
            raise
        err_console.print(f"internal error: {type(exc).__name__}: {_short(exc)} (run with --debug for the traceback)", markup=False)
        sys.exit(INTERNAL_ERROR)
