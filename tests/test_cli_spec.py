"""The command line is declared once (``cli/spec.py``) and the typer app (``cli/app.py``) is
derived from it. These tests check the derivation (every option of the table is a click
parameter of its command, with the same help and default, and in ``--help``), the values
a command line gives the command functions (``cli/run.py``), the table's checks (one line,
exit status 2, nothing written), the usage errors typer prints, and the summary table.
"""

from __future__ import annotations

import inspect
from pathlib import Path

import pytest

from conftest import PROBLEMS, run_cli
from counterpoise.cli import app as cli_app
from counterpoise.cli import run, spec
from counterpoise.cli.spec import COMMANDS

GROUP = None


def click_group():
    """The click group typer builds from the app (once)."""
    global GROUP
    if GROUP is None:
        import typer

        GROUP = typer.main.get_command(cli_app.app)
    return GROUP


# -- the derivation ----------------------------------------------------------------------------


def test_the_table_is_well_formed():
    assert len({c.name for c in COMMANDS}) == len(COMMANDS)
    for command in COMMANDS:
        dests = [p.dest for p in command.params]
        assert len(set(dests)) == len(dests), command.name
        flags = [f for p in command.params for f in p.flags]
        assert len(set(flags)) == len(flags) and "--help" not in flags and "--debug" not in flags, command.name
        for p in command.params:
            assert p.kind in spec.KINDS and p.help and p.help[-1] in ".)", (command.name, p.dest)
            assert all(f.startswith("--") for f in p.flags)
            assert p.kind == "flag" or len(p.flags) <= 1  # a pair of flags sets a boolean
            assert not p.choices or p.default in p.choices or p.default is None


def test_the_typer_app_has_the_tables_commands_options_help_and_defaults():
    """Every command of the table is registered, in order, with its one-line help; each of
    its arguments and options is a click parameter with the table's flags, help, default,
    required and repeatable: typer's ``--help`` and parsing come from the table."""
    group = click_group()
    assert list(group.commands) == [c.name for c in COMMANDS]
    assert cli_app.app.info.help == spec.DESCRIPTION
    for command in COMMANDS:
        click_command = group.commands[command.name]
        assert click_command.help == command.help
        params = [p for p in click_command.params if p.name != "help"]
        assert [p.name for p in params] == [p.dest for p in command.params], command.name
        for mine, theirs in zip(command.params, params):
            assert tuple(theirs.opts + theirs.secondary_opts) == (mine.flags or (mine.dest,)), (command.name, mine.dest)
            assert getattr(theirs, "help", mine.help) == mine.help
            assert theirs.required == mine.required
            assert theirs.multiple if mine.flags and mine.many else True
            if not mine.required:
                want = cli_app.default_value(mine)
                assert theirs.default == want or (theirs.default in ((), None) and want is None), (command.name, mine.dest)


def _help_text(capsys, argv: list[str], code: int = 0) -> str:
    """What ``counterpoise ARGV`` prints (a help page: on stdout with status 0, on stderr as
    a usage error), its wrapping undone."""
    with pytest.raises(SystemExit) as exit_:
        cli_app.main(argv)
    assert exit_.value.code == code
    printed = capsys.readouterr()
    return " ".join((printed.out if code == 0 else printed.err).split())


def test_every_commands_help_lists_every_option_of_the_table(monkeypatch, capsys):
    """``counterpoise COMMAND --help`` names every option and shows its help and default."""
    monkeypatch.setenv("COLUMNS", "400")
    monkeypatch.setenv("TERMINAL_WIDTH", "400")
    for command in COMMANDS:
        text = _help_text(capsys, [command.name, "--help"])
        assert " ".join(command.help.split()) in text
        for p in command.params:
            assert all(f in text for f in p.flags), (command.name, p.flags)
            assert " ".join(p.help.split()) in text, (command.name, p.dest)
            if p.show_default and not p.required and p.default not in (None, False, True):
                assert f"[default: {p.default}]" in text, (command.name, p.dest)


def test_top_level_help_lists_every_command(monkeypatch, capsys):
    """``counterpoise --help`` (status 0, on stdout) and ``counterpoise`` alone (status 2, on
    stderr, as a usage error) print the description and every command with its whole
    one-line help."""
    monkeypatch.setenv("COLUMNS", "400")
    monkeypatch.setenv("TERMINAL_WIDTH", "400")
    for argv, code in (["--help"], 0), ([], 2):
        text = _help_text(capsys, argv, code)
        assert spec.DESCRIPTION in text and "Usage: counterpoise" in text
        packed = "".join(text.split())  # click wraps at 80 columns, at a space or after a hyphen
        assert all(c.name + "".join(c.help.split()) in packed for c in COMMANDS), text


