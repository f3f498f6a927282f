"""Parameters, variables, gravity, scenarios and the objective."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ...errors import ProblemFileError
from ...model import expr as ex
from ...model.problem import Gravity, Objective, Parameter, Scenario, Variable
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
    display_unit,
    looks_like_quantity,
    pint_quantity,
    ureg,
)
from .context import Context, evaluate_checked, numpy_functions, suggest, topological

DEFAULT_SCENARIO = "nominal"


def parameters(ctx: Context) -> tuple[Parameter, ...]:
    entries = ctx.spec.parameters
    raw_values = {n: (e.value if hasattr(e, "value") else e) for n, e in entries.items()}
    descriptions = {n: getattr(e, "description", "") for n, e in entries.items()}
    literal: dict[str, Quantity] = {}
    derived: dict[str, ex.Expr] = {}
    for name, raw in raw_values.items():
        key = f"parameters.{name}"
        if isinstance(raw, str) and not looks_like_quantity(raw):
            derived[name] = ctx.expression(raw, key, entries.keys())
        else:
            literal[name] = ctx.literal(raw, key)
            ctx.symbol_unit[name] = literal[name].unit
            ctx.symbol_value[name] = literal[name].si
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
        ctx.symbol_unit[name] = unit
        ctx.symbol_value[name] = si
        out.append(Parameter(name, unit, expr=tree, description=descriptions[name]))
    ctx.derived_parameters = [p for p in out if not p.is_base]
    return tuple(out)


def variables(ctx: Context) -> tuple[Variable, ...]:
    out = []
    for name, v in ctx.spec.variables.items():
        key = f"variables.{name}"
        lower = ctx.literal(v.lower, f"{key}.lower")
        upper = ctx.literal(v.upper, f"{key}.upper")
        initial = ctx.literal(v.initial, f"{key}.initial") if v.initial is not None else None
        with ctx.at(f"{key}.unit"):
            unit = display_unit(v.unit) if v.unit is not None else (lower.unit if lower.unit.symbol else upper.unit)
        for part, q in (("lower", lower), ("upper", upper), ("initial", initial)):
            if q is not None and q.dimension != unit.dimension and not (q.si == 0 and q.unit.symbol == ""):
                raise ctx.fail(f"{key}.{part}", f"expected {dimension_name(unit.dimension)} like unit '{unit.label}', got {dimension_name(q.dimension)}")
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
    return tuple(out)


def _adjustment(ctx: Context, raw: Any, key: str, unit: DisplayUnit) -> float | None:
    """A variable's ``nominal`` or ``travel`` (SI), in the variable's dimension."""
    if raw is None:
        return None
    q = ctx.literal(raw, key)
    if q.dimension != unit.dimension and not (q.si == 0 and q.unit.symbol == ""):
        raise ctx.fail(key, f"expected {dimension_name(unit.dimension)} like unit '{unit.label}', got {dimension_name(q.dimension)}")
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
            values[pname] = q.si
        check_scenario_values(ctx, values, key)
        out.append(Scenario(name, g, values, sc.description))
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
                value = complex(ex.evaluate(p.expr, ctx.symbol_value, numpy_functions()))  # type: ignore[arg-type]
            if value.imag != 0 or not math.isfinite(value.real):
                raise ctx.fail(key, f"parameter '{p.name}' is not a finite number in this scenario")
            ctx.symbol_value[p.name] = value.real
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
