"""The console script's cache (``counterpoise.io.cache``): what it keeps besides loaded
problems (the load checks' warnings, ``solve``'s built designers), and when it refuses a
folder. A pickle runs code when it is read, so a folder or an entry that another user
could have written is never read. What a kept designer gives must be what a built one
gives, bit for bit (docs/performance.md)."""

from __future__ import annotations

import os
import pickle

import pytest

from conftest import PROBLEMS

#: set when a planted pickle is unpickled (it must never be)
PLANTED: list[str] = []


def _planted() -> None:
    PLANTED.append("unpickled")


class _Plant:
    def __reduce__(self) -> tuple[object, tuple[()]]:
        return (_planted, ())


@pytest.fixture
def cache_on(tmp_path, monkeypatch):
    """The cache as ``counterpoise solve`` has it (problems and built designers), in a
    temporary folder."""
    from counterpoise.io import cache

    folder = tmp_path / "cache"
    monkeypatch.setenv(cache.ENVIRONMENT, str(folder))
    monkeypatch.setattr(cache, "_enabled", True)
    monkeypatch.setattr(cache, "_built", True)
    PLANTED.clear()
    return folder


def _counting_check(calls: list[str], warnings: tuple[str, ...] = ("w",)):
    def check(problem):
        calls.append(problem.name)
        return warnings

    return check


def test_the_load_checks_warnings_are_kept_with_the_problem(tmp_path, cache_on):
    """The second load of a file takes the problem and its check's warnings from the entry
    (the check is not run again); a check that refuses the problem keeps nothing, so its
    error is raised every time."""
    from counterpoise.errors import ProblemFileError
    from counterpoise.io import cache

    file = tmp_path / "hybrid.toml"
    file.write_text((PROBLEMS / "yasir2019_hybrid.toml").read_text(encoding="utf-8"), encoding="utf-8")
    calls: list[str] = []
    check = _counting_check(calls, ("nothing to balance about 'x'",))
    first, found = cache.load_checked(file, {}, check)
    second, again = cache.load_checked(file, {}, check)
    assert calls == ["yasir2019_hybrid"] and found == again == ("nothing to balance about 'x'",)
    assert second == first and second is not first

    def refuse(problem):
        raise ProblemFileError(problem.path, "loops", "does not close")

    other = tmp_path / "other.toml"
    other.write_text(file.read_text(encoding="utf-8").replace('name = "yasir2019_hybrid"', 'name = "other"'), encoding="utf-8")
    for _ in range(2):
        with pytest.raises(ProblemFileError, match="does not close"):
            cache.load_checked(other, {}, refuse)
    assert len(list(cache_on.glob("*.pickle"))) == 1


def test_a_folder_others_may_write_or_that_is_not_ours_is_never_used(tmp_path, cache_on, monkeypatch):
    """An entry planted in a folder that its group or others may write, or that belongs to
    another user, is never unpickled, and nothing is written there; an entry that is
    itself writable by others is not read either."""
    from counterpoise.io import cache

    file = PROBLEMS / "yasir2019_counter_mass.toml"
    checked = cache.check_name(cache._no_check)
    entry = cache_on / f"{cache.key(str(file), file, file.read_bytes(), {}, checked)}.pickle"
    cache_on.mkdir(mode=0o700)
    entry.write_bytes(pickle.dumps(_Plant()))

    os.chmod(cache_on, 0o777)
    assert not cache.private(cache_on)
    assert cache.load(file).name == "yasir2019_counter_mass"
    assert PLANTED == [] and entry.read_bytes() == pickle.dumps(_Plant())  # neither read nor replaced

    os.chmod(cache_on, 0o700)
    real = os.geteuid()
    monkeypatch.setattr(cache.os, "geteuid", lambda: real + 1)  # as if the folder were another user's
    assert not cache.private(cache_on)
    cache.load(file)
    assert PLANTED == [] and entry.read_bytes() == pickle.dumps(_Plant())
    monkeypatch.setattr(cache.os, "geteuid", lambda: real)

    os.chmod(entry, 0o666)  # the folder is ours, the entry others may write: not read, replaced
    cache.load(file)
    assert PLANTED == [] and entry.read_bytes() != pickle.dumps(_Plant())
    entry.write_bytes(pickle.dumps(_Plant()))
    os.chmod(entry, 0o600)
    cache.load(file)  # ours and private: read (this shows what the checks above prevented)
    assert PLANTED == ["unpickled"]  # not a problem: dropped, the file loaded and kept in its place
    assert cache.load(file).name == "yasir2019_counter_mass" and PLANTED == ["unpickled"]