def test_the_check_modes_are_the_verifiers():
    """``--check`` is declared without importing the verifier; its choices are its modes."""
    from counterpoise.verify.check import CHECKS

    assert spec.CHECK_MODES == CHECKS


def test_a_command_function_must_take_the_tables_parameters():
    def solve(files, out):  # noqa: ANN001 - not the table's parameters
        pass

    with pytest.raises(TypeError, match="not the table's"):
        cli_app.command(solve)


@pytest.mark.parametrize("name, function", [("solve", run.solve_command), ("validate", run.validate_command), ("study", run.study_command)])
def test_the_run_function_takes_every_option_of_its_command(name, function):
    """The app's command hands its parsed values to the plain function of ``cli/run.py``."""
    keywords = [k for k, p in inspect.signature(function).parameters.items() if p.kind is p.KEYWORD_ONLY]
    assert keywords == [p.dest for p in spec.BY_NAME[name].params]


# -- what a command line gives the command -----------------------------------------------------


@pytest.fixture
def recorded(monkeypatch):
    """``solve_command``, ``validate_command`` and ``study_command`` replaced by a recorder (exit 0):
    the values the app hands them."""
    calls: list[dict] = []

    def record(*_, **values):
        calls.append(values)
        return 0

    for name in ("solve_command", "validate_command", "study_command"):
        monkeypatch.setattr(run, name, record)
    return calls


def _defaults(command: str) -> dict[str, object]:
    return {p.dest: cli_app.default_value(p) for p in spec.BY_NAME[command].params if not p.required}


READ = [
    (["solve", "a.toml"], {"files": [Path("a.toml")]}),
    (
        ["solve", "a.toml", "--set=x=1", "--debug", "--out=o", "--set", "y=2 mm", "b.toml", "--plot", "--starts", "3", "--", "--c.toml"],
        {"files": [Path("a.toml"), Path("b.toml"), Path("--c.toml")], "set_": ["x=1", "y=2 mm"], "out": Path("o"), "plot": True, "starts": 3},
    ),
    (["solve", "a.toml", "--jobs=2", "--wide", "--report", "csv", "--check", "auto"], {"files": [Path("a.toml")], "jobs": 2, "wide": True, "report": "csv", "check": "auto"}),
    (["solve", "a.toml", "--out", "x", "--out", "y", "--check", "auto", "--check=dense"], {"files": [Path("a.toml")], "out": Path("y")}),  # the last one
    (["solve", "-"], {"files": [Path("-")]}),
    (["solve", "--set", "a=[1, 2]", "a.toml", "--set=b={ c = 1 }"], {"files": [Path("a.toml")], "set_": ["a=[1, 2]", "b={ c = 1 }"]}),
    (["validate", "a.toml", "b.toml", "--set", "x=1"], {"files": [Path("a.toml"), Path("b.toml")], "set_": ["x=1"]}),
    (["validate", "--debug", "a.toml"], {"files": [Path("a.toml")]}),
    (["study", "a.toml", "--vary", "m=1 g:2 g:3"], {"file": Path("a.toml"), "vary": ["m=1 g:2 g:3"]}),
    (
        ["study", "a.toml", "--vary=m=1 g:2 g", "--vary", "r=1 mm:2 mm", "--samples", "5", "--method", "lhs", "--seed", "7", "--jobs", "2",
         "--out", "o", "--resume", "--time-limit", "1.5", "--batch-size", "4", "--no-plot", "--set", "x=1", "--check", "dense",
         "--scheduler", "local", "--scheduler-timeout", "2.5"],
        {"file": Path("a.toml"), "vary": ["m=1 g:2 g", "r=1 mm:2 mm"], "samples": 5, "method": "lhs", "seed": 7, "jobs": 2, "out": Path("o"),
         "resume": True, "time_limit": 1.5, "batch_size": 4, "plot": False, "set_": ["x=1"], "check": "dense", "scheduler": "local",
         "scheduler_timeout": 2.5},
    ),
]


@pytest.mark.parametrize("argv, given", READ, ids=range(len(READ)))
def test_the_command_gets_the_given_values_and_the_tables_defaults(recorded, argv, given):
    """Through the console script's entry point: every option not given has the table's
    default (a path as a Path), every one given its value (a repeated option: all its
    values; a single one given twice: the last)."""
    from counterpoise.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(list(argv))
    assert exit_.value.code == 0
    assert recorded == [{**_defaults(argv[0]), **given}]


