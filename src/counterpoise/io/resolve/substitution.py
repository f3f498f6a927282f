"""``[substitutions.<body>]``: a body replaced by point masses on its neighbours (I3).

The points' positions in the body's frame (``at``) must be fixed by parameters; they are
evaluated at the file's values, and the substitution is solved once as a linear system
(:mod:`counterpoise.model.substitution`). Each point mass becomes a body of the frame
that receives it, and a report quantity of the same name (design.csv, substitution.csv).

Assembly check: each point must be where it is substituted to. The point ``at`` of the
body and the point ``point`` of the receiving frame are placed in the world at the home
configuration (every coordinate at its home, the file's parameter values) and must
coincide (within :data:`COINCIDENCE_TOLERANCE` of the substitution's size); otherwise the
file describes a mechanism that cannot be assembled and is rejected, naming the point.
Home, not every configuration: the substituted body is not simulated (a platform written
in the ground frame stays put while the legs move), so only the assembled configuration
the file describes can be checked; over the motion, the joint at that point is what keeps
the two together in the real mechanism (docs/seeds.md#substitution-points).
The receiving point must therefore not depend on design variables at home. A point
whose frame is moved by a dependent coordinate of a closed loop (``[loops]``) is not
checked here: the file gives only an approximate home for such a coordinate (it picks the
assembly branch), and the exact home comes from the closure solver, a later layer.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ...model import expr as ex
from ...model.functions import NUMPY_FUNCTIONS
from ...model.mechanism import GROUND, Body, Frame, Point, Rotation
from ...model.problem import ReportQuantity
from ...model.substitution import SubstitutedMass, Substitution, substitution_gap, substitution_matrix
from ...model.units import LENGTH, DisplayUnit, display_unit
from .context import RESERVED, Context, suggest

#: A substitution exists when the least-squares residual of A μ = [1, c] is below this (relative).
GAP_TOLERANCE = 1e-9
#: A substitution point and the point that receives it coincide at home when they are less
#: than this (relative to the largest distance of the substitution's points from the origin
#: of the world, at least 1 mm) apart.
COINCIDENCE_TOLERANCE = 1e-9
#: The smallest length scale of the coincidence check (m): points near the world origin.
COINCIDENCE_SCALE_FLOOR = 1e-3


def substitutions(
    ctx: Context, bodies: tuple[Body, ...], frames: Mapping[str, Frame]
) -> tuple[tuple[Body, ...], tuple[Substitution, ...], tuple[ReportQuantity, ...]]:
    """The bodies with every substituted body replaced by its point masses."""
    specs = ctx.spec.substitutions
    if not specs:
        return bodies, (), ()
    by_name = {b.name: b for b in bodies}
    replaced: dict[str, list[Body]] = {}
    out_subs, reports = [], []
    names = set(by_name)
    fixed_by: dict[str, str] = {}  # parameter -> body whose substitution points it places
    for body_name, spec in specs.items():
        key = f"substitutions.{body_name}"
        body = by_name.get(body_name)
        if body is None:
            raise ctx.fail(key, f"unknown body '{body_name}'{suggest(body_name, by_name)}")
        at_points, masses_points = [], []
        for pname, p in spec.points.items():
            pkey = f"{key}.points.{pname}"
            if pname in RESERVED or pname in ctx.symbol_kind or pname in names:
                raise ctx.fail(pkey, f"name '{pname}' is already used (a substituted mass is reported under its point's name)")
            ctx.symbol_kind[pname] = "substitutions"
            names.add(pname)
            at = ctx.vector(p.at, f"{pkey}.at", LENGTH, "a position", ctx.parameter_names())
            for c in at:
                fixed_by.update({n: body_name for n in ex.names(c)})
            at_points.append([ctx.finite(c, raw, f"{pkey}.at.{i}") for i, (c, raw) in enumerate(zip(at, p.at))])
            masses_points.append((pname, ctx.point(p.frame, p.point, f"{pkey}.point", frames, f"{pkey}.frame")))
        points = np.array(at_points)
        com_values = [ctx.finite(c, c, f"bodies.{body_name}.com") for c in body.com.position]
        gap = substitution_gap(points, np.array(com_values))
        if not gap <= GAP_TOLERANCE:
            where = {1: "at the point", 2: "on the line through the two points", 3: "in the plane of the three points"}.get(len(points), "in the span of the points")
            raise ctx.fail(
                key,
                f"no substitution exists for body '{body_name}': its centre of mass must lie {where} "
                f"(relative gap {gap:.2g}); choose other points",
            )
        _check_coincidence(ctx, key, body, points, [p for _, p in masses_points], [n for n, _ in masses_points], frames)
        matrix = substitution_matrix(points)
        moments = [body.mass] + [ex.BinOp("*", body.mass, c) for c in body.com.position]
        unit = _mass_unit(ctx, body_name)
        new_bodies = []
        masses = []
        for j, (pname, point) in enumerate(masses_points):
            mass = _linear_combination(matrix[j], moments)
            masses.append(SubstitutedMass(pname, mass, point, tuple(float(v) for v in points[j])))  # type: ignore[arg-type]  # a row of points is three floats
            new_bodies.append(Body(pname, mass, point, ctx.subsystem_of(point.frame, frames), f"substituted from body '{body_name}'"))
            reports.append(ReportQuantity(pname, mass, unit, f"mass substituted from body '{body_name}' at {point.frame}"))
        replaced[body_name] = new_bodies
        out_subs.append(Substitution(body_name, body.com.frame, tuple(masses), spec.description))
    new: list[Body] = []
    for b in bodies:
        new.extend(replaced.get(b.name, [b]))
    _check_scenarios(ctx, fixed_by)
    return tuple(new), tuple(out_subs), tuple(reports)


def _check_coincidence(
    ctx: Context, key: str, body: Body, at: np.ndarray, received: list[Point], names: list[str], frames: Mapping[str, Frame]
) -> None:
    """Each substitution point coincides, at home, with the point that receives its mass."""
    env = {n: v for n, v in ctx.symbol_value.items() if ctx.symbol_kind.get(n) in ("parameters", "slots", "coordinates")}
    variables = {n for n, k in ctx.symbol_kind.items() if k == "variables"}
    moving = _names_of(Point(body.com.frame, (ex.Num(0.0),) * 3), frames) & variables
    if moving:
        raise ctx.fail(
            f"bodies.{body.name}.frame",
            f"the frame of substituted body '{body.name}' moves with design variable(s) {', '.join(sorted(moving))}: "
            "its substitution points must be fixed by parameters and coordinates",
        )
    dependent = {c for sub in ctx.spec.subsystems.values() for c, spec in sub.coordinates.items() if spec.dependent}
    if _names_of(Point(body.com.frame, (ex.Num(0.0),) * 3), frames) & dependent:
        return  # the body's home pose needs the closure solver (see the module docstring)
    rot, origin = _home_pose(body.com.frame, frames, env)
    world_at = [origin + rot @ a for a in at]
    world_received = []
    checked = []
    for name, point in zip(names, received):
        used = _names_of(point, frames) & variables
        if used:
            raise ctx.fail(
                f"{key}.points.{name}.point",
                f"the point receiving '{name}' moves with design variable(s) {', '.join(sorted(used))}: "
                "its home position must be fixed by parameters and coordinates",
            )
        checked.append(not (_names_of(point, frames) & dependent))
        rot_r, origin_r = _home_pose(point.frame, frames, env)
        world_received.append(origin_r + rot_r @ np.array([float(ex.evaluate(c, env, NUMPY_FUNCTIONS)) for c in point.position]))
    scale = max([COINCIDENCE_SCALE_FLOOR] + [float(np.linalg.norm(p)) for p in world_at + world_received])
    for name, point, a, r, check in zip(names, received, world_at, world_received, checked):
        gap = float(np.linalg.norm(a - r))
        if check and gap > COINCIDENCE_TOLERANCE * scale:
            mm = 1000.0
            raise ctx.fail(
                f"{key}.points.{name}",
                f"substitution point '{name}' does not coincide with the point of frame '{point.frame}' that receives it: "
                f"at home they are {gap * mm:.4g} mm apart (body point at ({', '.join(f'{v * mm:.4g}' for v in a)}) mm, "
                f"receiving point at ({', '.join(f'{v * mm:.4g}' for v in r)}) mm in the world); the mechanism cannot be assembled",
            )


def _home_pose(frame: str, frames: Mapping[str, Frame], env: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """World rotation and origin of ``frame`` with ``env``'s values (the home configuration)."""
    if frame == GROUND:
        return np.eye(3), np.zeros(3)
    f = frames[frame]
    rot, origin = _home_pose(f.parent, frames, env) if f.parent is not None else (np.eye(3), np.zeros(3))
    for t in f.transforms:
        if isinstance(t, Rotation):
            axis = np.array([float(ex.evaluate(c, env, NUMPY_FUNCTIONS)) for c in t.axis])
            angle = float(ex.evaluate(t.angle, env, NUMPY_FUNCTIONS))
            from scipy.spatial.transform import Rotation as SciRotation  # here: only substitutions pay its import

            rot = rot @ SciRotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()
        else:
            origin = origin + rot @ np.array([float(ex.evaluate(c, env, NUMPY_FUNCTIONS)) for c in t.vector])
    return rot, origin


