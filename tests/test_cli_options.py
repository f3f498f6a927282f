"""Every CLI option of ``solve`` and ``schedule`` against one problem of each kind.

Kinds: plain (IPOPT), LP (Clarabel), minimax (a directly attached spring), slots (a
catalogue part), payload (a payload range) and modes (working modes with an adjustment).
Each option either works on each kind or is an input error that names it (exit 2, one
line on stderr, nothing written). In-process (typer's runner) to stay quick.
"""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from typer.testing import CliRunner

from conftest import run_cli
from counterpoise.cli.app import app
from builders import pendulum_toml, slot_pendulum_toml
from test_catalogue import HEADER
from test_direct_springs import ARM
from test_methods import PAYLOAD_PENDULUM, TWO_TOOLS

FAST = "settings.verify_samples=2000"


def _kinds(tmp_path: Path) -> dict[str, Path]:
    (tmp_path / "parts.csv").write_text(HEADER + "\nGOOD,200,0.05,1,50,0.3,0.01,0.001,x\n", encoding="utf-8")
    texts = {
        "plain": pendulum_toml(0.8, 0.3, (0.02, 1.0), 25.0, name="plain"),
        "lp": pendulum_toml(0.8, 0.3, 0.2, 25.0, name="lp"),
        "minimax": ARM.format(spring='stiffness = "k"\nfree_length = "50 mm"\ninitial_tension = "2 N"\nmax_length = "0.6 m"', extra="", stiffness_parameter='k = "200 N/m"'),
        "slots": slot_pendulum_toml("pendulum_catalogue", 2.0 / (9.81 * 0.2)),
        "payload": PAYLOAD_PENDULUM,
        "modes": TWO_TOOLS.replace('m_tool = "5 kg"', 'm_tool = "1.5 kg"'),
    }
    paths = {}
    for kind, text in texts.items():
        paths[kind] = tmp_path / f"{kind}.toml"
        paths[kind].write_text(text, encoding="utf-8")
    return paths


@pytest.fixture(scope="module")
def kinds(tmp_path_factory):
    return _kinds(tmp_path_factory.mktemp("kinds"))


def _invoke(*args: str):
    return CliRunner().invoke(app, list(args))


def _one_line_error(result, fragment: str) -> None:
    assert result.exit_code == 2, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0], result.stderr
    assert "Traceback" not in result.stderr


KINDS = ["plain", "lp", "minimax", "slots", "payload", "modes"]
SOLVERS = {"plain": "ipopt", "lp": "clarabel", "minimax": "ipopt", "slots": "ipopt", "payload": "ipopt", "modes": "ipopt"}


@pytest.mark.parametrize("kind", KINDS)
def test_solve_takes_every_option_on_every_kind(kinds, kind, tmp_path):
    """--out, --set, --plot and --starts together: all act (the reports, energy plots,
    starts n/2, the kind's solver)."""
    out = tmp_path / "out"
    result = _invoke("solve", str(kinds[kind]), "--out", str(out), "--set", FAST, "--plot", "--starts", "2")
    assert result.exit_code == 0, (result.stdout, result.stderr)
    folder = next(out.iterdir())
    assert list(folder.glob("energy*.png"))  # energy-<scenario>.png with several scenarios
    row = next(csv.DictReader((folder / "summary.csv").open(encoding="utf-8")))
    assert row["status"] == "optimal"
    assert row["starts_reaching_best"].endswith("/2"), row
    assert row["solver"] == SOLVERS[kind], row


@pytest.mark.parametrize("kind", KINDS)
def test_solve_option_errors_name_the_option(kinds, kind, tmp_path):
    out = tmp_path / "out"
    _one_line_error(_invoke("solve", str(kinds[kind]), "--out", str(out), "--starts", "0"), "--starts")
    _one_line_error(_invoke("solve", str(kinds[kind]), "--out", str(out), "--set", "no_such_section.x=1"), "no_such_section")
    _one_line_error(_invoke("solve", str(kinds[kind]), "--out", str(out), "--set", "novalue"), "--set")
    assert not out.exists()


