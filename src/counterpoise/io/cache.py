"""Loaded problems and built designers kept on disk, keyed on content, for the command line.

Reading a problem file costs more than most designs: pint and its registry, pydantic and
the schema's validator, then the resolution (~0.3 s of a 0.5–0.9 s ``counterpoise solve``).
The console script keeps each problem it loaded as a pickle in a cache folder, with the
warnings its checks found at load (:func:`load_checked`), and a later run on the same
content unpickles both instead (~5 ms, importing neither pint nor pydantic).
``counterpoise solve`` (and ``study``, for its designer) also keeps what it built from a problem (:func:`fetch_built` /
:func:`keep_built`): the designer (its CasADi functions and the sampled balance
conditions) and the dense check's evaluators after their first check (the configurations,
their complex-step arrays, the box maximum's functions), which a later solve of the same
content unpickles instead of building (for the hybrid ~20 ms against ~0.15 s).

- **Key** (BLAKE2b): this format's version; the code (every file of the counterpoise
  package by path, size and modification time; the installed version of each library in
  :data:`LIBRARIES` (or :data:`BUILT_LIBRARIES`) from its ``.dist-info`` folder, and its
  ``__init__`` file's path, size and modification time; the Python version); for a
  problem, the file's name as given (it is the problem's ``path``, in every message), its
  absolute path, its bytes and the ``--set`` overrides; for a built object, the parts its
  builder names (the problem's content key, the options). Editing the file, a ``--set``,
  another counterpoise or library version: another key.
- **What is kept**: only problems whose loading reads no other file. A problem with a
  ``[robot]`` model or ``[catalogues]`` (the tables whose resolution reads files:
  :mod:`.resolve.robot`, :mod:`.resolve.parts`) is loaded from its files every time.
  A file that fails to load or to pass its checks is never kept (its error is reported
  every time).
- **Where**: ``$XDG_CACHE_HOME/counterpoise/problems`` (``~/.cache/counterpoise/problems``),
  or the folder ``COUNTERPOISE_CACHE`` names; ``COUNTERPOISE_CACHE=off`` turns it off.
  Built objects go to its subfolder ``built``. A pickle runs code when it is read, so the
  folder is used only when it belongs to this user and neither its group nor others may
  write into it (:func:`private`); otherwise it is left alone (read and written never),
  and each entry must be this user's file too. A folder the cache creates is ``0700``.
  Entries are written through a temporary file and a rename (a reader never sees half an
  entry), the least recently used beyond :data:`MAX_ENTRIES` (built objects: beyond
  :data:`MAX_BUILT` or :data:`MAX_BUILT_BYTES`) are removed, and an entry that cannot be
  read is removed and the work done as usual (then kept again). The cache is a copy:
  deleting the folder is always safe.
- **Who uses it**: the console script only (:func:`enable`, from
  :func:`counterpoise.cli.main` when it runs as the process's command; built objects only
  for ``solve``). In-process calls (``main([...])``, :func:`counterpoise.io.loader.load_problem`,
  a ``Designer`` built by a library user) never read or write it.
"""

from __future__ import annotations

import io
import os
import pickle
import stat
import sys
from collections.abc import Callable, Iterable, Mapping
from contextlib import AbstractContextManager, nullcontext
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeGuard, TypeVar

from ..hashing import blake2b

if TYPE_CHECKING:
    from ..model.problem import Problem

#: version of the entries' layout: changing what is kept or how changes it
FORMAT = 2
#: the environment variable naming the folder, or ``off``
ENVIRONMENT = "COUNTERPOISE_CACHE"
#: top-level tables whose resolution reads other files: such problems are not kept
FILE_TABLES = ("robot", "catalogues")
#: entries kept; the least recently used beyond this are removed when one is written
MAX_ENTRIES = 256
#: built objects kept (for the hybrid: its designer 0.4 MB, its dense check's evaluators
#: 6 MB); the least recently used beyond this many, or beyond :data:`MAX_BUILT_BYTES` in
#: all, are removed
MAX_BUILT = 64
MAX_BUILT_BYTES = 256 * 2**20
#: the subfolder of built objects
BUILT = "built"
#: a temporary file older than this (seconds) was left by a killed process: removed
STALE_SECONDS = 3600
#: libraries whose versions change what a load gives (besides counterpoise itself)
LIBRARIES = ("pint", "pydantic", "pydantic_core", "numpy")
#: libraries whose versions change what a built designer holds
BUILT_LIBRARIES = ("casadi", "numpy")
_OFF = ("off", "0", "no", "false", "none")

