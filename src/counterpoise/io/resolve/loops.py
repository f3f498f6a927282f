"""Loop closures: ``[loops.<joint>]`` tables and the dependent coordinates they solve.

Shape and names are checked here; whether a loop closes at home, and whether it stays
assembled over the ranges, needs the kinematics and is checked by
:func:`counterpoise.mechanics.closure.check_assembly` (called by the CLI right after
loading, and by the formulation), which raises the same one-line ProblemFileError.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

from ...model import expr as ex
from ...model.loops import PRISMATIC_JOINT, REVOLUTE_JOINT, Loop
from ...model.mechanism import GROUND, Coordinate, Frame, Point
from ...model.problem import Problem
from ...model.units import LENGTH, MAX_LENGTH_M, canonical_dimension, dimension_name
from .context import Context


def dependent_coordinate(ctx: Context, sname: str, cname: str, c: Any, key: str) -> Coordinate:
    """A coordinate solved from the loop closures: a home (its branch), no range."""
    if not c.dependent:
        raise ctx.fail(f"{key}.range", "missing required key (or mark the coordinate dependent = true and close its loop in [loops])")
    if c.range is not None:
        raise ctx.fail(f"{key}.range", "a dependent coordinate is solved from its loop closures and has no range of its own (remove the range, or dependent = true)")
    if c.home is None:
        raise ctx.fail(f"{key}.home", "missing required key: a dependent coordinate needs a home, which picks the assembly branch")
    home = ctx.literal(c.home, f"{key}.home")
    if home.dimension not in ("", canonical_dimension(LENGTH)):
        raise ctx.fail(f"{key}.home", f"a coordinate is an angle or a length, got {dimension_name(home.dimension)}")
    ctx.symbol_unit[cname] = home.unit
    ctx.symbol_value[cname] = home.si
    # expressions are checked for finiteness over this box: a dependent angle may take any value
    ctx.box[cname] = (home.si - math.pi, home.si + math.pi) if home.dimension == "" else (home.si, home.si)
    return Coordinate(cname, sname, home.si, home.si, home.si, home.unit, c.description, dependent=True)


def _check_position(ctx: Context, point: Point, raw: Any, key: str) -> None:
    """Each component of a loop point must be finite and within MAX_LENGTH_M (1000 km) at the
    file's values: a literal beyond it is refused where it is read; this catches an expression
    (a product of parameters) that reaches beyond it."""
    for i, tree in enumerate(point.position):
        shown = raw[i] if isinstance(raw, (list, tuple)) and i < len(raw) else raw
        value = ctx.finite(tree, shown, key)
        if abs(value) > MAX_LENGTH_M:
            raise ctx.fail(f"{key}.{i}", f"value out of range: '{shown}' is {value:.3g} m; positions up to {MAX_LENGTH_M:g} m (1000 km) are accepted")


def _frame_names(frame: str, frames: Mapping[str, Frame]) -> set[str]:
    """Every name the pose of ``frame`` depends on (its transforms and its ancestors')."""
    used: set[str] = set()
    name: str | None = frame
    while name is not None and name != GROUND:
        f = frames[name]
        used |= f.names()
        name = f.parent
    return used


def loops(ctx: Context, frames: Mapping[str, Frame], coordinates: tuple[Coordinate, ...]) -> tuple[Loop, ...]:
    """Resolve ``[loops]``; every subsystem with dependent coordinates must close a loop."""
    spec = ctx.spec
    out: list[Loop] = []
    variables = {n for n, k in ctx.symbol_kind.items() if k == "variables"}
    for name, lp in spec.loops.items():
        key = f"loops.{name}"
        points: list[Point] = []
        for side in ("a", "b"):
            end = getattr(lp, side)
            point = ctx.point(end.frame, end.point, f"{key}.{side}.point", frames, f"{key}.{side}.frame")
            _check_position(ctx, point, end.point, f"{key}.{side}.point")
            points.append(point)
        a, b = points
        subs = {n for n in (ctx.subsystem_of(p.frame, frames) for p in points) if n is not None}
        if not subs:
            raise ctx.fail(key, f"frames '{a.frame}' and '{b.frame}' are both fixed to ground: a loop must pass through moving frames")
        if len(subs) > 1:
            raise ctx.fail(key, f"joins subsystems {' and '.join(sorted(subs))}; a loop must close within one subsystem")
        if a.frame == b.frame:
            raise ctx.fail(f"{key}.b.frame", f"both ends are in frame '{a.frame}': the loop is not open at this joint")
        geometry = set().union(*(ex.names(c) for p in points for c in p.position)) | _frame_names(a.frame, frames) | _frame_names(b.frame, frames)
        if geometry & variables:
            raise ctx.fail(key, f"the loop's geometry depends on design variable '{sorted(geometry & variables)[0]}'; closures must be fixed by parameters and coordinates")
        axis = axis_b = None
        if lp.joint in (REVOLUTE_JOINT, PRISMATIC_JOINT):
            if lp.axis is None:
                raise ctx.fail(f"{key}.axis", f"missing required key: a {lp.joint} joint needs its axis (in frame a's coordinates)")
            axis = ctx.axis(lp.axis, f"{key}.axis")
        elif lp.axis is not None:
            raise ctx.fail(f"{key}.axis", "a spherical joint has no axis (remove it, or joint = \"revolute\")")
        if lp.axis_b is not None:
            if lp.joint != REVOLUTE_JOINT:
                why = "a spherical joint has no axis" if lp.joint != PRISMATIC_JOINT else "a prismatic joint keeps the frames' relative orientation of home"
                raise ctx.fail(f"{key}.axis_b", f"only a revolute joint has axis_b ({why})")
            axis_b = ctx.axis(lp.axis_b, f"{key}.axis_b")
        sub = next(iter(subs))
        out.append(Loop(name, lp.joint, a, b, axis, sub, lp.description, axis_b))
    closed = {loop.subsystem for loop in out}
    for c in coordinates:
        if c.dependent and c.subsystem not in closed:
            raise ctx.fail(f"subsystems.{c.subsystem}.coordinates.{c.name}.dependent", f"no loop of [loops] closes subsystem '{c.subsystem}': nothing determines '{c.name}'")
    for sub in sorted(closed):
        mine = [c for c in coordinates if c.subsystem == sub]
        first = next(loop for loop in out if loop.subsystem == sub)
        if not any(c.dependent for c in mine):
            raise ctx.fail(f"loops.{first.name}", f"subsystem '{sub}' has no dependent coordinate (mark the coordinates the loop determines dependent = true)")
        if all(c.dependent for c in mine):
            raise ctx.fail(f"loops.{first.name}", f"every coordinate of subsystem '{sub}' is dependent: give at least one a range")
    if out:
        for sname, s in spec.springs.items():
            if s.slot is not None and s.mount == "direct":
                raise ctx.fail(
                    f"springs.{sname}.mount",
                    "closed loops take catalogue parts behind a string only (mount = \"pulley\"): the screening of "
                    "directly attached parts samples the open box of coordinates, not the loop's manifold (see docs/loops.md)",
                )
    return tuple(out)




def assembled_homes(problem: Problem) -> Problem:
    """The problem with every dependent coordinate's home replaced by the assembled home.

    The file's homes are starting guesses (a few digits do); the closure's home solve
    (:class:`counterpoise.mechanics.closure.Closure`, at the first scenario's parameter
    values) corrects them on every closure equation, and the corrected values are what every
    later step sees: report quantities at home, `frames`, `draw`, the part search's home
    design. A loop that cannot close at home raises the same ProblemFileError as
    :func:`counterpoise.mechanics.closure.check_assembly`.
    """
    if not problem.loops:
        return problem
    from ...mechanics.closure import closure, scenario_base  # the kinematics: only for files with loops

    base = scenario_base(problem, problem.scenarios[0].name)
    home: dict[str, float] = {}
    for sub in dict.fromkeys(loop.subsystem for loop in problem.loops):
        c = closure(problem, sub, base)
        home.update({c.names[i]: float(c.home[i]) for i in c.dependent})
    coordinates = tuple(
        dataclasses.replace(co, home=home[co.name], lower=home[co.name], upper=home[co.name]) if co.name in home else co for co in problem.coordinates
    )
    return dataclasses.replace(problem, coordinates=coordinates)
