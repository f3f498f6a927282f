"""The command line is declared once (``cli/spec.py``) and both parsers are derived from it:
the typer app (``cli/app.py``) and the fast path's argparse parser (``cli/light.py``),
which runs ``solve`` without importing typer and rich. These tests check the derivation
(every option of the table is in both parsers, with the same help and default), that both
parsers read the same command line to the same values, that the table's checks give the
same one line on either path, and what the fast path prints (the same as rich would).
"""

from __future__ import annotations

import inspect
import re

import pytest

from conftest import PROBLEMS, run_cli
from counterpoise.cli import app as cli_app
from counterpoise.cli import light, spec
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
                want = light.convert(mine.kind, mine.default)
                assert theirs.default == want or (theirs.default in ((), None) and want is None), (command.name, mine.dest)


def test_the_fast_parser_has_the_tables_options_help_and_defaults():
    """The argparse parser of every command (the fast path serves ``solve``; the others are
    derived the same way) holds each argument and option with the table's help."""
    for command in COMMANDS:
        actions = [a for a in light.parser(command)._actions]
        for p in command.params:
            mine = [a for a in actions if a.dest == p.dest]
            assert mine, (command.name, p.dest)
            assert sorted(f for a in mine for f in a.option_strings) == sorted(p.flags)
            assert all(a.help.replace("%%", "%") == p.help for a in mine)
            assert mine[0].required == p.required
            assert mine[0].default == (None if p.required or not p.flags else p.default)


def test_every_commands_help_lists_every_option_of_the_table(monkeypatch, capsys):
    """``counterpoise COMMAND --help`` (typer) names every option and shows its help."""
    monkeypatch.setenv("COLUMNS", "400")
    monkeypatch.setenv("TERMINAL_WIDTH", "400")
    for command in COMMANDS:
        with pytest.raises(SystemExit) as exit_:
            cli_app.main([command.name, "--help"])
        assert exit_.value.code == 0
        text = " ".join(re.sub(r"[│╭╮╰╯─]", " ", capsys.readouterr().out).split())
        for p in command.params:
            assert all(f in text for f in p.flags), (command.name, p.flags)
            assert " ".join(p.help.split()) in text, (command.name, p.dest)


def test_the_check_modes_are_the_verifiers():
    """``--check`` is declared without importing the verifier; its choices are its modes."""
    from counterpoise.verify.check import CHECKS

    assert spec.CHECK_MODES == CHECKS


def test_top_level_help_lists_every_command():
    text = spec.top_level_help()
    assert all(f"  {c.name}" in text and c.help in text for c in COMMANDS)
    assert spec.DESCRIPTION in text


def test_a_command_function_must_take_the_tables_parameters():
    def solve(files, out):  # noqa: ANN001 - not the table's parameters
        pass

    with pytest.raises(TypeError, match="not the table's"):
        cli_app.command(solve)


@pytest.mark.parametrize("name, function", [("solve", light.run_solve), ("validate", light.run_validate), ("study", light.run_study)])
def test_the_shared_function_takes_every_option_of_its_command(name, function):
    """The fast path and the app call the same function with the parsed values."""
    assert name in light.FAST
    keywords = [k for k, p in inspect.signature(function).parameters.items() if p.kind is p.KEYWORD_ONLY]
    assert keywords[: len(spec.BY_NAME[name].params)] == [p.dest for p in spec.BY_NAME[name].params]


# -- both parsers read the same values ---------------------------------------------------------


@pytest.fixture
def recorded(monkeypatch):
    """``run_solve`` and ``run_validate`` replaced by a recorder (exit 0): what each path
    hands them."""
    calls: list[dict] = []

    def record(err, printer, /, loaded=None, **values):
        calls.append(values)
        return 0

    monkeypatch.setattr(light, "run_solve", record)
    monkeypatch.setattr(light, "run_validate", record)
    monkeypatch.setattr(light, "run_study", record)
    return calls