@pytest.mark.parametrize("kind", [k for k in KINDS if k != "payload"])
def test_schedule_needs_a_payload_range(kinds, kind):
    _one_line_error(_invoke("schedule", str(kinds[kind]), "--payload", "0.5 kg"), "payloads: no payload range declared")


def test_schedule_options_on_a_payload_range(kinds):
    path = str(kinds["payload"])
    inside = _invoke("schedule", path, "--payload", "0.5 kg", "--set", FAST)
    assert inside.exit_code == 0, (inside.stdout, inside.stderr)
    assert "settings for payload tool = 0.5 kg" in inside.stdout
    # m = 2 kg through --set: M = (2 + 1)·0.3/0.3 = 3 kg, b(0.5 kg) = 2.5·0.3/3 = 0.25 m
    heavier = _invoke("schedule", path, "--payload", "0.5 kg", "--set", "parameters.m=2 kg")
    assert heavier.exit_code == 0, (heavier.stdout, heavier.stderr)
    cells = [[c.strip() for c in line.split("│")[1:-1]] for line in heavier.stdout.splitlines() if "│" in line]
    assert ["b", "0.25", "m"] in cells, heavier.stdout
    outside = _invoke("schedule", path, "--payload", "3 kg")
    assert outside.exit_code == 1 and "outside the balanceable range" in outside.stdout
    assert "lies outside the declared range 0 kg to 1 kg" in outside.stdout
    _one_line_error(_invoke("schedule", path, "--payload", "0.5 m"), "--payload: expected a mass")
    _one_line_error(_invoke("schedule", path, "--payload", "0.5 kg", "--set", "novalue"), "--set")


def _design_files(folder: Path) -> dict[str, str]:
    """Every CSV of a solve's reports but the timings: summary.csv without its time columns."""
    texts = {}
    for path in sorted(folder.rglob("*.csv")):
        rows = list(csv.reader(path.open(encoding="utf-8")))
        if path.name == "summary.csv":
            timed = [j for j, name in enumerate(rows[0]) if name.endswith("_s")]
            rows = [[c for j, c in enumerate(row) if j not in timed] for row in rows]
        texts[str(path.relative_to(folder))] = repr(rows)
    return texts


def test_solve_jobs_gives_the_designs_and_summary_of_one_process(kinds, tmp_path):
    """``solve --jobs 2`` (a process pool; through the entry point and typer's runner): the same report files
    as one process but for the timings, and one summary table with the problems in the
    files' order; a problem that fails keeps its line and exit status."""
    files = [str(kinds[k]) for k in ("payload", "plain", "lp", "modes")]
    serial = run_cli("solve", *files, "--out", str(tmp_path / "serial"), "--set", FAST)
    pooled = run_cli("solve", *files, "--out", str(tmp_path / "pooled"), "--set", FAST, "--jobs", "2")
    assert serial.returncode == pooled.returncode == 0, (serial.stderr, pooled.stderr)
    assert _design_files(tmp_path / "pooled") == _design_files(tmp_path / "serial")
    names = [line.split("│")[1].strip() for line in pooled.stdout.splitlines() if line.startswith("│")]
    assert names == ["pendulum_payload_lever", "plain", "lp", "two_tools"], pooled.stdout
    # typer's runner, and an infeasible problem among them: exit 1, its message after the table
    app = _invoke("solve", files[1], files[2], "--out", str(tmp_path / "app"), "--set", "variables.M.upper=0.01 kg", "--jobs", "2")
    assert app.exit_code == 1, (app.stdout, app.stderr)
    assert "plain: " in app.stdout and "infeasible" in app.stdout, app.stdout


@pytest.mark.parametrize("value", ["0", "-1"])
def test_solve_jobs_must_be_a_positive_count(kinds, tmp_path, value):
    out = tmp_path / "out"
    result = run_cli("solve", str(kinds["plain"]), "--out", str(out), "--jobs", value)
    assert result.returncode == 2 and "--jobs" in result.stderr and len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert not out.exists()
