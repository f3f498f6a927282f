"""Resolution: a shape-checked :class:`~counterpoise.io.schema.ProblemFile` -> a typed
:class:`~counterpoise.model.problem.Problem`, section by section.

:mod:`.context` holds the symbol tables and shared checks; :mod:`.quantities`,
:mod:`.mechanism` and :mod:`.report` resolve their sections in dependency order.
"""

from __future__ import annotations

from ...model.problem import Problem, Settings
from ..schema import ProblemFile
from . import loops, mechanism, parts, payloads, quantities, report, substitution
from .context import REPORT_FUNCTIONS, RESERVED, Context

__all__ = ["REPORT_FUNCTIONS", "RESERVED", "resolve"]


def resolve(spec: ProblemFile, label: str) -> Problem:
    """Resolve ``spec`` (read from ``label``); every error is a one-line ProblemFileError."""
    ctx = Context(spec, label)
    for kind in ("parameters", "variables", "report"):
        for name in getattr(spec, kind):
            ctx.declare(kind, name)
    payloads.declare(ctx)
    for name in spec.slots:
        ctx.declare("slots", name)
    for sub in spec.subsystems.values():
        for cname in sub.coordinates:
            ctx.declare("coordinates", cname)
    if spec.payloads and spec.slots:
        raise ctx.fail("slots", "spring slots and payload ranges cannot be combined yet: choose the parts for one payload first")
    parameters = quantities.parameters(ctx) + payloads.parameters(ctx)
    catalogues = parts.catalogues(ctx)
    parameters += parts.slot_parameters(ctx, catalogues)
    variables = quantities.variables(ctx)
    payloads.check_adjustments(ctx, variables)
    subsystems, coordinates = mechanism.subsystems(ctx)
    frames = mechanism.frames(ctx)
    by_name = {f.name: f for f in frames}
    closures = loops.loops(ctx, by_name, coordinates)
    payload_bodies, payload_ranges = payloads.bodies(ctx, by_name)
    bodies, substitutions, substituted = substitution.substitutions(ctx, mechanism.bodies(ctx, by_name) + payload_bodies, by_name)
    counter_masses = mechanism.counter_masses(ctx, by_name)
    springs = mechanism.springs(ctx, by_name)
    slot_springs: dict[str, list[str]] = {}
    for s in springs:
        if s.slot is not None:
            slot_springs.setdefault(s.slot, []).append(s.name)
    slots = parts.slots(ctx, catalogues, slot_springs)
    selection = parts.selection(ctx)
    gravity = quantities.gravity(ctx, spec.gravity, "gravity")
    scenarios = quantities.scenarios(ctx, gravity, parameters)
    objective = quantities.objective(ctx)
    reports = report.report(ctx, subsystems, by_name)
    meta = spec.problem
    return Problem(
        name=meta.name,
        title=meta.title,
        source=meta.source,
        description=meta.description,
        path=label,
        parameters=parameters,
        variables=variables,
        subsystems=subsystems,
        coordinates=coordinates,
        frames=frames,
        bodies=bodies,
        counter_masses=counter_masses,
        springs=springs,
        scenarios=scenarios,
        objective=objective,
        report=reports + substituted,
        settings=Settings(**spec.settings.model_dump()),
        substitutions=substitutions,
        payloads=payload_ranges,
        slots=slots,
        selection=selection,
        loops=closures,
    )
