"""A topology as an ordinary problem file: the file's own tables without ``[synthesis]``,
plus a variable, a spring or counter-mass for each chosen element.

Two forms (docs/synthesis.md#refinement):

- ``fixed``: every point where the grid design has it (a literal position), the rates and
  masses free within the synthesis bounds (the linear program of the engine's LP path);
- ``free``: every point of a convex region written as ``origin + Σ u_i axis_i`` with a
  variable u_i in [0, 1] per side of the region (a list of holes keeps its hole): the
  engine's NLP frees the points in their regions (refinement).

With ``adjust`` (a payload range), the grid design's free ends and the counter-masses'
positions are ``adjustable`` variables: they are re-set per payload.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..model.problem import Problem
from ..model.synthesis import SynthesisSpec
from .milp import Element
from .structure import SPRING, ElementClass, region_arrays

FIXED, FREE = "fixed", "free"
#: the written files' verification tolerance at most (the acceptance of a synthesised design)
VERIFY_TOLERANCE = 1e-9
#: sections whose entries' names the written elements must not take
_NAMED = ("parameters", "variables", "frames", "bodies", "counter_masses", "springs", "payloads", "report", "scenarios", "subsystems", "constraints", "slots", "catalogues", "loops")


@dataclass(frozen=True)
class Written:
    """A topology's problem data, and where each element's values live in it: per element,
    the magnitude's variable and the point variables (end index -> variable names)."""

    data: dict[str, Any]
    magnitudes: tuple[str, ...]
    point_variables: tuple[dict[int, tuple[str, ...]], ...]


def _mm(value: float) -> str | float:
    """A length in mm, exactly enough ('120 mm'; 0 as 0)."""
    return 0 if value == 0 else f"{value * 1e3:.15g} mm"


def _names(raw: Mapping[str, Any], problem: Problem) -> set[str]:
    out = {c.name for c in problem.coordinates} | {f.name for f in problem.frames} | {"ground"}
    for section in _NAMED:
        table = raw.get(section)
        if isinstance(table, dict):
            out |= set(table)
    for sub in problem.subsystems:
        out.add(sub.name)
    return out


def _unique(name: str, taken: set[str]) -> str:
    name = re.sub(r"[^A-Za-z0-9_]", "_", name)
    if not name[:1].isalpha():
        name = "e_" + name
    out, i = name, 2
    while out in taken:
        out = f"{name}_{i}"
        i += 1
    taken.add(out)
    return out


