"""Parameters, variables, gravity, scenarios and the objective."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

import numpy as np

from ...errors import InputError, ProblemFileError, UnitError
from ...model import expr as ex
from ...model.mechanism import Rotation
from ...model.problem import Gravity, Objective, Parameter, Scenario, Variable
from ...model.tilt import FULL_TURN, MAX_SCENARIOS, Tilt, angle_name, tilt_nodes, tilt_text, tilted
from ...model.units import (
    ACCELERATION,
    COMPLIANCE_MASS,
    INVERSE_AREA,
    DisplayUnit,
    Quantity,
    base_unit_symbol,
    check_dimension,
    dimension_name,
    dimensionality_of,
    angle_hint,
    display_unit,
    is_angle_unit,
    looks_like_quantity,
    parse_quantity,
    pint_quantity,
    ureg,
)
from .context import Context, evaluate_checked, numpy_functions, read_quantity, suggest, topological

DEFAULT_SCENARIO = "nominal"


def parameters(ctx: Context) -> tuple[Parameter, ...]:
    entries = ctx.spec.parameters
    raw_values = {n: (e.value if hasattr(e, "value") else e) for n, e in entries.items()}
    descriptions = {n: getattr(e, "description", "") for n, e in entries.items()}
    literal: dict[str, Quantity] = {}
    derived: dict[str, ex.Expr] = {}
    for name, raw in raw_values.items():
        key = f"parameters.{name}"
        with ctx.item():  # every bad parameter is reported
            if isinstance(raw, str) and not _is_literal(raw):
                derived[name] = ctx.expression(raw, key, entries.keys())
            else:
                literal[name] = ctx.literal(raw, key)
                ctx.symbol_unit[name] = literal[name].unit
                ctx.symbol_value[name] = literal[name].si
    ctx.check()
    order = topological(derived, lambda n: ex.names(derived[n]) & derived.keys(), "parameters", ctx.label)
    out: list[Parameter] = [Parameter(n, q.unit, value=q.si, description=descriptions[n]) for n, q in literal.items()]
    for name in order:
        key = f"parameters.{name}"
        tree = derived[name]
        env = {n: pint_quantity(ctx.symbol_value[n], ctx.symbol_unit[n]) for n in ex.names(tree) if n in ctx.symbol_value}  # not pi
        with ctx.at(key):
            value = evaluate_checked(tree, env, numpy_functions(), raw_values[name])
        value = value if isinstance(value, ureg().Quantity) else ureg().Quantity(value, "")
        si = float(value.to_base_units().magnitude)
        if not math.isfinite(si):
            raise ctx.fail(key, f"'{raw_values[name]}' does not evaluate to a finite number")
        unit = DisplayUnit(base_unit_symbol(value), 1.0, dimensionality_of(value.to_base_units()))
        ctx.name_kinds[name] = ctx.angle_kind(tree, raw_values[name], key)
        ctx.symbol_unit[name] = unit
        ctx.symbol_value[name] = si
        out.append(Parameter(name, unit, expr=tree, description=descriptions[name]))
    ctx.derived_parameters = [p for p in out if not p.is_base]
    return tuple(out)


def _is_literal(raw: str) -> bool:
    """'135 mm' is a literal; '90 deg - 5 deg' and 'r_a + 1' are expressions."""
    if not looks_like_quantity(raw):
        return False
    try:
        parse_quantity(raw)
    except UnitError:
        try:
            ex.parse(raw, ex.MATH_FUNCTIONS, read_quantity)
        except InputError:
            return True  # not an expression either: the literal's error is the one to report
        return False
    return True


def angle(ctx: Context, value: Any, key: str) -> float:
    """An angle literal ('90 deg', '1.5708 rad', or 0), in radians.

    A bare number other than 0 is an error that says how to write it (for locked joints
    and anything else that must be an angle).
    """
    q = ctx.literal(value, key)
    if q.unit.symbol == "" and q.unit.dimension == "" and q.si != 0:
        raise ctx.fail(key, f"a bare number used as an angle: {angle_hint(q.si)}")
    if q.dimension != "" or not (q.unit.symbol == "" or is_angle_unit(q.unit.symbol)):
        raise ctx.fail(key, f"expected an angle (deg or rad), got {dimension_name(q.dimension) if q.dimension else repr(str(value))}")
    return q.si


def same_angle_unit(ctx: Context, reference: DisplayUnit, q: Quantity, raw: Any, key: str) -> None:
    """Where the reference (a coordinate's range, a parameter, a variable's bounds) is an
    angle, a bare number other than 0 is an error: it would silently be radians."""
    if is_angle_unit(reference.symbol) and q.unit.symbol == "" and q.si != 0:
        raise ctx.fail(key, f"a bare number used as an angle ({reference.symbol} elsewhere): {angle_hint(q.si)}")


def variables(ctx: Context) -> tuple[Variable, ...]:
    out = []
    for name, v in ctx.spec.variables.items():
        with ctx.item():
            key = f"variables.{name}"
            lower = ctx.literal(v.lower, f"{key}.lower")
            upper = ctx.literal(v.upper, f"{key}.upper")
            initial = ctx.literal(v.initial, f"{key}.initial") if v.initial is not None else None
            with ctx.at(f"{key}.unit"):
                unit = display_unit(v.unit) if v.unit is not None else (lower.unit if lower.unit.symbol else upper.unit)
            for part, q in (("lower", lower), ("upper", upper), ("initial", initial)):
                if q is not None and q.dimension != unit.dimension and not (q.si == 0 and q.unit.symbol == ""):
                    raise ctx.fail(f"{key}.{part}", f"expected {dimension_name(unit.dimension)} like unit '{unit.label}', got {dimension_name(q.dimension)}")
                if q is not None:
                    same_angle_unit(ctx, unit, q, getattr(v, part), f"{key}.{part}")
            if lower.si > upper.si:
                raise ctx.fail(key, f"lower bound {v.lower} is greater than upper bound {v.upper}")
            if not math.isfinite(upper.si - lower.si):
                raise ctx.fail(key, f"the bounds {v.lower} and {v.upper} are too far apart (their difference overflows)")
            init = initial.si if initial is not None else 0.5 * (lower.si + upper.si)
            if not lower.si <= init <= upper.si:
                raise ctx.fail(f"{key}.initial", f"initial value {v.initial} lies outside [{v.lower}, {v.upper}]")
            nominal = _adjustment(ctx, v.nominal, f"{key}.nominal", unit)
            travel = _adjustment(ctx, v.travel, f"{key}.travel", unit)
            if nominal is not None and not lower.si <= nominal <= upper.si:
                raise ctx.fail(f"{key}.nominal", f"nominal {v.nominal} lies outside the bounds [{v.lower}, {v.upper}]")
            if travel is not None and travel < 0:
                raise ctx.fail(f"{key}.travel", "must not be negative")
            if travel is not None and travel > upper.si - lower.si:
                raise ctx.fail(f"{key}.travel", f"travel {v.travel} exceeds the span of the bounds [{v.lower}, {v.upper}]")
            ctx.symbol_unit[name] = unit
            ctx.symbol_value[name] = init
            ctx.variable_lower[name] = lower.si
            ctx.box[name] = (lower.si, upper.si)
            out.append(Variable(name, lower.si, upper.si, init, unit, v.adjustable, v.description, nominal, travel))
    ctx.check()
    return tuple(out)


def _adjustment(ctx: Context, raw: Any, key: str, unit: DisplayUnit) -> float | None:
    """A variable's ``nominal`` or ``travel`` (SI), in the variable's dimension."""
    if raw is None:
        return None
    q = ctx.literal(raw, key)
    if q.dimension != unit.dimension and not (q.si == 0 and q.unit.symbol == ""):
        raise ctx.fail(key, f"expected {dimension_name(unit.dimension)} like unit '{unit.label}', got {dimension_name(q.dimension)}")
    same_angle_unit(ctx, unit, q, raw, key)
    return q.si


def gravity(ctx: Context, g: Any, key: str) -> Gravity:
    acc = ctx.literal(g.acceleration, f"{key}.acceleration")
    with ctx.at(f"{key}.acceleration"):
        check_dimension(acc.dimension, ACCELERATION, f"'{g.acceleration}'")
    if acc.si < 0:
        raise ctx.fail(f"{key}.acceleration", "must not be negative (give the direction instead)")
    d = [float(c) for c in g.direction]
    norm = math.sqrt(sum(c * c for c in d))
    if not math.isfinite(norm) or norm == 0:
        raise ctx.fail(f"{key}.direction", "must be a non-zero vector of finite numbers")
    return Gravity(acc.si, (d[0] / norm, d[1] / norm, d[2] / norm))


def scenarios(ctx: Context, default_gravity: Gravity, parameters: tuple[Parameter, ...]) -> tuple[Scenario, ...]:
    if not ctx.spec.scenarios:
        return (Scenario(DEFAULT_SCENARIO, default_gravity, {}),)
    base = {p.name: p for p in parameters if p.is_base}
    out = []
    for name, sc in ctx.spec.scenarios.items():
        with ctx.item():
            key = f"scenarios.{name}"
            g = gravity(ctx, sc.gravity, f"{key}.gravity") if sc.gravity is not None else default_gravity
            values: dict[str, float] = {}
            for pname, raw in sc.parameters.items():
                pkey = f"{key}.parameters.{pname}"
                if pname not in base:
                    hint = " (only literal parameters can change per scenario)" if pname in ctx.spec.parameters else suggest(pname, base)
                    raise ctx.fail(pkey, f"unknown parameter '{pname}'{hint}")
                q = ctx.literal(raw, pkey)
                if q.dimension != base[pname].unit.dimension and not (q.si == 0 and not q.unit.symbol):
                    raise ctx.fail(pkey, f"expected {dimension_name(base[pname].unit.dimension)}, got {dimension_name(q.dimension)}")
                same_angle_unit(ctx, base[pname].unit, q, raw, pkey)
                values[pname] = q.si
            check_scenario_values(ctx, values, key)
            out.append(Scenario(name, g, values, sc.description))
    ctx.check()
    return tuple(out)


def tilts(ctx: Context, g: Any) -> tuple[Tilt, ...]:
    """The base tilts of ``[gravity] tilt``: each an axis of the base and a range of angles."""
    out = []
    for i, t in enumerate(getattr(g, "tilt", ()) or ()):
        key = f"gravity.tilt[{i}]"
        with ctx.item():
            axis = [float(c) for c in t.axis]
            norm = math.sqrt(sum(c * c for c in axis))
            if not math.isfinite(norm) or norm == 0:
                raise ctx.fail(f"{key}.axis", "must be a non-zero vector of finite numbers")
            ends = [ctx.literal(r, f"{key}.range") for r in t.range]
            if all(q.unit.symbol == "" and q.dimension == "" for q in ends) and any(q.si != 0 for q in ends):
                lo_text, hi_text = (f"{q.si:g}" for q in ends)
                raise ctx.fail(f"{key}.range", f"bare numbers used as an angle: write ['{lo_text} deg', '{hi_text} deg'] or give the unit rad")
            if any(q.dimension != "" for q in ends):
                raise ctx.fail(f"{key}.range", "a tilt is an angle: write it like '15 deg'")
            lo, hi = (q.si for q in ends)
            if not lo <= hi:
                raise ctx.fail(f"{key}.range", f"empty range [{t.range[0]}, {t.range[1]}]: the lower end must not be above the upper end")
            if hi - lo > FULL_TURN + 1e-12:
                raise ctx.fail(f"{key}.range", "a tilt range spans at most a full turn (360 deg)")
            out.append(Tilt((axis[0] / norm, axis[1] / norm, axis[2] / norm), lo, hi, t.description))
    ctx.check()
    return tuple(out)


def tilted_scenarios(ctx: Context, scenarios: tuple[Scenario, ...], tilts: tuple[Tilt, ...]) -> tuple[Scenario, ...]:
    """Each scenario once per node of the tilt grid (:func:`tilt_nodes`); the copies of one
    scenario share its setting (an adjustment is not reset as the base tilts). More than
    :data:`~counterpoise.model.tilt.MAX_SCENARIOS` of them is an input error (before any is made)."""
    if not tilts:
        return scenarios
    import itertools

    nodes = math.prod(len(tilt_nodes(t)) for t in tilts)
    if nodes * len(scenarios) > MAX_SCENARIOS:
        ranged = sum(len(tilt_nodes(t)) > 1 for t in tilts)
        per = f" for each of the {len(scenarios)} scenarios" if len(scenarios) > 1 else ""
        raise ctx.fail(
            "gravity.tilt",
            f"{ranged} tilt ranges give 3^{ranged} = {nodes:,} tilt nodes{per}: {nodes * len(scenarios):,} balance scenarios, more than the "
            f"{MAX_SCENARIOS} designed at once (MAX_SCENARIOS, counterpoise/model/tilt.py); use fewer tilt axes, fix a tilt at one angle "
            "(range = ['5 deg', '5 deg']: one node)" + (", or fewer [scenarios]" if len(scenarios) > 1 else ""),
        )

    grid = list(itertools.product(*(tilt_nodes(t) for t in tilts)))
    default_only = len(scenarios) == 1 and scenarios[0].name == DEFAULT_SCENARIO and not scenarios[0].parameters
    out = []
    for s in scenarios:
        for angles in grid:
            suffix = "tilt_" + "_".join(angle_name(a) for a in angles)
            name = suffix if default_only else f"{s.name}_{suffix}"
            direction = tilted(s.gravity.direction, tilts, angles)
            text = tilt_text(tilts, angles)
            description = f"{s.description}, {text}" if s.description else text
            out.append(
                Scenario(name, Gravity(s.gravity.acceleration, direction), s.parameters, description, s.setting or s.name, tuple(angles), s.gravity)
            )
    return tuple(out)


def check_scenario_values(ctx: Context, values: Mapping[str, float], key: str) -> None:
    """Masses and stiffnesses stay finite and ≥ 0 with a scenario's parameter values."""
    if not values:
        return
    saved = dict(ctx.symbol_value)
    try:
        for name, value in values.items():
            ctx.symbol_value[name] = value
        for p in ctx.derived_parameters:
            with np.errstate(all="ignore"):
                z = complex(ex.evaluate(p.expr, ctx.symbol_value, numpy_functions()))  # type: ignore[arg-type]  # a derived parameter has its expr
            if z.imag != 0 or not math.isfinite(z.real):
                raise ctx.fail(key, f"parameter '{p.name}' is not a finite number in this scenario")
            ctx.symbol_value[p.name] = z.real
        for what_key, tree, raw, what in ctx.signed:
            try:
                value = ctx.finite(tree, raw, key)
            except ProblemFileError as exc:
                raise ctx.fail(key, f"{exc.message} (for {what_key} in this scenario)") from None
            if value < 0:
                raise ctx.fail(key, f"{what} {what_key} = '{raw}' is negative in this scenario")
    finally:
        ctx.symbol_value = saved


