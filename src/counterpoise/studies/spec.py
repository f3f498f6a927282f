"""What a study varies (``--vary``) and the points it runs: a full grid or a Latin hypercube.

``--vary NAME=START:STOP:N`` (grid) or ``--vary NAME=START:STOP`` with ``--samples N``
(Latin hypercube, ``--seed S``; default :data:`DEFAULT_SEED`). START and STOP are
quantities with units (``'m_endo=500 g:900 g:41'``; a bare ``0`` is allowed, and a bare
number for an angle is an error: ``theta_L=0:90 deg:3``). NAME is

- a literal parameter of the file: ``m_endo`` or ``parameters.m_endo``;
- a variable's bound: ``M_b.upper`` or ``variables.M_b.upper`` (``.lower`` likewise);
- an objective weight: ``inertia_weight`` / ``objective.inertia_weight``, ``mass_weight``.

Parameters and bounds are changed per call of the built solver; a weight is part of the
NLP, so each distinct weight builds its own solver (once per worker).
Every mistake raises a one-line :class:`~counterpoise.errors.ProblemFileError`
``<file>: --vary NAME: <message>``.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import NoReturn

import numpy as np

from ..errors import ProblemFileError, UnitError
from ..model import expr as ex
from ..model.problem import Problem
from ..model.units import (
    DIMENSIONLESS,
    INVERSE_AREA,
    DisplayUnit,
    Quantity,
    angle_hint,
    canonical_dimension,
    check_length_range,
    dimension_name,
    is_angle_unit,
    parse_quantity,
)

DEFAULT_SEED = 20260101
WEIGHTS = {"mass_weight": DIMENSIONLESS, "inertia_weight": INVERSE_AREA}


@dataclass(frozen=True)
class Vary:
    """One varied key: SI range, number of grid values (None for a sample), display unit."""

    key: str  # point key: 'm_endo', 'M_b.upper', 'objective.inertia_weight'
    start: float
    stop: float
    count: int | None
    unit: DisplayUnit
    text: str  # as given on the command line

    @property
    def header(self) -> str:
        """CSV header: the key and its display unit, e.g. ``m_endo [g]``."""
        return f"{self.key} [{self.unit.label}]"

    def as_dict(self) -> dict[str, object]:
        return {"key": self.key, "start": self.start, "stop": self.stop, "count": self.count, "unit": self.unit.symbol, "text": self.text}


@dataclass(frozen=True)
class StudyPlan:
    """The varied keys, how points are drawn, and the points (SI), numbered from 0."""

    varies: tuple[Vary, ...]
    method: str  # 'grid' or 'lhs'
    samples: int | None
    seed: int | None  # LHS only
    points: tuple[dict[str, float], ...]

    def identity(self) -> dict[str, object]:
        """What must match for ``--resume`` to continue a study file."""
        return {"method": self.method, "samples": self.samples, "seed": self.seed, "vary": [v.as_dict() for v in self.varies]}


def _resolve_key(problem: Problem, name: str, fail: Callable[[str], NoReturn]) -> tuple[str, str, DisplayUnit | None]:
    """(point key, expected dimension, unit the file uses) of a --vary name."""
    bare = name.removeprefix("parameters.").removeprefix("variables.").removeprefix("objective.")
    parameters = {p.name: p for p in problem.parameters}
    if bare in parameters and not name.startswith(("variables.", "objective.")):
        p = parameters[bare]
        if not p.is_base:
            fail("is computed from other parameters (an expression); vary the parameters it is built from")
        return bare, p.unit.dimension, p.unit
    if bare in WEIGHTS and not name.startswith(("parameters.", "variables.")):
        return f"objective.{bare}", canonical_dimension(WEIGHTS[bare]), None
    variable, _, side = bare.rpartition(".")
    if side in ("lower", "upper") and variable in problem.variable and not name.startswith(("parameters.", "objective.")):
        v = problem.variable[variable]
        return f"{variable}.{side}", v.unit.dimension, v.unit
    candidates = [p.name for p in problem.base_parameters] + list(WEIGHTS)
    candidates += [f"{v.name}.{s}" for v in problem.variables for s in ("lower", "upper")]
    if bare in problem.variable:
        fail(f"'{bare}' is a design variable: vary its bounds ({bare}.lower, {bare}.upper) instead")
    fail(f"unknown key{ex.suggest(bare, candidates)}: expected a literal parameter, VARIABLE.lower/.upper, mass_weight or inertia_weight")
    raise AssertionError  # pragma: no cover - fail raises


#: a number (as :func:`~counterpoise.model.units.parse_quantity` reads one) and the unit after it
_WRITTEN = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(\S.*?)\s*$")


def _quantity(text: str, file_unit: DisplayUnit | None) -> Quantity:
    """:func:`~counterpoise.model.units.parse_quantity` of ``text``; a quantity written in
    the unit the file gives the key (``m_endo=400 g:...`` where the file says ``"692.3 g"``)
    takes that unit as the file resolved it (the same symbol, size and dimension) instead
    of asking pint again: a study of a problem read from the cache then needs no pint."""
    written = _WRITTEN.match(text)
    if file_unit is None or not file_unit.symbol or written is None or written.group(2) != file_unit.symbol:
        return parse_quantity(text)
    si = float(written.group(1)) * file_unit.to_si
    if not math.isfinite(si):
        return parse_quantity(text)  # its error message
    check_length_range(si, file_unit.dimension, text)
    return Quantity(si, file_unit)


def parse_vary(problem: Problem, text: str, label: str) -> Vary:
    """One ``NAME=START:STOP[:N]``."""
    name, sep, rest = text.partition("=")
    name = name.strip()

    def fail(message: str) -> NoReturn:
        raise ProblemFileError(label, f"--vary {name or text}", message)

    if not sep or not name:
        fail("expected NAME=START:STOP:N (grid) or NAME=START:STOP (with --samples)")
    parts = [s.strip() for s in rest.split(":")]
    if len(parts) not in (2, 3) or not all(parts):
        fail(f"expected START:STOP:N or START:STOP, got '{rest.strip()}'")
    key, dimension, file_unit = _resolve_key(problem, name, fail)
    values = []
    unit = None
    for part in parts[:2]:
        try:
            q = _quantity(part, file_unit)
        except UnitError as exc:
            fail(str(exc))
        if q.dimension != dimension and not (q.si == 0 and not q.unit.symbol):  # a bare 0 is 0 in any unit
            hint = f" such as '{parts[0]} {file_unit.symbol}'" if file_unit is not None and file_unit.symbol and q.unit.symbol == "" else ""
            fail(f"'{part}' is {dimension_name(q.dimension)}, expected {dimension_name(dimension)}{hint}")
        if file_unit is not None and not q.unit.symbol and q.si != 0 and is_angle_unit(file_unit.symbol):
            fail(f"'{part}' is a bare number used as an angle ({name} is in {file_unit.symbol}): {angle_hint(q.si)}")
        values.append(q.si)
        unit = unit or (q.unit if q.unit.symbol else None)
    count = None
    if len(parts) == 3:
        try:
            count = int(parts[2])
        except ValueError:
            fail(f"N must be a whole number ≥ 1, got '{parts[2]}'")
        if count < 1:
            fail(f"N must be at least 1, got {count}")
    display = unit or (file_unit if file_unit is not None and file_unit.dimension == dimension else DisplayUnit("", 1.0, dimension))
    return Vary(key, values[0], values[1], count, display, text)


def plan_study(problem: Problem, texts: list[str], label: str, samples: int | None = None, method: str | None = None, seed: int | None = None) -> StudyPlan:
    """Parse every ``--vary`` and draw the points (grid or Latin hypercube)."""
    if not texts:
        raise ProblemFileError(label, "--vary", "give at least one --vary NAME=START:STOP:N")
    varies = tuple(parse_vary(problem, t, label) for t in texts)
    seen: set[str] = set()
    for v in varies:
        if v.key in seen:
            raise ProblemFileError(label, f"--vary {v.key}", "varied twice")
        seen.add(v.key)
    method = method or ("lhs" if samples is not None else "grid")
    if method not in ("grid", "lhs"):
        raise ProblemFileError(label, "--method", f"expected grid or lhs, got '{method}'")
    if method == "grid":
        if samples is not None:
            raise ProblemFileError(label, "--samples", "a grid takes N from each --vary; --samples goes with --method lhs")
        for v in varies:
            if v.count is None:
                raise ProblemFileError(label, f"--vary {v.key}", "a grid needs N (NAME=START:STOP:N), or use --samples N --method lhs")
        axes = [np.linspace(v.start, v.stop, v.count) for v in varies]  # type: ignore[arg-type]  # every count is set: checked just above
        points = tuple({v.key: float(x) for v, x in zip(varies, combo)} for combo in itertools.product(*axes))
        return StudyPlan(varies, method, None, None, points)
    if samples is None:
        raise ProblemFileError(label, "--method", "a Latin hypercube needs --samples N")
    if samples < 1:
        raise ProblemFileError(label, "--samples", f"must be at least 1, got {samples}")
    for v in varies:
        if v.count is not None:
            raise ProblemFileError(label, f"--vary {v.key}", "gives N, but --samples draws the points: write NAME=START:STOP with --samples")
    seed = DEFAULT_SEED if seed is None else seed
    unit_points = latin_hypercube(samples, len(varies), seed)
    points = tuple({v.key: float(v.start + (v.stop - v.start) * u[j]) for j, v in enumerate(varies)} for u in unit_points)
    return StudyPlan(varies, method, samples, seed, points)


def latin_hypercube(n: int, dimensions: int, seed: int) -> np.ndarray:
    """``n`` points in [0, 1)^dimensions, one in each of the n strata of every axis."""
    rng = np.random.default_rng(seed)
    out = np.empty((n, dimensions))
    for j in range(dimensions):
        out[:, j] = (rng.permutation(n) + rng.random(n)) / n
    return out