@pytest.mark.parametrize(
    "argv",
    [
        ["solve"],  # no file
        ["solve", "a.toml", "--starts", "two"],
        ["solve", "a.toml", "--out"],
        ["solve", "a.toml", "--plot=yes"],
        ["solve", "a.toml", "--no-such-option"],
        ["solve", "a.toml", "--ou", "x"],  # no abbreviations
        ["solve", "a.toml", "-1"],
        ["solve", "a.toml", "--debug", "--debug"],  # the first --debug is the entry point's, not the second
        ["validate", "a.toml", "--plot"],
        ["study", "a.toml", "--samples", "two", "--vary", "m=1 g:2 g"],
        ["study", "a.toml", "--vary"],
        ["nosuchcommand"],
    ],
)
def test_a_call_typer_does_not_accept_is_a_usage_error(recorded, capsys, argv):
    """Exit status 2, typer's usage error on stderr (no traceback), nothing run."""
    from counterpoise.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(list(argv))
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "Error" in err and "Traceback" not in err, err
    assert recorded == []


@pytest.mark.parametrize(
    "option, line",
    [
        (["--starts", "0"], "--starts: must be at least 1, got 0"),
        (["--jobs", "-1"], "--jobs: must be at least 1, got -1"),
        (["--report", "pdf"], "--report: expected one of html, csv, got 'pdf'"),
        (["--check", "exactly"], "--check: expected one of auto, dense, got 'exactly'"),
        (["--set", "novalue"], "--set novalue: expected KEY=VALUE"),
        (["--set", "a=[1"], "--set a: cannot read '[1' as a TOML array: "),
    ],
)
def test_a_wrong_value_is_one_line_exit_2_nothing_written(tmp_path, option, line):
    problem = str(PROBLEMS / "yasir2019_counter_mass.toml")
    done = run_cli("solve", problem, "--out", str(tmp_path / "out"), *option)
    assert done.returncode == 2
    assert done.stderr.startswith(line) and done.stderr.count("\n") == 1, done.stderr
    assert done.stdout == "" and not (tmp_path / "out").exists()


def test_a_study_check_is_checked_by_the_table(tmp_path):
    out = tmp_path / "out"
    done = run_cli("study", str(PROBLEMS / "yasir2019_hybrid.toml"), "--vary", "m_endo=500 g:900 g:2", "--check", "x", "--out", str(out))
    assert done.returncode == 2 and done.stderr == "--check: expected one of auto, dense, got 'x'\n"
    assert not out.exists()


def test_validate_says_ok_per_file_or_one_line_per_error():
    good = str(PROBLEMS / "yasir2019_counter_mass.toml")
    done = run_cli("validate", good, str(PROBLEMS / "yasir2019_hybrid.toml"))
    assert done.returncode == 0 and [line.split()[:2] for line in done.stdout.splitlines()] == [["ok", good], ["ok", str(PROBLEMS / "yasir2019_hybrid.toml")]]
    done = run_cli("validate", good, str(PROBLEMS / "no_such_file.toml"))
    assert done.returncode == 2 and done.stdout == "" and done.stderr.count("\n") == 1 and "no_such_file.toml" in done.stderr
    assert "Traceback" not in done.stderr


# -- the summary table -------------------------------------------------------------------------


def _row(**changed):
    row = {
        "problem": "yasir2019_hybrid", "status": "optimal", "added_mass_kg": 5.753, "added_inertia_kg_m2": 0.0665714, "objective": 5.753,
        "residual_ratio": 1.23e-15, "checked_configurations": 30024, "solve_time_s": 0.0123, "wall_s": 0.151, "folder": "out/yasir2019_hybrid",
        "message": "ok",
    }
    return {**row, **changed}


def _printed(rows, wide=False, width=160) -> str:
    import io

    from rich.console import Console

    buffer = io.StringIO()
    cli_app.print_summary(rows, wide, Console(file=buffer, width=width))
    return buffer.getvalue()


def test_the_summary_lists_each_design_then_what_is_wrong_and_where_the_reports_are():
    text = _printed([_row(), _row(problem="p", status="infeasible", message="balance cannot be met: M at its upper bound", folder="out/p")])
    lines = text.splitlines()
    assert lines[0].strip() == cli_app.SUMMARY_TITLE
    body = [line for line in lines if line.startswith("│")]
    assert [line.split("│")[1].strip() for line in body] == ["yasir2019_hybrid", "p"]
    assert lines[-2:] == ["p: balance cannot be met: M at its upper bound", "reports in out/<problem>/"]
    assert _printed([]) == ""  # no design, no table


def test_the_summary_prints_part_names_and_messages_as_written():
    """A part's name comes from a catalogue (any text) and a message may quote input: rich
    reads neither as markup nor as an emoji code. (Before, a part ``EXT[red]1:cat:`` was
    printed as ``EXT1🐱``: the cells were markup strings and the consoles replaced emoji
    codes, messages included.)"""
    parts = "spring_a: EXT[red]1:cat:"
    text = _printed([_row(parts=parts), _row(problem="q", status="infeasible", message="x:cat: [bold]y", folder="out/q")], width=200)
    assert parts in text and "q: x:cat: [bold]y" in text
