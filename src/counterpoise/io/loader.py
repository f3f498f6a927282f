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
from typing import Any

from ..errors import ProblemFileError
from ..model import expr as ex
from ..model.problem import Problem
from .repeat import expand_repeats
from .resolve import resolve
from .schema import ProblemFile

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def load_problem(path: str | Path, overrides: Mapping[str, str] | None = None) -> Problem:
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


def load_problem_text(text: str, label: str = "<string>", overrides: Mapping[str, str] | None = None) -> Problem:
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


def load_problem_data(data: Mapping[str, Any], label: str = "<data>", overrides: Mapping[str, Any] | None = None) -> Problem:
    """As :func:`load_problem`, from already parsed data (nested dicts, as TOML gives them)."""
    import copy

    try:
        raw = copy.deepcopy(dict(data))
    except RecursionError:
        raise ProblemFileError(label, "file", "arrays or tables nested too deeply") from None
    for key, value in (overrides or {}).items():
        _apply_override(raw, key, value, label)
    raw = expand_repeats(raw, label)
    from pydantic import ValidationError

    try:
        spec = ProblemFile.model_validate(raw)
    except ValidationError as exc:
        errors = exc.errors()
        # an unknown key explains a missing one next to it ('uper' hides 'upper'): report it first
        err = next((e for e in errors if e.get("type") == "extra_forbidden"), errors[0])
        loc = _clean_loc(raw, err["loc"], keep_last=err.get("type") == "missing")
        key = ".".join(str(k) for k in loc) or "file"
        raise ProblemFileError(label, key, _pydantic_message(err, errors)) from None
    return resolve(spec, label)


def _apply_override(raw: dict[str, Any], key: str, value: Any, label: str) -> None:
    parts = key.split(".")
    node: Any = raw
    for part in parts[:-1]:
        if not isinstance(node, dict):
            raise ProblemFileError(label, key, "override path does not lead to a table")
        node = node.setdefault(part, {})
    if not isinstance(node, dict) or not parts[-1]:
        raise ProblemFileError(label, key, "override path does not lead to a table")
    node[parts[-1]] = value


def _clean_loc(raw: Any, loc: Iterable[Any], keep_last: bool) -> list[Any]:
    """Keep the parts of a pydantic error location that are real keys of the file.

    pydantic adds union tags and markers such as ``[key]``; they are dropped. A missing
    key (``keep_last``) is named although the file does not contain it.
    """
    out: list[Any] = []
    node = raw
    items = list(loc)
    for i, part in enumerate(items):
        if isinstance(node, dict) and part in node:
            node = node[part]
            out.append(part)
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            node = node[part]
            out.append(part)
        elif keep_last and i == len(items) - 1:
            out.append(part)
    return out


def _pydantic_message(err: Mapping[str, Any], errors: list[Any]) -> str:
    kind = err.get("type", "")
    if kind == "extra_forbidden":
        loc = tuple(err["loc"])
        missing = [e["loc"][-1] for e in errors if e.get("type") == "missing" and tuple(e["loc"][:-1]) == loc[:-1]]
        hint = ex.suggest(str(loc[-1]), [str(m) for m in missing])
        return f"unknown key{hint}"
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
    if kind == "literal_error":
        return f"expected one of {(err.get('ctx') or {}).get('expected', '')}, got {err.get('input')!r}"
    msg = str(err.get("msg", "invalid value"))
    return msg.removeprefix("Value error, ")


# --------------------------------------------------------------------------------------
# Resolution: names, units, graph
# --------------------------------------------------------------------------------------