def _coordinates(point: np.ndarray, origin: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """u in [0, 1]^m with origin + axes u = point (least squares, clipped)."""
    if axes.shape[1] == 0:
        return np.zeros(0)
    u = np.linalg.lstsq(axes, point - origin, rcond=None)[0]
    return np.clip(u, 0.0, 1.0)


def _expression(origin: np.ndarray, axes: np.ndarray, names: Sequence[str]) -> list[Any]:
    out: list[Any] = []
    for i in range(3):
        terms = [] if origin[i] == 0 else [f"{origin[i] * 1e3:.15g} mm"]
        for j, name in enumerate(names):
            d = axes[i, j]
            if d != 0:
                terms.append(f"{d * 1e3:.15g} mm * {name}")
        if not terms:
            out.append(0)
            continue
        text = terms[0]
        for t in terms[1:]:
            text += f" - {t[1:]}" if t.startswith("-") else f" + {t}"
        out.append(text)
    return out


def topology_data(
    raw: Mapping[str, Any],
    problem: Problem,
    spec: SynthesisSpec,
    classes: Sequence[ElementClass],
    elements: Sequence[Element],
    form: str,
    name: str,
    title: str,
    free_ends: Sequence[int | None] = (),
) -> Written:
    """The problem data of one topology (see the module). ``elements``: the design's values
    (rates and masses, points per payload setting: the first setting's are the initial
    values); ``free_ends``: per element, the end the grid left free (the one adjusted per
    payload with ``adjust``), None when none."""
    data = copy.deepcopy(dict(raw))
    data.pop("synthesis", None)
    data["problem"] = dict(data.get("problem", {}))
    data["problem"]["name"] = name
    data["problem"]["title"] = title
    taken = _names(raw, problem)
    variables = data.setdefault("variables", {})
    springs = data.setdefault("springs", {})
    masses = data.setdefault("counter_masses", {})
    shared = None
    magnitudes, point_variables = [], []
    for index, e in enumerate(elements):
        cls = classes[e.cls]
        free_end = free_ends[index] if index < len(free_ends) else None
        points = e.points[0]
        if cls.kind == SPRING:
            base = f"{cls.frames[0]}_{cls.frames[1]}"
            if spec.same_rate:
                if shared is None:
                    shared = _unique("k", taken)
                    variables[shared] = {"lower": f"{spec.min_rate / 1e3!r} N/mm", "upper": f"{spec.max_rate / 1e3!r} N/mm", "initial": f"{e.magnitude / 1e3!r} N/mm",
                                         "description": "the one rate of every synthesised spring"}
                kname = shared
            else:
                kname = _unique(f"k_{base}", taken)
                variables[kname] = {"lower": f"{spec.min_rate / 1e3!r} N/mm", "upper": f"{spec.max_rate / 1e3!r} N/mm", "initial": f"{e.magnitude / 1e3!r} N/mm",
                                    "description": f"rate of the synthesised spring {cls.name}"}
            sname = _unique(f"s_{base}", taken)
            ends: list[list[Any]] = []
            pv: dict[int, tuple[str, ...]] = {}
            for end in (0, 1):
                region = cls.regions[end]
                free = region.convex and (form == FREE or (spec.adjust and free_end == end))
                if free:
                    origin, axes = region_arrays(region)
                    u = _coordinates(points[end], origin, axes)
                    unames = tuple(_unique(f"u_{sname}_{'from' if end == 0 else 'to'}{i}", taken) for i in range(axes.shape[1]))
                    for uname, value in zip(unames, u):
                        variables[uname] = {"lower": 0, "upper": 1, "initial": float(value), "description": f"{cls.frames[end]}'s end of {sname}: along side {unames.index(uname) + 1} of {region.key}"}
                        if spec.adjust and free_end == end:
                            variables[uname]["adjustable"] = True
                    ends.append(_expression(origin, axes, unames))
                    pv[end] = unames
                else:
                    ends.append([_mm(float(v)) for v in points[end]])
            springs[sname] = {"stiffness": kname, "from": {"frame": cls.frames[0], "point": ends[0]}, "to": {"frame": cls.frames[1], "point": ends[1]},
                              "description": f"synthesised: a spring between {cls.frames[0]} and {cls.frames[1]}"}
            magnitudes.append(kname)
            point_variables.append(pv)
        else:
            mname = _unique(f"M_{cls.name}", taken)
            variables[mname] = {"lower": f"{spec.min_mass!r} kg", "upper": f"{spec.max_mass!r} kg", "initial": f"{e.magnitude!r} kg", "description": f"synthesised counter-mass at site {cls.name}"}
            cname = _unique(cls.name if cls.name not in taken else f"cm_{cls.name}", taken)
            region = cls.regions[0]
            pv = {}
            if region.convex and (form == FREE or spec.adjust):
                origin, axes = region_arrays(region)
                u = _coordinates(points[0], origin, axes)
                unames = tuple(_unique(f"u_{cname}{i}", taken) for i in range(axes.shape[1]))
                for uname, value in zip(unames, u):
                    variables[uname] = {"lower": 0, "upper": 1, "initial": float(value), "description": f"position of {cname}: along side {unames.index(uname) + 1} of {region.key}"}
                    if spec.adjust:
                        variables[uname]["adjustable"] = True
                position = _expression(origin, axes, unames)
                pv[0] = unames
            else:
                position = [_mm(float(v)) for v in points[0]]
            masses[cname] = {"frame": cls.frames[0], "mass": mname, "position": position, "description": "synthesised counter-mass"}
            magnitudes.append(mname)
            point_variables.append(pv)
    for section in ("variables", "springs", "counter_masses"):
        if not data[section]:
            del data[section]
    settings = data.setdefault("settings", {})
    settings["verify_tolerance"] = min(float(settings.get("verify_tolerance", 1e-8)), VERIFY_TOLERANCE)
    # the synthesis proves exact balance of ideal elements (zero-free-length springs at their
    # rates): a topology's file says so, and its status gives the as-built figure beside it
    # (docs/synthesis.md#what-the-written-files-are; docs/build.md#ideal-springs)
    settings["ideal_springs"] = True
    return Written(data, tuple(magnitudes), tuple(point_variables))


def toml_text(data: Mapping[str, Any], header: str = "") -> str:
    """``data`` as TOML (tomli-w), after ``header`` (comment lines)."""
    import tomli_w

    lines = "".join(f"# {line}\n" if line else "#\n" for line in header.splitlines())
    return lines + ("\n" if lines else "") + tomli_w.dumps(dict(data), multiline_strings=False)
