"""The suite's own set-up for two pytest-xdist workers (docs/development.md#running-the-tests)."""

from __future__ import annotations

import threading

import conftest
from conftest import ROOT, _solved_once


def test_make_test_runs_two_workers_a_file_each_heaviest_first():
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    recipe = makefile.split("\ntest:", 1)[1].split("\n\n", 1)[0]
    line = next(x for x in recipe.splitlines() if "-m pytest" in x)
    assert "-n 2" in line and "--dist loadfile" in line and "--no-loadscope-reorder" in line
    # the workers and the processes tests start keep the .pyc they compile (docs/development.md)
    assert line.lstrip().startswith("PYTHONDONTWRITEBYTECODE= ")


def test_the_heavy_files_exist_and_are_named_once():
    """A renamed file would silently drop out of the order that balances the workers."""
    assert len(set(conftest.HEAVY_FILES)) == len(conftest.HEAVY_FILES)
    for name in conftest.HEAVY_FILES:
        assert (ROOT / "tests" / name).is_file(), name


def test_a_shared_result_is_solved_once_and_read_by_the_others(tmp_path):
    calls = []

    def solve():
        calls.append(1)
        return {"ratio": 1e-12, "values": (1.0, 2.0)}

    first = _solved_once(tmp_path, ("pendulum", ()), solve)
    second = _solved_once(tmp_path, ("pendulum", ()), solve)
    assert len(calls) == 1 and second == first and second is not first  # the second read from the file
    other = _solved_once(tmp_path, ("pendulum", (("m", "2 kg"),)), solve)  # other overrides: another result
    assert len(calls) == 2 and other == first


def test_workers_asking_at_once_wait_for_the_one_solving(tmp_path, monkeypatch):
    """Two threads stand for two workers: the lock (flock on separate open files, as two
    processes hold it) lets one solve while the other waits, then reads its result. The
    second asks for the lock while the first holds it inside its solve (the solve waits
    for ``release``), so it must wait, and it has read nothing before the solve ends."""
    import fcntl

    started, asked, release = threading.Event(), threading.Event(), threading.Event()
    calls: list[int] = []
    results: list[object] = []
    real_flock = fcntl.flock

    def slow():
        calls.append(1)
        started.set()
        release.wait(10)
        return [1, 2, 3]

    def worker():
        results.append(_solved_once(tmp_path, ("slow", ()), slow))

    threads = [threading.Thread(target=worker) for _ in range(2)]

    def flock(fd, operation):
        if threading.current_thread() is threads[1]:
            asked.set()  # the second worker asks while the first holds the lock
        return real_flock(fd, operation)

    monkeypatch.setattr(fcntl, "flock", flock)
    threads[0].start()
    assert started.wait(10)
    threads[1].start()
    assert asked.wait(10)
    assert results == [] and len(calls) == 1  # the second waits: nothing read, nothing solved again
    release.set()
    for t in threads:
        t.join(10)
    assert len(calls) == 1 and results == [[1, 2, 3], [1, 2, 3]]


def test_a_result_that_cannot_be_pickled_is_returned_and_not_shared(tmp_path):
    calls = []

    def solve():
        calls.append(1)
        return lambda: None  # a local function cannot be pickled

    assert callable(_solved_once(tmp_path, ("local", ()), solve))
    assert callable(_solved_once(tmp_path, ("local", ()), solve))
    assert len(calls) == 2 and not list(tmp_path.glob("*.pickle"))
