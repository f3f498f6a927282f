"""Shared fixtures: paths, hypothesis profiles and a cache of solved problem files."""

from __future__ import annotations

import os
import tempfile
from functools import lru_cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PROBLEMS = ROOT / "problems"

# the console script's cache of loaded problems (counterpoise.io.cache) stays off in the
# processes tests start: each test says whether it wants it (tests/test_fast_paths.py)
os.environ.setdefault("COUNTERPOISE_CACHE", "off")

try:
    from hypothesis import HealthCheck, settings
    from hypothesis.configuration import set_hypothesis_home_dir

    # hypothesis keeps its files (example database, constants cache) outside the repository,
    # one home per pytest-xdist worker (PYTEST_XDIST_WORKER is set before this file is
    # imported), so that parallel workers never write the same files
    set_hypothesis_home_dir(os.path.join(tempfile.gettempdir(), "counterpoise-hypothesis", os.environ.get("PYTEST_XDIST_WORKER", "main")))

    # CI (the CI variable is set) replays the same examples on every run; locally the
    # property tests keep exploring new ones. HYPOTHESIS_PROFILE chooses explicitly.
    settings.register_profile("ci", derandomize=True, database=None, deadline=None, suppress_health_check=[HealthCheck.too_slow])
    settings.register_profile("dev", deadline=None, suppress_health_check=[HealthCheck.too_slow])
    settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci" if os.environ.get("CI") else "dev"))
except ImportError:  # pragma: no cover
    pass


#: under pytest-xdist (``make test`` runs two workers): a folder all workers of this run
#: share, where ``solved`` keeps its results (set by the session fixture below)
_SHARED: "Path | None" = None


@pytest.fixture(scope="session", autouse=True)
def _work_outside_the_repository(tmp_path_factory):
    """Run every test from a scratch folder: nothing (MuJoCo's MUJOCO_LOG.TXT, stray outputs)
    lands in the repository. Tests name their files through ROOT, never relative to the cwd.
    Each pytest-xdist worker has its own base temporary folder (``.../popen-gw0``), so its
    own scratch cwd; their parent, this run's base folder, is shared by the workers."""
    global _SHARED
    here = os.getcwd()
    os.chdir(tmp_path_factory.mktemp("cwd"))
    if os.environ.get("PYTEST_XDIST_WORKER"):
        _SHARED = tmp_path_factory.getbasetemp().parent / "solved"
        _SHARED.mkdir(exist_ok=True)
    yield
    os.chdir(here)
    _SHARED = None


@lru_cache(maxsize=None)
def solved(name: str, overrides: tuple[tuple[str, str], ...] = ()):
    """Design result of problems/<name>.toml (with overrides), solved through the general
    engine once per test run: in this process (the cache), and under pytest-xdist once for
    all workers (:func:`_solved_once`)."""
    from counterpoise.io.loader import load_problem
    from counterpoise.pipeline import design

    def solve():
        return design(load_problem(PROBLEMS / f"{name}.toml", dict(overrides)))

    return solve() if _SHARED is None else _solved_once(_SHARED, (name, overrides), solve)


