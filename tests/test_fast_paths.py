"""What the single-solve and robot-validate speed-ups (issue 19, part 5) must not change.

Speed itself is measured in ``benchmarks/`` (no timed tests). These tests pin that the
faster paths give the same answers: a URDF read without running trimesh's ``__init__``
gives the same model as with the whole package, and trimesh stays whole afterwards.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import PROBLEMS, ROOT, console_solve_twice, fresh_python

URDFS = sorted((PROBLEMS / "robots").glob("*.urdf")) + sorted((ROOT / "tests" / "bad_problems" / "robots").glob("*.urdf"))


_READ_ALL = (
    "from pathlib import Path\n"
    "from counterpoise.errors import InputError\n"
    "from counterpoise.io.robot import read_robot\n"
    "for f in {files!r}:\n"
    "    try:\n"
    "        print(repr(read_robot(Path(f), 'urdf')))\n"
    "    except InputError as exc:\n"
    "        print('error:', exc)\n"
)


def test_urdf_is_read_without_trimesh_and_reads_the_same():
    """Every URDF of the problems and of the bad-problem files (their error messages too)
    reads to the same model whether yourdfpy was imported with trimesh's stand-in or after
    the whole of trimesh; the stand-in imports neither trimesh's ``__init__`` nor scipy nor
    networkx, and ``import trimesh`` afterwards gives the whole package, which yourdfpy
    then uses too."""
    pytest.importorskip("yourdfpy")
    files = [str(f) for f in URDFS]
    assert any("ur5" in f for f in files)
    read = _READ_ALL.format(files=files)
    light = fresh_python(
        "import sys\n" + read + "print('heavy', sorted(m for m in ('trimesh', 'scipy', 'networkx', 'rtree', 'shapely') if m in sys.modules))\n"
        "import trimesh, yourdfpy\n"
        "print('whole', hasattr(trimesh, 'Trimesh') and yourdfpy.urdf.trimesh.Scene is trimesh.Scene and yourdfpy.urdf.tra is trimesh.transformations)\n",
        cwd=ROOT,
    ).splitlines()
    whole = fresh_python("import trimesh\n" + read, cwd=ROOT).splitlines()
    assert light[: len(whole)] == whole
    assert light[len(whole) :] == ["heavy []", "whole True"]


# -- the console script's cache of loaded problems (counterpoise.io.cache) -------------------

RESULTS = ROOT / "results"
#: report files compared with the committed results (summary.csv holds the solve time)
COMPARED = ("design.csv", "status.txt", "springs.csv", "build.csv", "schedule.csv", "tolerance.csv")
#: quick problems of several kinds: springs designed to the rate (LP), counter-masses,
#: a closed four-bar, a payload range with its schedule
SAME_AS_RESULTS = ("yasir2019_hybrid", "yasir2019_counter_mass", "fourbar_counter_mass", "woo2019_springs")


@pytest.fixture
def cache_on(tmp_path, monkeypatch):
    """The cache as the console script has it, in a temporary folder."""
    from counterpoise.io import cache

    folder = tmp_path / "cache"
    monkeypatch.setenv(cache.ENVIRONMENT, str(folder))
    monkeypatch.setattr(cache, "_enabled", True)
    return folder


def _cells(text: str) -> list[list[str]]:
    import csv
    import io

    return list(csv.reader(io.StringIO(text)))


def _same_cell(a: str, b: str) -> bool:
    """Equal text, or numbers within 1e-6 relative (results/ was written on another run,
    perhaps another machine: rounding at 1e-15 of a residual may differ) or both below
    1e-9 in size (a residual of a balanced design: rounding)."""
    if a == b:
        return True
    try:
        x, y = float(a), float(b)
    except ValueError:
        return False
    return abs(x - y) <= 1e-6 * max(abs(x), abs(y)) or max(abs(x), abs(y)) <= 1e-9


def _verdict(status: str) -> list[str]:
    """The status and message lines of a status.txt (its solver iterations, times and small
    residual forces differ between machines and library builds)."""
    return [line for line in status.splitlines() if line.startswith(("status:", "message:"))]


def _same_file(name: str, mine: str, committed: str) -> bool:
    if name == "status.txt":
        return _verdict(mine) == _verdict(committed) != []
    if not name.endswith(".csv"):
        return mine == committed
    a, b = _cells(mine), _cells(committed)
    return len(a) == len(b) and all(len(r) == len(s) and all(_same_cell(x, y) for x, y in zip(r, s)) for r, s in zip(a, b))


@pytest.mark.parametrize("name", SAME_AS_RESULTS)
def test_solve_through_the_cache_writes_the_committed_results(name, tmp_path, cache_on, capsys):
    """``counterpoise solve`` (with the cache, as the console script runs it) writes the
    same report files as the committed ``results/`` (made by ``make demo``), the first time
    (the file loaded, then kept) and the second (the problem unpickled from the cache)."""
    from counterpoise.cli import main

    file = PROBLEMS / f"{name}.toml"
    for run in ("first", "second"):
        with pytest.raises(SystemExit) as stop:
            main(["solve", str(file), "--out", str(tmp_path / run)])
        assert stop.value.code == 0, capsys.readouterr().err
        folder = tmp_path / run / name
        compared = [f for f in COMPARED if (RESULTS / name / f).is_file()]
        assert "design.csv" in compared and "status.txt" in compared
        for f in compared:
            assert _same_file(f, (folder / f).read_text(encoding="utf-8"), (RESULTS / name / f).read_text(encoding="utf-8")), f"{run} run: {name}/{f}"
        assert len(list(cache_on.glob("*.pickle"))) == 1


def test_cache_hit_is_the_same_problem_and_an_edit_misses(tmp_path, cache_on):
    """The second load of a file is its kept copy, equal to a fresh load; changing a byte
    of the file or an override gives another entry; a truncated entry is dropped and the
    file loaded again."""
    from counterpoise.io import cache
    from counterpoise.io.loader import load_problem

    file = tmp_path / "hybrid.toml"
    file.write_text((PROBLEMS / "yasir2019_hybrid.toml").read_text(encoding="utf-8"), encoding="utf-8")
    first = cache.load(file)
    [entry] = cache_on.glob("*.pickle")
    second = cache.load(file)
    assert second is not first and second == first == load_problem(file)
    assert second.path == str(file)
    changed = cache.load(file, {"parameters.m_endo": "700 g"})
    assert changed != first and len(list(cache_on.glob("*.pickle"))) == 2
    file.write_text(file.read_text(encoding="utf-8").replace("name = \"yasir2019_hybrid\"", "name = \"edited\""), encoding="utf-8")
    assert cache.load(file).name == "edited" and len(list(cache_on.glob("*.pickle"))) == 3
    entry.write_bytes(entry.read_bytes()[:50])
    file.write_text((PROBLEMS / "yasir2019_hybrid.toml").read_text(encoding="utf-8"), encoding="utf-8")
    assert cache.load(file) == first


def test_problems_that_read_other_files_are_not_kept(tmp_path, cache_on):
    """A ``[robot]`` model or a catalogue is read again at every load (its file may change
    without the problem file changing): such problems are never kept."""
    from counterpoise.io import cache

    for name in ("ur5_shoulder_elbow", "lamp_catalogue"):
        assert cache._may_keep((PROBLEMS / f"{name}.toml").read_text(encoding="utf-8"), {}) is False
        cache.load(PROBLEMS / f"{name}.toml")
    assert not list(cache_on.glob("*.pickle"))


def test_cache_off_and_in_process_calls_write_nothing(tmp_path, monkeypatch, capsys):
    """``COUNTERPOISE_CACHE=off`` turns it off; without the console script's
    :func:`~counterpoise.io.cache.enable` (an in-process ``main([...])``), nothing is kept."""
    from counterpoise.cli import main
    from counterpoise.io import cache

    folder = tmp_path / "cache"
    monkeypatch.setenv(cache.ENVIRONMENT, str(folder))
    assert cache.folder() is None  # not enabled in this process
    with pytest.raises(SystemExit):
        main(["validate", str(PROBLEMS / "yasir2019_counter_mass.toml")])
    monkeypatch.setattr(cache, "_enabled", True)
    assert cache.folder() == folder
    monkeypatch.setenv(cache.ENVIRONMENT, "off")
    assert cache.folder() is None
    cache.load(PROBLEMS / "yasir2019_counter_mass.toml")
    assert not folder.exists()


def test_console_script_keeps_the_problem_and_then_imports_neither_pint_nor_pydantic(tmp_path):
    """The console script (a real process: :func:`counterpoise.cli.main` without
    arguments) keeps the loaded problem; its next run on the same file unpickles it and
    imports neither pint nor the problem schema (pydantic's models; pydantic itself is
    typer's) nor the loader, and writes the same reports. That run imports neither the
    closed loops' ``mechanics.closure`` (this chain is open) nor the degeneracy checks
    (kept with the problem)."""
    runs = console_solve_twice(tmp_path, PROBLEMS / "yasir2019_counter_mass.toml", """
print(sorted(m for m in ('counterpoise.mechanics.closure', 'counterpoise.formulation.assumptions') if m in sys.modules))
print(status, sorted(m for m in ('pint', 'counterpoise.io.schema', 'counterpoise.io.loader') if m in sys.modules))
""")
    outs = [lines[-1] for lines in runs]
    lines = runs[-1]
    assert outs == ["0 ['counterpoise.io.loader', 'counterpoise.io.schema', 'pint']", "0 []"]
    # nor, on the repeated run, what an open chain read from the cache does without
    assert lines[-2] == "[]"
    assert len(list((tmp_path / "cache").glob("*.pickle"))) == 1
    for f in ("design.csv", "status.txt", "build.csv"):
        assert (tmp_path / "first" / "yasir2019_counter_mass" / f).read_text() == (tmp_path / "second" / "yasir2019_counter_mass" / f).read_text()


def test_cache_keeps_at_most_max_entries_and_drops_stale_temporaries(tmp_path, cache_on, monkeypatch):
    """Writing an entry removes the oldest beyond MAX_ENTRIES (here 2) and temporary files
    of killed writers older than STALE_SECONDS; without a known home folder (and no
    XDG_CACHE_HOME) the cache is off rather than relative to the working folder."""
    from counterpoise.io import cache

    monkeypatch.setattr(cache, "MAX_ENTRIES", 2)
    cache_on.mkdir()
    stale = cache_on / ".abc.tmp"
    stale.write_bytes(b"")
    os.utime(stale, (0, 0))
    for g in (500, 600, 700):
        cache.load(PROBLEMS / "yasir2019_counter_mass.toml", {"parameters.m_c": f"{g} g"})
    assert len(list(cache_on.glob("*.pickle"))) == 2 and not stale.exists()
    monkeypatch.delenv(cache.ENVIRONMENT)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setattr(os.path, "expanduser", lambda path: path)  # as when HOME is unset and no user entry exists
    assert cache.folder() is None
