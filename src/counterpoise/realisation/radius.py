"""What a point pulley's radius would cost, and where a pin would make it free (docs/build.md#pulleys).

A design with point pulleys (radius 0) pulls k·d exactly; a real pulley has a radius. To
first order in r, the cable's path over a pulley of radius r is d + r θ (θ the arc it
wraps), so with the anchor set for the best constant c the spring's energy gains
k r d (θ − c), and every residual gains

    δr_j = r · k ∂[d (θ − c)]/∂q_j.

:func:`radius_notes` evaluates that slope on sampled configurations of each point-pulley
spring's subsystem (complex-step derivatives of the same cable geometry the design uses,
:mod:`counterpoise.mechanics.cable`), takes the best c (a one-dimensional convex minimax),
and says what a radius of 1 mm adds to the residual ratio and the largest radius the
design's tolerance allows. It also names, for a spring whose link point turns against its
pulley, a frame of the mechanism that keeps the pulley frame's orientation: a cable wrapped
onto a pin of the pulley's radius there is exact at any radius (``pin = true``).
Open chains only (a closed loop's coordinates are not independent: no estimate, said so).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from ..designer.minimax import minimax_of
from ..mechanics import Mechanics
from ..mechanics.cable import cable
from ..model.elements import Pulley, ZeroFreeLengthSpring
from ..model.problem import Problem
from ..verify.checks import PRISMATIC, REVOLUTE, Verification

#: sampled configurations per subsystem for the estimate
SAMPLES = 2000
#: the complex step
STEP = 1e-30
#: a frame keeps another's orientation when it turns by less than this (rad) over the samples
SAME_ORIENTATION = 1e-9


def radius_notes(solution: Any, verification: Verification) -> tuple[str, ...]:
    """status.txt's lines on the point pulleys of an exact design (none for a minimax one,
    none when it has no point pulley)."""
    problem: Problem = solution.problem
    if minimax_of(solution) is not None:
        return ()
    springs = [s for s in problem.springs if s.direct is None and s.pulley is not None and s.pulley.radius == 0.0 and s.subsystem is not None]
    if not springs:
        return ()
    scenario = problem.scenarios[0]
    gravity, base = solution.scenario_parameters[scenario.name]
    variables = solution.variable_values(scenario.name)
    tolerance = problem.settings.verify_tolerance
    out = []
    for s in springs:
        if problem.subsystem_loops(s.subsystem):  # type: ignore[arg-type]  # filtered above: a spring in a subsystem
            out.append(f"spring {s.name}: a point pulley; its radius's cost is not estimated on a closed loop")
            continue
        k = float(Mechanics(problem, base, variables, {c.name: c.home for c in problem.coordinates}, gravity).value(s.stiffness))
        if not k > 0:
            continue
        with np.errstate(invalid="ignore", divide="ignore"):  # an undefined plane is NaN, said below
            slope = _slope(problem, s, k, base, variables, gravity, verification)
            pin = _pin_frames(problem, s, base, variables, gravity)
        if math.isnan(slope):
            out.append(
                f"spring {s.name}: a point pulley; its radius's cost is not estimated: the pulley's plane is not defined "
                "(its lead, from the spring's 'from' point towards its 'to' point at home, lies along the pulley's axis, or the two meet); "
                "give pulley.axis and pulley.lead to estimate it (docs/build.md#pulleys)"
            )
            continue
        if slope > 0:
            largest = tolerance / slope
            text = (
                f"spring {s.name}: a point pulley; a pulley of radius r instead leaves about {slope * 1e-3:.3g} × r/mm of residual ratio "
                f"(to first order, its anchor set at best): within verify_tolerance {tolerance:.0e}, r ≤ {_length(largest)}"
            )
        else:
            text = f"spring {s.name}: a point pulley; a pulley of radius r adds no residual to first order"
        if pin:
            text += f"; a cable wrapped onto a pin of the pulley's radius on frame '{pin}', which keeps the pulley frame's orientation, is exact at any radius (pin = true)"
        out.append(text)
    return tuple(out)


def _length(metres: float) -> str:
    for scale, unit in ((1e-3, "mm"), (1e-6, "µm")):
        if metres >= scale:
            return f"{metres / scale:.3g} {unit}"
    return f"{metres / 1e-9:.3g} nm"


def _slope(problem: Problem, s: ZeroFreeLengthSpring, k: float, base: Any, variables: Any, gravity: Any, verification: Verification) -> float:
    """max over samples and coordinates of |k ∂[d (θ − c)]/∂q_j| / reference, at the best c."""
    from ..springs.workspace import SEED_OFFSET, sample

    coords = problem.subsystem_coordinates(s.subsystem)  # type: ignore[arg-type]  # a spring in a subsystem
    # the realisation limits' sample (same size and seed: one cached draw), its first SAMPLES rows
    q = sample(problem, base, problem.settings.verify_samples, problem.settings.seed + SEED_OFFSET)[s.subsystem][:SAMPLES]  # type: ignore[index]  # a spring in a subsystem
    point = replace(s, pulley=replace(s.pulley or Pulley(), radius=0.0))
    home = {c.name: c.home for c in problem.coordinates}
    g_rows, h_rows, scales = [], [], []
    for j, c in enumerate(coords):
        values: dict[str, Any] = {**home, **{x.name: q[:, i] for i, x in enumerate(coords)}}
        values[c.name] = q[:, j] + 1j * STEP
        mech = Mechanics(problem, base, variables, values, gravity)
        geometry = cable(mech, point)
        d = np.asarray(geometry.distance)
        wrap = np.asarray(geometry.wrap)
        g_rows.append(np.imag(d * wrap) / STEP)
        h_rows.append(np.imag(d) / STEP)
        kind = REVOLUTE if c.unit.dimension == "" else PRISMATIC
        reference = verification.reference(kind)
        scales.append(k / reference if reference > 0 else math.nan)
    g = np.array(g_rows) * np.array(scales)[:, None]
    h = np.array(h_rows) * np.array(scales)[:, None]
    finite = np.all(np.isfinite(g), axis=0) & np.all(np.isfinite(h), axis=0)  # a sample where the ends meet has no plane
    if not np.any(finite):
        return math.nan
    g, h = g[:, finite], h[:, finite]

    def worst(c: float) -> float:
        return float(np.max(np.abs(g - c * h)))

    lo, hi = -4 * math.pi, 4 * math.pi  # the wrap is in (0, 2π): the best constant lies within
    for _ in range(200):
        m1, m2 = lo + (hi - lo) / 3, hi - (hi - lo) / 3
        if worst(m1) < worst(m2):
            hi = m2
        else:
            lo = m1
    return worst((lo + hi) / 2)


def _pin_frames(problem: Problem, s: ZeroFreeLengthSpring, base: Any, variables: Any, gravity: Any) -> str | None:
    """The link point's own frame when it keeps the pulley frame's orientation over sampled
    configurations; else another frame that moves against the pulley's frame but keeps its
    orientation (the first in the file's order); None when there is none."""
    from ..springs.workspace import SEED_OFFSET, sample

    coords = problem.subsystem_coordinates(s.subsystem)  # type: ignore[arg-type]  # a spring in a subsystem
    q = sample(problem, base, problem.settings.verify_samples, problem.settings.seed + SEED_OFFSET)[s.subsystem][:200]  # type: ignore[index]  # a spring in a subsystem
    values: dict[str, Any] = {c.name: c.home for c in problem.coordinates}
    values.update({c.name: q[:, i] for i, c in enumerate(coords)})
    mech = Mechanics(problem, base, variables, values, gravity)
    pulley_frame = s.ends[0].frame
    ra, oa = mech.pose(pulley_frame)

    def relative(frame: str) -> tuple[np.ndarray, np.ndarray]:
        rb, ob = mech.pose(frame)
        rot = np.array([[np.broadcast_to(np.asarray(sum(np.asarray(ra[k][i]) * np.asarray(rb[k][j]) for k in range(3)), dtype=float), (len(q),)) for j in range(3)] for i in range(3)])
        shift = np.array([np.broadcast_to(np.asarray(ob[i], dtype=float) - np.asarray(oa[i], dtype=float), (len(q),)) for i in range(3)])
        return rot, shift

    rot, _ = relative(s.ends[1].frame)
    if float(np.max(np.abs(rot - rot[:, :, :1]))) <= SAME_ORIENTATION:
        return s.ends[1].frame  # the link point's own frame keeps the orientation: ``pin = true`` there
    for f in problem.frames:
        if f.name == pulley_frame:
            continue
        rot, shift = relative(f.name)
        if float(np.max(np.abs(rot - rot[:, :, :1]))) <= SAME_ORIENTATION and float(np.max(np.ptp(shift, axis=1))) > 1e-6:
            return f.name
    return None