def test_libraries_are_fingerprinted_by_their_installed_version(tmp_path, monkeypatch):
    """An upgrade that leaves a library's ``__init__`` file as it was (same size and
    modification time) still changes the fingerprint: the version of its ``.dist-info``
    folder is part of it (read without importing the library)."""
    from counterpoise.io import cache

    site = tmp_path / "site"
    (site / "fakelib").mkdir(parents=True)
    init = site / "fakelib" / "__init__.py"
    init.write_text("VALUE = 1\n", encoding="utf-8")
    os.utime(init, (1_000_000_000, 1_000_000_000))
    (site / "fakelib-1.0.dist-info").mkdir()
    monkeypatch.syspath_prepend(str(site))
    cache.code_fingerprint.cache_clear()
    before = cache.code_fingerprint(("fakelib",))
    (site / "fakelib-1.0.dist-info").rename(site / "fakelib-1.1.dist-info")
    os.utime(init, (1_000_000_000, 1_000_000_000))
    cache.code_fingerprint.cache_clear()
    assert cache.code_fingerprint(("fakelib",)) != before
    assert cache._dist_versions(str(site)) == {"fakelib": "1.1"}
    cache.code_fingerprint.cache_clear()


def test_built_objects_round_trip_and_a_bad_entry_is_dropped(cache_on):
    """:func:`keep_built` / :func:`fetch_built`: the shared objects are put back in their
    places (not copies); another key misses; a truncated entry is removed; nothing is kept
    when built objects are off (any process but ``counterpoise solve``'s)."""
    from counterpoise.io import cache

    shared = object()
    cache.keep_built("thing", ("a",), {"x": [1.5], "shared": shared}, {"shared": shared})
    back = cache.fetch_built("thing", ("a",), {"shared": shared})
    assert back == {"x": [1.5], "shared": shared} and back["shared"] is shared
    assert cache.fetch_built("thing", ("b",), {"shared": shared}) is None
    [entry] = (cache_on / cache.BUILT).glob("thing.*.pickle")
    entry.write_bytes(entry.read_bytes()[:20])
    assert cache.fetch_built("thing", ("a",), {"shared": shared}) is None and not entry.exists()
    cache.keep_built("thing", ("a",), {"x": [1.5], "shared": shared}, {"shared": shared})
    os.chmod(cache_on, 0o777)  # the cache folder others may write: its built objects are not used
    assert cache.fetch_built("thing", ("a",), {"shared": shared}) is None
    os.chmod(cache_on, 0o700)
    assert cache.fetch_built("thing", ("a",), {"shared": shared}) is not None
    cache._built = False
    cache.keep_built("thing", ("c",), 1, {})
    assert cache.fetch_built("thing", ("c",), {}) is None and len(list((cache_on / cache.BUILT).glob("*.pickle"))) == 1


def test_a_built_entry_gives_back_only_what_its_builder_makes(cache_on, monkeypatch):
    """:func:`built_entry` (the one glue the designer, the dense check and the springs'
    sample use): keyed on the problem's content and the parts; a kept object its builder
    would not make (``valid`` says no) is not handed back; no entry at all when built
    objects are not kept in this process."""
    from builders import pendulum
    from counterpoise.io import cache

    problem = pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build()
    entry = cache.built_entry("thing", problem, "a", shared={"problem": problem})
    assert entry is not None
    entry.keep({"problem": problem, "x": 1.5})

    def is_dict(found: object) -> bool:
        return isinstance(found, dict)

    back = cache.built_entry("thing", problem, "a", shared={"problem": problem}).fetch(is_dict)
    assert back == {"problem": problem, "x": 1.5} and back["problem"] is problem
    assert cache.built_entry("thing", problem, "a", shared={"problem": problem}).fetch(lambda found: isinstance(found, list)) is None
    assert cache.built_entry("thing", problem, "b", shared={"problem": problem}).fetch(is_dict) is None
    other = pendulum(0.9, 0.3, (0.02, 1.0), 25.0).build()  # another content: another key
    assert cache.built_entry("thing", other, "a", shared={"problem": other}).fetch(is_dict) is None
    monkeypatch.setattr(cache, "_built", False)
    assert cache.built_entry("thing", problem, "a") is None


@pytest.mark.parametrize("which", ["lp", "nlp"])
def test_a_kept_designer_is_the_built_one(which, cache_on, monkeypatch):
    """A designer built with the cache on is kept; the next one of the same problem is
    unpickled (nothing is built: the formulation is not constructed) and solves to the same
    design, bit for bit: the LP path (``yasir2019_hybrid``, Clarabel) and the NLP path (a
    pendulum whose counter-mass and lever are both free, IPOPT)."""
    from builders import pendulum
    from counterpoise.designer import designer as module
    from counterpoise.io.loader import load_problem

    problem = load_problem(PROBLEMS / "yasir2019_hybrid.toml") if which == "lp" else pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build()
    built = module.Designer(problem)
    assert len(list((cache_on / "built").glob("designer.*.pickle"))) == 1

    def no_build(*args, **kwargs):
        raise AssertionError("the designer was built again")

    monkeypatch.setattr(module, "Formulation", no_build)
    kept = module.Designer(problem)
    assert kept.problem is problem and kept.formulation.problem is problem
    a, b = built.solve(), kept.solve()
    assert (a.status, a.values, a.objective, a.stats.iterations) == (b.status, b.values, b.objective, b.stats.iterations)
    assert (which == "lp") == (a.stats.solver == "clarabel")


