"""The realisation limits of a design's springs over its whole workspace (docs/build.md#realisation-limits).

A spring behind a pulley pulls as the design model says only while it is built so that

- **clearance**: the link point (or its pin) never comes within the pulley's radius plus
  its ``clearance`` of the pulley's axis (a pin: twice the radius plus the clearance);
- **slack**: the spring stays stretched beyond its free length by ``slack_margin``
  everywhere: F_min − k·margin ≥ F0 (its initial tension), for a point pulley
  d_min ≥ F0/k + margin. Attached directly: d − cable − L0 ≥ margin;
- **wrap**: over a pulley or pin of radius > 0 the cable stays wrapped, by
  :data:`~counterpoise.model.elements.MIN_WRAP` at least and a full turn less that much at
  most;
- **plane**: over a pulley of radius > 0 the link point stays in the pulley's plane;
- **spring**: a designed spring can be wound within the rules (windable initial tension,
  strength at the upper end of its rate tolerance, envelope); a catalogue part stays within
  its own limits (checked by the part search, :mod:`counterpoise.selection`).

:func:`evaluate` measures every limit on the dense sample of the workspace (the sample the
designed springs and catalogue parts are checked on) and returns :class:`Limit` values:
the worst value of each, the bound it must keep, and where the worst is.
:func:`constraints` turns the violated limits that the design itself can move into design
constraints (:class:`~counterpoise.model.constraints.Constraint`, kind ``realisation``),
which :class:`~counterpoise.realisation.method.RealisationMethod` adds before solving again.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..mechanics import Mechanics
from ..mechanics.cable import cable, spring_quantities
from ..model import expr as ex
from ..model.constraints import REALISATION, Constraint
from ..model.elements import MIN_WRAP, ZeroFreeLengthSpring
from ..model.problem import Problem
from ..model.units import display_unit
from ..designer.solution import Solution
from ..payload.result import PayloadDesign
from ..robust.result import RobustReport
from ..springs.design import NEGLIGIBLE_FORCE
from ..verify.residuals import RememberingFunctions

#: a limit counts as met when it misses its bound by less than this share of the bound's
#: (or the value's) size, plus ABSOLUTE (SI: m, N, rad): rounding, and the same extreme
#: found on another draw of the same sample
TOLERANCE = 1e-7
ABSOLUTE = 1e-12
#: the link point counts as in the pulley's plane within this distance (m)
PLANE_TOLERANCE = 1e-6
#: a slack constraint asks this share more than the initial tension it must reach
SLACK_HEADROOM = 1e-3
#: the quantities measured per spring
QUANTITIES = ("force", "length", "path", "wrap", "plane")

LIMIT_TEXT = {
    "clearance": "the link point comes too close to the pulley",
    "slack": "the spring goes slack",
    "wrap": "the cable leaves the pulley",
    "plane": "the link point leaves the pulley's plane",
    "spring": "the spring cannot be made",
}


@dataclass(frozen=True)
class Limit:
    """One realisation limit of one spring: its worst ``value`` over the workspace (SI),
    the ``bound`` it must keep (``side`` lower: value ≥ bound; upper: value ≤ bound)."""

    spring: str
    kind: str  # a key of LIMIT_TEXT
    value: float
    bound: float
    side: str
    unit: str  # the display unit of value and bound: "mm", "N", "deg"
    scenario: str = ""
    configuration: Mapping[str, float] | None = None
    detail: str = ""  # what the bound is made of, or why a spring cannot be made

    @property
    def margin(self) -> float:
        """How far inside its bound the value is (SI; < 0: violated; NaN: not measured)."""
        return self.value - self.bound if self.side == "lower" else self.bound - self.value

    @property
    def met(self) -> bool:
        if self.kind == "spring":  # a spring that cannot be made, or not as the design needs it
            return False
        size = max(abs(self.bound), abs(self.value)) if math.isfinite(self.value) else abs(self.bound)
        return not self.margin < -(TOLERANCE * size + ABSOLUTE)  # NaN (unknown) counts as met

    def text(self, problem: Problem | None = None) -> str:
        """'spring lower: the spring goes slack: force margin 2.1 N below its initial tension 3 N (at q=40 deg)'."""
        scale, label = _display(self.unit)
        if self.kind == "spring":
            head = f"spring {self.spring}: {LIMIT_TEXT[self.kind]}: {self.detail}"
        else:
            relation = "≥" if self.side == "lower" else "≤"
            head = (
                f"spring {self.spring}: {LIMIT_TEXT[self.kind]}: {self.value * scale:.4g} {label} where it must be "
                f"{relation} {self.bound * scale:.4g} {label}" + (f" ({self.detail})" if self.detail else "")
            )
        return head + _where(problem, self.configuration, self.scenario)


def _display(unit: str) -> tuple[float, str]:
    return {"mm": (1e3, "mm"), "deg": (180.0 / math.pi, "deg")}.get(unit, (1.0, unit))


def _where(problem: Problem | None, configuration: Mapping[str, float] | None, scenario: str) -> str:
    parts = []
    if configuration:
        if problem is not None:
            parts.append(", ".join(f"{n}={problem.coordinate[n].unit.from_si(x):.4g} {problem.coordinate[n].unit.label}".rstrip() for n, x in configuration.items()))
        else:
            parts.append(", ".join(f"{n}={x:.4g}" for n, x in configuration.items()))
    text = f" at {parts[0]}" if parts else ""
    if problem is not None and scenario and len(problem.scenarios) > 1:
        text += f" in scenario '{scenario}'"
    return text


@dataclass(frozen=True)
class Extreme:
    """A quantity's least and greatest value over the workspace, and where (coordinates)."""

    low: float
    high: float
    at_low: Mapping[str, float]
    at_high: Mapping[str, float]