SAME = [
    ["solve", "a.toml"],
    ["solve", "a.toml", "--set=x=1", "--debug", "--out=o", "--set", "y=2 mm", "b.toml", "--plot", "--starts", "3", "--", "--c.toml"],
    ["solve", "a.toml", "--jobs=2", "--wide", "--report", "csv", "--check", "auto"],
    ["solve", "a.toml", "--out", "x", "--out", "y"],  # the last one, as click
    ["solve", "a.toml", "--starts", "+3", "--plot", "--plot"],
    ["solve", "a.toml", "--out", "-1"],
    ["solve", "a.toml", "--out="],
    ["solve", "-"],
    ["solve", "a.toml", "--", "--", "-x"],
    ["solve", "--set", "a=[1, 2]", "a.toml", "--set=b={ c = 1 }"],
    ["validate", "a.toml", "b.toml", "--set", "x=1"],
    ["validate", "--debug", "a.toml"],
    ["study", "a.toml", "--vary", "m=1 g:2 g:3"],
    ["study", "a.toml", "--vary=m=1 g:2 g", "--vary", "r=1 mm:2 mm", "--samples", "5", "--method", "lhs", "--seed", "7", "--jobs", "2",
     "--out", "o", "--resume", "--time-limit", "1.5", "--batch-size", "4", "--no-plot", "--set", "x=1", "--check", "dense"],
    ["study", "a.toml", "--vary", "m=1 g:2 g:3", "--scheduler", "local", "--scheduler-timeout", "2.5", "--plot"],
]


@pytest.mark.parametrize("argv", SAME, ids=range(len(SAME)))
def test_the_fast_path_and_the_app_read_the_same_values(recorded, argv):
    from counterpoise.cli import main

    assert light.parse([a for a in argv if a != "--debug"]) is not None  # served by the fast path
    for entry in (main, cli_app.main):
        with pytest.raises(SystemExit) as exit_:
            entry(list(argv))
        assert exit_.value.code == 0
    fast, app = recorded
    assert fast == app
    assert sorted(fast) == sorted(p.dest for p in spec.BY_NAME[argv[0]].params)


@pytest.mark.parametrize(
    "argv",
    [
        ["solve"],  # no file: the app's usage error
        ["solve", "a.toml", "--help"],
        ["solve", "a.toml", "--starts", "two"],
        ["solve", "a.toml", "--starts", " 3"],  # numbers the app reads its own way
        ["solve", "a.toml", "--jobs", "3_0"],
        ["solve", "a.toml", "--out"],
        ["solve", "a.toml", "--out", "--plot"],
        ["solve", "a.toml", "--plot=yes"],
        ["solve", "a.toml", "--no-such-option"],
        ["solve", "a.toml", "--ou", "x"],  # no abbreviations
        ["solve", "a.toml", "-1"],  # an unknown option to click, a file to argparse
        ["solve", "a.toml", "--x y"],
        ["solve", "a.toml", "--debug"],  # --debug is taken out before parsing
        ["validate", "a.toml", "--plot"],
        ["study", "a.toml", "--samples", "two", "--vary", "m=1 g:2 g"],
        ["study", "a.toml", "--vary"],
        ["schedule", "a.toml", "--payload", "1 kg"],  # not served here
    ],
)
def test_the_fast_path_hands_unusual_calls_to_the_app(argv):
    assert light.parse(argv) is None


def test_a_second_debug_goes_to_the_app(recorded):
    assert light.run(["solve", "a.toml", "--debug", "--debug"]) is None
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
def test_a_wrong_value_is_one_line_exit_2_nothing_written_on_either_path(tmp_path, capsys, option, line):
    problem = str(PROBLEMS / "yasir2019_counter_mass.toml")
    fast = run_cli("solve", problem, "--out", str(tmp_path / "out"), *option)
    with pytest.raises(SystemExit) as exit_:
        cli_app.main(["solve", problem, "--out", str(tmp_path / "out"), *option])
    app_err = capsys.readouterr().err
    assert fast.returncode == exit_.value.code == 2
    assert fast.stderr == app_err and fast.stderr.startswith(line) and fast.stderr.count("\n") == 1, fast.stderr
    assert not (tmp_path / "out").exists()