def test_designers_are_not_kept_outside_solve(tmp_path, monkeypatch):
    """Only ``counterpoise solve`` (and ``study``, before its pool forks: the next test)
    keeps designers: with the cache on for problems alone (``validate``, the other
    commands) nothing is written under ``built``."""
    from builders import pendulum
    from counterpoise.designer.designer import Designer
    from counterpoise.io import cache

    monkeypatch.setenv(cache.ENVIRONMENT, str(tmp_path / "cache"))
    monkeypatch.setattr(cache, "_enabled", True)
    monkeypatch.setattr(cache, "_built", False)
    Designer(pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build())
    assert cache.built_folder() is None and not (tmp_path / "cache").exists()
    monkeypatch.setattr(cache, "_built", True)
    monkeypatch.setenv(cache.ENVIRONMENT, "off")  # COUNTERPOISE_CACHE=off: nothing kept by solve either
    Designer(pendulum(0.8, 0.3, (0.02, 1.0), 25.0).build())
    assert cache.built_folder() is None and not (tmp_path / "cache").exists()


def test_the_dense_checks_evaluators_are_kept_after_their_first_check(cache_on, monkeypatch):
    """With ``solve``'s cache on, the dense check keeps its evaluators after their first
    check; a later process (here: the in-process evaluators forgotten, the problem loaded
    again) takes them from the disk (no evaluator is constructed) and gives the same
    verification, every figure equal."""
    from counterpoise import pipeline
    from counterpoise.io.loader import load_problem
    from counterpoise.verify import check, residuals

    file = PROBLEMS / "yasir2019_hybrid.toml"
    first = pipeline.design(load_problem(file))
    # the design's evaluators, and those of its balancer as built (rebuilt from its build sheet)
    assert len(list((cache_on / "built").glob("evaluators.*.pickle"))) == 2
    monkeypatch.setattr(check, "_cache", {})

    def no_build(self, *args, **kwargs):
        raise AssertionError("an evaluator was built again")

    monkeypatch.setattr(residuals.SubsystemResiduals, "__init__", no_build)
    again = pipeline.design(load_problem(file))
    assert again.verification == first.verification and again.solution.values == first.solution.values
    # what the first check found (the refined maxima and where they were) is not kept: a later
    # solve with other designs or options refines from its own samples, as a cold one would
    problem = load_problem(file)
    settings = problem.settings
    entry = check.kept_entry(problem, settings.verify_samples, settings.seed + 1)
    kept = entry.fetch(check._evaluators_of) if entry is not None else None
    assert kept is not None and any(e.box_state for *_, e in kept)  # the box maximum's functions are kept
    assert all("maximisers" not in e.box_state and not e.box_state.get("found") for *_, e in kept)


def test_built_objects_beyond_the_byte_budget_are_removed(cache_on, monkeypatch):
    """Writing a built object removes the least recently used beyond MAX_BUILT_BYTES (the
    one just written stays, whatever its size); one read is used again, so it stays."""
    from counterpoise.io import cache

    monkeypatch.setattr(cache, "MAX_BUILT_BYTES", 2500)
    for name in ("a", "b"):
        cache.keep_built("thing", (name,), b"x" * 1000, {})
    for entry in (cache_on / cache.BUILT).glob("*.pickle"):
        os.utime(entry, (1000, 1000))  # both written long ago...
    assert cache.fetch_built("thing", ("a",), {}) == b"x" * 1000  # ...but "a" is read now
    cache.keep_built("thing", ("c",), b"x" * 1000, {})
    assert cache.fetch_built("thing", ("a",), {}) is not None and cache.fetch_built("thing", ("c",), {}) is not None
    assert cache.fetch_built("thing", ("b",), {}) is None
    cache.keep_built("thing", ("d",), b"x" * 5000, {})
    assert [cache.fetch_built("thing", (n,), {}) is not None for n in "abcd"] == [False, False, False, True]


