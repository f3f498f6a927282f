"""Dataclass methods compiled once per user (``counterpoise.io.compiled``, docs/performance.md):
the classes made through kept codes are the classes :mod:`dataclasses` makes, the codes are
read back instead of compiled, and a file that is not the user's private one, or that
cannot be read, is never used."""

from __future__ import annotations

import dataclasses
import os
import sys
import types

import pytest

from conftest import PROBLEMS, ROOT, console_solve_twice, fresh_python

#: a module of frozen and plain dataclasses, with postponed annotations (the generated
#: methods must not inherit that flag: their annotations are the objects, as without the cache)
SOURCE = '''
from __future__ import annotations
from dataclasses import dataclass, field

@dataclass(frozen=True)
class Point:
    x: float
    y: float = 0.0
    tags: tuple[str, ...] = ()

@dataclass
class Box:
    corner: Point
    names: list[str] = field(default_factory=list)
'''


def _module(name: str) -> types.ModuleType:
    module = types.ModuleType(name)
    sys.modules[name] = module
    try:
        exec(compile(SOURCE, f"<{name}>", "exec", dont_inherit=True), module.__dict__)
    finally:
        del sys.modules[name]
    return module


def _behaviour(module: types.ModuleType) -> list[object]:
    point, box = module.Point(1.0, tags=("a",)), module.Box(module.Point(2.0))
    with pytest.raises(dataclasses.FrozenInstanceError):
        point.x = 3.0  # type: ignore[misc]
    box.names.append("n")
    codes = [module.Point.__init__.__code__, module.Box.__init__.__code__, module.Point.__setattr__.__code__]
    return [
        repr(point),
        repr(box),
        point == module.Point(1.0, 0.0, ("a",)),
        hash(point) == hash(module.Point(1.0, 0.0, ("a",))),
        module.Box.__hash__,
        module.Point.__init__.__annotations__,
        [(c.co_code, c.co_consts, c.co_names, c.co_varnames, c.co_filename, c.co_flags) for c in codes],
    ]


@pytest.fixture
def compiled(tmp_path):
    from counterpoise.io import compiled

    folder = tmp_path / "cache"
    compiled.install(folder)
    yield compiled, folder
    compiled.uninstall()


def test_kept_codes_make_the_same_classes_and_are_not_compiled_again(compiled):
    """A first process compiles the methods and saves them (one file for the package,
    another Python's file of it removed); a second reads them back and compiles nothing; both make the classes plain
    :mod:`dataclasses` makes (same code, annotations as objects: no ``__future__`` flag
    inherited)."""
    module, folder = compiled
    module.uninstall()
    plain = _behaviour(_module("cp_kept"))
    module.install(folder)
    first = _behaviour(_module("cp_kept"))
    # frozen Point: __init__, __repr__, __eq__, __setattr__, __delattr__, __hash__ (6);
    # Box: __init__, __repr__, __eq__ (3; eq without frozen sets __hash__ to None, no code)
    assert module.compiles == 9
    stale = folder / "dataclass-code.cpython-000-0-O0.cp_kept.marshal"  # another Python's file
    folder.mkdir(mode=0o700, exist_ok=True)
    stale.write_bytes(b"")
    os.chmod(stale, 0o600)
    module.save()
    (entry,) = folder.glob("dataclass-code.*.cp_kept.marshal")  # the other Python's is removed
    assert entry != stale and entry.stat().st_mode & 0o077 == 0
    module.uninstall()
    module.install(folder)
    second = _behaviour(_module("cp_kept"))
    assert module.compiles == 0
    assert first == second == plain


def test_a_file_others_may_write_or_that_cannot_be_read_is_not_used(compiled):
    """A kept file that its group or others may write is never read (its codes are
    compiled again, the file left alone); a file that cannot be read is removed."""
    module, folder = compiled
    _module("cp_kept")
    module.save()
    (entry,) = folder.glob("dataclass-code.*.cp_kept.marshal")
    module.uninstall()
    os.chmod(entry, 0o666)
    module.install(folder)
    _module("cp_kept")
    assert module.compiles == 9 and entry.exists()
    module.uninstall()
    os.chmod(entry, 0o600)
    entry.write_bytes(b"not marshal")
    module.install(folder)
    _module("cp_kept")
    assert module.compiles == 9 and not entry.exists()


def test_a_folder_others_may_write_is_not_used(tmp_path):
    """In a cache folder others may write, nothing is installed: dataclasses compile as usual."""
    from counterpoise.io import compiled

    folder = tmp_path / "cache"
    folder.mkdir()
    os.chmod(folder, 0o777)
    compiled.install(folder)
    try:
        assert getattr(dataclasses, "exec", None) is None
    finally:
        compiled.uninstall()


def test_console_script_compiles_no_dataclass_method_on_its_second_run(tmp_path):
    """The console script (a real process) installs the kept codes: its first run compiles
    every dataclass method it creates and keeps them, its second compiles none, and both
    write the same reports; in-process calls do not install it."""
    runs = console_solve_twice(tmp_path, PROBLEMS / "yasir2019_counter_mass.toml", """
import dataclasses
from counterpoise.io import compiled
print(status, compiled.compiles > 0, getattr(dataclasses, 'exec', None) is compiled._exec)
""")
    outs = [lines[-1] for lines in runs]
    assert outs == ["0 True True", "0 False True"]
    assert list((tmp_path / "cache").glob("dataclass-code.*.counterpoise.marshal"))
    for f in ("design.csv", "status.txt", "build.csv"):
        assert (tmp_path / "first" / "yasir2019_counter_mass" / f).read_text() == (tmp_path / "second" / "yasir2019_counter_mass" / f).read_text()
    assert getattr(dataclasses, "exec", None) is None  # this (test) process: never installed
