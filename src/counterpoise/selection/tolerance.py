"""How much a built balancer can be off: the worst case over the parts' tolerance band.

A part's rate scatters by ±t_k and its initial tension by ±t_F (fractions; each spring
independently). Behind its string the spring's length is L = d + L0 − F0/k (the string is set
for the nominal part), so a part with k + Δk and F0 + ΔF0 pulls with
F0 + ΔF0 + (k + Δk)(d − F0/k) = k·d + Δk (d − F0/k) + ΔF0: the rate error acts on the
extension d − F0/k beyond the initial tension, not on d. The balance residual is *linear* in
every spring's Δk and ΔF0:

    r_j(q) = r_j,nominal(q) + Σ_i Δk_i (d_i − F0_i/k_i) ∂d_i/∂q_j + Σ_i ΔF0_i ∂d_i/∂q_j.

Its worst case over the box |Δk_i| ≤ t_k k_i, |ΔF0_i| ≤ t_F F0_i is therefore exact without
enumerating corners: |r_j,nominal| + Σ_i t_k k_i |d_i − F0_i/k_i| |∂d_i/∂q_j| + Σ_i t_F F0_i |∂d_i/∂q_j|,
maximised over the checked configurations and divided by the same reference as the
verification's ``residual_ratio`` (the largest unbalanced gravity torque of any revolute
coordinate, gravity force for sliders).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..mechanics import Mechanics
from ..mechanics.closure import along_manifold, independent_names
from ..model.problem import Problem
from ..verify.residuals import residuals
from .geometry import Gravity3, spring_length_gradients

#: per scenario: (variables, base parameters, gravity)
ScenarioValues = Mapping[str, tuple[Mapping[str, float], Mapping[str, float], Gravity3]]


@dataclass(frozen=True)
class ToleranceBand:
    """Residual ratios of one design: nominal, and worst case over the tolerance band."""

    nominal: float
    worst: float  # rate and initial tension at their worst
    worst_rate: float  # rate tolerance alone
    worst_tension: float  # initial-tension tolerance alone


def tolerance_band(
    problem: Problem,
    values: ScenarioValues,
    tension: Mapping[str, float],
    rate_tolerance: Mapping[str, float],
    tension_tolerance: Mapping[str, float],
    q: Mapping[str, np.ndarray],
    offsets: Mapping[str, float] | None = None,
) -> ToleranceBand:
    """Ratios for the springs named in ``tension`` (their part's F0, N) and tolerances (fractions).

    The rate term is t_k·k·|x|·|∂d/∂q| with x the extension the rate acts on: behind a pulley
    x = d − F0/k (the string set for the nominal part, see the module docstring);
    ``offsets``: for directly attached springs, cable + free length (m), x = d − offset.
    """
    offsets = offsets or {}
    rows: list[tuple[bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
    for scenario in problem.scenarios:
        variables, base, gravity = values[scenario.name]
        for sub in problem.subsystems:
            qs = q[sub.name]
            r, t = residuals(problem, sub.name, qs, dict(variables), dict(base), gravity)
            # closed loops: every term along the manifold, onto the independent coordinates (docs/loops.md)
            r, t = (along_manifold(problem, sub.name, qs, base, v) for v in (np.asarray(r), np.asarray(t)))
            geometry = spring_length_gradients(problem, sub.name, qs, variables, base, gravity)
            rate_term = np.zeros_like(r)
            tension_term = np.zeros_like(r)
            mech = Mechanics(problem, base, variables, {}, gravity)
            for spring in problem.springs:
                if spring.name not in tension or spring.name not in geometry:
                    continue
                length, grad = geometry[spring.name]
                grad = along_manifold(problem, sub.name, qs, base, grad)
                k = float(mech.value(spring.stiffness))
                slope = np.abs(grad) / (2 * np.maximum(length, 1e-12))[:, None]  # |∂d/∂q|
                # behind a pulley the rate acts on d − F0/k (a part's rate error times F0/k is a
                # constant force along the string, −Δk·F0/k); attached directly on d − cable − L0
                offset = offsets.get(spring.name, tension[spring.name] / k if spring.direct is None and k > 0 else 0.0)
                extension = np.abs(length - offset)[:, None]
                rate_term += rate_tolerance[spring.name] * k * extension * slope
                tension_term += tension_tolerance[spring.name] * tension[spring.name] * slope
            for j, name in enumerate(independent_names(problem, sub.name)):
                revolute = problem.coordinate[name].unit.dimension == ""
                rows.append((revolute, np.abs(r[:, j]), np.abs(t[:, j]), rate_term[:, j], tension_term[:, j]))
    out = []
    for kind in (True, False):
        mine = [row for row in rows if row[0] is kind]
        if not mine:
            continue
        reference = max(float(row[2].max()) for row in mine)
        if reference <= 0:
            reference = max(float((row[1] + row[3]).max()) for row in mine) or 1.0
        out.append(
            [
                max(float(row[1].max()) for row in mine) / reference,
                max(float((row[1] + row[3] + row[4]).max()) for row in mine) / reference,
                max(float((row[1] + row[3]).max()) for row in mine) / reference,
                max(float((row[1] + row[4]).max()) for row in mine) / reference,
            ]
        )
    worst = np.max(np.array(out), axis=0) if out else np.zeros(4)
    return ToleranceBand(*(float(v) for v in worst))