def test_solve_twice_through_the_kept_designer_and_evaluators_writes_the_same_files(tmp_path, cache_on, capsys, monkeypatch):
    """``counterpoise solve`` as the console script runs it (problems and built objects
    kept): the second run takes the problem, the designer, the evaluators and the designed
    springs' sample from the disk (nothing is built or drawn: that would fail) and writes
    the same report files, byte for byte (the summary and status hold timings)."""
    from counterpoise.cli import main
    from counterpoise.designer import designer
    from counterpoise.mechanics import sampling
    from counterpoise.verify import residuals

    def no_build(*args, **kwargs):
        raise AssertionError("built again")

    file = PROBLEMS / "yasir2019_hybrid.toml"
    for run in ("first", "second"):
        if run == "second":
            monkeypatch.setattr(designer, "Formulation", no_build)
            monkeypatch.setattr(residuals.SubsystemResiduals, "__init__", no_build)
            monkeypatch.setattr(sampling, "configurations", no_build)
        with pytest.raises(SystemExit) as stop:
            main(["solve", str(file), "--out", str(tmp_path / run)])
        assert stop.value.code == 0, capsys.readouterr().err
    # the design's and the as-built balancer's evaluators and samples (realisation/asbuilt.py)
    assert sorted(p.name.split(".")[0] for p in (cache_on / "built").glob("*.pickle")) == ["designer", "evaluators", "evaluators", "workspace", "workspace"]
    for name in ("design.csv", "springs.csv", "build.csv", "verification.csv"):
        first = (tmp_path / "first" / "yasir2019_hybrid" / name).read_bytes()
        assert (tmp_path / "second" / "yasir2019_hybrid" / name).read_bytes() == first, name


def test_a_study_keeps_the_designer_it_builds_before_its_pool_forks(tmp_path, cache_on, capsys, monkeypatch):
    """``counterpoise study --jobs 2`` builds its design method once, before the pool forks
    (the workers inherit it): under the console script that designer is kept, and the
    same study run again takes it from the disk (building would fail) and gives the same
    ``study.csv`` cells. Nothing is kept after the fork: the designer is the only entry,
    and the process keeps no more built objects once the points start."""
    import csv

    from counterpoise.cli import main
    from counterpoise.designer import designer
    from counterpoise.io import cache

    def no_build(*args, **kwargs):
        raise AssertionError("built again")

    file = PROBLEMS / "yasir2019_hybrid.toml"
    found = []
    for run in ("first", "second"):
        monkeypatch.setattr(cache, "_built", True)  # as the console script enables it
        if run == "second":
            monkeypatch.setattr(designer, "Formulation", no_build)
        with pytest.raises(SystemExit) as stop:
            main(["study", str(file), "--vary", "m_endo=400g:1000g:4", "--jobs", "2", "--no-plot", "--out", str(tmp_path / run)])
        assert stop.value.code == 0, capsys.readouterr().err
        assert cache._built is False
        with (tmp_path / run / "yasir2019_hybrid-study" / "study.csv").open(newline="") as handle:
            found.append([{k: v for k, v in row.items() if k != "solve_time_s"} for row in csv.DictReader(handle)])
    assert [p.name.split(".")[0] for p in (cache_on / "built").glob("*.pickle")] == ["designer"]
    assert found[0] == found[1] and len(found[0]) == 4


def test_a_solve_of_several_files_keeps_no_built_objects(tmp_path, cache_on, capsys):
    """``counterpoise solve A B`` (a batch such as ``make demo``) keeps the loaded problems but
    no designers or evaluators: those are for the repeated solve of one file."""
    from counterpoise.cli import main

    files = [str(PROBLEMS / "fourbar_springs.toml"), str(PROBLEMS / "yasir2019_counter_mass.toml")]
    with pytest.raises(SystemExit) as stop:
        main(["solve", *files, "--out", str(tmp_path / "out")])
    assert stop.value.code == 0, capsys.readouterr().err
    assert not list((cache_on / "built").glob("*.pickle"))
    assert list(cache_on.rglob("*.pickle")), "the loaded problems are kept"


def test_folders_the_cache_creates_are_private_whatever_the_umask(tmp_path, monkeypatch):
    """The first entry written may be a built one (its problem was not kept: a robot model),
    two folders below a cache folder that does not exist yet: each folder made is 0700, so
    the cache is used afterwards (with a umask of 002 ``mkdir(parents=True)`` gives the
    parents 0775, which :func:`private` refuses for good)."""
    import os
    import stat

    from counterpoise.io import cache

    folder = tmp_path / "made" / "cache"
    monkeypatch.setenv(cache.ENVIRONMENT, str(folder))
    monkeypatch.setattr(cache, "_enabled", True)
    monkeypatch.setattr(cache, "_built", True)
    old = os.umask(0o002)
    try:
        cache.keep_built("test", ("a",), {"x": 1}, {})
    finally:
        os.umask(old)
    for made in (tmp_path / "made", folder, cache.built_folder()):
        assert made is not None and stat.S_IMODE(made.stat().st_mode) == 0o700, made
    assert cache.fetch_built("test", ("a",), {}) == {"x": 1}