#: Largest objective weight (SI): the convex path's scaled LP data stop being accurate
#: beyond ~1e20 (Clarabel reports a feasible LP infeasible at 1e40, fails at 1e200, and a
#: weight of 1e308 makes the data infinite), while a weight's size alone never changes the
#: design (only the weights' ratio does).
MAX_OBJECTIVE_WEIGHT = 1e12


def objective(ctx: Context) -> Objective:
    o = ctx.spec.objective
    if isinstance(o, str):  # objective = "max_payload_range"
        return Objective(goal=o)
    key = "objective.inertia_weight"
    w = ctx.literal(o.inertia_weight, key)
    if w.si != 0 or w.unit.symbol:  # only a bare 0 fits any dimension; '0 kg' is a mass
        with ctx.at(key):
            check_dimension(w.dimension, INVERSE_AREA, f"'{o.inertia_weight}'")
    if w.si < 0:
        raise ctx.fail(key, "must not be negative")
    skey = "objective.stiffness_weight"
    ws = ctx.literal(o.stiffness_weight, skey)
    if ws.si != 0 or ws.unit.symbol:  # as above: only a bare 0 fits any dimension
        with ctx.at(skey):
            check_dimension(ws.dimension, COMPLIANCE_MASS, f"'{o.stiffness_weight}'")
    if ws.si < 0:
        raise ctx.fail(skey, "must not be negative")
    for wkey, value, raw in (("objective.mass_weight", o.mass_weight, o.mass_weight), (key, w.si, o.inertia_weight), (skey, ws.si, o.stiffness_weight)):
        if value > MAX_OBJECTIVE_WEIGHT:
            raise ctx.fail(wkey, f"'{raw}' is too large: weights above {MAX_OBJECTIVE_WEIGHT:g} (SI) overflow the solvers' scaled data; "
                                 "only the ratio of the weights changes the design, so scale them all down")
    return Objective(o.mass_weight, w.si, ws.si)


