"""Report quantities: named expressions shown in design.csv."""

from __future__ import annotations

from collections.abc import Mapping


from ...model import expr as ex
from ...model.mechanism import GROUND, Frame, Subsystem
from ...model.problem import ReportQuantity
from ...model.units import (
    dimension_name,
    display_unit,
    ureg,
)
from .context import REPORT_FUNCTIONS, Context, suggest, topological


def report(ctx: Context, subsystems: tuple[Subsystem, ...], frames: Mapping[str, Frame]) -> tuple[ReportQuantity, ...]:
    specs = ctx.spec.report
    known = ctx.design_names() | set(specs)
    functions = ex.MATH_FUNCTIONS | REPORT_FUNCTIONS
    trees: dict[str, ex.Expr] = {}
    sub_names = {s.name for s in subsystems}
    for name, r in specs.items():
        key = f"report.{name}.expression"
        tree = ctx.expression(r.expression, key, known, functions)
        for call in ex.calls(tree):
            if call.func in REPORT_FUNCTIONS:
                report_call(ctx, call, r.expression, key, sub_names, frames)
        trees[name] = tree
    order = topological(trees, lambda n: ex.names(trees[n], REPORT_FUNCTIONS) & trees.keys(), "report", ctx.label)
    extra = {
        "total_mass": ex.NameArgs(lambda *a: ureg().Quantity(1.0, "kg")),
        "com_distance": ex.NameArgs(lambda *a: ureg().Quantity(0.1, "m")),
    }
    out = []
    for name in order:
        r = specs[name]
        key = f"report.{name}"
        with ctx.at(f"{key}.unit"):
            unit = display_unit(r.unit)
        found = ctx.dimension(trees[name], r.expression, f"{key}.expression", extra)
        if found == "zero":
            found = unit.dimension
        if found != unit.dimension:
            raise ctx.fail(f"{key}.unit", f"'{r.expression}' is {dimension_name(found)} but the unit '{unit.label}' is {dimension_name(unit.dimension)}")
        ctx.symbol_unit[name] = unit
        ctx.symbol_value[name] = 1.0
        out.append(ReportQuantity(name, trees[name], unit, r.description))
    return tuple(out)


def report_call(ctx: Context, call: ex.Call, raw: str, key: str, subsystems: set[str], frames: Mapping[str, Frame]) -> None:
    arity = {"total_mass": (1, 1), "com_distance": (1, 2)}[call.func]
    if not arity[0] <= len(call.args) <= arity[1] or not all(isinstance(a, ex.Name) for a in call.args):
        usage = "total_mass(subsystem)" if call.func == "total_mass" else "com_distance(subsystem[, frame])"
        raise ctx.fail(key, f"'{raw}': use {usage} with names")
    sub = call.args[0].id  # type: ignore[union-attr]  # checked above: every argument is a name
    if sub not in subsystems:
        raise ctx.fail(key, f"unknown subsystem '{sub}' in '{raw}'{suggest(sub, subsystems)}")
    if len(call.args) == 2:
        fr = call.args[1].id  # type: ignore[union-attr]  # checked above: every argument is a name
        if fr != GROUND and fr not in frames:
            raise ctx.fail(key, f"unknown frame '{fr}' in '{raw}'{suggest(fr, list(frames) + [GROUND])}")
