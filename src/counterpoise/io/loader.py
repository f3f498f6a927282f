"""Load a problem file (or the same data built in code) into a typed :class:`Problem`.

Three passes, each failing with a one-line :class:`ProblemFileError` naming the file and
the key: TOML syntax (``tomllib``), shape (:mod:`.schema`, pydantic), then meaning
(:mod:`.resolve`): units and dimensions, names in expressions, the frame graph, bounds
and signs. :func:`load_problem_data` takes the parsed data directly: the Python API
(:mod:`.builder`) goes through it, so code-built problems get exactly
the checks a file gets.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from types import UnionType
from typing import Annotated, Any, Union, get_args, get_origin

from pydantic import BaseModel, Tag

from ..errors import ProblemFileError, clip, raise_errors
from ..model import expr as ex
from ..model.problem import Problem
from .repeat import expand_repeats
from .resolve import resolve
from .schema import ProblemFile

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def load_problem(path: str | Path, overrides: Mapping[str, object] | None = None) -> Problem:
    """Read, validate and resolve one problem file.

    ``overrides`` maps dotted keys to values applied to the TOML before validation, e.g.
    ``{"objective.inertia_weight": "50 1/m^2", "parameters.r_a": "140 mm"}``.
    """
    path = Path(path)
    label = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ProblemFileError(label, "file", f"cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise ProblemFileError(label, "file", "not UTF-8 text") from None
    return load_problem_text(text, label, overrides)


def load_problem_text(text: str, label: str = "<string>", overrides: Mapping[str, object] | None = None) -> Problem:
    """As :func:`load_problem`, from TOML text (``label`` names it in error messages)."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        line = re.search(r"line (\d+)", msg)
        key = f"line {line.group(1)}" if line else "toml"
        raise ProblemFileError(label, key, f"TOML syntax error: {re.sub(r' ?[(]at line.*', '', msg)}") from None
    except RecursionError:  # tomllib parses nested arrays and tables recursively
        raise ProblemFileError(label, "toml", "TOML syntax error: arrays or tables nested too deeply") from None
    return load_problem_data(raw, label, overrides)


def load_problem_data(data: Mapping[str, Any], label: str = "<data>", overrides: Mapping[str, object] | None = None) -> Problem:
    """As :func:`load_problem`, from already parsed data (nested dicts, as TOML gives them)."""
    raw = expand_repeats(apply_overrides(data, overrides, label), label)
    from pydantic import ValidationError

    try:
        spec = ProblemFile.model_validate(raw)
    except ValidationError as exc:
        raise_errors(_schema_errors(raw, exc.errors(), label))
    return resolve(spec, label)


def apply_overrides(data: Mapping[str, Any], overrides: Mapping[str, object] | None, label: str = "<data>") -> dict[str, Any]:
    """A deep copy of parsed ``data`` with the dotted-key ``overrides`` applied, as
    :func:`load_problem_data` applies them (``--set``): what a file says once they are
    set (``counterpoise synthesise`` writes its topologies' files from it)."""
    import copy

    try:
        raw = copy.deepcopy(dict(data))
    except RecursionError:
        raise ProblemFileError(label, "file", "arrays or tables nested too deeply") from None
    if overrides:
        known = _entry_names(raw, label)
        for key, value in overrides.items():
            _apply_override(raw, key, value, label, known)
    return raw


#: tables whose entries an override may change but not create: a new parameter is used by
#: nothing (a typo in ``--set parameters.m_cc=...`` would otherwise change nothing); other
#: tables may gain an entry (a scenario, say), which the schema then checks whole
NAMED_TABLES = frozenset({"parameters"})


def _entry_names(raw: dict[str, Any], label: str) -> dict[str, list[str]]:
    """The names of every named table's entries, those a ``[repeat]`` makes included."""
    import copy

    try:
        expanded = expand_repeats(copy.deepcopy(raw), label)
    except ProblemFileError:
        expanded = raw  # the file's own error is reported when it is loaded
    return {t: list(expanded[t]) if isinstance(expanded.get(t), dict) else [] for t in NAMED_TABLES}


