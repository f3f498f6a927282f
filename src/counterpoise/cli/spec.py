"""The command line, declared once: every command, argument and option with its type,
default, help and checks (the standard library only).

The typer app (:mod:`.app`) is derived from :data:`COMMANDS`, and nothing about an option
is written anywhere else: each command's typer signature is built from its entry
(:func:`counterpoise.cli.app.command`), typer prints ``--help`` and the usage errors, and
the checks declared here (:func:`invalid`: ``minimum``, ``choices``) run before the
command, so a wrong value gives one line and exit status 2. A command is added as an entry
here and a function of the same name in :mod:`.app`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import NamedTuple

#: The default of an argument or option that must be given.
REQUIRED = ...

#: Value kinds: ``path`` (a :class:`pathlib.Path`), ``str``, ``int``, ``float`` and ``flag``
#: (a boolean option taking no value).
KINDS = ("path", "str", "int", "float", "flag")


class Param(NamedTuple):
    """One argument (no ``flags``) or option of a command."""

    #: the command function's keyword (and the key of the parsed values)
    dest: str
    kind: str
    help: str
    #: ``("--out",)``; a flag pair ``("--plot", "--no-plot")`` sets True/False; () an argument
    flags: tuple[str, ...] = ()
    #: the value when not given (None: no value); :data:`REQUIRED`: must be given
    default: object = None
    #: repeatable option, or an argument taking one value or more (a list)
    many: bool = False
    metavar: str | None = None
    show_default: bool = True
    #: the values allowed (checked by :func:`invalid`)
    choices: tuple[str, ...] = ()
    #: the smallest value allowed (checked by :func:`invalid`)
    minimum: int | None = None

    @property
    def name(self) -> str:
        """How a message names it: its first flag, or its name in capitals (an argument)."""
        return self.flags[0] if self.flags else self.dest.upper()

    @property
    def required(self) -> bool:
        return self.default is REQUIRED


class Command(NamedTuple):
    name: str
    #: one line: the command's help and its line in ``counterpoise --help``
    help: str
    params: tuple[Param, ...]


DESCRIPTION = "Design gravity balancers for mechanisms. Add --debug to see the traceback of an internal error."

#: ``solve --report``: ``html`` (the default) writes report.html beside the CSV files, ``csv`` only those
REPORTS = ("html", "csv")
#: ``solve --check`` / ``study --check``: ``dense`` the dense random check; ``auto`` the exact
#: certificate where the residual is a trigonometric polynomial and it proves balance, else
#: the dense check (as :data:`counterpoise.verify.check.CHECKS`; kept here: no import at start)
CHECK_MODES = ("auto", "dense")

FILES = Param("files", "path", "Problem files (TOML).", many=True, default=REQUIRED, show_default=False)
FILE = Param("file", "path", "Problem file (TOML).", default=REQUIRED, show_default=False)
SET = Param("set_", "str", "Override a key before validation, e.g. --set 'parameters.r_a=140 mm' (repeatable).", ("--set",), many=True)
AT = Param(
    "at",
    "str",
    "A coordinate (or design variable) and its value with a unit, e.g. --at 'elbow_joint=30 deg' (repeatable); the others stay at home.",
    ("--at",),
    many=True,
)
DESIGN = Param(
    "design",
    "path",
    "A solved design: the folder solve wrote (results/<problem>). Its variables and chosen parts are shown, "
    "with the parts' spring forces; without it, the file's initial values.",
    ("--design",),
    show_default=False,
)


def _out(help: str) -> Param:
    return Param("out", "path", help, ("--out",), default="results")


#: Every command, in the order of ``counterpoise --help``.
COMMANDS: tuple[Command, ...] = (
    Command("validate", "Check problem files without solving them.", (FILES, SET)),
    Command(
        "catalogue",
        "Check spring catalogues (every row) and print their ranges (docs/catalogues.md).",
        (
            Param("files", "path", "Catalogue files (CSV), or 'shipped'.", many=True, default=REQUIRED, show_default=False),
            Param("columns", "str", "Column preset: counterpoise, vendor or vendor_inch.", ("--columns",), default="counterpoise"),
            Param("units", "str", "Unit system: SI, N-mm or inch (default: the preset's).", ("--units",)),
        ),
    ),
    Command(
        "solve",
        "Solve problem files and write their reports.",
        (
            FILES,
            _out("Folder for the reports (one subfolder per problem)."),
            SET,
            Param(
                "plot",
                "flag",
                "Also write energy.png (energies and residual torque) and mechanism.png (the mechanism with its design) next to the reports.",
                ("--plot",),
                default=False,
            ),
            Param("starts", "int", "Seeded multi-start over the free geometry: number of starts.", ("--starts",), default=1, minimum=1),
            Param(
                "report",
                "str",
                "html: also write report.html, one self-contained page of the design (docs/build.md); csv: the CSV files only.",
                ("--report",),
                default="html",
                choices=REPORTS,
            ),
            Param("wide", "flag", "Show every column of the summary (inertia, objective, configurations, solve time).", ("--wide",), default=False),
            Param(
                "check",
                "str",
                "dense: the dense random check (default); auto: the exact certificate where the residual is a trigonometric "
                "polynomial and it proves balance, else dense (docs/studies.md).",
                ("--check",),
                default="dense",
                choices=CHECK_MODES,
            ),
            Param(
                "jobs",
                "int",
                "Worker processes solving the problems (1 = in this process); one summary, in the files' order.",
                ("--jobs",),
                default=1,
                minimum=1,
            ),
        ),
    ),
    Command(
        "schedule",
        "Print the adjustments for one payload: what an operator sets at the table.",
        (
            Param("file", "path", "Problem file with a payload range.", default=REQUIRED, show_default=False),
            Param("payload", "str", "Payload mass to print the settings for, e.g. '31 g'.", ("--payload",), default=REQUIRED, show_default=False),
            SET,
        ),
    ),
    Command(
        "study",
        "Solve a problem over a grid or a Latin hypercube of parameters, bounds or weights.",
        (
            FILE,
            Param(
                "vary",
                "str",
                "NAME=START:STOP:N (grid) or NAME=START:STOP (with --samples), with units, e.g. 'm_endo=500 g:900 g:41'.",
                ("--vary",),
                default=REQUIRED,
                many=True,
            ),
            Param("samples", "int", "Number of Latin-hypercube samples.", ("--samples",)),
            Param("method", "str", "grid or lhs (default: lhs with --samples, else grid).", ("--method",)),
            Param("seed", "int", "Seed of the Latin hypercube (the default is written in study.json).", ("--seed",)),
            _out("Folder for <problem>-study/."),
            Param("jobs", "int", "Worker processes (default: the number of cores; 1 = in this process).", ("--jobs",)),
            Param("scheduler", "str", "tcp://HOST:PORT of a Dask scheduler, or local for a Dask LocalCluster.", ("--scheduler",)),
            Param("scheduler_timeout", "float", "Seconds to wait for the Dask scheduler.", ("--scheduler-timeout",), default=10.0),
            Param("resume", "flag", "Skip the points already in study.csv.", ("--resume",), default=False),
            Param("time_limit", "float", "Seconds per point; a point past it is recorded as timeout.", ("--time-limit",)),
            Param("batch_size", "int", "Points per batch (one task of a worker).", ("--batch-size",), default=16),
            Param("plot", "flag", "Write study.png (and pareto.png when a weight is varied).", ("--plot", "--no-plot"), default=True),
            SET,
            Param(
                "check",
                "str",
                "auto: each point by the exact certificate where the residual is a trigonometric polynomial and it proves "
                "balance, else the dense check (default); dense: the dense random check always.",
                ("--check",),
                default="auto",
                choices=CHECK_MODES,
            ),
        ),
    ),
    Command(
        "synthesise",
        "Choose the fewest balancing elements of a [synthesis] superstructure, proven minimal; write every minimal topology (docs/synthesis.md).",
        (
            FILE,
            _out("Folder for <problem>-synthesis/ (synthesis.csv, each topology's problem file and reports)."),
            SET,
            Param(
                "refine",
                "flag",
                "Free each topology's attachment points in their regions and re-solve (the NLP); --no-refine keeps the grid's design.",
                ("--refine", "--no-refine"),
                default=True,
            ),
            Param(
                "report",
                "str",
                "html: each topology's report.html beside its CSV files; csv: the CSV files only.",
                ("--report",),
                default="html",
                choices=REPORTS,
            ),
        ),
    ),
    Command(
        "plot",
        "Write plots: energy.png of a problem's design, or study.png/pareto.png of a study.",
        (
            Param(
                "file",
                "path",
                "A problem file (solve it, plot its energies), or a study folder or its study.csv.",
                default=REQUIRED,
                show_default=False,
            ),
            _out("Folder for <problem>/energy.png (problem files)."),
            SET,
        ),
    ),
    Command(
        "frames",
        "Print the world position of every frame, centre of mass, counter-mass and spring end.",
        (FILE, AT, Param("csv", "flag", "Print CSV instead of a table.", ("--csv",), default=False), SET, DESIGN),
    ),
    Command(
        "draw",
        "Draw the mechanism (a kinematic sketch) at home and at the corners of its ranges.",
        (FILE, AT, _out("Folder for <problem>/mechanism.png."), SET, DESIGN),
    ),
)

BY_NAME: dict[str, Command] = {c.name: c for c in COMMANDS}


def invalid(command: Command, values: Mapping[str, object]) -> str | None:
    """The first value of ``values`` (as typer parsed them) that the table does not allow,
    as one line naming its option; None when all are allowed."""
    for p in command.params:
        value = values.get(p.dest)
        if value is None:
            continue
        if p.minimum is not None and isinstance(value, int) and value < p.minimum:
            return f"{p.name}: must be at least {p.minimum}, got {value}"
        if p.choices and value not in p.choices:
            return f"{p.name}: expected one of {', '.join(p.choices)}, got '{value}'"
    return None