def test_a_study_check_is_checked_by_the_table(tmp_path):
    out = tmp_path / "out"
    run = run_cli("study", str(PROBLEMS / "yasir2019_hybrid.toml"), "--vary", "m_endo=500 g:900 g:2", "--check", "x", "--out", str(out))
    assert run.returncode == 2 and run.stderr == "--check: expected one of auto, dense, got 'x'\n"
    assert not out.exists()


# -- what the fast path prints -----------------------------------------------------------------


def _rows():
    base = {"added_inertia_kg_m2": 0.0665714, "objective": 5.753, "residual_ratio": 1.23e-15, "checked_configurations": 30024, "solve_time_s": 0.0123}
    return [
        {**base, "problem": "yasir2019_hybrid", "status": "optimal", "added_mass_kg": 5.753, "wall_s": 0.151, "folder": "out/yasir2019_hybrid", "message": "ok"},
        {**base, "problem": "p", "status": "infeasible", "added_mass_kg": -123456789.0, "wall_s": 1234.5, "folder": "out/p", "message": "balance cannot be met: M at its upper bound"},
    ]


@pytest.mark.parametrize("which", [slice(0, 1), slice(0, 2), slice(1, 2)])
def test_plain_summary_is_what_the_app_prints(which, monkeypatch, capsys):
    """The plain-text table is byte for byte the app's rich table on a 160-column console
    that is not a terminal (including a cell wider than its right-justified header)."""
    import io

    from rich.console import Console

    rows = _rows()[which]
    buffer = io.StringIO()
    monkeypatch.setattr(cli_app, "out_console", Console(file=buffer, width=light.PLAIN_WIDTH))
    cli_app._print_summary(rows)
    monkeypatch.setattr(light, "rich_is_terminal", lambda stream, environ=None: False)
    light.print_summary(rows)
    assert light.plain_table(light.SUMMARY_TITLE, light.SUMMARY_COLUMNS, [light.summary_cells(r) for r in rows], light.PLAIN_WIDTH) is not None
    assert capsys.readouterr().out == buffer.getvalue()


def test_plain_summary_defers_to_rich_when_rich_would_differ():
    cells = [light.summary_cells(r) for r in _rows()]
    table = lambda rows, width=light.PLAIN_WIDTH: light.plain_table(light.SUMMARY_TITLE, light.SUMMARY_COLUMNS, rows, width)  # noqa: E731
    assert table(cells) is not None
    assert table(cells, width=100) is None  # rich would shrink and wrap columns
    assert table([]) is None
    assert table([["[bold]x", *cells[0][1:]]]) is None  # markup
    assert table([["a:smile:", *cells[0][1:]]]) is None  # emoji code
    assert table([["é", *cells[0][1:]]]) is None  # width not known here
    assert light.rich_is_terminal(_stream(False), {"FORCE_COLOR": "1"})
    assert not light.rich_is_terminal(_stream(True), {"TTY_COMPATIBLE": "0"})
    assert light.rich_is_terminal(_stream(True), {}) and not light.rich_is_terminal(_stream(False), {})


def _stream(tty: bool):
    class Stream:
        def isatty(self) -> bool:
            return tty

    return Stream()


def _untimed(text: str) -> str:
    """The summary with its total (s) column masked (in a UTF-8 or an ASCII box)."""
    return re.sub(r"(?<=[│|]) +\d+\.\d{3} (?=[│|])", " T ", text)


def _both_paths(tmp_path, capsys, *args: str, command: str = "solve"):
    """The same ``solve`` (or ``command``) call through the fast path and through the typer app, in this
    process: (exit status, stdout with the times masked, stderr, output folder) of each."""
    from counterpoise.cli import main

    runs = []
    for name, entry in (("fast", main), ("app", cli_app.main)):
        out = tmp_path / name
        with pytest.raises(SystemExit) as exit_:
            entry([command, *args, "--out", str(out)] if command == "solve" else [command, *args])
        captured = capsys.readouterr()
        text = captured.out.replace(str(out), "OUT")
        text = _untimed(text)
        runs.append((exit_.value.code, text, captured.err.replace(str(out), "OUT"), out))
    return runs