_enabled = False
_built = False

#: what a checked load found: the warnings of the problem's checks (see :func:`load_checked`)
Warnings = tuple[str, ...]
Check = Callable[["Problem"], Warnings]


def enable(built: bool = False) -> None:
    """Let :func:`load` use the cache in this process (the console script's); ``built``:
    :func:`fetch_built` and :func:`keep_built` too (``counterpoise solve``, and ``study``
    until its pool forks: :func:`keep_no_built`)."""
    global _enabled, _built
    _enabled = True
    _built = built


def keep_no_built() -> None:
    """Stop :func:`fetch_built` and :func:`keep_built` in this process (a ``solve`` of several
    files: the built objects are kept for the repeated solve of one file, the edit-and-solve
    loop; a batch such as ``make demo`` would fill the folder with each problem's evaluators,
    ~6 MB each, and pay their writing on every file; a study once its pool forks)."""
    global _built
    _built = False


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


def private(where: Path | int) -> bool:
    """Whether ``where`` (a path, or an open file's descriptor) belongs to this user and
    neither its group nor others may write it: unpickling what someone else could have
    written would run their code. False where the system has no POSIX owners."""
    if not hasattr(os, "geteuid"):  # pragma: no cover - no owners to check (Windows): not used
        return False
    try:
        st = os.fstat(where) if isinstance(where, int) else os.stat(where)
    except OSError:
        return False
    return st.st_uid == os.geteuid() and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def _dist_versions(site: str) -> dict[str, str]:
    """{normalised project name: version} of the ``.dist-info`` folders in ``site``."""
    found: dict[str, str] = {}
    try:
        entries = os.scandir(site)
    except OSError:
        return found
    with entries:
        for entry in entries:
            if entry.name.endswith(".dist-info"):
                project, _, version = entry.name[: -len(".dist-info")].partition("-")
                found[project.replace("-", "_").replace(".", "_").lower()] = version
    return found


#: the files of the package that are code or data (their path, size and modification time are digested)
CODE_SUFFIXES = (".py", ".csv", ".txt", ".toml", ".json")


@lru_cache(maxsize=1)
def _package_fingerprint() -> str:
    """counterpoise's own files (path, size, modification time) and the Python version."""
    h = blake2b(digest_size=16)
    h.update(f"{FORMAT};{sys.version};{sys.implementation.cache_tag};".encode())
    parts: list[str] = []
    _package_files(os.path.dirname(os.path.dirname(os.path.realpath(__file__))), "", parts)
    h.update("".join(parts).encode("utf-8", "surrogatepass"))
    return h.hexdigest()


def _package_files(folder: str, prefix: str, parts: list[str]) -> None:
    """``path:size:mtime;`` of each code or data file under ``folder`` (paths relative to
    the package, ``/``-separated), the files of a folder by name, then its subfolders by
    name (``__pycache__`` left out). One ``scandir`` per folder: ~1.5 ms for the package,
    where ``os.walk``, ``os.stat`` and ``os.path.relpath`` took ~5–8 ms."""
    with os.scandir(folder) as found:
        entries = sorted(found, key=lambda e: e.name)
    for entry in entries:
        if entry.name.endswith(CODE_SUFFIXES) and entry.is_file():
            st = entry.stat()
            parts.append(f"{prefix}{entry.name}:{st.st_size}:{st.st_mtime_ns};")
    for entry in entries:
        if entry.name != "__pycache__" and entry.is_dir(follow_symlinks=False):
            _package_files(entry.path, f"{prefix}{entry.name}/", parts)


@lru_cache(maxsize=4)
def code_fingerprint(libraries: tuple[str, ...] = LIBRARIES) -> str:
    """Digest of the code a load (or a build) runs: counterpoise's files (path, size,
    modification time), each of ``libraries`` by its installed version (its ``.dist-info``
    folder beside the package, read without importing it) and its ``__init__`` file, and
    the Python version."""
    h = blake2b(digest_size=16)
    h.update(_package_fingerprint().encode())
    sites: dict[str, dict[str, str]] = {}
    for library in libraries:
        origin = getattr(_find_spec(library), "origin", None)
        if origin and os.path.exists(origin):
            st = os.stat(origin)
            site = os.path.dirname(os.path.dirname(origin)) if os.path.basename(origin).startswith("__init__.") else os.path.dirname(origin)
            if site not in sites:
                sites[site] = _dist_versions(site)
            version = sites[site].get(library.lower(), "-")
            h.update(f"{library}:{version}:{origin}:{st.st_size}:{st.st_mtime_ns};".encode())
        else:
            h.update(f"{library}:-;".encode())
    return h.hexdigest()