def _apply_override(raw: dict[str, Any], key: str, value: Any, label: str, known: Mapping[str, list[str]] | None = None) -> None:
    parts = key.split(".")
    if known is not None and len(parts) >= 2 and parts[0] in NAMED_TABLES:
        names = known[parts[0]]
        if parts[1] not in names:
            close = ex.nearest(parts[1], names)
            hint = f" (did you mean '{close}'?)" if close else (f" (it has: {', '.join(names[:12])})" if names else "")
            raise ProblemFileError(label, key, f"the file has no {parts[0]} entry '{parts[1]}' to override{hint}")
    node: Any = raw
    for i, part in enumerate(parts[:-1]):
        if isinstance(node, list):
            node = node[_index(node, part, label, ".".join(parts[: i + 1]))]
            continue
        if not isinstance(node, dict):
            raise ProblemFileError(label, key, "override path does not lead to a table")
        node = node.setdefault(part, {})
    if isinstance(node, list):  # one entry of an array: KEY.0=VALUE
        node[_index(node, parts[-1], label, key)] = value
        return
    if not isinstance(node, dict) or not parts[-1]:
        raise ProblemFileError(label, key, "override path does not lead to a table")
    node[parts[-1]] = value


def _index(node: list[Any], part: str, label: str, key: str) -> int:
    """The entry ``part`` (0, 1, ...) of an array in an override path."""
    if not part.isdigit() or int(part) >= len(node):
        raise ProblemFileError(
            label, key, f"the array has {len(node)} entries: set one by its index 0 to {len(node) - 1}, or the whole array as TOML, "
            "e.g. --set 'gravity.direction=[0, 0, -1]'"
        )
    return int(part)


def _schema_errors(raw: dict[str, Any], errors: list[Any], label: str) -> list[ProblemFileError]:
    """One error per offending key, in the file's order (pydantic's), each naming the key.

    An unknown key is reported with the nearest key its table knows; a required key that
    this suggestion names is then not reported as missing too ('uper' hides 'upper').
    """
    located = []
    for err in errors:
        path, known = _locate(raw, err["loc"], keep_last=err.get("type") == "missing")
        located.append((err, path, known))
    suggested: set[tuple[Any, ...]] = set()
    messages: dict[tuple[Any, ...], str] = {}
    for err, path, known in located:
        if err.get("type") == "extra_forbidden" and path:
            present = _node(raw, path[:-1])
            candidates = [k for k in known if not (isinstance(present, dict) and k in present)]
            close = ex.nearest(str(path[-1]), candidates)
            messages[tuple(path)] = "unknown key" + (f" (did you mean '{close}'?)" if close else "")
            if close:
                suggested.add((*path[:-1], close))
    out: list[ProblemFileError] = []
    seen: set[tuple[Any, ...]] = set()
    for err, path, _ in located:
        where = tuple(path)
        if where in seen or (err.get("type") == "missing" and where in suggested):
            continue
        seen.add(where)
        key = ".".join(str(k) for k in path) or "file"
        out.append(ProblemFileError(label, key, messages.get(where) or _pydantic_message(err)))
    return out


def _node(raw: Any, path: list[Any]) -> Any:
    for part in path:
        raw = raw[part]
    return raw


def _unwrap(tp: Any) -> Any:
    """``tp`` without ``Annotated`` metadata and without ``None`` in an optional."""
    while True:
        if get_origin(tp) is Annotated:
            tp = get_args(tp)[0]
            continue
        if get_origin(tp) in (Union, UnionType):
            members = [m for m in get_args(tp) if m is not type(None)]
            if len(members) == 1:
                tp = members[0]
                continue
        return tp


