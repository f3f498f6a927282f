"""Loaded problems kept on disk, keyed on content, for the command line.

Reading a problem file costs more than most designs: pint and its registry, pydantic and
the schema's validator, then the resolution (~0.3 s of a 0.5–0.9 s ``counterpoise solve``).
The console script keeps each problem it loaded as a pickle in a cache folder, and a later
run on the same content unpickles it instead (~5 ms, importing neither pint nor pydantic).

- **Key** (BLAKE2b): this format's version; the code that loads (every file of the
  counterpoise package by path, size and modification time; pint's, pydantic's,
  pydantic-core's and numpy's ``__init__`` likewise; the Python version); the file's name
  as given (it is the problem's ``path``, in every message) and its absolute path; the
  file's bytes; the ``--set`` overrides. Editing the file, a ``--set``, another
  counterpoise or library version: another key.
- **What is kept**: only problems whose loading reads no other file. A problem with a
  ``[robot]`` model or ``[catalogues]`` (the tables whose resolution reads files:
  :mod:`.resolve.robot`, :mod:`.resolve.parts`) is loaded from its files every time.
  A file that fails to load is never kept (its error is reported every time).
- **Where**: ``$XDG_CACHE_HOME/counterpoise/problems`` (``~/.cache/counterpoise/problems``),
  or the folder ``COUNTERPOISE_CACHE`` names; ``COUNTERPOISE_CACHE=off`` turns it off.
  Entries are written through a temporary file and a rename (a reader never sees half an
  entry), the oldest beyond :data:`MAX_ENTRIES` are removed, and an entry that cannot be
  read is removed and the file loaded as usual. The cache is a copy: deleting the folder
  is always safe.
- **Who uses it**: the console script only (:func:`enable`, from
  :func:`counterpoise.cli.main` when it runs as the process's command). In-process calls
  (``main([...])``, :func:`counterpoise.io.loader.load_problem`) never read or write it.
"""

from __future__ import annotations

import hashlib
import io
import os
import pickle
import sys
import tempfile
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..model.problem import Problem

#: version of the entries' layout: changing what is kept or how changes it
FORMAT = 1
#: the environment variable naming the folder, or ``off``
ENVIRONMENT = "COUNTERPOISE_CACHE"
#: top-level tables whose resolution reads other files: such problems are not kept
FILE_TABLES = ("robot", "catalogues")
#: entries kept; the oldest beyond this are removed when one is written
MAX_ENTRIES = 256
#: a temporary file older than this (seconds) was left by a killed process: removed
STALE_SECONDS = 3600
#: libraries whose versions change what a load gives (besides counterpoise itself)
LIBRARIES = ("pint", "pydantic", "pydantic_core", "numpy")
_OFF = ("off", "0", "no", "false", "none")

_enabled = False


def enable() -> None:
    """Let :func:`load` use the cache in this process (the console script's)."""
    global _enabled
    _enabled = True


def folder() -> Path | None:
    """The cache folder, or None when the cache is off (not enabled, or ``COUNTERPOISE_CACHE=off``)."""
    if not _enabled:
        return None
    setting = os.environ.get(ENVIRONMENT, "").strip()
    if setting.lower() in _OFF:
        return None
    if setting:
        return Path(setting)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    if not os.path.isabs(base):  # no home folder known: never a folder relative to the working one
        return None
    return Path(base) / "counterpoise" / "problems"


@lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """Digest of the code a load runs: counterpoise's files and the libraries' entry files
    (path, size, modification time), and the Python version."""
    import importlib.util

    h = hashlib.blake2b(digest_size=16)
    h.update(f"{FORMAT};{sys.version};{sys.implementation.cache_tag};".encode())
    package = Path(__file__).resolve().parent.parent
    for root, dirs, files in os.walk(package):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            if name.endswith((".py", ".csv", ".txt", ".toml", ".json")):
                stat = os.stat(os.path.join(root, name))
                h.update(f"{os.path.relpath(os.path.join(root, name), package)}:{stat.st_size}:{stat.st_mtime_ns};".encode())
    for library in LIBRARIES:
        spec = importlib.util.find_spec(library)
        origin = getattr(spec, "origin", None)
        if origin and os.path.exists(origin):
            stat = os.stat(origin)
            h.update(f"{library}:{origin}:{stat.st_size}:{stat.st_mtime_ns};".encode())
        else:
            h.update(f"{library}:-;".encode())
    return h.hexdigest()