def _find_spec(library: str) -> Any:
    """Where ``library`` is: an imported module's spec, else the path finder's (without
    importing :mod:`importlib.util`), else :func:`importlib.util.find_spec`'s (a library that
    another finder installs)."""
    module = sys.modules.get(library)
    if module is not None:
        return getattr(module, "__spec__", None)
    from importlib.machinery import PathFinder

    spec = PathFinder.find_spec(library)
    if spec is None:
        import importlib.util

        spec = importlib.util.find_spec(library)
    return spec


def key(label: str, path: Path, data: bytes, overrides: Mapping[str, object], checked: str = "") -> str:
    """The entry's key (see the module docstring); ``checked``: the name of the check whose
    result the entry holds (:func:`check_name`)."""
    h = blake2b(digest_size=20)
    for part in (code_fingerprint(), label, str(path.resolve()), repr(sorted((str(k), repr(v)) for k, v in overrides.items())), checked):
        h.update(part.encode("utf-8", "surrogatepass") + b"\0")
    h.update(data)
    return h.hexdigest()


def load(path: str | Path, overrides: Mapping[str, object] | None = None) -> Problem:
    """:func:`counterpoise.io.loader.load_problem` of ``path``, from the cache when it holds
    this content (and kept there after loading when it may be)."""
    return load_checked(path, overrides, _no_check)[0]


def _no_check(problem: Problem) -> Warnings:
    return ()


def load_checked(path: str | Path, overrides: Mapping[str, object] | None, check: Check) -> tuple[Problem, Warnings]:
    """``path`` loaded (:func:`counterpoise.io.loader.load_problem`) and ``check``-ed: the
    problem and the warnings ``check`` returned. ``check`` raises for a problem that must
    not be used (a :class:`~counterpoise.errors.ProblemFileError`, passed on); it depends
    on the problem's content only. Both come from the cache when it holds this content
    and ``check`` (by :func:`check_name`, part of the key), and are kept there when they
    may be."""
    overrides = dict(overrides or {})
    where = folder()
    path = Path(path)
    if where is None:
        problem = _load_file(path, overrides)
        return problem, check(problem)
    try:
        data = path.read_bytes()
        text = io.TextIOWrapper(io.BytesIO(data), encoding="utf-8").read()  # as Path.read_text: universal newlines
    except (OSError, UnicodeDecodeError):
        problem = _load_file(path, overrides)  # its one-line error
        return problem, check(problem)
    label = str(path)
    checked = check_name(check)
    entry = where / f"{key(label, path, data, overrides, checked)}.pickle"
    found = _read(entry, label, checked) if private(where) else None
    if found is not None:
        return found
    from .loader import load_problem_text

    problem = load_problem_text(text, label, overrides)
    warnings = check(problem)
    if _may_keep(text, overrides):
        from ..model.digest import content_key

        content_key(problem)  # kept on the problem (and so in the entry): the key of the designers built from it
        _write(entry, (problem, checked, warnings), MAX_ENTRIES)
    return problem, warnings


def check_name(check: Check) -> str:
    """The name a check's result is kept under (its module and name)."""
    return f"{getattr(check, '__module__', '?')}.{getattr(check, '__qualname__', '?')}"


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


def _unpickle(entry: Path, loads: Callable[[io.BufferedReader], object]) -> object | None:
    """``loads`` of the open entry; None when there is none, and when it is not this
    user's private file or cannot be read (then it is removed)."""
    try:
        handle = entry.open("rb")
    except FileNotFoundError:
        return None
    except OSError:
        return None
    try:
        with handle:
            if not private(handle.fileno()):  # not ours: never unpickled, left alone
                return None
            found = loads(handle)
            try:
                os.utime(handle.fileno())  # used now: the least recently used are removed first
            except OSError:
                pass
            return found
    except Exception:  # noqa: BLE001 - any unreadable entry (truncated, another format): drop it, redo the work
        entry.unlink(missing_ok=True)
        return None


def _read(entry: Path, label: str, checked: str) -> tuple[Problem, Warnings] | None:
    from ..model.problem import Problem

    found = _unpickle(entry, pickle.load)
    if found is None:
        return None
    if isinstance(found, tuple) and len(found) == 3:
        problem, name, warnings = found
        if isinstance(problem, Problem) and problem.path == label and name == checked and isinstance(warnings, tuple) and all(isinstance(w, str) for w in warnings):
            return problem, warnings
    entry.unlink(missing_ok=True)
    return None


