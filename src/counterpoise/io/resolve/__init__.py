"""Resolution: a shape-checked :class:`~counterpoise.io.schema.ProblemFile` -> a typed
:class:`~counterpoise.model.problem.Problem`, section by section.

:mod:`.context` holds the symbol tables and shared checks; :mod:`.quantities`,
:mod:`.mechanism` and :mod:`.report` resolve their sections in dependency order.
"""

from __future__ import annotations

from ...errors import ProblemFileError, raise_errors
from ...model.problem import Problem, Settings
from ..schema import ProblemFile
from . import constraints, loops, mechanism, parts, payloads, pulleys, quantities, report, robot, robust, substitution, synthesis
from .context import REPORT_FUNCTIONS, RESERVED, Context, combinations

__all__ = ["REPORT_FUNCTIONS", "RESERVED", "resolve"]


def resolve(spec: ProblemFile, label: str) -> Problem:
    """Resolve ``spec`` (read from ``label``); every error is a one-line ProblemFileError.

    Independent entries are resolved on after an error (:meth:`Context.item`), so a file
    with several mistakes gets one line for each (a :class:`ProblemFileErrors`); what
    failed later only because of an earlier error is not reported.
    """
    ctx = Context(spec, label)
    try:
        problem = _resolve(ctx)
    except ProblemFileError as exc:
        raise_errors([*ctx.errors, exc])
        raise  # unreachable: raise_errors raised
    except Exception:
        ctx.check()  # a failure that follows from an error already found
        raise
    ctx.check()
    problem = loops.assembled_homes(problem)  # closed loops: the homes the closure assembles (docs/loops.md#the-home)
    return pulleys.finish(ctx, problem)  # pulleys of radius > 0: pins checked, zero-force lengths as variables


def _resolve(ctx: Context) -> Problem:
    spec, label = ctx.spec, ctx.label
    for kind in ("parameters", "variables", "report"):
        for name in getattr(spec, kind):
            ctx.declare(kind, name)
    payloads.declare(ctx)
    for name in spec.slots:
        ctx.declare("slots", name)
    for sub in spec.subsystems.values():
        for cname in sub.coordinates:
            ctx.declare("coordinates", cname)
    if not spec.subsystems and spec.robot is None:
        raise ctx.fail("subsystems", "missing required key (or a [robot] model whose joints move)")
    robot_model = robot.read(ctx)
    parameters = quantities.parameters(ctx) + payloads.parameters(ctx)
    catalogues = parts.catalogues(ctx)
    parameters += parts.slot_parameters(ctx, catalogues)
    variables = quantities.variables(ctx)
    payloads.check_adjustments(ctx, variables)
    subsystems, coordinates = mechanism.subsystems(ctx)
    robot_subsystems, robot_coordinates = robot.coordinates(ctx, robot_model)
    subsystems, coordinates = robot_subsystems + subsystems, robot_coordinates + coordinates
    frames = mechanism.frames(ctx, robot.frames(ctx, robot_model))
    quantities.check_angles(ctx, frames)
    by_name = {f.name: f for f in frames}
    closures = loops.loops(ctx, by_name, coordinates)
    payload_bodies, payload_ranges = payloads.bodies(ctx, by_name)
    given_bodies = robot.bodies(ctx, robot_model, by_name) + mechanism.bodies(ctx, by_name)
    bodies, substitutions, substituted = substitution.substitutions(ctx, given_bodies + payload_bodies, by_name)
    counter_masses = mechanism.counter_masses(ctx, by_name)
    springs = mechanism.springs(ctx, by_name)
    slot_springs: dict[str, list[str]] = {}
    for s in springs:
        if s.slot is not None:
            slot_springs.setdefault(s.slot, []).append(s.name)
    slots = parts.slots(ctx, catalogues, slot_springs)
    selection = parts.selection(ctx)
    gravity = quantities.gravity(ctx, spec.gravity, "gravity")
    tilts = quantities.tilts(ctx, spec.gravity)
    scenarios = quantities.tilted_scenarios(ctx, quantities.scenarios(ctx, gravity, parameters), tilts)
    objective = quantities.objective(ctx)
    reports = report.report(ctx, subsystems, by_name)
    design_constraints = constraints.constraints(ctx, subsystems, by_name, springs, counter_masses)
    combinations(ctx)  # before the layers' own tables are read: a table a layer cannot take yet is named first
    robust_spec = robust.robust(ctx, bodies, springs, counter_masses, [b.name for b in payload_bodies])
    synthesis_spec = synthesis.synthesis(ctx, by_name)
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
        constraints=design_constraints,
        tilts=tilts,
        robust=robust_spec,
        synthesis=synthesis_spec,
    )
