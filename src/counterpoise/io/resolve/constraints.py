"""Design constraints: the file's ``[constraints.<name>]`` and the springs' force limits.

Each constraint's expression goes through the whitelist parser, its names and named
quantities are checked (a spring, a counter-mass, a subsystem that exists), its dimension
must match its bounds', and a workspace extreme (``force_max(s)``...) must enter so that
the bound limits it on its own side (see :func:`_extreme_side`): ``force_max(s) ≤ 60 N``
is "at every configuration", ``force_max(s) ≥ 60 N`` would be "at one configuration",
which is not a constraint the designers can impose on samples.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from ...model import expr as ex
from ...model.constraints import (
    CONSTRAINT_FUNCTIONS,
    COUNTER_MASS_HOME,
    SPRING_EXTREMES,
    SPRING_HOME,
    TOTALS,
    Constraint,
    extreme_calls,
    force_limit,
)
from ...model.elements import CounterMass, ZeroFreeLengthSpring
from ...model.mechanism import Frame, Subsystem
from ...model.units import FORCE, DisplayUnit, base_unit_symbol, dimension_name, dimensionality_of, display_unit, looks_like_quantity, pint_quantity, ureg
from .context import REPORT_FUNCTIONS, Context, evaluate_checked, numpy_functions, suggest
from .report import report_call

#: representative values of the named quantities for dimension checks (SI, with units)
_UNITS = {"force": "N", "length": "m", "wrap": "rad"}


def _plain_number(raw: Any) -> float | None:
    """A bound written as a number in a string (``"100"``, ``"1e2"``): the number, as the
    bare TOML number ``100`` is (a dimensionless expression's bound is a plain number);
    None for anything else."""
    if not isinstance(raw, str):
        return None
    try:
        number = float(raw.strip())
    except ValueError:
        return None
    return number if math.isfinite(number) else None


def designed_spring_force_limit(spring: ZeroFreeLengthSpring) -> tuple[float, str] | None:
    """HOOK: the default largest force (N, and where it comes from) of a designed spring,
    one whose stiffness is free (not a catalogue slot), when the file gives no ``max_force``.

    None: such a spring's largest force is not a row of the NLP unless the file gives
    ``max_force``. Its designed spring reports the force it can carry
    (``counterpoise.springs.force_limit``, springs.csv's ``part_max_load_N``) and status.txt
    says when no spring can be wound for it. Entering that default as a row of every
    free-spring problem was tried: far from binding (188 N against 2030 N), the extra
    inequality made IPOPT fail on a random two-link chain that balances without it
    (tests/test_engine.py's random chains), and it cost each study point.
    """
    del spring
    return None


def constraints(
    ctx: Context,
    subsystems: tuple[Subsystem, ...],
    frames: Mapping[str, Frame],
    springs: tuple[ZeroFreeLengthSpring, ...],
    counter_masses: tuple[CounterMass, ...],
) -> tuple[Constraint, ...]:
    """The file's constraints, then one force limit per spring that has one."""
    out: list[Constraint] = []
    spring_names = {s.name for s in springs}
    mass_names = {c.name for c in counter_masses}
    sub_names = {s.name for s in subsystems}
    known = ctx.design_names() | {n for n, k in ctx.symbol_kind.items() if k == "report"}
    functions = ex.MATH_FUNCTIONS | REPORT_FUNCTIONS | CONSTRAINT_FUNCTIONS
    for name, spec in ctx.spec.constraints.items():
        key = f"constraints.{name}"
        with ctx.item():
            ekey = f"{key}.expression"
            tree = ctx.expression(spec.expression, ekey, known, functions)
            for call in ex.calls(tree):
                if call.func in REPORT_FUNCTIONS:
                    report_call(ctx, call, spec.expression, ekey, sub_names, frames)
                elif call.func in CONSTRAINT_FUNCTIONS:
                    _named_call(ctx, call, spec.expression, ekey, spring_names, mass_names)
            value = _pint_value(ctx, tree, spec.expression, ekey)
            dimension = dimensionality_of(value) if isinstance(value, ureg().Quantity) else ""
            if spec.lower is None and spec.upper is None:
                raise ctx.fail(key, "give lower and/or upper (a constraint without bounds constrains nothing)")
            bounds: dict[str, float | None] = {"lower": None, "upper": None}
            unit: DisplayUnit | None = None
            for side in ("lower", "upper"):
                raw = getattr(spec, side)
                if raw is None:
                    continue
                plain = _plain_number(raw)
                if dimension == "" and plain is None and isinstance(raw, str) and not looks_like_quantity(raw):
                    raise ctx.fail(f"{key}.{side}", f"expected a plain number such as 100 ('{spec.expression}' is dimensionless), got '{raw}'")
                q = ctx.literal(raw if plain is None else plain, f"{key}.{side}")
                if q.dimension != dimension and not (q.si == 0 and q.unit.symbol == ""):
                    if plain is not None or not isinstance(raw, str):  # a number without a unit
                        example = f"'{str(raw).strip()} {base_unit_symbol(value)}'" if isinstance(value, ureg().Quantity) else "its unit"
                        raise ctx.fail(f"{key}.{side}", f"'{raw}' is a plain number but '{spec.expression}' is {dimension_name(dimension)}: give the bound with its unit, such as {example}")
                    raise ctx.fail(f"{key}.{side}", f"'{raw}' is {dimension_name(q.dimension)} but '{spec.expression}' is {dimension_name(dimension)}")
                if not math.isfinite(q.si):
                    raise ctx.fail(f"{key}.{side}", "must be finite")
                bounds[side] = q.si
                if q.unit.symbol and unit is None:
                    unit = q.unit
            lo, hi = bounds["lower"], bounds["upper"]
            if lo is not None and hi is not None and lo > hi:
                raise ctx.fail(key, f"lower {spec.lower} is greater than upper {spec.upper}")
            if spec.unit is not None:
                with ctx.at(f"{key}.unit"):
                    unit = display_unit(spec.unit)
                if unit.dimension != dimension:
                    raise ctx.fail(f"{key}.unit", f"'{spec.expression}' is {dimension_name(dimension)} but the unit '{unit.label}' is {dimension_name(unit.dimension)}")
            if unit is None:
                unit = DisplayUnit(base_unit_symbol(value), 1.0, dimension) if isinstance(value, ureg().Quantity) else DisplayUnit("", 1.0, "")
            _check_extremes(ctx, tree, spec.expression, ekey, lo is not None, hi is not None)
            out.append(Constraint(name, tree, lo, hi, unit, spec.description))
    ctx.check()
    newton = display_unit("N")
    for spring in springs:
        s = ctx.spec.springs[spring.name]
        key = f"springs.{spring.name}.max_force"
        limit: tuple[float, str] | None = None
        with ctx.item():
            if s.max_force is not None:
                q = ctx.literal(s.max_force, key)
                if q.dimension != FORCE:
                    raise ctx.fail(key, f"expected a force (e.g. '60 N'), got {dimension_name(q.dimension)}")
                if not q.si > 0:
                    raise ctx.fail(key, "must be positive")
                limit = (q.si, "max_force in the file")
                limit_unit = q.unit
            elif spring.slot is None and _designed(ctx, spring):
                limit = designed_spring_force_limit(spring)
                limit_unit = newton
            if limit is not None:
                out.append(force_limit(spring.name, limit[0], limit_unit, limit[1]))
    ctx.check()
    return tuple(out)


def _designed(ctx: Context, spring: ZeroFreeLengthSpring) -> bool:
    """Whether the spring's stiffness is free (depends on a design variable)."""
    return bool(ex.names(spring.stiffness) & {n for n, k in ctx.symbol_kind.items() if k == "variables"})


def _named_call(ctx: Context, call: ex.Call, raw: str, key: str, springs: set[str], masses: set[str]) -> None:
    """A named quantity's arguments: one spring, one counter-mass, or none."""
    if call.func in TOTALS:
        if call.args:
            raise ctx.fail(key, f"'{raw}': {call.func}() takes no argument")
        return
    what, names = ("spring", springs) if call.func in SPRING_HOME or call.func in SPRING_EXTREMES else ("counter-mass", masses)
    if len(call.args) != 1 or not isinstance(call.args[0], ex.Name):
        raise ctx.fail(key, f"'{raw}': use {call.func}(<{what}>) with the {what}'s name")
    name = call.args[0].id
    if name not in names:
        hint = suggest(name, names) if names else f" (the problem has no {what})"
        raise ctx.fail(key, f"unknown {what} '{name}' in '{raw}'{hint}")


def _extra_functions() -> dict[str, Any]:
    """Named quantities as pint values of their dimension (for dimension checks)."""
    reg = ureg()
    out: dict[str, Any] = {
        "total_mass": ex.NameArgs(lambda *a: reg.Quantity(1.0, "kg")),
        "com_distance": ex.NameArgs(lambda *a: reg.Quantity(0.1, "m")),
        "added_mass": ex.NameArgs(lambda *a: reg.Quantity(1.0, "kg")),
        "added_inertia": ex.NameArgs(lambda *a: reg.Quantity(1.0, "kg*m^2")),
    }
    for name in SPRING_HOME:
        out[name] = ex.NameArgs(lambda *a, u=_UNITS[name.split("_")[0]]: reg.Quantity(1.0, u))
    for name, (quantity, _) in SPRING_EXTREMES.items():
        out[name] = ex.NameArgs(lambda *a, u=_UNITS[quantity]: reg.Quantity(1.0, u))
    for name in COUNTER_MASS_HOME:
        out[name] = ex.NameArgs(lambda *a: reg.Quantity(0.1, "m"))
    return out


def _pint_value(ctx: Context, tree: ex.Expr, raw: str, key: str) -> Any:
    """The expression on representative values with units (its dimension is the result's)."""
    if isinstance(tree, ex.Num):
        unit = ctx.literal_unit.get(key)
        return ureg().Quantity(tree.value, unit.symbol) if unit is not None and unit.symbol else tree.value
    ctx.angle_kind(tree, raw, key)
    env = {n: pint_quantity(ctx.symbol_value[n], ctx.symbol_unit[n]) for n in ex.names(tree, REPORT_FUNCTIONS | CONSTRAINT_FUNCTIONS) if n in ctx.symbol_unit}
    functions = {**numpy_functions(), **_extra_functions()}
    with ctx.at(key):
        return evaluate_checked(tree, env, functions, raw)


def _check_extremes(ctx: Context, tree: ex.Expr, raw: str, key: str, has_lower: bool, has_upper: bool) -> None:
    """At most one workspace extreme, entering linearly, bounded on its own side."""
    found = extreme_calls(tree)
    if not found:
        return
    if len(found) > 1:
        raise ctx.fail(key, f"'{raw}': one workspace extreme (force_max, length_min, ...) per constraint; split it into several constraints")
    call = found[0]
    side = _extreme_side(ctx, tree, call)
    if side is None:
        raise ctx.fail(key, f"'{raw}': {call.func}() must enter linearly (a sum or a constant multiple), so that the bound holds at every configuration")
    given = {"lower": has_lower, "upper": has_upper}
    other = "lower" if side == "upper" else "upper"
    if given[other]:
        spring = call.args[0].id  # type: ignore[union-attr]  # the parser checked the argument is a name
        raise ctx.fail(
            f"{key.rsplit('.', 1)[0]}.{other}",
            f"'{raw}' may only have {'an upper' if side == 'upper' else 'a lower'} bound: {call.func}({spring}) {'≤' if side == 'upper' else '≥'} a bound holds at every "
            f"configuration, the other side would hold at one configuration only (bound {call.func.split('_')[0]}_"
            f"{'min' if call.func.endswith('max') else 'max'}({spring}) instead)",
        )


def _extreme_side(ctx: Context, tree: ex.Expr, call: ex.Call) -> str | None:
    """Which bound (``upper``/``lower``) limits the extreme ``call`` at every configuration,
    or None when it does not enter linearly (checked on representative values)."""
    plain = {n: v for n, v in ctx.symbol_value.items()}

    def value(e: float) -> float:
        functions: dict[str, Any] = dict(numpy_functions())
        for name in CONSTRAINT_FUNCTIONS | REPORT_FUNCTIONS:
            functions[name] = ex.NameArgs(lambda *a: 1.0)
        functions[call.func] = ex.NameArgs(lambda *a: e)
        try:
            return float(ex.evaluate(tree, plain, functions))
        except (ArithmeticError, ValueError, TypeError):
            return math.nan

    v1, v2, v3 = value(1.0), value(2.0), value(3.0)
    slope = v2 - v1
    if not (math.isfinite(slope) and slope != 0 and abs((v3 - v2) - slope) <= 1e-9 * max(abs(slope), abs(v1), abs(v3))):
        return None
    maximum = SPRING_EXTREMES[call.func][1] == "max"
    return "upper" if (slope > 0) == maximum else "lower"