@pytest.mark.parametrize(
    "args",
    [
        (str(PROBLEMS / "yasir2019_hybrid.toml"), str(PROBLEMS / "yasir2019_counter_mass.toml")),
        (str(PROBLEMS / "yasir2019_counter_mass.toml"), "--set", "variables.M_c.upper=100 g"),  # infeasible: exit 1, message
        (str(PROBLEMS / "yasir2019_counter_mass.toml"), str(PROBLEMS / "no_such_file.toml")),  # load error: one line, exit 2
    ],
)
def test_the_fast_path_prints_and_writes_what_the_app_does(tmp_path, capsys, args):
    (code_a, out_a, err_a, dir_a), (code_b, out_b, err_b, dir_b) = _both_paths(tmp_path, capsys, *args)
    assert (code_a, out_a, err_a) == (code_b, out_b, err_b)
    files_a = sorted(p.relative_to(dir_a) for p in dir_a.rglob("*.csv")) if dir_a.exists() else []
    files_b = sorted(p.relative_to(dir_b) for p in dir_b.rglob("*.csv")) if dir_b.exists() else []
    assert files_a == files_b
    for rel in files_a:
        if rel.name != "summary.csv":  # solve_time_s differs
            assert (dir_a / rel).read_text() == (dir_b / rel).read_text(), rel


@pytest.mark.parametrize(
    "args",
    [
        (str(PROBLEMS / "yasir2019_hybrid.toml"), str(PROBLEMS / "yasir2019_counter_mass.toml")),
        (str(PROBLEMS / "yasir2019_counter_mass.toml"), str(PROBLEMS / "no_such_file.toml"), "--set", "x=1"),
        (str(PROBLEMS / "yasir2019_counter_mass.toml"), "--set", "novalue"),
    ],
)
def test_validate_prints_what_the_app_prints(tmp_path, capsys, args):
    (code_a, out_a, err_a, _), (code_b, out_b, err_b, _) = _both_paths(tmp_path, capsys, *args, command="validate")
    assert (code_a, out_a, err_a) == (code_b, out_b, err_b)
    assert code_a == 0 or (code_a == 2 and out_a == "" and "Traceback" not in err_a), err_a  # one line per error


def test_a_long_or_unusual_line_is_printed_by_rich(monkeypatch, capsys):
    """Plain only what rich would print unchanged; a line wider than the console, or with
    text rich measures otherwise, goes to rich (which folds it as the app does)."""
    monkeypatch.setattr(light, "rich_is_terminal", lambda stream, environ=None: False)
    for line in ("ok  " + "x" * 200, "ok  é", "ok  plain"):
        light._out(line)
        mine = capsys.readouterr().out
        cli_app._out_line(line)
        assert mine == capsys.readouterr().out


def test_the_fast_summary_without_utf8_stdout_is_richs(tmp_path, capsys, monkeypatch):
    """A stdout that is not UTF-8: the fast path leaves the summary to rich, so both paths
    print the same (rich draws an ASCII box)."""
    import io
    import sys

    ends = []
    for name in ("fast", "app"):
        stream = io.TextIOWrapper(io.BytesIO(), encoding="ascii")
        monkeypatch.setattr(sys, "stdout", stream)
        from counterpoise.cli import main

        entry = main if name == "fast" else cli_app.main
        with pytest.raises(SystemExit) as exit_:
            entry(["solve", str(PROBLEMS / "yasir2019_counter_mass.toml"), "--out", str(tmp_path / name)])
        stream.flush()
        text = stream.buffer.getvalue().decode("ascii").replace(str(tmp_path / name), "OUT")
        ends.append((exit_.value.code, _untimed(text), capsys.readouterr().err))
    assert ends[0] == ends[1]
    assert "+----" in ends[0][1]  # rich's ASCII box