def _tags(tp: Any) -> dict[str, Any]:
    """The members of a tagged union (``Tag("rotate")`` -> RotateSpec), or {}."""
    out = {}
    if get_origin(tp) in (Union, UnionType):
        for member in get_args(tp):
            if get_origin(member) is Annotated:
                for meta in get_args(member)[1:]:
                    if isinstance(meta, Tag):
                        out[meta.tag] = member
    return out


def _child(tp: Any, part: Any) -> Any:
    """The type of entry ``part`` of a value of type ``tp`` (None when unknown)."""
    tp = _unwrap(tp)
    if get_origin(tp) in (Union, UnionType):  # an untagged union: the member that has entries
        members = [_unwrap(m) for m in get_args(tp)]
        tables = [m for m in members if isinstance(m, type) and issubclass(m, BaseModel) or get_origin(m) in (dict, tuple)]
        tp = tables[0] if tables else None
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        for name, field in tp.model_fields.items():
            if part in (name, field.alias):
                return field.annotation
        return None
    if get_origin(tp) is dict:
        return get_args(tp)[1]
    if get_origin(tp) is tuple:
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return args[0]
        return args[part] if isinstance(part, int) and 0 <= part < len(args) else None
    return None


def _known_keys(tp: Any) -> list[str]:
    tp = _unwrap(tp)
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        return [field.alias or name for name, field in tp.model_fields.items()]
    return []


def _locate(raw: Any, loc: Iterable[Any], keep_last: bool) -> tuple[list[Any], list[str]]:
    """The keys of the file a pydantic error location names, and the keys known where the
    last one is (for a suggestion).

    pydantic adds the tags of unions (``rotate``, ``translate``: also key names) and the
    names of union members to locations; the schema's types say which parts they are. A
    missing key (``keep_last``) is named although the file does not contain it.
    """
    out: list[Any] = []
    node: Any = raw
    tp: Any = ProblemFile
    known: list[str] = _known_keys(tp)
    items = list(loc)
    for i, part in enumerate(items):
        tags = _tags(_unwrap_annotated(tp))
        if isinstance(part, str) and part in tags:
            tp = tags[part]  # a union tag, not a key of the file
            continue
        known = _known_keys(tp)
        if isinstance(node, dict) and part in node:
            node = node[part]
            out.append(part)
            tp = _child(tp, part)
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            node = node[part]
            out.append(part)
            tp = _child(tp, part)
        elif keep_last and i == len(items) - 1:
            out.append(part)
    return out, known


def _unwrap_annotated(tp: Any) -> Any:
    while get_origin(tp) is Annotated:
        tp = get_args(tp)[0]
    return tp


def _pydantic_message(err: Mapping[str, Any]) -> str:
    kind = err.get("type", "")
    if kind == "extra_forbidden":
        return "unknown key"
    if kind == "missing":
        return "missing required key"
    if kind == "too_short":
        return "must not be empty"
    if kind == "string_pattern_mismatch":
        if "." in (err.get("ctx") or {}).get("pattern", ""):  # problem.name
            rule = "letters, digits, '_', '.' and '-', starting with a letter or digit"
        else:
            rule = "letters, digits and '_', starting with a letter"
        return f"invalid name {err.get('input')!r}: use {rule}"
    if kind in ("tuple_type", "list_type"):  # arrays are set whole: --set 'KEY=[...]' is read as TOML
        return f"expected an array such as [0, 0, -1], got {clip(repr(err.get('input')))} (with --set, write the array: --set 'KEY=[...]')"
    if kind == "string_too_long":
        limit = (err.get("ctx") or {}).get("max_length")
        return f"too long ({len(str(err.get('input', '')))} characters; at most {limit}, since it names the report folder)"
    if kind == "literal_error":
        return f"expected one of {(err.get('ctx') or {}).get('expected', '')}, got {err.get('input')!r}"
    msg = str(err.get("msg", "invalid value"))
    return msg.removeprefix("Value error, ")


# --------------------------------------------------------------------------------------
# Resolution: names, units, graph
# --------------------------------------------------------------------------------------