def check_angles(ctx: Context, frames: Any) -> None:
    """Every place of the file where an angle is expected holds one (see
    :meth:`Context.angle_kind`): coordinate ranges and homes, the rotations and DH rows of
    the file's frames, coupled coordinates. Frames made by other means (an imported robot
    model, whose angles are radians by definition) are not the file's text: not checked."""
    for sname, sub in ctx.spec.subsystems.items():
        for cname, c in sub.coordinates.items():
            key = f"subsystems.{sname}.coordinates.{cname}"
            with ctx.item():
                if c.range is None:  # a dependent coordinate of a closed loop: its home only
                    if c.home is not None:
                        home = ctx.literal(c.home, f"{key}.home")
                        if home.unit.symbol == "" and home.dimension == "" and home.si != 0:
                            raise ctx.fail(
                                f"{key}.home", f"a bare number used as an angle: write '{home.si:g} deg' or '{home.si:g} rad' (a sliding coordinate: give its length unit)"
                            )
                    continue
                ends = [ctx.literal(r, f"{key}.range") for r in c.range]
                if all(q.unit.symbol == "" and q.dimension == "" for q in ends) and any(q.si != 0 for q in ends):
                    lo, hi = (f"{q.si:g}" for q in ends)
                    raise ctx.fail(
                        f"{key}.range",
                        f"bare numbers used as an angle: write ['{lo} deg', '{hi} deg'] or give the unit rad ('[{lo}, {hi}]' would be radians)",
                    )
                unit = next((q.unit for q in ends if q.unit.symbol), None)
                if c.home is not None and unit is not None:
                    same_angle_unit(ctx, unit, ctx.literal(c.home, f"{key}.home"), c.home, f"{key}.home")
        for name, raw in sub.coupled.items():
            with ctx.item():
                key = f"subsystems.{sname}.coupled.{name}"
                if name in ctx.coupled:
                    ctx.angle_kind(ctx.coupled[name], raw, key)
    _check_robot_angles(ctx)
    for frame in frames:
        spec = ctx.spec.frames.get(frame.name)
        if spec is None:
            continue
        for i, t in enumerate(frame.transforms):
            if not isinstance(t, Rotation):
                continue
            key = frame.key(i)
            key = key if key.endswith((".alpha", ".theta")) else f"{key}.angle"
            raw = _raw_at(spec, frame.name, key)
            if raw is None:
                continue  # not a rotation written in the file (an orientation = "<frame>", ...)
            with ctx.item():
                ctx.expect_angle(t.angle, raw, key)
    ctx.check()