def _names_of(point: Point, frames: Mapping[str, Frame]) -> set[str]:
    """Every name the world position of ``point`` depends on (its frame chain included)."""
    out: set[str] = set()
    for c in point.position:
        out |= ex.names(c)
    frame: str | None = point.frame
    while frame != GROUND and frame is not None:
        f = frames[frame]
        out |= f.names()
        frame = f.parent
    return out


def _check_scenarios(ctx: Context, fixed_by: Mapping[str, str]) -> None:
    """The substitution is solved once, at the file's values: a scenario may not move its points."""
    derived = {p.name: p for p in ctx.derived_parameters}
    roots: dict[str, str] = {}
    stack = list(fixed_by.items())
    while stack:  # a derived parameter fixes the literal parameters it is built on
        name, body = stack.pop()
        expr = derived[name].expr if name in derived else None
        if expr is not None:
            stack.extend((n, body) for n in ex.names(expr) if n not in roots)
        roots[name] = body
    for sname, sc in ctx.spec.scenarios.items():
        for pname in sc.parameters:
            if pname in roots:
                raise ctx.fail(
                    f"scenarios.{sname}.parameters.{pname}",
                    f"'{pname}' places the substitution points of body '{roots[pname]}', which are fixed at the file's values",
                )


def _linear_combination(coefficients: np.ndarray, terms: list[ex.Expr]) -> ex.Expr:
    """Σ c_i t_i as a tree, skipping coefficients that are zero to rounding."""
    largest = float(np.abs(coefficients).max(initial=0.0))
    out: ex.Expr | None = None
    for c, t in zip(coefficients, terms):
        if abs(c) <= 1e-13 * largest:
            continue
        term = t if c == 1.0 else ex.BinOp("*", ex.Num(float(c)), t)
        out = term if out is None else ex.BinOp("+", out, term)
    return out if out is not None else ex.Num(0.0)


def _mass_unit(ctx: Context, body: str) -> DisplayUnit:
    """The display unit of a body's mass: the unit written in the file, else kg."""
    key = f"bodies.{body}.mass"
    if key in ctx.literal_unit:
        return ctx.literal_unit[key]
    raw = ctx.spec.bodies[body].mass
    if isinstance(raw, str) and raw in ctx.symbol_unit:
        return ctx.symbol_unit[raw]
    return display_unit("kg")
