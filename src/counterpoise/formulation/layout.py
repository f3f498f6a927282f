"""Where each number lives in the NLP's vectors: the design vector and the parameter vector.

Two small objects own all the indexing, so nothing else counts offsets:

- :class:`DesignLayout`: one *slot* per shared variable, and one per scenario for an
  ``adjustable`` variable; bounds, initial values and the scaling IPOPT sees.
- :class:`ParameterLayout`: per scenario, the gravity vector then the literal (base)
  parameters, in SI. A study changes these values without rebuilding the solver.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..model.problem import Problem

Gravity3 = tuple[float, float, float]


@dataclass(frozen=True)
class Slot:
    """One entry of the design vector: a variable, in one scenario if it is adjustable."""

    variable: str
    scenario: str | None  # None: shared by every scenario; else the scenario's setting


class DesignLayout:
    """The design vector x (SI) and its scaled form z = x / scale that the solver sees."""

    def __init__(self, problem: Problem) -> None:
        self.problem = problem
        #: adjustable variables get one slot per setting (a scenario's own name unless
        #: several scenarios share a setting, as the working modes at one payload do)
        settings = tuple(dict.fromkeys(s.setting or s.name for s in problem.scenarios))
        self.setting = {s.name: s.setting or s.name for s in problem.scenarios}
        self.slots: tuple[Slot, ...] = tuple(
            Slot(v.name, setting if v.adjustable else None) for v in problem.variables for setting in (settings if v.adjustable else settings[:1])
        )
        self.index: Mapping[Slot, int] = {slot: i for i, slot in enumerate(self.slots)}
        variable = problem.variable
        self.lower = np.array([variable[s.variable].lower for s in self.slots], dtype=float)
        self.upper = np.array([variable[s.variable].upper for s in self.slots], dtype=float)
        self.initial = np.array([variable[s.variable].initial for s in self.slots], dtype=float)
        #: variables are scaled by their largest bound so that the solver sees O(1) numbers
        self.scale = np.maximum(np.maximum(np.abs(self.lower), np.abs(self.upper)), 1e-12)

    def __len__(self) -> int:
        return len(self.slots)

    def slot(self, variable: str, scenario: str) -> Slot:
        """The slot that holds ``variable`` as seen by ``scenario``."""
        return Slot(variable, self.setting[scenario] if self.problem.variable[variable].adjustable else None)

    def to_z(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(x, dtype=float) / self.scale

    def to_x(self, z: np.ndarray) -> np.ndarray:
        return np.asarray(z, dtype=float).reshape(-1) * self.scale

    def vector(self, values: Mapping[Slot, float], base: np.ndarray | None = None) -> np.ndarray:
        """A design vector (SI) from ``base`` (default: the initial design) with ``values`` set."""
        x = (self.initial if base is None else np.asarray(base, dtype=float)).copy()
        for slot, value in values.items():
            x[self.index[slot]] = value
        return x

    def bounds(self, overrides: Mapping[Slot | str, tuple[float, float]] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Scaled bounds (lbz, ubz). ``overrides`` maps a slot, or a variable name (all its
        slots), to SI bounds for one call: branch-and-bound nodes and schedules use it."""
        lo, hi = self.lower.copy(), self.upper.copy()
        for key, (a, b) in (overrides or {}).items():
            targets = [self.index[key]] if isinstance(key, Slot) else [i for i, s in enumerate(self.slots) if s.variable == key]
            if not targets:
                raise KeyError(f"no design variable '{key}'")
            for i in targets:
                lo[i], hi[i] = a, b
        return lo / self.scale, hi / self.scale

    def symbols(self, x: Any, scenario: str) -> dict[str, Any]:
        """Each variable's entry of the (SI) design vector ``x`` as seen by ``scenario``."""
        return {v.name: x[self.index[self.slot(v.name, scenario)]] for v in self.problem.variables}

    def values(self, x: np.ndarray) -> dict[Slot, float]:
        return {slot: float(v) for slot, v in zip(self.slots, np.asarray(x, dtype=float).reshape(-1))}


class ParameterLayout:
    """The parameter vector p: per scenario, gravity (3) then the base parameters (SI)."""

    def __init__(self, problem: Problem) -> None:
        self.problem = problem
        self.base_names: tuple[str, ...] = tuple(p.name for p in problem.base_parameters)
        self.stride = 3 + len(self.base_names)
        self.size = self.stride * len(problem.scenarios)

    def values(self, overrides: Mapping[str, float] | None = None, gravity: Sequence[float] | None = None) -> np.ndarray:
        """The vector at the file's values; ``overrides`` replaces base parameters (SI) in
        every scenario and ``gravity`` the gravity vector of every scenario (a study)."""
        unknown = set(overrides or {}) - set(self.base_names)
        if unknown:
            raise KeyError(f"not a literal parameter: {', '.join(sorted(unknown))}")
        base = {p.name: p.value for p in self.problem.base_parameters}
        out: list[float] = []
        for scenario in self.problem.scenarios:
            out += list(gravity) if gravity is not None else list(scenario.gravity.vector)
            for name in self.base_names:
                value = (overrides or {}).get(name, scenario.parameters.get(name, base[name]))
                out.append(float(value))  # type: ignore[arg-type]  # a base parameter has its SI value
        return np.array(out, dtype=float)

    def split(self, p: Any, scenario: int) -> tuple[list[Any], dict[str, Any]]:
        """Gravity vector and base parameters of scenario number ``scenario`` in ``p``
        (numbers or symbols)."""
        offset = scenario * self.stride
        gravity = [p[offset + i] for i in range(3)]
        base = {name: p[offset + 3 + i] for i, name in enumerate(self.base_names)}
        return gravity, base

    def scenario_values(self, p: np.ndarray) -> dict[str, tuple[Gravity3, dict[str, float]]]:
        """Per scenario name: gravity and base-parameter values (floats) in ``p``."""
        out = {}
        for c, scenario in enumerate(self.problem.scenarios):
            gravity, base = self.split(np.asarray(p, dtype=float), c)
            out[scenario.name] = (tuple(float(g) for g in gravity), {k: float(v) for k, v in base.items()})
        return out  # type: ignore[return-value]  # gravity is three floats