def _solved_once(folder: Path, key: tuple, solve):
    """The result for ``key`` pickled in ``folder``, shared by the pytest-xdist workers of
    one run: the first worker to ask solves it under an exclusive file lock and writes it,
    a worker asking meanwhile waits for it and reads it (the same object a single process
    would have cached, without solving it twice). A result that cannot be pickled, or a
    platform without ``fcntl``, is solved in each worker, as without xdist."""
    import hashlib
    import pickle

    try:
        import fcntl
    except ImportError:  # pragma: no cover - not on Linux/macOS
        return solve()
    stem = hashlib.sha256(repr(key).encode()).hexdigest()[:24]
    path = folder / f"{stem}.pickle"
    with open(folder / f"{stem}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if path.exists():
            with open(path, "rb") as f:
                return pickle.load(f)
        result = solve()
        try:
            data = pickle.dumps(result, protocol=pickle.HIGHEST_PROTOCOL)
        except (pickle.PicklingError, TypeError, AttributeError, RecursionError):
            return result
        part = path.with_suffix(".part")
        part.write_bytes(data)
        part.replace(path)  # whole or absent: never half a file
        return result


def value(result, name: str, unit: str | None = None) -> float:
    """A variable or report quantity of a result, in its display unit (checked if given)."""
    from counterpoise.report import design_table

    table = design_table(result)
    row = table[table["name"] == name]
    if len(row) != 1:
        raise KeyError(f"{name} not in design table of {result.problem.name}: {list(table['name'])}")
    if unit is not None:
        assert row["unit"].iloc[0] == unit, f"{name} is reported in {row['unit'].iloc[0]}, expected {unit}"
    return float(row["value"].iloc[0])


@pytest.fixture
def approx():
    """pytest.approx with the acceptance tolerance of the seed reproductions (0.1 %)."""
    return lambda expected: pytest.approx(expected, rel=1e-3)


class CliRun:
    """What an in-process CLI call returned: as ``subprocess.CompletedProcess`` has it."""

    def __init__(self, returncode: int, stdout: str, stderr: str) -> None:
        self.returncode, self.stdout, self.stderr = returncode, stdout, stderr


def run_cli(*args: str, cwd: "Path | None" = None) -> CliRun:
    """Run ``counterpoise ARGS`` in this process (its entry point, as the console script
    calls it, without the process start-up: ~2 s a call under load). A test about the
    process itself (exit codes of a real process, signals, start-up) starts a subprocess."""
    import contextlib
    import io

    from counterpoise.cli import main

    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    code = 0
    try:
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                main(list(args))
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        os.chdir(here)
    return CliRun(code, out.getvalue(), err.getvalue())


def fresh_python(code: str, cwd: "Path | None" = None, **env: str) -> str:
    """Run ``code`` in a fresh interpreter with this checkout's ``src`` first on the path, for
    a test about the process itself (what it imports, how it starts); its stdout. ``env``:
    variables added to the environment; ``cwd``: where it runs (default: the test's scratch
    folder, see :func:`_work_outside_the_repository`)."""
    import subprocess
    import sys

    environ = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT / "src"), os.environ.get("PYTHONPATH")])), **env}
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=environ, cwd=cwd)
    assert run.returncode == 0, run.stderr
    return run.stdout


def console_solve_twice(tmp_path: "Path", file: "Path", report: str) -> "list[list[str]]":
    """``counterpoise solve FILE --out tmp_path/<run>`` as the console script runs it (a real
    process: :func:`counterpoise.cli.main` without arguments, the cache in
    ``tmp_path/cache``), twice: a ``first`` and a ``second`` run. ``report``: Python lines
    run as the process ends, with ``status`` (its exit status) and ``sys`` at hand, that
    print what the test reads; the lines each run printed."""
    body = "".join(f"    {line}\n" for line in report.strip().splitlines())
    environ = {"COUNTERPOISE_CACHE": str(tmp_path / "cache")}
    runs = []
    for run in ("first", "second"):
        code = (
            "import os, sys\n"
            f"sys.argv = ['counterpoise', 'solve', {str(file)!r}, '--out', {str(tmp_path / run)!r}]\n"
            "end = os._exit\n"
            "def report(status):\n"
            f"{body}"
            "    sys.stdout.flush()\n"
            "    end(status)\n"
            "os._exit = report\n"
            "from counterpoise.cli import main\n"
            "main()\n"
        )
        runs.append(fresh_python(code, cwd=ROOT, **environ).strip().splitlines())
    return runs


#: the test files that take the most CPU (measured with two pytest-xdist workers,
#: benchmarks/README.md#the-test-suite-on-two-workers), heaviest first. With ``--dist loadfile`` a file runs
#: on one worker, so a heavy file handed out last would keep one worker busy while the other
#: idles; ``make test`` hands these out first (``--no-loadscope-reorder`` keeps this order
#: instead of xdist's own, by number of tests) and the many light files fill in behind them.
#: A file missing here only runs later; the order changes no test's outcome.
HEAVY_FILES = (
    "test_payload.py",
    "test_build_sheet.py",
    "test_methods.py",
    "test_cli_options.py",
    "test_loops_whole.py",
    "test_direct_search.py",
    "test_report_html.py",
    "test_search_screening.py",
    "test_speed.py",
    "test_studies.py",
    "test_synthesis.py",
)


def pytest_collection_modifyitems(session, config, items):
    """The files of :data:`HEAVY_FILES` first, in that order; every other file after them in
    its usual order (the sort is stable: the tests inside a file keep their order)."""
    rank = {name: i for i, name in enumerate(HEAVY_FILES)}
    items.sort(key=lambda item: rank.get(item.path.name, len(HEAVY_FILES)))
