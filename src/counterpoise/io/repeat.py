"""``[repeat.<name>]``: repeated structure (the legs of a parallel mechanism, the links of a
long chain) written once.

A repeat table holds ``values`` — one list per placeholder, all of the same length — and
any of the sections of a problem file as templates. Before validation the templates are
copied once per position of the lists, with ``{placeholder}`` replaced in every key and
string by that position's value, and merged into the file's own sections::

    [repeat.legs]
    values = { i = [1, 2, 3], psi = ["30 deg", "150 deg", "270 deg"] }
    [repeat.legs.frames."leg{i}_base"]
    transforms = [{ rotate = "z", angle = "{psi}" }]

gives frames ``leg1_base``, ``leg2_base`` and ``leg3_base``. A string that is exactly one
placeholder takes the value itself (a number stays a number). Tables merge with the
file's (``substitutions.platform.points`` may collect one point per leg); a name defined
twice is an error, and so is a placeholder without values.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

from ..errors import ProblemFileError

PLACEHOLDER = re.compile(r"\{([A-Za-z_][A-Za-z0-9_]*)\}")
#: Sections a repeat may generate.
SECTIONS = (
    "parameters",
    "subsystems",
    "frames",
    "bodies",
    "counter_masses",
    "springs",
    "substitutions",
    "variables",
    "report",
    "scenarios",
)


def expand_repeats(raw: dict[str, Any], label: str) -> dict[str, Any]:
    """``raw`` with every ``[repeat.<name>]`` table expanded into the sections (in place)."""
    repeats = raw.pop("repeat", None)
    if repeats is None:
        return raw
    if not isinstance(repeats, dict):
        raise ProblemFileError(label, "repeat", "expected tables [repeat.<name>]")
    for name, spec in repeats.items():
        key = f"repeat.{name}"
        if not isinstance(spec, dict):
            raise ProblemFileError(label, key, "expected a table with 'values' and section templates")
        values = spec.get("values")
        if not isinstance(values, dict) or not values:
            raise ProblemFileError(label, f"{key}.values", "missing required key: one list per placeholder, e.g. values = { i = [1, 2, 3] }")
        lengths = set()
        for pname, items in values.items():
            if not isinstance(items, list) or not items:
                raise ProblemFileError(label, f"{key}.values.{pname}", "expected a non-empty list")
            lengths.add(len(items))
        if len(lengths) != 1:
            raise ProblemFileError(label, f"{key}.values", f"the lists have different lengths ({', '.join(str(n) for n in sorted(lengths))})")
        count = lengths.pop()
        for section, template in spec.items():
            if section == "values":
                continue
            if section not in SECTIONS:
                raise ProblemFileError(label, f"{key}.{section}", f"a repeat cannot generate [{section}] (allowed: {', '.join(SECTIONS)})")
            if not isinstance(template, dict):
                raise ProblemFileError(label, f"{key}.{section}", "expected a table")
            for k in range(count):
                env = {p: items[k] for p, items in values.items()}
                copy = _fill(template, env, f"{key}.{section}", label)
                _merge(raw.setdefault(section, {}), copy, section, label, key)
    return raw


def _fill(node: Any, env: Mapping[str, Any], key: str, label: str) -> Any:
    if isinstance(node, dict):
        return {_text(k, env, f"{key}.{k}", label): _fill(v, env, f"{key}.{k}", label) for k, v in node.items()}
    if isinstance(node, list):
        return [_fill(v, env, f"{key}.{i}", label) for i, v in enumerate(node)]
    if isinstance(node, str):
        whole = PLACEHOLDER.fullmatch(node)
        if whole and whole.group(1) in env:
            return env[whole.group(1)]
        return _text(node, env, key, label)
    return node


def _text(text: str, env: Mapping[str, Any], key: str, label: str) -> str:
    def replace(match: re.Match[str]) -> str:
        name = match.group(1)
        if name not in env:
            raise ProblemFileError(label, key, f"unknown placeholder '{{{name}}}' (values has {', '.join(sorted(env))})")
        return str(env[name])

    return PLACEHOLDER.sub(replace, text)


#: Tables below a section that collect named entries, so that a repeat may add to them (a
#: coordinate to a subsystem, a point to a substitution); anything else defined twice is an error.
MERGEABLE = (re.compile(r"^(subsystems|substitutions)\.[^.]+$"), re.compile(r"^subsystems\.[^.]+\.(coordinates|coupled)$"), re.compile(r"^substitutions\.[^.]+\.points$"))


def _merge(target: dict[str, Any], new: Mapping[str, Any], path: str, label: str, repeat_key: str) -> None:
    for k, v in new.items():
        if k in target:
            child = f"{path}.{k}"
            if isinstance(target[k], dict) and isinstance(v, dict) and any(m.match(child) for m in MERGEABLE):
                _merge(target[k], v, child, label, repeat_key)
                continue
            raise ProblemFileError(label, f"{path}.{k}", f"defined twice (by the file and {repeat_key}, or twice by {repeat_key})")
        target[k] = v
