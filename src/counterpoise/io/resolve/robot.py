"""``[robot]``: a URDF or MJCF model becomes frames, coordinates and bodies.

Every link is a frame named after the link: its parent link's frame, then the joint
origin (translation xyz, then the rotation Rz(yaw) Ry(pitch) Rx(roll)), then the joint's
motion about (or along) its axis. Moving joints (``joints.<name>``) are coordinates of the
robot's subsystem; locked joints (``locked.<name>``) are held at the given value, every
other joint at 0; a mimic joint follows its joint as a coupled coordinate. Every link
with a mass is a body named after the link at its inertial origin (docs/robots.md).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import TYPE_CHECKING

from ...errors import InputError
from ...model import expr as ex
from ...model.mechanism import GROUND, Body, Coordinate, Frame, Point, Rotation, Subsystem, Transform, Translation
from ...model.units import LENGTH, DisplayUnit, canonical_dimension, dimension_name
from ..schema import RobotSpec
from .context import RESERVED, Context, suggest

if TYPE_CHECKING:  # the reader (and its dataclasses) is imported only for a [robot] table
    from ..robot import Matrix, RobotJoint, RobotModel

#: a joint range may pass the model's limits by this much (SI) without an error: limits are
#: often written with fewer digits than the range (6.28318530718 for 2π)
LIMIT_SLACK = 1e-9
IDENTIFIER = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
X, Y, Z = ((ex.Num(1.0), ex.Num(0.0), ex.Num(0.0)), (ex.Num(0.0), ex.Num(1.0), ex.Num(0.0)), (ex.Num(0.0), ex.Num(0.0), ex.Num(1.0)))


def read(ctx: Context) -> RobotModel | None:
    """Read the model of ``[robot]`` (None without one) and declare its moving joints."""
    spec = ctx.spec.robot
    if spec is None:
        return None
    given = [k for k in ("urdf", "mjcf") if getattr(spec, k) is not None]
    if len(given) != 1:
        raise ctx.fail("robot.urdf", "give the model file as urdf = \"...\" or mjcf = \"...\"" + (", not both" if given else ""))
    fmt = given[0]
    raw = Path(getattr(spec, fmt))
    path = raw if raw.is_absolute() else Path(ctx.label).parent / raw
    try:
        from ..robot import read_robot

        model = read_robot(path, fmt)
    except InputError as exc:
        raise ctx.fail(f"robot.{fmt}", str(exc)) from None
    joints = model.joints()
    links = {link.name for link in model.links}
    fixed = {link.joint_name for link in model.links if link.joint_name and not link.joints}
    for section in ("joints", "locked"):
        for name in getattr(spec, section):
            key = f"robot.{section}.{name}"
            if name not in joints:
                what = "a fixed joint: it does not move" if name in fixed else f"unknown joint '{name}' in {path.name}{suggest(name, list(joints))}"
                raise ctx.fail(key, what)
            mimic = joints[name].mimic
            if mimic is not None:
                raise ctx.fail(key, f"joint '{name}' follows joint '{mimic[0]}' (mimic): list that joint instead")
    for name in spec.locked:
        if name in spec.joints:
            raise ctx.fail(f"robot.locked.{name}", f"joint '{name}' is listed both as moving (robot.joints) and as locked")
    if spec.subsystem in ctx.spec.subsystems:
        raise ctx.fail("robot.subsystem", f"'{spec.subsystem}' is also a [subsystems] table: name the robot's subsystem otherwise")
    for name in spec.joints:
        if not IDENTIFIER.match(name):
            fixed_name = re.sub(r"[^A-Za-z0-9_]", "_", name)
            fixed_name = fixed_name if fixed_name[:1].isalpha() else f"j_{fixed_name}"
            raise ctx.fail(
                f"robot.joints.{name}",
                f"'{name}' cannot be a coordinate name (letters, digits and '_', starting with a letter): rename the joint in a copy "
                f"of the model, e.g. sed 's/\"{name}\"/\"{fixed_name}\"/g' {path.name} > renamed_{path.name}, and list joints.{fixed_name} "
                "(a joint that is only locked or held may keep its name; see docs/robots.md)",
            )
        if name in RESERVED or name in ctx.symbol_kind:
            where = f" by {ctx.symbol_kind[name]}.{name}" if name in ctx.symbol_kind else " (reserved)"
            raise ctx.fail(f"robot.joints.{name}", f"name '{name}' is already used{where}")
        ctx.symbol_kind[name] = "coordinates"
    for link in model.links:
        if link.name == GROUND:
            raise ctx.fail(f"robot.{fmt}", f"{path.name}: a link is named 'ground', the name of the fixed world frame")
    for name in ctx.spec.frames:
        if name in links:
            raise ctx.fail(f"frames.{name}", f"'{name}' is a link of the robot model {path.name} (robot links are frames already)")
    for name in ctx.spec.bodies:
        if name in links:
            raise ctx.fail(f"bodies.{name}", f"'{name}' is a link of the robot model {path.name} (each link's mass is a body already)")
    return model


def _unit_for(joint: RobotJoint) -> str:
    return canonical_dimension(LENGTH) if joint.kind == "prismatic" else ""


def _bare_angle(raw: object) -> bool:
    """A number without a unit (not 0): an angle must say whether it is in deg or rad."""
    if isinstance(raw, bool):
        return False
    if isinstance(raw, (int, float)):
        return raw != 0
    try:
        return float(str(raw)) != 0
    except ValueError:
        return False


def _check_dimension(ctx: Context, joint: RobotJoint, dimension: str, key: str, raw: object) -> None:
    wanted = _unit_for(joint)
    if not wanted and _bare_angle(raw):
        raise ctx.fail(key, f"an angle needs its unit: write '{raw} deg' or '{raw} rad'")
    if dimension != wanted:
        what = "a length (prismatic joint)" if wanted else "an angle (revolute joint)"
        raise ctx.fail(key, f"expected {what}, got {dimension_name(dimension)} ('{raw}')")


def _within(ctx: Context, joint: RobotJoint, values: list[float], unit: DisplayUnit, key: str, what: str) -> None:
    if joint.limits is None:
        return
    lo, hi = joint.limits
    if any(v < lo - LIMIT_SLACK or v > hi + LIMIT_SLACK for v in values):
        # enough digits that a limit of ±3.14159 rad does not read as the ±180 deg it misses
        show = [f"{unit.from_si(v):.10g} {unit.symbol}".strip() for v in (lo, hi)]
        worst = max(max(lo - v, v - hi) for v in values)
        beyond = f"{unit.from_si(worst) if unit.symbol != '' else worst:.3g} {unit.symbol}".strip()
        raise ctx.fail(key, f"{what} goes beyond the joint's limits [{show[0]}, {show[1]}] in the model (by {beyond})")


def coordinates(ctx: Context, model: RobotModel | None) -> tuple[tuple[Subsystem, ...], tuple[Coordinate, ...]]:
    """The robot's subsystem and its coordinates (one per moving joint)."""
    spec = ctx.spec.robot
    if model is None or spec is None:
        return (), ()
    joints = model.joints()
    coords = []
    for name, j in spec.joints.items():
        key = f"robot.joints.{name}"
        joint = joints[name]
        lo = ctx.literal(j.range[0], f"{key}.range")
        hi = ctx.literal(j.range[1], f"{key}.range")
        _check_dimension(ctx, joint, lo.dimension, f"{key}.range", j.range[0])
        _check_dimension(ctx, joint, hi.dimension, f"{key}.range", j.range[1])
        if not lo.si < hi.si:
            raise ctx.fail(f"{key}.range", f"empty range [{j.range[0]}, {j.range[1]}]: the lower end must be below the upper end")
        _within(ctx, joint, [lo.si, hi.si], lo.unit, f"{key}.range", f"range [{j.range[0]}, {j.range[1]}]")
        home = 0.5 * (lo.si + hi.si)
        if j.home is not None:
            given = ctx.literal(j.home, f"{key}.home")
            _check_dimension(ctx, joint, given.dimension, f"{key}.home", j.home)
            home = given.si
        if not lo.si <= home <= hi.si:
            raise ctx.fail(f"{key}.home", "home lies outside the range")
        ctx.symbol_unit[name] = lo.unit
        ctx.symbol_value[name] = home
        ctx.box[name] = (lo.si, hi.si)
        coords.append(Coordinate(name, spec.subsystem, lo.si, hi.si, home, lo.unit, j.description))
    if not coords:
        raise ctx.fail("robot.joints", "no moving joint: list the joints to balance as joints.<name> = { range = [...] }")
    return (Subsystem(spec.subsystem, tuple(spec.joints), spec.description),), tuple(coords)


