"""Payload masses become scenarios; a fixed design becomes an adjustment-only problem.

Two problems are derived from a problem with a payload range, both through
``dataclasses.replace`` so that every layer below sees an ordinary :class:`Problem`:

- :func:`sampled_problem`: one scenario per (working mode, sampled payload mass). The
  scenarios of one payload mass share a *setting*: each adjustable variable has one value
  per payload mass, the same in every working mode (what an operator sets for a tool).
  Every other variable is shared by all scenarios.
- :func:`adjustment_problem`: the design's shared variables frozen as parameters, the
  adjustable variables as the only unknowns (bounds narrowed by their travel), the
  working modes as scenarios and the payload mass a literal parameter, so one solver
  serves every payload of a schedule.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace

from ..formulation.layout import Slot
from ..model.payload import MIN_ADDED, Payload
from ..model.problem import Parameter, Problem, Scenario, Variable

#: the scenario a file without [scenarios] gets (see io.resolve.quantities)
_DEFAULT = "nominal"


def payload_of(problem: Problem) -> Payload:
    return problem.payloads[0]


def modes(problem: Problem) -> tuple[Scenario, ...]:
    """The file's own scenarios (working modes); the implicit 'nominal' one counts as none."""
    s = problem.scenarios
    if len(s) == 1 and s[0].name == _DEFAULT and not s[0].parameters and not s[0].description:
        return ()
    return s


@dataclass(frozen=True)
class Sampled:
    """A problem whose scenarios are (mode, payload mass) pairs, and each setting's mass."""

    problem: Problem
    masses: tuple[float, ...]  # SI, ascending
    setting_mass: Mapping[str, float]


def setting_name(payload: Payload, mass: float) -> str:
    """'added_31g', 'added_34p771g': a payload mass as a name (solver functions need
    identifiers: letters, digits, single underscores)."""
    number = f"{payload.unit.from_si(mass):.6g}".replace(".", "p").replace("-", "m").replace("+", "")
    unit = re.sub(r"[^A-Za-z0-9]", "", payload.unit.symbol)
    return re.sub(r"_+", "_", f"{payload.name}_{number}{unit}")


def sampled_problem(problem: Problem, masses: Iterable[float]) -> Sampled:
    """One scenario per working mode and payload mass (masses sorted, repeats dropped)."""
    payload = payload_of(problem)
    ordered = tuple(sorted(set(float(m) for m in masses)))
    own = modes(problem)
    scenarios, setting_mass = [], {}
    for mass in ordered:
        setting = setting_name(payload, mass)
        setting_mass[setting] = mass
        for mode in own or problem.scenarios:
            name = f"{mode.name}_{setting}" if own else setting
            values = {**mode.parameters, payload.name: mass}
            scenarios.append(replace(mode, name=name, parameters=values, setting=setting))  # keeps a tilt's angles
    return Sampled(replace(problem, scenarios=tuple(scenarios)), ordered, setting_mass)


def design_bounds(sampled: Sampled) -> dict[Slot, tuple[float, float]]:
    """Per-slot bounds of a design solve: an adjustment with a ``nominal`` is pinned to it at
    the nominal payload and kept within its travel of it at every other payload."""
    problem = sampled.problem
    payload = payload_of(problem)
    out: dict[Slot, tuple[float, float]] = {}
    for v in problem.variables:
        if not v.adjustable or v.nominal is None:
            continue
        for setting, mass in sampled.setting_mass.items():
            out[Slot(v.name, setting)] = (v.nominal, v.nominal) if mass == payload.nominal else v.adjusted_bounds()
    return out


def is_pinned(problem: Problem, slot: Slot, setting_mass: Mapping[str, float]) -> bool:
    """True for an adjustment's slot at the nominal payload when it is fixed to its nominal."""
    v = problem.variable[slot.variable]
    return bool(v.adjustable and v.nominal is not None and setting_mass.get(slot.scenario or "") == payload_of(problem).nominal)


def adjustment_problem(problem: Problem, shared: Mapping[str, float]) -> Problem:
    """The adjustments of a fixed design as the only unknowns (see the module docstring).

    ``shared`` holds the SI value of every non-adjustable variable. The payload parameter is
    set to a non-zero mass of the range at build time, so that the compression of the
    balance conditions sees the payload's terms (a zero mass would hide them).
    """
    payload = payload_of(problem)
    frozen = tuple(
        Parameter(v.name, v.unit, value=float(shared[v.name]), description=v.description) for v in problem.variables if not v.adjustable
    )
    build_mass = payload.upper if payload.upper > 0 else payload.nominal
    parameters = tuple(replace(p, value=build_mass) if p.name == payload.name else p for p in problem.parameters)
    variables = []
    for v in problem.variables:
        if v.adjustable:
            lo, hi = v.adjusted_bounds()
            start = v.nominal if v.nominal is not None else min(max(v.initial, lo), hi)
            variables.append(Variable(v.name, lo, hi, start, v.unit, False, v.description))
    base_scenarios = tuple(replace(s, setting=None) for s in problem.scenarios)
    return replace(
        problem,
        parameters=frozen + parameters,
        variables=tuple(variables),
        scenarios=base_scenarios,
        objective=replace(problem.objective, goal=MIN_ADDED),
        payloads=(),
    )


def adjustable(problem: Problem) -> tuple[Variable, ...]:
    return tuple(v for v in problem.variables if v.adjustable)