def _check_robot_angles(ctx: Context) -> None:
    """The ranges, homes and locked values a file gives an imported robot's joints (a
    ``[robot]`` table, when the schema has one): bare numbers other than 0 are errors. A
    prismatic joint's values are lengths: a bare number there fails its dimension check
    before this one runs, so a bare number reaching here is an angle."""
    robot = getattr(ctx.spec, "robot", None)
    if robot is None:
        return
    for name, joint in (getattr(robot, "joints", None) or {}).items():
        key = f"robot.joints.{name}"
        with ctx.item():
            ends = [ctx.literal(r, f"{key}.range") for r in joint.range]
            if all(q.unit.symbol == "" for q in ends) and any(q.si != 0 for q in ends):
                lo, hi = (f"{q.si:g}" for q in ends)
                raise ctx.fail(f"{key}.range", f"bare numbers used as an angle: write ['{lo} deg', '{hi} deg'] or give the unit rad")
            unit = next((q.unit for q in ends if q.unit.symbol), None)
            home = getattr(joint, "home", None)
            if home is not None and unit is not None:
                same_angle_unit(ctx, unit, ctx.literal(home, f"{key}.home"), home, f"{key}.home")
    for name, raw in (getattr(robot, "locked", None) or {}).items():
        with ctx.item():
            q = ctx.literal(raw, f"robot.locked.{name}")
            if q.unit.symbol == "" and q.si != 0:
                raise ctx.fail(f"robot.locked.{name}", f"a bare number used as an angle: {angle_hint(q.si)}")


_ROTATION_KEY = re.compile(r"^frames\.(?P<frame>[^.]+)\.transforms\.(?P<index>\d+)\.(?:angle|dh\.(?P<dh>alpha|theta))$")


def _raw_at(spec: Any, name: str, key: str) -> Any:
    """The text written at ``frames.<name>.transforms.<i>.angle`` (or ``.dh.alpha``,
    ``.dh.theta``) of frame ``spec``; None when ``key`` is no such place."""
    match = _ROTATION_KEY.match(key)
    if match is None or match["frame"] != name or int(match["index"]) >= len(spec.transforms):
        return None
    node = spec.transforms[int(match["index"])]
    field = match["dh"]
    if field is not None:
        return getattr(node.dh, field, None) if hasattr(node, "dh") else None
    return getattr(node, "angle", None)