def _values(ctx: Context, model: RobotModel, spec: RobotSpec) -> dict[str, ex.Expr]:
    """The value of every joint: its coordinate, its locked value, a mimic's expression, or 0."""
    joints = model.joints()
    out: dict[str, ex.Expr] = {name: ex.Name(name) for name in spec.joints}
    for name, raw in spec.locked.items():
        key = f"robot.locked.{name}"
        locked = ctx.literal(raw, key)
        _check_dimension(ctx, joints[name], locked.dimension, key, raw)
        _within(ctx, joints[name], [locked.si], locked.unit, key, f"locked value '{raw}'")
        out[name] = ex.Num(locked.si)

    def value(name: str, seen: tuple[str, ...]) -> ex.Expr:
        if name in out:
            return out[name]
        joint = joints.get(name)
        if joint is None or joint.mimic is None:
            if joint is not None and joint.kind != "fixed" and joint.limits is not None and not joint.limits[0] - LIMIT_SLACK <= 0.0 <= joint.limits[1] + LIMIT_SLACK:
                raise ctx.fail(
                    f"robot.locked.{name}",
                    f"joint '{name}' is neither moving nor locked, so it is held at 0, outside its limits in the model: lock it at a value within them",
                )
            out[name] = ex.Num(0.0)
            return out[name]
        other, scale, offset = joint.mimic
        if other in seen:
            raise ctx.fail(f"robot.{model.format}", f"mimic joints follow each other in a cycle: {' -> '.join(seen + (other,))}")
        base = value(other, seen + (other,))
        if isinstance(base, ex.Num):
            tree: ex.Expr = ex.Num(scale * base.value + offset)
        else:
            tree = ex.BinOp("+", ex.BinOp("*", ex.Num(scale), base), ex.Num(offset)) if offset else ex.BinOp("*", ex.Num(scale), base)
        out[name] = tree
        return tree

    for name in joints:
        tree = value(name, (name,))
        if not isinstance(tree, ex.Num) and IDENTIFIER.match(name) and name not in ctx.symbol_kind and name not in RESERVED:
            ctx.symbol_kind[name] = "coupled"  # a mimic joint's name is usable in expressions
            ctx.coupled[name] = tree
    return out