def _make_folders(folder: Path) -> None:
    """Create ``folder`` and each missing folder above it as the user's own (``0700``: the
    problems may be private, and :func:`private` refuses a folder others may write);
    ``Path.mkdir(parents=True)`` would give the missing parents the umask's mode."""
    missing = []
    while not folder.exists():
        missing.append(folder)
        folder = folder.parent
    for made in reversed(missing):
        made.mkdir(mode=0o700, exist_ok=True)


def _write(entry: Path, value: object, limit: int, dump: Callable[[object, Any], None] | None = None, size: float = float("inf")) -> None:
    """Keep ``value`` under ``entry`` (a temporary file renamed into place; ``dump(value,
    handle)``, default :func:`pickle.dump`); a cache that cannot be written, or a folder
    that is not :func:`private`, is left alone (the next run does the work again). The
    least recently used entries beyond ``limit`` (or ``size`` bytes) are removed."""
    import tempfile  # only when writing (it imports shutil, random, bz2, lzma)

    try:
        _make_folders(entry.parent)
        if not private(entry.parent):
            return
        fd, tmp = tempfile.mkstemp(prefix=f".{entry.stem[:12]}.", suffix=".tmp", dir=entry.parent)
        try:
            with os.fdopen(fd, "wb") as handle:
                if dump is None:
                    pickle.dump(value, handle, protocol=pickle.HIGHEST_PROTOCOL)
                else:
                    dump(value, handle)
            os.replace(tmp, entry)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        _prune(entry.parent, limit, size)
    except (OSError, pickle.PicklingError, TypeError, AttributeError, RecursionError):
        return


def _prune(where: Path, limit: int = MAX_ENTRIES, size: float = float("inf")) -> None:
    """Remove the least recently used entries (by modification time: an entry read is
    touched) beyond ``limit`` or beyond ``size`` bytes in all, and temporary files older
    than :data:`STALE_SECONDS` (left by a process killed while writing)."""
    import time

    entries, stale = [], []
    now = time.time()
    for item in os.scandir(where):
        try:
            if item.name.endswith(".pickle") and item.is_file(follow_symlinks=False):
                st = item.stat()
                entries.append((st.st_mtime_ns, st.st_size, item.path))
            elif item.name.endswith(".tmp") and now - item.stat().st_mtime > STALE_SECONDS:
                stale.append(item.path)
        except OSError:
            continue
    total = 0
    for rank, (_, bytes_, name) in enumerate(sorted(entries, reverse=True)):  # newest first
        total += bytes_
        if rank >= limit or (rank and total > size):  # the newest is kept whatever its size
            stale.append(name)
    for name in stale:
        try:
            os.unlink(name)
        except OSError:
            pass


# -- built objects (counterpoise solve) ----------------------------------------------------


def built_folder() -> Path | None:
    """The folder of built objects, or None when they are not kept in this process."""
    where = folder() if _built else None
    return None if where is None else where / BUILT


def built_parts(problem: Any, *parts: str) -> tuple[str, ...] | None:
    """The key parts of an object built from ``problem`` (its content key, then ``parts``:
    what else the object depends on), or None when built objects are not kept in this
    process (anything but the console script's ``solve`` of one file)."""
    if built_folder() is None:
        return None
    from ..model.digest import content_key

    return (content_key(problem), *parts)


def _built_entry(where: Path, kind: str, parts: Iterable[str]) -> Path:
    h = blake2b(digest_size=20)
    for part in (code_fingerprint(BUILT_LIBRARIES), kind, *parts):
        h.update(part.encode("utf-8", "surrogatepass") + b"\0")
    return where / f"{kind}.{h.hexdigest()}.pickle"


def fetch_built(
    kind: str, parts: Iterable[str], shared: Mapping[str, object], context: Callable[[], AbstractContextManager[object]] = nullcontext
) -> object | None:
    """The object kept by :func:`keep_built` under ``kind`` and ``parts``, or None (not
    kept, the cache off or not :func:`private`, an unreadable entry: removed). ``shared``:
    the objects that were left out of the entry by name (the problem the object was built
    from), put back in their places; ``context``: a context manager the unpickling runs
    in (CasADi's ``global_unpickle_context``, so symbols shared between expressions stay
    shared)."""
    where = built_folder()
    if where is None or not private(where.parent) or not private(where):
        return None
    entry = _built_entry(where, kind, parts)

    def loads(handle: io.BufferedReader) -> object:
        reader = pickle.Unpickler(handle)

        def persistent_load(pid: object) -> object:
            if not isinstance(pid, str) or pid not in shared:
                raise pickle.UnpicklingError(f"unknown shared object {pid!r}")
            return shared[pid]

        reader.persistent_load = persistent_load  # type: ignore[method-assign]  # pickle's documented hook
        with context():
            return reader.load()

    return _unpickle(entry, loads)