def checked_solution(solution: Solution) -> Solution:
    """The solution the limits are measured on: a payload design's schedule (every payload
    it sets), else the solution itself."""
    outcome = solution.extra(PayloadDesign)
    if outcome is not None and outcome.schedule is not None:
        return outcome.schedule_solution()
    return solution


def tuned_envelope(solution: Solution) -> Mapping[str, Any]:
    """Per spring: the forces and distances it must serve at every tuned corner of a [robust]
    design with ``tune`` (:mod:`counterpoise.robust.limits`); empty otherwise."""
    report = solution.extra(RobustReport)
    return report.envelope if report is not None else {}


def extremes(solution: Any) -> dict[tuple[str, str], dict[str, Extreme]]:
    """Per (spring, scenario): the extremes of its quantities (:data:`QUANTITIES`) over the
    dense sample of its subsystem's workspace (:func:`counterpoise.springs.workspace.sample`)."""
    from ..springs.workspace import SEED_OFFSET, sample

    checked = checked_solution(solution)
    problem: Problem = checked.problem
    settings = problem.settings
    out: dict[tuple[str, str], dict[str, Extreme]] = {}
    drawn: dict[tuple[tuple[str, float], ...], Mapping[str, np.ndarray]] = {}
    # per sample and subsystem: the coordinates' arrays, the same objects for every scenario,
    # so that the functions remember their sin and cos (a payload range's scenarios share them)
    columns: dict[tuple[tuple[tuple[str, float], ...], str | None], tuple[list[str], np.ndarray, dict[str, Any]]] = {}
    functions = RememberingFunctions()
    for scenario in problem.scenarios:
        gravity, base = checked.scenario_parameters[scenario.name]
        key = tuple(sorted(base.items())) if problem.loops else ()
        if key not in drawn:
            drawn[key] = sample(problem, base, settings.verify_samples, settings.seed + SEED_OFFSET)
        q = drawn[key]
        variables = checked.variable_values(scenario.name)
        # one mechanics per subsystem: its springs share the sample and the frames' poses
        mechanics: dict[str | None, Mechanics] = {}
        for s in problem.springs:
            if (key, s.subsystem) not in columns:
                names = [c.name for c in problem.subsystem_coordinates(s.subsystem)] if s.subsystem is not None else []
                coords: dict[str, Any] = {c.name: c.home for c in problem.coordinates}
                rows = q[s.subsystem] if s.subsystem is not None else np.zeros((1, 0))
                coords.update({n: np.ascontiguousarray(rows[:, i]) for i, n in enumerate(names)})
                columns[(key, s.subsystem)] = (names, rows, coords)
            names, rows, coords = columns[(key, s.subsystem)]
            if s.subsystem not in mechanics:
                mechanics[s.subsystem] = Mechanics(problem, base, variables, coords, gravity, functions=functions)
            mech = mechanics[s.subsystem]
            values = {k: np.broadcast_to(np.asarray(v, dtype=float), (rows.shape[0],)) for k, v in spring_quantities(mech, s).items()}
            if s.pulley is not None and s.direct is None and s.pulley.radius > 0.0:
                c = cable(mech, s)
                values["plane"] = np.broadcast_to(np.abs(np.asarray(c.off_plane, dtype=float)), (rows.shape[0],))
                if c.pin_wrap is not None:  # the pin's wrap: the least of both wraps counts
                    pin = np.broadcast_to(np.asarray(c.pin_wrap, dtype=float), (rows.shape[0],))
                    values["wrap"] = np.minimum(values["wrap"], pin)
                    values["wrap_high"] = np.maximum(np.broadcast_to(np.asarray(c.wrap, dtype=float), (rows.shape[0],)), pin)
            else:
                values["plane"] = np.zeros(rows.shape[0])
            found = {}
            for name in QUANTITIES:
                low_values = values[name]
                high_values = values.get(f"{name}_high", low_values)
                i, j = int(np.nanargmin(low_values)), int(np.nanargmax(high_values))
                found[name] = Extreme(float(low_values[i]), float(high_values[j]), _configuration(names, rows, i), _configuration(names, rows, j))
            out[(s.name, scenario.name)] = found
    return out


