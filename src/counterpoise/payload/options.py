"""Solve options of a payload-range design, mapped onto its sampled and adjustment problems.

``parameters`` act on every sample and every schedule payload, ``bounds`` (by variable
name) on every sample (inside the adjustments' pins and travel) and on the schedule's
adjustments, ``initial`` (by slot or variable name) on every sample's slots.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..errors import ProblemFileError
from ..designer.options import BoundsOverride
from ..formulation.layout import Slot
from ..model.problem import Problem
from .scenarios import Sampled, design_bounds, payload_of


def check_options(problem: Problem, parameters: Mapping[str, float] | None, bounds: BoundsOverride | None) -> None:
    """The payload's own mass is set by the range, not by ``parameters``; bounds name variables."""
    payload = payload_of(problem)
    if parameters and payload.name in parameters:
        raise ProblemFileError(problem.path, "parameters", f"'{payload.name}' is the payload of a payload range: change payloads.{payload.name}.range instead")
    for key in bounds or {}:
        name = key.variable if isinstance(key, Slot) else key
        if name not in problem.variable:
            raise ProblemFileError(problem.path, "bounds", f"no design variable '{name}'")


def _within_travel(problem: Problem, name: str, bounds: tuple[float, float]) -> tuple[float, float]:
    """A call's bounds of variable ``name`` (they replace the file's, as for any problem: a
    study may raise an upper bound), narrowed by the adjustment's travel around its nominal."""
    v = problem.variable[name]
    lo, hi = bounds
    if v.nominal is not None and v.travel is not None:
        lo, hi = max(lo, v.nominal - v.travel), min(hi, v.nominal + v.travel)
    return lo, hi


def merged_bounds(sampled: Sampled, bounds: BoundsOverride | None) -> dict[Slot | str, tuple[float, float]]:
    """The call's bounds (by variable, on every sample) with the adjustments' pins and travel
    windows (:func:`.scenarios.design_bounds`) inside them."""
    given = {(k.variable if isinstance(k, Slot) else k): v for k, v in (bounds or {}).items()}
    out: dict[Slot | str, tuple[float, float]] = {name: window for name, window in given.items()}
    for slot, (lo, hi) in design_bounds(sampled).items():
        if slot.variable in given and lo != hi:
            lo, hi = _within_travel(sampled.problem, slot.variable, given[slot.variable])
        out[slot] = (lo, hi)
    return out


def adjustment_bounds(problem: Problem, bounds: BoundsOverride | None) -> dict[str, tuple[float, float]]:
    """The call's bounds on adjustable variables, for the schedule's adjustment solves: the
    same bounds the samples were designed with (:func:`merged_bounds`)."""
    out = {}
    for key, given in (bounds or {}).items():
        name = key.variable if isinstance(key, Slot) else key
        if problem.variable[name].adjustable:
            out[name] = _within_travel(problem, name, given)
    return out


def sampled_initial(sampled: Sampled, initial: Mapping[Slot, float] | Mapping[str, float] | None) -> dict[Slot, float] | None:
    """Initial values given for ``problem``'s slots (or variable names), on every sample's slot."""
    if not initial:
        return None
    by_name = {(k.variable if isinstance(k, Slot) else k): v for k, v in initial.items()}
    out = {}
    for v in sampled.problem.variables:
        if v.name not in by_name:
            continue
        if v.adjustable:
            out.update({Slot(v.name, setting): by_name[v.name] for setting in sampled.setting_mass})
        else:
            out[Slot(v.name, None)] = by_name[v.name]
    return out
