"""The top-level help without importing typer: the standard library only.

``tests/test_speed.py`` checks that :data:`COMMANDS` lists exactly the commands of the
typer app (:mod:`.app`), with the same one-line help: a command added there must be added
here too.
"""

from __future__ import annotations

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