def key(label: str, path: Path, data: bytes, overrides: Mapping[str, object]) -> str:
    """The entry's key (see the module docstring)."""
    h = hashlib.blake2b(digest_size=20)
    for part in (code_fingerprint(), label, str(path.resolve()), repr(sorted((str(k), repr(v)) for k, v in overrides.items()))):
        h.update(part.encode("utf-8", "surrogatepass") + b"\0")
    h.update(data)
    return h.hexdigest()


def load(path: str | Path, overrides: Mapping[str, object] | None = None) -> Problem:
    """:func:`counterpoise.io.loader.load_problem` of ``path``, from the cache when it holds
    this content (and kept there after loading when it may be)."""
    overrides = dict(overrides or {})
    where = folder()
    path = Path(path)
    if where is None:
        return _load_file(path, overrides)
    try:
        data = path.read_bytes()
        text = io.TextIOWrapper(io.BytesIO(data), encoding="utf-8").read()  # as Path.read_text: universal newlines
    except (OSError, UnicodeDecodeError):
        return _load_file(path, overrides)  # its one-line error
    label = str(path)
    entry = where / f"{key(label, path, data, overrides)}.pickle"
    found = _read(entry, label)
    if found is not None:
        return found
    from .loader import load_problem_text

    problem = load_problem_text(text, label, overrides)
    if _may_keep(text, overrides):
        _write(entry, problem)
    return problem


def _load_file(path: Path, overrides: Mapping[str, object]) -> Problem:
    from .loader import load_problem

    return load_problem(path, overrides)


def _may_keep(text: str, overrides: Mapping[str, object]) -> bool:
    """Whether loading this text read no other file (no table of :data:`FILE_TABLES`, in
    the file or in an override)."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib

    raw = tomllib.loads(text)  # it loaded, so it parses
    return not any(t in raw for t in FILE_TABLES) and not any(str(k).split(".")[0] in FILE_TABLES for k in overrides)


def _read(entry: Path, label: str) -> Problem | None:
    from ..model.problem import Problem

    try:
        with entry.open("rb") as handle:
            problem = pickle.load(handle)
    except FileNotFoundError:
        return None
    except Exception:  # noqa: BLE001 - any unreadable entry (truncated, another format): drop it, load the file
        entry.unlink(missing_ok=True)
        return None
    if not isinstance(problem, Problem) or problem.path != label:
        entry.unlink(missing_ok=True)
        return None
    return problem


def _write(entry: Path, problem: Problem) -> None:
    """Keep ``problem`` under ``entry`` (a temporary file renamed into place); a cache that
    cannot be written is left alone (the next run loads the file again)."""
    try:
        entry.parent.mkdir(mode=0o700, parents=True, exist_ok=True)  # the user's own: problems may be private
        fd, tmp = tempfile.mkstemp(prefix=f".{entry.stem[:12]}.", suffix=".tmp", dir=entry.parent)
        try:
            with os.fdopen(fd, "wb") as handle:
                pickle.dump(problem, handle, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(tmp, entry)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        _prune(entry.parent)
    except (OSError, pickle.PicklingError, TypeError, AttributeError, RecursionError):
        return


def _prune(where: Path) -> None:
    """Remove the oldest entries beyond :data:`MAX_ENTRIES`, and temporary files older than
    :data:`STALE_SECONDS` (left by a process killed while writing)."""
    import time

    entries, stale = [], []
    now = time.time()
    for item in os.scandir(where):
        try:
            if item.name.endswith(".pickle"):
                entries.append((item.stat().st_mtime_ns, item.path))
            elif item.name.endswith(".tmp") and now - item.stat().st_mtime > STALE_SECONDS:
                stale.append(item.path)
        except OSError:
            continue
    for _, name in sorted(entries)[: max(0, len(entries) - MAX_ENTRIES)]:
        stale.append(name)
    for name in stale:
        try:
            os.unlink(name)
        except OSError:
            pass
