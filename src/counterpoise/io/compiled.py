"""The methods of dataclasses compiled once per user, for the command line.

:mod:`dataclasses` writes each class's ``__init__``, ``__repr__``, ``__eq__``, ``__hash__``
(and, for a frozen class, ``__setattr__`` and ``__delattr__``) as source text and compiles
it with :func:`exec` when the class is created, in every process. Compiling is about three
quarters of the cost of a dataclass (~0.5 of ~0.7 ms for a frozen one), and a
``counterpoise solve`` creates 65 of them (~380 methods) before it reads its problem.

When the console script runs with the cache on, :func:`counterpoise.cli.main` calls
:func:`install`: the :mod:`dataclasses` module's ``exec`` becomes :func:`_exec`, which
compiles each text once and keeps its code object in the cache folder
(:func:`counterpoise.io.cache.folder`), read back with :mod:`marshal` as Python reads its
``.pyc`` files. The code is the one :func:`exec` compiles from the same text (file name
``<string>``, no ``__future__`` flags inherited, the interpreter's optimisation level),
then run by :func:`exec` with the same globals and locals: the classes are the same, only
the compiling is skipped.

- One file per top-level package whose dataclasses are created (``counterpoise``, and
  ``pint``, ``pydantic``... when a problem file is read), read when the first dataclass of
  that package is created, so a solve that reads its problem from the cache reads
  counterpoise's file only.
- Keyed on the Python version (code objects and marshal's format belong to it) and its
  optimisation level (``-O``); each code under the BLAKE2b digest of its text. A file
  holds at most :data:`MAX_CODES` codes (beyond that it starts again).
- :func:`save` (the command line, before it exits) writes a package's file back when this
  process compiled new codes for it (the first run, another counterpoise, pint, pydantic
  or Python version), through a temporary file and a rename, and removes that package's
  files of other Python versions or levels (never read again).
- Read only from a :func:`~counterpoise.io.cache.private` folder and file, like every
  entry of the cache (marshal, like pickle, must not read what others could write); a file
  that cannot be read is removed and its codes compiled again. In-process calls
  (``main([...])``, a program using the library) never install it.
"""

from __future__ import annotations

import builtins
import marshal
import os
import sys
from pathlib import Path
from types import CodeType
from typing import Any

from ..hashing import blake2b

#: codes kept in one package's file at most (counterpoise's dataclasses need ~400)
MAX_CODES = 2048

#: the cache folder while installed (:func:`install`)
_folder: Path | None = None
#: package -> digest of a method's text -> its code
_codes: dict[str, dict[bytes, CodeType]] = {}
#: packages whose table gained codes in this process
_added: set[str] = set()
#: texts compiled in this process (none when every code was kept)
compiles = 0


def _digest(source: str) -> bytes:
    return blake2b(source.encode("utf-8", "surrogatepass"), digest_size=16).digest()


def _file(folder: Path, package: str) -> Path:
    return folder / f"dataclass-code.{sys.implementation.cache_tag}-{sys.hexversion:x}-O{sys.flags.optimize}.{package}.marshal"


def _package(globals: dict[str, Any]) -> str:
    name = globals.get("__name__")
    package = name.partition(".")[0] if isinstance(name, str) else ""
    return package if package.isidentifier() else "_"


def _read(folder: Path, package: str) -> dict[bytes, CodeType]:
    """The codes kept for ``package``: empty when there are none, and when the file is not
    this user's private one (left alone) or cannot be read (removed)."""
    from .cache import private

    if not private(folder):  # as every entry of the cache: never from a folder others may write
        return {}
    entry = _file(folder, package)
    try:
        handle = entry.open("rb")
    except OSError:
        return {}
    with handle:
        if not private(handle.fileno()):
            return {}
        try:
            found = marshal.loads(handle.read())  # one read: marshal.load reads a file piece by piece
        except (OSError, EOFError, ValueError, TypeError):
            found = None
    if isinstance(found, dict) and all(type(k) is bytes and type(v) is CodeType for k, v in found.items()):
        return found
    entry.unlink(missing_ok=True)
    return {}


def _table(package: str) -> dict[bytes, CodeType]:
    table = _codes.get(package)
    if table is None:
        table = _codes[package] = _read(_folder, package) if _folder is not None else {}
    return table


def _exec(source: Any, globals: dict[str, Any] | None = None, locals: Any = None, /, **kwargs: Any) -> None:
    """:func:`exec` for :mod:`dataclasses`: a text's code is compiled once (module docstring)."""
    global compiles
    if globals is None:  # exec's own default: the caller's globals (and locals)
        frame = sys._getframe(1)
        globals = frame.f_globals
        if locals is None:
            locals = frame.f_locals
    if type(source) is str and not kwargs:
        package = _package(globals)
        table = _table(package)
        key = _digest(source)
        code = table.get(key)
        if code is None:
            code = table[key] = compile(source, "<string>", "exec", dont_inherit=True)
            _added.add(package)
            compiles += 1
        source = code
    builtins.exec(source, globals, locals, **kwargs)


def install(folder: Path) -> None:
    """Compile dataclass methods once, with their codes kept in ``folder`` (the cache
    folder; read only when it is private): see the module docstring."""
    global _folder
    import dataclasses

    from .cache import private

    if folder.exists() and not private(folder):
        return
    _folder = folder
    dataclasses.exec = _exec  # type: ignore[attr-defined]  # the name dataclasses' code calls


def save() -> None:
    """Write back each package's codes to which this process added (see the module docstring)."""
    if _folder is None:
        return
    from .cache import MAX_ENTRIES, _write, private

    for package in sorted(_added):
        codes = _codes[package]
        if len(codes) > MAX_CODES:
            codes = {}
        entry = _file(_folder, package)
        _write(entry, codes, MAX_ENTRIES, _dump)
        if not private(_folder):  # nothing was written there
            continue
        for other in _folder.glob(f"dataclass-code.*.{package}.marshal"):  # another Python's: never read again
            if other != entry and private(other):
                other.unlink(missing_ok=True)
    _added.clear()


def uninstall() -> None:
    """Give :mod:`dataclasses` the built-in :func:`exec` back and forget the codes (tests)."""
    global _folder, compiles
    import dataclasses

    if getattr(dataclasses, "exec", None) is _exec:
        del dataclasses.exec  # type: ignore[attr-defined]  # the name install() set, unknown to the stubs
    _folder = None
    compiles = 0
    _codes.clear()
    _added.clear()


def _dump(value: Any, handle: Any) -> None:
    """:func:`marshal.dump` with the signature the cache's writer takes."""
    marshal.dump(value, handle)