def _configuration(names: Sequence[str], rows: np.ndarray, i: int) -> dict[str, float]:
    return {n: float(rows[i, c]) for c, n in enumerate(names)}


def evaluate(solution: Any, designed: Sequence[Any] = (), parts: Any = None, found: Mapping[tuple[str, str], Mapping[str, Extreme]] | None = None) -> tuple[Limit, ...]:
    """Every realisation limit of ``solution``'s springs (see the module docstring): the worst
    value of each over every scenario. ``designed``: the designed springs
    (:class:`~counterpoise.springs.workspace.DesignedSpring`, their initial tension and
    whether they can be wound); ``parts``: the chosen catalogue parts
    (:class:`~counterpoise.selection.parts.PartsReport`)."""
    problem: Problem = checked_solution(solution).problem
    found = extremes(solution) if found is None else found
    designs = {d.spring: d for d in designed if d.scenario == "all"}
    designs.update({d.spring: d for d in designed if d.spring not in designs})
    uses = {u.spring: u for u in parts.springs} if parts is not None else {}
    out: list[Limit] = []
    for s in problem.springs:
        mine = {scenario: v for (name, scenario), v in found.items() if name == s.name}
        if not mine:
            continue
        out += _spring_limits(problem, s, mine, designs.get(s.name), uses.get(s.name), solution)
    return tuple(out)


def _worst(mine: Mapping[str, Mapping[str, Extreme]], quantity: str, side: str) -> tuple[float, str, Mapping[str, float]]:
    """The least (side 'low') or greatest value of ``quantity`` over the scenarios."""
    best: tuple[float, str, Mapping[str, float]] | None = None
    for scenario, values in mine.items():
        e = values[quantity]
        v, at = (e.low, e.at_low) if side == "low" else (e.high, e.at_high)
        if best is None or (v < best[0] if side == "low" else v > best[0]):
            best = (v, scenario, at)
    if best is None:
        raise ValueError("no scenario measured")
    return best