def keep_built(
    kind: str,
    parts: Iterable[str],
    value: object,
    shared: Mapping[str, object],
    reducers: Mapping[type, Callable[[Any], tuple[Any, ...]]] | None = None,
    context: Callable[[], AbstractContextManager[object]] = nullcontext,
) -> None:
    """Keep ``value`` for :func:`fetch_built` (nothing when built objects are not kept in
    this process). ``shared``: objects referred to by name instead of being written (the
    same objects must be handed to :func:`fetch_built`); ``reducers``: how to pickle
    objects of these types (``copyreg``'s reduce functions, for this entry only);
    ``context``: a context manager the pickling runs in. An object that cannot be pickled
    leaves nothing behind."""
    where = built_folder()
    if where is None:
        return
    if where.parent.exists() and not private(where.parent):  # the cache folder itself is someone else's
        return
    entry = _built_entry(where, kind, parts)
    import copyreg

    names = {id(obj): name for name, obj in shared.items()}
    table: dict[Any, Any] = {**copyreg.dispatch_table, **(reducers or {})}

    def dump(obj: object, handle: Any) -> None:
        class Writer(pickle.Pickler):
            dispatch_table = table

            def persistent_id(self, o: object) -> str | None:
                return names.get(id(o))

        with context():
            Writer(handle, protocol=pickle.HIGHEST_PROTOCOL).dump(obj)

    try:
        _write(entry, value, MAX_BUILT, dump, MAX_BUILT_BYTES)
    except Exception:  # noqa: BLE001 - CasADi raises plain Exception for what it cannot serialize: keep nothing
        return


#: what a valid kept object is (see :meth:`BuiltEntry.fetch`)
T = TypeVar("T")


class BuiltEntry:
    """One object built from a problem and kept on disk by ``counterpoise solve``: the glue
    between a builder (a designer, the dense check's evaluators, the springs' workspace
    sample) and :func:`fetch_built` / :func:`keep_built`, written once.

    ``shared``: objects the entry refers to by name (the problem it was built from, the
    object restored into), the same at :meth:`fetch` and :meth:`keep`; ``reducers``: how
    objects of these types pickle in this entry; ``casadi``: the entry holds CasADi
    expressions or functions, pickled and unpickled in one CasADi context (symbols shared
    between expressions stay shared). Made by :func:`built_entry`, which gives None when
    built objects are not kept in this process."""

    def __init__(
        self,
        kind: str,
        parts: tuple[str, ...],
        shared: Mapping[str, object] | None = None,
        reducers: Mapping[type, Callable[[Any], tuple[Any, ...]]] | None = None,
        casadi: bool = False,
    ) -> None:
        self.kind = kind
        self.parts = parts
        self.shared = dict(shared or {})
        self.reducers = reducers
        self.casadi = casadi

    def fetch(self, valid: Callable[[object], TypeGuard[T]]) -> T | None:
        """The kept object when there is one and ``valid`` says it is what the builder makes; else None."""
        context: Callable[[], AbstractContextManager[object]] = nullcontext
        if self.casadi:
            import casadi as ca

            context = ca.global_unpickle_context
        found = fetch_built(self.kind, self.parts, self.shared, context)
        return found if found is not None and valid(found) else None

    def keep(self, value: object) -> None:
        """Keep ``value`` for a later :meth:`fetch` of the same entry."""
        context: Callable[[], AbstractContextManager[object]] = nullcontext
        if self.casadi:
            import casadi as ca

            context = ca.global_pickle_context
        keep_built(self.kind, self.parts, value, self.shared, self.reducers, context)


def built_entry(
    kind: str,
    problem: Any,
    *parts: str,
    shared: Mapping[str, object] | None = None,
    reducers: Mapping[type, Callable[[Any], tuple[Any, ...]]] | None = None,
    casadi: bool = False,
) -> BuiltEntry | None:
    """The entry of an object of ``kind`` built from ``problem`` (key: the problem's content,
    then ``parts``), or None when built objects are not kept in this process (anything but
    the console script's ``solve`` of one file). See :class:`BuiltEntry`."""
    key = built_parts(problem, *parts)
    return None if key is None else BuiltEntry(kind, key, shared, reducers, casadi)
