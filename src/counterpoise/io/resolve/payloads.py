"""Payload ranges and the adjustable-variable keys that only make sense with them.

A ``[payloads.<name>]`` table becomes a literal parameter ``<name>`` (the nominal mass; the
payload layer overrides it per scenario) and a body of that mass at the payload's point.
``nominal`` and ``travel`` of an adjustable variable are checked here too.
"""

from __future__ import annotations

from collections.abc import Mapping

from ...model import expr as ex
from ...model.mechanism import Body, Frame
from ...model.payload import MAX_PAYLOAD_RANGE, Payload
from ...model.problem import Parameter, Variable
from ...model.units import MASS, canonical_dimension, dimension_name
from .context import Context



def declare(ctx: Context) -> None:
    """Payload names are parameters (their mass) in expressions: declare them."""
    for name in ctx.spec.payloads:
        ctx.declare("parameters", name)
        if name in ctx.spec.bodies:
            raise ctx.fail(f"payloads.{name}", f"name '{name}' is already used by bodies.{name}")


def parameters(ctx: Context) -> tuple[Parameter, ...]:
    """One literal parameter per payload: its nominal mass (checked range, in SI)."""
    if len(ctx.spec.payloads) > 1:
        second = list(ctx.spec.payloads)[1]
        raise ctx.fail(f"payloads.{second}", "only one payload range per problem is supported")
    out = []
    for name, spec in ctx.spec.payloads.items():
        key = f"payloads.{name}"
        lo = ctx.literal(spec.range[0], f"{key}.range")
        hi = ctx.literal(spec.range[1], f"{key}.range")
        for q, raw in ((lo, spec.range[0]), (hi, spec.range[1])):
            if q.dimension != canonical_dimension(MASS):
                raise ctx.fail(f"{key}.range", f"expected a mass, got {dimension_name(q.dimension)} ('{raw}')")
        if lo.si < 0:
            raise ctx.fail(f"{key}.range", f"a payload mass must not be negative, got '{spec.range[0]}'")
        if lo.si > hi.si:
            raise ctx.fail(f"{key}.range", f"lower end {spec.range[0]} is greater than upper end {spec.range[1]}")
        nominal = lo
        if spec.nominal is not None:
            nominal = ctx.literal(spec.nominal, f"{key}.nominal")
            if nominal.dimension != canonical_dimension(MASS):
                raise ctx.fail(f"{key}.nominal", f"expected a mass, got {dimension_name(nominal.dimension)} ('{spec.nominal}')")
            if not lo.si <= nominal.si <= hi.si:
                raise ctx.fail(f"{key}.nominal", f"nominal {spec.nominal} lies outside the range [{spec.range[0]}, {spec.range[1]}]")
        ctx.symbol_unit[name] = lo.unit
        ctx.symbol_value[name] = nominal.si
        ctx.payload_masses[name] = (lo.si, hi.si, nominal.si, lo.unit)
        out.append(Parameter(name, lo.unit, value=nominal.si, description=spec.description or f"payload '{name}' (nominal mass)"))
    for sname, sc in ctx.spec.scenarios.items():
        for name in ctx.spec.payloads:
            if name in sc.parameters:
                raise ctx.fail(f"scenarios.{sname}.parameters.{name}", f"'{name}' is a payload: its mass is set by payloads.{name}.range")
    return tuple(out)


def bodies(ctx: Context, frames: Mapping[str, Frame]) -> tuple[tuple[Body, ...], tuple[Payload, ...]]:
    """The payload bodies and the typed payloads."""
    out_bodies, out_payloads = [], []
    for name, spec in ctx.spec.payloads.items():
        key = f"payloads.{name}"
        point = ctx.point(spec.frame, spec.position, f"{key}.position", frames, f"{key}.frame")
        subsystem = ctx.subsystem_of(spec.frame, frames)
        lo, hi, nominal, unit = ctx.payload_masses[name]
        out_bodies.append(Body(name, ex.Name(name), point, subsystem, f"payload '{name}'"))
        out_payloads.append(Payload(name, point, lo, hi, nominal, unit, subsystem, spec.description))
    return tuple(out_bodies), tuple(out_payloads)


def check_adjustments(ctx: Context, variables: tuple[Variable, ...]) -> None:
    """``nominal``/``travel`` of variables, and ``max_payload_range``, need a payload."""
    for v in variables:
        key = f"variables.{v.name}"
        for part, value in (("nominal", v.nominal), ("travel", v.travel)):
            if value is None:
                continue
            if not v.adjustable:
                raise ctx.fail(f"{key}.{part}", f"only an adjustable variable has a {part} (add adjustable = true)")
            if not ctx.spec.payloads:
                raise ctx.fail(f"{key}.{part}", f"a {part} is measured over a payload range: declare one in [payloads.<name>]")
        if v.travel is not None and v.nominal is None:
            raise ctx.fail(f"{key}.travel", "a travel is measured from the nominal setting: give nominal too")
    if ctx.spec.objective == MAX_PAYLOAD_RANGE and not ctx.spec.payloads:
        raise ctx.fail("objective", "max_payload_range needs a payload range: declare one in [payloads.<name>]")