def _rotations(matrix: Matrix) -> list[Transform]:
    from ..robot import rpy_from_matrix

    roll, pitch, yaw = rpy_from_matrix(matrix)
    return [Rotation(axis, ex.Num(angle)) for axis, angle in ((Z, yaw), (Y, pitch), (X, roll)) if angle != 0.0]


def _motion(joint: RobotJoint, value: ex.Expr) -> list[Transform]:
    if joint.reference:
        value = ex.Num(value.value - joint.reference) if isinstance(value, ex.Num) else ex.BinOp("-", value, ex.Num(joint.reference))
    if isinstance(value, ex.Num) and value.value == 0.0:
        return []
    norm = math.sqrt(sum(c * c for c in joint.axis))
    axis = tuple(ex.Num(c / norm) for c in joint.axis)
    if joint.kind == "prismatic":
        return [Translation(tuple(ex.BinOp("*", a, value) if a.value else ex.Num(0.0) for a in axis))]  # type: ignore[arg-type]  # an axis is three components
    motion: list[Transform] = [Rotation(axis, value)]  # type: ignore[arg-type]  # an axis is three components
    if any(joint.anchor):
        there = tuple(ex.Num(c) for c in joint.anchor)
        back = tuple(ex.Num(-c) for c in joint.anchor)
        motion = [Translation(there), *motion, Translation(back)]  # type: ignore[arg-type]  # there and back are three components
    return motion


def frames(ctx: Context, model: RobotModel | None) -> tuple[Frame, ...]:
    """One frame per link, parents first."""
    spec = ctx.spec.robot
    if model is None or spec is None:
        return ()
    values = _values(ctx, model, spec)
    moving: dict[str, str | None] = {}
    out = []
    for link in model.links:
        transforms: list[Transform] = []
        keys: list[str] = []
        origin_key = f"robot.{model.format}"
        if any(link.xyz):
            transforms.append(Translation(tuple(ex.Num(c) for c in link.xyz)))  # type: ignore[arg-type]  # a vector of the model is three floats
            keys.append(origin_key)
        rotations = _rotations(link.rotation)
        transforms += rotations
        keys += [origin_key] * len(rotations)
        for joint in link.joints:
            motion = _motion(joint, values[joint.name])
            transforms += motion
            section = "locked" if joint.name in spec.locked else "joints"
            keys += [f"robot.{section}.{joint.name}"] * len(motion)
        used = set().union(*(ex.names(t.angle) if isinstance(t, Rotation) else set().union(*(ex.names(c) for c in t.vector)) for t in transforms))
        parent = link.parent
        sub = spec.subsystem if used or (parent is not None and moving.get(parent)) else None
        moving[link.name] = sub
        out.append(Frame(link.name, parent if parent is not None else GROUND, tuple(transforms), sub, "", tuple(keys), None, True))
    return tuple(out)


def bodies(ctx: Context, model: RobotModel | None, frames: dict[str, Frame]) -> tuple[Body, ...]:
    """One body per link with a mass, at its inertial origin."""
    if model is None:
        return ()
    out = []
    for link in model.links:
        if link.mass > 0:
            com = Point(link.name, tuple(ex.Num(c) for c in link.com))  # type: ignore[arg-type]  # a vector of the model is three floats
            out.append(Body(link.name, ex.Num(link.mass), com, frames[link.name].subsystem, f"link of {Path(model.path).name}"))
    return tuple(out)