def _spring_limits(problem: Problem, s: ZeroFreeLengthSpring, mine: Mapping[str, Mapping[str, Extreme]], design: Any, use: Any, solution: Any) -> list[Limit]:
    out: list[Limit] = []
    p = s.pulley
    margin = s.slack_margin
    f_max, _, _ = _worst(mine, "force", "high")
    if not _rate(problem, s, solution, next(iter(mine))) > 0.0 or abs(f_max) < NEGLIGIBLE_FORCE:
        return out  # stiffness 0 (to rounding): the design leaves the spring out, nothing is built
    if s.direct is not None:
        d_min, scenario, at = _worst(mine, "length", "low")
        cable_length, free = _direct_lengths(problem, s, solution, scenario)
        out.append(Limit(s.name, "slack", d_min - cable_length - free, margin, "lower", "mm", scenario, at,
                         f"extension beyond the free length {free * 1e3:.4g} mm, through a {cable_length * 1e3:.4g} mm cable, of at least slack_margin"))
    elif p is not None:
        d_min, scenario, at = _worst(mine, "length", "low")
        reach = p.clearance + (2.0 if p.pin else 1.0) * p.radius
        what = f"pin and pulley of radius {p.radius * 1e3:.4g} mm" if p.pin else f"pulley radius {p.radius * 1e3:.4g} mm"
        out.append(Limit(s.name, "clearance", d_min, reach, "lower", "mm", scenario, at, f"{what} + clearance {p.clearance * 1e3:.4g} mm"))
        f0 = _initial_tension(design, use)
        if f0 is not None:
            f_min, scenario, at = _worst(mine, "force", "low")
            k = _rate(problem, s, solution, scenario)
            # the spring as made: a designed spring pulls at its wound rate (the design's rate
            # until the design is solved again for it)
            wound = float(design.design.rate) if design is not None and design.ok else k
            pull = f_min * wound / k if k > 0 else f_min
            out.append(Limit(s.name, "slack", pull - wound * margin, f0, "lower", "N", scenario, at,
                             f"its least pull less k × slack_margin {margin * 1e3:.4g} mm must reach its initial tension"))
        if p.radius > 0.0:
            w_min, scenario, at = _worst(mine, "wrap", "low")
            out.append(Limit(s.name, "wrap", w_min, MIN_WRAP, "lower", "deg", scenario, at, "least wrap on the pulley" + (" and the pin" if p.pin else "")))
            w_max, scenario, at = _worst(mine, "wrap", "high")
            out.append(Limit(s.name, "wrap", w_max, 2 * math.pi - MIN_WRAP, "upper", "deg", scenario, at, "a full turn less the least wrap"))
            off, scenario, at = _worst(mine, "plane", "high")
            out.append(Limit(s.name, "plane", off, PLANE_TOLERANCE, "upper", "mm", scenario, at, "distance of the link point from the pulley's plane; give the pulley's axis"))
    if design is not None and not design.ok:
        out.append(Limit(s.name, "spring", float("nan"), float("nan"), "lower", "", design.scenario, None, "; ".join(design.design.reasons)))
    elif design is None and use is not None and not use.fits:
        out.append(Limit(s.name, "spring", float("nan"), float("nan"), "lower", "", use.scenario, None, f"part {use.part_number} is used beyond its limits"))
    return out


def _initial_tension(design: Any, use: Any) -> float | None:
    """The initial tension of a designed spring (the one it needs when it cannot keep the
    cable taut) or of a catalogue part; None when not known."""
    if use is not None:
        return float(use.initial_tension)
    if design is None:
        return None
    made = design.design
    if not made.ok and math.isfinite(made.needed_distance):
        # refused for slack alone: the smallest windable F0 of a spring that keeps every
        # other rule, needed_distance = F0/k + margin (its rate: the design rate here)
        need = made.requirement
        return float(need.rate * (made.needed_distance - need.slack_margin))
    f0 = float(made.initial_tension)
    return None if math.isnan(f0) else f0


