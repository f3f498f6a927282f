"""Tolerances as parameters: the problem whose residual is affine in every deviation.

Each toleranced quantity gets a literal parameter δ (nominal value 0) that no file can
name (``robust:<kind>:<item>[:<component>]``), written into the element's expression tree:

- a rate:       k → k·(1 + δ)   (relative)  or  k + δ   (absolute, N/m);
- a body mass:  m → m·(1 + δ)               or  m + δ   (kg);
- a centre of mass component (body frame):  c_x → c_x + δ   (m);
- a spring end component (its frame):       a_x → a_x + δ   (m), both ends.

The energy Σ −m g·p + Σ ½ k |a − b|² is then affine in every single δ (a mass or a rate
multiplies fixed geometry; a centre of mass enters −m g·R(c + δ) linearly; one end of a
spring enters ½ k |a + Rδ − b|², whose term ½ k |δ|² does not depend on the configuration).
Products of deviations of one element (δm·δc of one body, δa·δb of one spring's two ends,
δk·δa) keep the residual multi-affine: :mod:`.affine` evaluates each such element's group
at every vertex of its box, so the worst case over the box is exact (docs/robust.md). An
initial tension ΔF0 behind a pulley is not a parameter here: it adds the force ΔF0 along
the cable, ΔF0·∂d/∂q, which :mod:`.affine` adds directly; a directly attached spring's is
(its force F0 + ΔF0 + k x: affine in ΔF0). A point of a directly attached spring enters
its length |a + δ − b| nonlinearly (:func:`nonaffine`): the worst case is then taken over the
box's corners, not exact.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from ..model import expr as ex
from ..model.mechanism import Point
from ..model.problem import Parameter, Problem
from ..model.robust import Tolerance
from ..model.units import display_unit

PREFIX = "robust"
AXES = "xyz"


@dataclass(frozen=True)
class Deviation:
    """One deviation parameter: ``parameter`` ranges over [−half_width, +half_width]."""

    parameter: str
    tolerance: Tolerance
    component: str  # "" or x/y/z (a centre of mass, a spring end "from.x")
    half_width: float

    @property
    def label(self) -> str:
        t = self.tolerance
        return f"{t.kind} {t.item}" + (f" {self.component}" if self.component else "")


def _name(*parts: str) -> str:
    return ":".join((PREFIX, *parts))


def _scaled(tree: ex.Expr, name: str, relative: bool) -> ex.Expr:
    delta = ex.Name(name)
    return ex.BinOp("*", tree, ex.BinOp("+", ex.Num(1.0), delta)) if relative else ex.BinOp("+", tree, delta)


def _shifted(point: Point, names: tuple[str, str, str]) -> Point:
    return Point(point.frame, tuple(ex.BinOp("+", c, ex.Name(n)) for c, n in zip(point.position, names)))  # type: ignore[arg-type]  # a point of three coordinates stays one


def perturbed(problem: Problem) -> tuple[Problem, tuple[Deviation, ...]]:
    """``problem`` with one zero-valued deviation parameter per toleranced quantity (rates,
    masses, centres of mass, spring ends, a directly attached spring's initial tension; not a
    pulley spring's initial tension), and those deviations."""
    spec = problem.robust
    if spec is None:
        return problem, ()
    deviations: list[Deviation] = []
    bodies = {b.name: b for b in problem.bodies}
    masses = {c.name: c for c in problem.counter_masses}
    springs = {s.name: s for s in problem.springs}
    for t in spec.tolerances:
        if t.amount == 0:
            continue
        if t.kind == "initial_tension":
            mount = springs[t.item].direct
            if mount is None:
                continue  # behind a pulley: a constant force along the cable (affine.Decomposition)
            name = _name("initial_tension", t.item)
            springs[t.item] = replace(springs[t.item], direct=replace(mount, initial_tension=_scaled(mount.initial_tension, name, False)))
            deviations.append(Deviation(name, t, "", t.amount))
            continue
        if t.kind == "rate":
            name = _name("rate", t.item)
            springs[t.item] = replace(springs[t.item], stiffness=_scaled(springs[t.item].stiffness, name, t.relative))
            deviations.append(Deviation(name, t, "", t.amount))
        elif t.kind == "mass":
            name = _name("mass", t.item)
            if t.item in masses:  # a counter-mass: its (designed) mass as made
                masses[t.item] = replace(masses[t.item], mass=_scaled(masses[t.item].mass, name, t.relative))
            else:
                bodies[t.item] = replace(bodies[t.item], mass=_scaled(bodies[t.item].mass, name, t.relative))
            deviations.append(Deviation(name, t, "", t.amount))
        elif t.kind == "com":
            names = tuple(_name("com", t.item, a) for a in AXES)
            if t.item in masses:  # a counter-mass: where its centre of mass sits on the link
                masses[t.item] = replace(masses[t.item], position=_shifted(masses[t.item].position, names))  # type: ignore[arg-type]  # a point of three coordinates stays one
            else:
                bodies[t.item] = replace(bodies[t.item], com=_shifted(bodies[t.item].com, names))  # type: ignore[arg-type]  # a point of three coordinates stays one
            deviations += [Deviation(n, t, a, t.amount) for n, a in zip(names, AXES)]
        elif t.kind == "point":
            spring = springs[t.item]
            ends = []
            for end, point in zip(("from", "to"), spring.ends):
                names = tuple(_name("point", t.item, end, a) for a in AXES)
                ends.append(_shifted(point, names))  # type: ignore[arg-type]  # a point of three coordinates stays one
                deviations += [Deviation(n, t, f"{end}.{a}", t.amount) for n, a in zip(names, AXES)]
            springs[t.item] = replace(spring, ends=(ends[0], ends[1]))
    unit = display_unit("")
    extra = tuple(Parameter(d.parameter, unit, value=0.0, description=f"deviation of {d.label}") for d in deviations)
    out = replace(
        problem,
        parameters=problem.parameters + extra,
        bodies=tuple(bodies[b.name] for b in problem.bodies),
        counter_masses=tuple(masses[c.name] for c in problem.counter_masses),
        springs=tuple(springs[s.name] for s in problem.springs),
    )
    return out, tuple(deviations)


def nonaffine(problem: Problem, deviations: tuple[Deviation, ...]) -> tuple[str, ...]:
    """The deviations (their labels) the residual is not affine in: a point of a directly
    attached spring: its length |a + δ − b| enters the force F0 + k (|a + δ − b| − c − L0)
    along the unit vector (a + δ − b)/|a + δ − b|, not through ½ k |a + δ − b|². Every other
    deviation enters affinely (a rate or an initial tension multiplies or adds to fixed
    geometry, a mass and a centre of mass enter −m g·p)."""
    direct = {s.name for s in problem.springs if s.direct is not None}
    return tuple(d.label for d in deviations if d.tolerance.kind == "point" and d.tolerance.item in direct)


def corner_name(scenario: str, signs: tuple[int, ...]) -> str:
    """``corner_pm0``: p for +h, m for −h, 0 for nominal, per deviation in order (a name
    name); ``<scenario>_corner_...`` when a scenario is named."""
    body = "".join("p" if s > 0 else "m" if s < 0 else "0" for s in signs)
    return f"{scenario}_corner_{body}" if scenario else f"corner_{body}"


def corner_text(deviations: tuple[Deviation, ...], signs: tuple[int, ...]) -> str:
    parts = []
    for d, s in zip(deviations, signs):
        if s == 0:
            continue
        t = d.tolerance
        amount = f"{100 * t.amount:g} %" if t.relative else _absolute(t.kind, t.amount)
        parts.append(f"{d.label} {'+' if s > 0 else '-'}{amount}")
    return ", ".join(parts) or "nominal"


def _absolute(kind: str, amount: float) -> str:
    """An absolute tolerance in the unit people write it in (mm, N, N/m, g)."""
    if kind in ("com", "point"):
        return f"{amount * 1e3:g} mm"
    if kind == "initial_tension":
        return f"{amount:g} N"
    if kind == "rate":
        return f"{amount:g} N/m"
    return f"{amount * 1e3:g} g"
