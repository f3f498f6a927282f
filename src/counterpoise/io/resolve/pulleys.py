"""Pulleys of radius > 0 (docs/build.md#pulleys), once the problem is resolved.

- Ideal springs (``[settings] ideal_springs``) keep no slack margin: no realisation limit
  applies to them (the minimax designer's and the part search's margins included).

- A cable wrapped onto a pin (``pin = true``) makes the spring pull k·d exactly only while
  the pin's frame keeps the pulley frame's orientation: checked on sampled configurations
  of the workspace (on the configuration manifold for closed loops), at the variables'
  initial values. A pin on a frame that turns is an input error naming the key.
- A cable to a point over a pulley of radius r > 0 pulls k·(ℓ − ℓ*): ℓ* (where the spring's
  anchor is set) becomes a design variable of its own, ``<spring>.zero_length``.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from ...model.elements import ZeroFreeLengthSpring
from ...model.problem import Problem, Variable
from ...model.units import display_unit
from .context import Context

if TYPE_CHECKING:
    from ...mechanics import Mechanics

#: configurations on which a pin's frame is checked to keep the pulley frame's orientation
PIN_SAMPLES = 64
#: the largest turn (rad) of the pin's frame against the pulley's that counts as none
PIN_TURN_TOLERANCE = 1e-9
#: the suffix of the zero-force length's variable
ZERO_LENGTH = "zero_length"


def finish(ctx: Context, problem: Problem) -> Problem:
    """``problem`` with each pin checked and a zero-force length variable per cable to a point
    over a pulley of radius > 0 (a problem without such pulleys is returned as it is)."""
    if problem.settings.ideal_springs and any(s.slack_margin for s in problem.springs):
        # ideal springs (a paper's idealised design): no realisation limit, no slack margin either
        problem = replace(problem, springs=tuple(replace(s, slack_margin=0.0) for s in problem.springs))
    springs = [s for s in problem.springs if s.pulley is not None and s.pulley.radius > 0.0]
    if not springs:
        return problem
    for s in springs:
        if s.pulley is not None and s.pulley.pin:
            turn = relative_turn(problem, s)
            if turn > PIN_TURN_TOLERANCE:
                raise ctx.fail(
                    f"springs.{s.name}.pulley.pin",
                    f"frame '{s.ends[1].frame}' turns by up to {math.degrees(turn):.3g} deg against frame '{s.ends[0].frame}' over the "
                    "workspace: a cable wrapped onto a pin pulls k·d only when the pin's frame keeps the pulley frame's orientation "
                    "(a parallelogram's coupler, a slide); attach the pin to such a frame, or set pin = false",
                )
    for s in springs:
        key = f"springs.{s.name}.pulley.radius"
        if s.pulley is not None and not s.pulley.pin:
            if s.slot is not None:
                raise ctx.fail(key, "not combinable: a catalogue part behind a pulley of radius > 0 needs the cable wrapped onto a pin (pin = true), "
                               "or a point pulley (radius 0): the part search balances exactly")
            if problem.robust is not None:
                raise ctx.fail(key, "not combinable with [robust]: a pulley of radius > 0 without a pin has no exact worst case; "
                               "wrap the cable onto a pin (pin = true) or use a point pulley")
    variables = list(problem.variables)
    out = []
    for s in problem.springs:
        p = s.pulley
        if p is not None and p.radius > 0.0 and not p.pin:
            name = f"{s.name}.{ZERO_LENGTH}"
            scale = max(home_distance(problem, s) + 2 * math.pi * p.radius, 10 * p.radius)
            variables.append(
                Variable(
                    name,
                    -3.0 * scale,
                    scale,
                    min(math.pi * p.radius, scale),
                    display_unit("mm"),
                    description=f"spring {s.name}: the cable length over its pulley at which it would pull nothing (sets its anchor)",
                )
            )
            s = replace(s, pulley=replace(p, zero_length=name))
        out.append(s)
    return replace(problem, variables=tuple(variables), springs=tuple(out))


def _mechanics(problem: Problem, coordinates: dict[str, np.ndarray | float]) -> "Mechanics":
    from ...mechanics import Mechanics

    base = {p.name: float(p.value) for p in problem.base_parameters if p.value is not None}
    base.update({k: float(v) for k, v in problem.scenarios[0].parameters.items()})
    variables = {v.name: v.initial for v in problem.variables}
    gravity = problem.scenarios[0].gravity.vector
    return Mechanics(problem, base, variables, coordinates, gravity)


def _workspace(problem: Problem, subsystem: str | None) -> dict[str, np.ndarray | float]:
    """Coordinates of sampled configurations of ``subsystem`` (homes elsewhere)."""
    out: dict[str, np.ndarray | float] = {c.name: c.home for c in problem.coordinates}
    if subsystem is None:
        return out
    rng = np.random.default_rng(problem.settings.seed)
    coords = problem.subsystem_coordinates(subsystem)
    if problem.subsystem_loops(subsystem):
        from ...mechanics.closure import manifold_configurations, scenario_base

        q = manifold_configurations(problem, subsystem, PIN_SAMPLES, rng, scenario_base(problem, problem.scenarios[0].name)).q
    else:
        from ...mechanics.sampling import configurations

        q = configurations(problem, subsystem, PIN_SAMPLES, rng)
    out.update({c.name: q[:, i] for i, c in enumerate(coords)})
    return out


def relative_turn(problem: Problem, spring: ZeroFreeLengthSpring) -> float:
    """The largest angle (rad) by which the ``to`` frame of ``spring`` turns against its
    ``from`` frame over sampled configurations, from their relative orientation at home."""
    a, b = spring.ends
    coordinates = _workspace(problem, spring.subsystem)
    n = max((np.size(v) for v in coordinates.values()), default=1)
    moving = _stacked(_relative(_mechanics(problem, coordinates), a.frame, b.frame), n)
    fixed = _stacked(_relative(_mechanics(problem, {c.name: c.home for c in problem.coordinates}), a.frame, b.frame), n)
    # the angle θ between the two orientations: |R − R_home|_F = 2√2 sin(θ/2) (accurate
    # near 0, where the arccos of the trace is not)
    distance = np.sqrt(np.sum((moving - fixed) ** 2, axis=(0, 1)))
    return float(np.max(2.0 * np.arcsin(np.clip(distance / (2.0 * np.sqrt(2.0)), 0.0, 1.0))))


def _stacked(matrix: list[list[object]], n: int) -> np.ndarray:
    """A 3×3 nested list of scalars or arrays as a (3, 3, n) array."""
    return np.array([[np.broadcast_to(np.asarray(v, dtype=float).reshape(-1), (n,)) for v in row] for row in matrix])


def _relative(mech: "Mechanics", frame_a: str, frame_b: str) -> list[list[object]]:
    """R_a^T R_b (3×3 nested lists of arrays)."""
    ra = mech.pose(frame_a)[0]
    rb = mech.pose(frame_b)[0]
    return [[sum(np.asarray(ra[k][i]) * np.asarray(rb[k][j]) for k in range(3)) for j in range(3)] for i in range(3)]


def home_distance(problem: Problem, spring: ZeroFreeLengthSpring) -> float:
    """|from − to| at home with the variables' initial values."""
    mech = _mechanics(problem, {c.name: c.home for c in problem.coordinates})
    a, b = (np.asarray(mech.position(p), dtype=float) for p in spring.ends)
    return float(np.linalg.norm(a - b))