def _values(problem: Problem, solution: Any, scenario: str) -> Mechanics:
    checked = checked_solution(solution)
    gravity, base = checked.scenario_parameters[scenario]
    return Mechanics(problem, base, checked.variable_values(scenario), {c.name: c.home for c in problem.coordinates}, gravity)


def _rate(problem: Problem, s: ZeroFreeLengthSpring, solution: Any, scenario: str) -> float:
    return float(_values(problem, solution, scenario).value(s.stiffness))


def _direct_lengths(problem: Problem, s: ZeroFreeLengthSpring, solution: Any, scenario: str) -> tuple[float, float]:
    mech = _values(problem, solution, scenario)
    m = s.direct
    if m is None:
        raise ValueError(f"spring {s.name} is not attached directly")
    return float(mech.value(m.cable)), float(mech.value(m.free_length))


def constraints(problem: Problem, limits: Sequence[Limit]) -> tuple[Constraint, ...]:
    """Design constraints that keep the violated limits the design can move (clearance,
    slack, wrap), tightened to what the limit needs; the problem's own constraints of the
    same name are replaced (a later round needs more)."""
    springs = {s.name: s for s in problem.springs}
    out: dict[str, Constraint] = {}
    for lim in limits:
        if lim.met or lim.kind not in ("clearance", "slack", "wrap"):
            continue
        s = springs[lim.spring]
        me = ex.Name(s.name)
        if lim.kind == "clearance":
            out[f"{s.name}.clearance"] = Constraint(f"{s.name}.clearance", ex.Call("length_min", (me,)), lim.bound, None, display_unit("mm"),
                                                  f"spring {s.name}: the link point clear of the pulley ({lim.detail})", REALISATION, s.name)
        elif lim.kind == "slack" and s.direct is not None:
            m = s.direct
            expr = ex.BinOp("-", ex.BinOp("-", ex.Call("length_min", (me,)), m.cable), m.free_length)
            out[f"{s.name}.slack"] = Constraint(f"{s.name}.slack", expr, lim.bound, None, display_unit("mm"),
                                              f"spring {s.name}: stretched at least slack_margin beyond its free length", REALISATION, s.name)
        elif lim.kind == "slack":
            expr = ex.BinOp("-", ex.Call("force_min", (me,)), ex.BinOp("*", s.stiffness, ex.Num(s.slack_margin)))
            old = next((c for c in problem.constraints if c.name == f"{s.name}.slack"), None)
            # a little headroom: the design then keeps the limit at the wound rate too, and
            # a spring chosen at the edge of its band is still windable
            bound = lim.bound * (1.0 + SLACK_HEADROOM)
            bound = max(bound, old.lower or 0.0) if old is not None else bound
            out[f"{s.name}.slack"] = Constraint(f"{s.name}.slack", expr, bound, None, display_unit("N"),
                                              f"spring {s.name}: its least pull less k × slack_margin reaches its initial tension", REALISATION, s.name)
        elif lim.side == "lower":
            out[f"{s.name}.wrap_min"] = Constraint(f"{s.name}.wrap_min", ex.Call("wrap_min", (me,)), lim.bound, None, display_unit("deg"),
                                                 f"spring {s.name}: the cable stays wrapped on its pulley", REALISATION, s.name)
        else:
            out[f"{s.name}.wrap_max"] = Constraint(f"{s.name}.wrap_max", ex.Call("wrap_max", (me,)), None, lim.bound, display_unit("deg"),
                                                 f"spring {s.name}: the cable wraps less than a full turn", REALISATION, s.name)
    return tuple(out.values())
