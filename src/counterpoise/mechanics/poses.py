"""World positions of everything a problem places, at one configuration.

Frame origins (with their rotations), bodies' centres of mass, counter-masses and spring
ends, through the same :class:`~counterpoise.mechanics.energy.Mechanics` the optimiser
uses. ``counterpoise frames`` prints them and ``counterpoise draw`` draws them: the check
a user runs after writing a problem file or importing a robot.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from ..model.mechanism import GROUND
from ..model.problem import Problem, Scenario
from .energy import Mechanics


@dataclass(frozen=True)
class Placed:
    """One placed thing: ``kind`` is frame, body, counter_mass or spring (one row per end)."""

    kind: str
    name: str
    frame: str
    position: tuple[float, float, float]  # world, SI
    subsystem: str | None
    mass: float = 0.0  # bodies and counter-masses (kg)
    force: float = 0.0  # springs: k |a - b| (N)
    rotation: tuple[tuple[float, ...], ...] = ()  # frames: world axes (columns)
    parent: str | None = None  # frames: parent frame


def default_values(problem: Problem) -> tuple[dict[str, float], dict[str, float]]:
    """Home configuration and initial design (SI)."""
    return {c.name: c.home for c in problem.coordinates}, {v.name: v.initial for v in problem.variables}


def mechanics(problem: Problem, coordinates: Mapping[str, float], variables: Mapping[str, float], scenario: Scenario | None = None) -> Mechanics:
    sc = scenario or problem.scenarios[0]
    gravity = [sc.gravity.acceleration * d for d in sc.gravity.direction]
    base = {p.name: sc.parameters.get(p.name, p.value) for p in problem.parameters if p.is_base}
    return Mechanics(problem, base, dict(variables), dict(coordinates), gravity)


def _f(v: object) -> float:
    return float(v)  # type: ignore[arg-type]  # a placed point is three floats


def place(problem: Problem, coordinates: Mapping[str, float], variables: Mapping[str, float], scenario: Scenario | None = None) -> list[Placed]:
    """Every frame origin, centre of mass, counter-mass and spring end, in world coordinates."""
    mech = mechanics(problem, coordinates, variables, scenario)
    out: list[Placed] = []
    for f in problem.frames:
        rot, origin = mech.pose(f.name)
        out.append(
            Placed("frame", f.name, f.name, tuple(_f(c) for c in origin), f.subsystem,  # type: ignore[arg-type]  # a placed point is three floats
                   rotation=tuple(tuple(_f(c) for c in row) for row in rot), parent=f.parent)
        )
    for b in problem.bodies:
        out.append(Placed("body", b.name, b.com.frame, tuple(_f(c) for c in mech.position(b.com)), b.subsystem, mass=_f(mech.value(b.mass))))  # type: ignore[arg-type]  # a placed point is three floats
    for c in problem.counter_masses:
        out.append(Placed("counter_mass", c.name, c.position.frame, tuple(_f(v) for v in mech.position(c.position)), c.subsystem, mass=_f(mech.value(c.mass))))  # type: ignore[arg-type]  # a placed point is three floats
    for s in problem.springs:
        ends = [tuple(_f(v) for v in mech.position(p)) for p in s.ends]
        length = math.dist(ends[0], ends[1])
        force = _f(mech.value(s.stiffness)) * length
        if s.direct is not None:  # a real spring through a cable: F0 + k (d - cable - L0)
            stretch = length - _f(mech.value(s.direct.cable)) - _f(mech.value(s.direct.free_length))
            force = _f(mech.value(s.direct.initial_tension)) + _f(mech.value(s.stiffness)) * stretch
        for label, p, end in zip(("from", "to"), s.ends, ends):
            out.append(Placed("spring", f"{s.name}.{label}", p.frame, end, s.subsystem, force=force))  # type: ignore[arg-type]  # a placed point is three floats
    return out


def ground_row() -> Placed:
    return Placed("frame", GROUND, GROUND, (0.0, 0.0, 0.0), None, rotation=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)))


def assembled(problem: Problem, coordinates: Mapping[str, float]) -> dict[str, float]:
    """``coordinates`` with every closed loop's dependent coordinates solved from its
    independent ones, on the home configuration's branch (:mod:`.closure`); a configuration
    that cannot be assembled raises ProblemFileError naming it."""
    out = dict(coordinates)
    subsystems = [sub for sub in problem.subsystems if problem.subsystem_loops(sub.name)]
    if not subsystems:
        return out
    import numpy as np

    from .closure import closure, scenario_base

    base = scenario_base(problem, problem.scenarios[0].name)
    for sub in subsystems:
        c = closure(problem, sub.name, base)
        q = c.solve(np.array([[out[c.names[i]] for i in c.independent]])).q[0]
        out.update({c.names[i]: float(q[i]) for i in c.dependent})
    return out

