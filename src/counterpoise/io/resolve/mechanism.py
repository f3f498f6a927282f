"""The mechanism: subsystems and coordinates, frames, bodies, counter-masses, springs."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any


from ...model import expr as ex
from ...model.elements import PULLEY_CLEARANCE, SLACK_MARGIN, CounterMass, DirectMount, Pulley, SpringDesignOptions, ZeroFreeLengthSpring
from ...model.mechanism import GROUND, Body, Coordinate, Frame, Rotation, Subsystem, Transform, Translation
from ...model.units import (
    DIMENSIONLESS,
    FORCE,
    LENGTH,
    MASS,
    STIFFNESS,
    canonical_dimension,
    check_dimension,
    dimension_name,
)
from ..schema import DHSpec, RotateSpec
from . import loops
from .context import RESERVED, Context, suggest, topological
from .parts import tolerance
from .quantities import same_angle_unit


def subsystems(ctx: Context) -> tuple[tuple[Subsystem, ...], tuple[Coordinate, ...]]:
    subs, coords = [], []
    for sname, sub in ctx.spec.subsystems.items():
        for cname, c in sub.coordinates.items():
            key = f"subsystems.{sname}.coordinates.{cname}"
            if c.dependent or c.range is None:
                coords.append(loops.dependent_coordinate(ctx, sname, cname, c, key))
                continue
            lo = ctx.literal(c.range[0], f"{key}.range")
            hi = ctx.literal(c.range[1], f"{key}.range")
            if lo.dimension != hi.dimension:
                raise ctx.fail(f"{key}.range", "both ends of a range need the same dimension")
            if lo.dimension not in ("", canonical_dimension(LENGTH)):
                raise ctx.fail(f"{key}.range", f"a coordinate is an angle or a length, got {dimension_name(lo.dimension)}")
            if not lo.si < hi.si:
                raise ctx.fail(f"{key}.range", f"empty range [{c.range[0]}, {c.range[1]}]: the lower end must be below the upper end")
            home = 0.5 * (lo.si + hi.si)
            if c.home is not None:
                given = ctx.literal(c.home, f"{key}.home")
                same_angle_unit(ctx, lo.unit, given, c.home, f"{key}.home")  # 'home = 90': radians? say so before the range
                home = given.si
            if not lo.si <= home <= hi.si:
                raise ctx.fail(f"{key}.home", "home lies outside the range")
            ctx.symbol_unit[cname] = lo.unit
            ctx.symbol_value[cname] = home
            ctx.box[cname] = (lo.si, hi.si)
            coords.append(Coordinate(cname, sname, lo.si, hi.si, home, lo.unit, c.description))
        subs.append(Subsystem(sname, tuple(sub.coordinates), sub.description))
        coupled(ctx, sname, sub)
    return tuple(subs), tuple(coords)


def coupled(ctx: Context, sname: str, sub: Any) -> None:
    """``coupled.<name> = <expression of this subsystem's coordinates and parameters>``.

    The name may then appear wherever a coordinate may (frame angles and translations);
    it is replaced by its expression, so the frame is driven by the coordinates it uses.
    """
    own = set(sub.coordinates)
    for name, raw in sub.coupled.items():
        key = f"subsystems.{sname}.coupled.{name}"
        if name in RESERVED or name in ctx.symbol_kind:
            where = f" by {ctx.symbol_kind[name]}.{name}" if name in ctx.symbol_kind else " (reserved)"
            raise ctx.fail(key, f"name '{name}' is already used{where}")
        tree = ctx.expression(raw, key, own | ctx.parameter_names() | set(ctx.coupled))
        if not ex.names(tree) & own:
            raise ctx.fail(key, f"'{raw}' uses none of the coordinates of subsystem '{sname}' ({', '.join(sorted(own))})")
        ctx.symbol_kind[name] = "coupled"
        ctx.coupled[name] = tree


def frames(ctx: Context, given: tuple[Frame, ...] = ()) -> tuple[Frame, ...]:
    """The frames of ``[frames]``, after ``given`` ones (a robot's links), which they may hang from."""
    specs = ctx.spec.frames
    known = {f.name: f for f in given}
    coordinate_subsystem = {c: s for s, sub in ctx.spec.subsystems.items() for c in sub.coordinates}
    if ctx.spec.robot is not None:
        coordinate_subsystem.update({c: ctx.spec.robot.subsystem for c in ctx.spec.robot.joints})
    for name, f in specs.items():
        if name == GROUND:
            raise ctx.fail(f"frames.{name}", "'ground' is the fixed world frame and cannot be declared")
        for field, target in (("parent", f.parent), ("orientation", f.orientation)):
            if target is not None and target != GROUND and target not in specs and target not in known:
                close = suggest(target, list(specs) + list(known) + [GROUND])
                ctx.defer(ctx.fail(f"frames.{name}.{field}", f"unknown frame '{target}'{close}"))
    ctx.check()  # every unknown parent or orientation frame, one line each
    order = topological(
        {n: None for n in specs},
        lambda n: {p for p in (specs[n].parent, specs[n].orientation) if p is not None} & specs.keys(),
        "frames",
        ctx.label,
        key_suffix="parent",
    )
    frames: dict[str, Frame] = dict(known)
    for name in order:
        f = specs[name]
        key = f"frames.{name}"
        transforms: list[Transform] = []
        used: set[str] = set()
        keys: list[str] = []
        for i, t in enumerate(f.transforms):
            tkey = f"{key}.transforms.{i}"
            if isinstance(t, DHSpec):
                used |= dh_row(ctx, t, f"{tkey}.dh", transforms, keys)
                continue
            keys.append(tkey)
            if isinstance(t, RotateSpec):
                axis = ctx.axis(t.rotate, f"{tkey}.rotate")
                angle = ctx.expression(t.angle, f"{tkey}.angle", ctx.geometry_names())
                ctx.expect(angle, t.angle, f"{tkey}.angle", DIMENSIONLESS, "an angle")
                used |= ex.names(angle)
                transforms.append(Rotation(axis, angle))
            else:
                vec = ctx.vector(t.translate, f"{tkey}.translate", LENGTH, "a translation", ctx.geometry_names())
                for comp in vec:
                    used |= ex.names(comp)
                transforms.append(Translation(vec))
        if f.orientation is not None:
            turns = reorientation(f.parent, transforms, f.orientation, frames)
            for turn in turns:
                used |= ex.names(turn.angle)
            transforms += turns
            keys += [f"{key}.orientation"] * len(turns)
        subsystems = {coordinate_subsystem[n] for n in used if n in coordinate_subsystem}
        for other in (f.parent, f.orientation):
            other_sub = frames[other].subsystem if other not in (None, GROUND) else None
            if other_sub is not None:
                subsystems.add(other_sub)
        if len(subsystems) > 1:
            raise ctx.fail(
                key, f"moves with coordinates of several subsystems ({', '.join(sorted(subsystems))}); subsystems must move independently"
            )
        frames[name] = Frame(
            name, f.parent, tuple(transforms), next(iter(subsystems), None), f.description, tuple(keys), f.orientation
        )
    return tuple(given) + tuple(frames[n] for n in order)


def _path(name: str, frames: Mapping[str, Frame]) -> list[str]:
    """The frames from the ground to ``name`` (ground first, ``name`` last)."""
    out = [name]
    while out[-1] != GROUND:
        parent = frames[out[-1]].parent
        out.append(parent if parent is not None else GROUND)
    return out[::-1]


def _inverse(rotations: list[Rotation]) -> list[Rotation]:
    return [Rotation(r.axis, ex.Num(-r.angle.value) if isinstance(r.angle, ex.Num) else ex.Neg(r.angle)) for r in reversed(rotations)]


def reorientation(parent: str, own: list[Transform], target: str, frames: Mapping[str, Frame]) -> list[Rotation]:
    """Rotations that, appended to a frame with ``parent`` and transforms ``own``, turn its
    axes into those of ``target``: undo ``own`` and the parent chain down to the common
    ancestor, then redo the chain from there up to ``target``. Each step is a rotation by
    an affine angle, so the energy stays a trigonometric polynomial of the coordinates."""
    up, down = _path(parent, frames), _path(target, frames)
    common = 0
    while common < min(len(up), len(down)) and up[common] == down[common]:
        common += 1
    undo: list[Rotation] = _inverse([t for t in own if isinstance(t, Rotation)])
    for name in reversed(up[common:]):
        undo += _inverse([t for t in frames[name].transforms if isinstance(t, Rotation)])
    redo = [t for name in down[common:] for t in frames[name].transforms if isinstance(t, Rotation)]
    return undo + redo


X_AXIS = (ex.Num(1.0), ex.Num(0.0), ex.Num(0.0))
Z_AXIS = (ex.Num(0.0), ex.Num(0.0), ex.Num(1.0))
ZERO = ex.Num(0.0)


def dh_row(ctx: Context, spec: DHSpec, key: str, transforms: list[Transform], keys: list[str]) -> set[str]:
    """A modified (Craig) DH row: Rot_x(alpha) Trans_x(a) Rot_z(theta) Trans_z(d), appended
    to ``transforms``; returns the names it uses."""
    row = spec.dh
    used: set[str] = set()
    trees = {}
    for field, dimension, what in (("alpha", DIMENSIONLESS, "an angle"), ("a", LENGTH, "a length"), ("theta", DIMENSIONLESS, "an angle"), ("d", LENGTH, "a length")):
        raw = getattr(row, field)
        tree = ctx.expression(raw, f"{key}.{field}", ctx.geometry_names())
        ctx.expect(tree, raw, f"{key}.{field}", dimension, what)
        used |= ex.names(tree)
        trees[field] = tree
    transforms += [
        Rotation(X_AXIS, trees["alpha"]),
        Translation((trees["a"], ZERO, ZERO)),
        Rotation(Z_AXIS, trees["theta"]),
        Translation((ZERO, ZERO, trees["d"])),
    ]
    keys += [f"{key}.alpha", f"{key}.a", f"{key}.theta", f"{key}.d"]
    return used


def bodies(ctx: Context, frames: Mapping[str, Frame]) -> tuple[Body, ...]:
    out = []
    for name, b in ctx.spec.bodies.items():
        key = f"bodies.{name}"
        mass = ctx.expression(b.mass, f"{key}.mass", ctx.design_names())
        ctx.nonnegative(mass, b.mass, f"{key}.mass", MASS, "a mass")
        com = ctx.point(b.frame, b.com, f"{key}.com", frames, f"{key}.frame")
        out.append(Body(name, mass, com, ctx.subsystem_of(b.frame, frames), b.description))
    return tuple(out)


def counter_masses(ctx: Context, frames: Mapping[str, Frame]) -> tuple[CounterMass, ...]:
    out = []
    for name, c in ctx.spec.counter_masses.items():
        key = f"counter_masses.{name}"
        mass = ctx.expression(c.mass, f"{key}.mass", ctx.design_names())
        ctx.nonnegative(mass, c.mass, f"{key}.mass", MASS, "a mass")
        pos = ctx.point(c.frame, c.position, f"{key}.position", frames, f"{key}.frame")
        carrier = joint(ctx, c.frame, c.joint, frames, f"{key}.joint")
        out.append(CounterMass(name, mass, pos, carrier, ctx.subsystem_of(c.frame, frames), c.description))
    return tuple(out)


def joint(ctx: Context, frame: str, coordinate: str | None, frames: Mapping[str, Frame], key: str) -> tuple[str, int] | None:
    """Innermost rotation of the chain driven by ``coordinate`` (any coordinate if None)."""
    coordinates = {n for n, k in ctx.symbol_kind.items() if k == "coordinates"}
    if coordinate is not None and coordinate not in coordinates:
        raise ctx.fail(key, f"unknown coordinate '{coordinate}'{suggest(coordinate, coordinates)}")
    wanted = {coordinate} if coordinate else coordinates
    name: str | None = frame
    while name is not None and name != GROUND:
        f = frames[name]
        for i in range(len(f.transforms) - 1, -1, -1):
            t = f.transforms[i]
            if isinstance(t, Rotation) and ex.names(t.angle) & wanted:
                return (name, i)
        name = f.parent
    if coordinate is not None:
        raise ctx.fail(key, f"no rotation driven by '{coordinate}' carries frame '{frame}'")
    return None


def springs(ctx: Context, frames: Mapping[str, Frame]) -> tuple[ZeroFreeLengthSpring, ...]:
    out = []
    for name, s in ctx.spec.springs.items():
        key = f"springs.{name}"
        if s.slot is not None:
            if s.stiffness is not None:
                raise ctx.fail(f"{key}.slot", "give either a stiffness or a slot (the slot's part sets the stiffness), not both")
            if ctx.symbol_kind.get(s.slot) != "slots":
                raise ctx.fail(f"{key}.slot", f"unknown slot '{s.slot}'{suggest(s.slot, list(ctx.spec.slots))}")
            k: ex.Expr = ex.Name(s.slot)
        elif s.stiffness is None:
            raise ctx.fail(f"{key}.stiffness", "missing required key (or give a slot = \"<name>\" of [slots])")
        else:
            k = ctx.expression(s.stiffness, f"{key}.stiffness", ctx.design_names())
            ctx.nonnegative(k, s.stiffness, f"{key}.stiffness", STIFFNESS, "a stiffness")
        a = ctx.point(s.from_.frame, s.from_.point, f"{key}.from.point", frames, f"{key}.from.frame")
        b = ctx.point(s.to.frame, s.to.point, f"{key}.to.point", frames, f"{key}.to.frame")
        subs = {n for n in (ctx.subsystem_of(a.frame, frames), ctx.subsystem_of(b.frame, frames)) if n is not None}
        if len(subs) > 1:
            raise ctx.fail(key, f"connects subsystems {' and '.join(sorted(subs))}; subsystems must move independently")
        options = design_options(ctx, s, key)
        direct = direct_mount(ctx, s, key)
        margin = SLACK_MARGIN if s.slack_margin is None else length(ctx, s.slack_margin, f"{key}.slack_margin")
        out.append(ZeroFreeLengthSpring(name, k, (a, b), next(iter(subs), None), s.description, s.slot, direct, options, pulley(ctx, s, key), margin))
    return tuple(out)


def length(ctx: Context, value: Any, key: str) -> float:
    """A literal length ≥ 0 (SI)."""
    q = ctx.literal(value, key)
    with ctx.at(key):
        check_dimension(q.dimension, LENGTH, f"'{value}'")
    if not (math.isfinite(q.si) and q.si >= 0):
        raise ctx.fail(key, f"must be a length ≥ 0, got '{value}'")
    return q.si


def direction(ctx: Context, value: Any, key: str) -> tuple[float, float, float]:
    """A literal direction (three plain numbers, not all 0), normalised."""
    if isinstance(value, str) or len(value) != 3 or not all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in value):
        raise ctx.fail(key, f"expected a direction of three plain numbers such as [0, -1, 0], got {value!r}")
    norm = math.sqrt(sum(float(c) ** 2 for c in value))
    if norm == 0:
        raise ctx.fail(key, "the direction must not be the zero vector")
    x, y, z = (float(c) / norm for c in value)
    return (x, y, z)


def pulley(ctx: Context, s: Any, key: str) -> Pulley | None:
    """A pulley mount's pulley (docs/build.md#pulleys); None for a direct mount."""
    spec = s.pulley
    if s.mount == "direct":
        if spec is not None:
            raise ctx.fail(f"{key}.pulley", 'a directly attached spring (mount = "direct") has no pulley')
        return None
    if spec is None:
        return Pulley()
    pkey = f"{key}.pulley"
    radius = 0.0 if spec.radius is None else length(ctx, spec.radius, f"{pkey}.radius")
    clearance = PULLEY_CLEARANCE if spec.clearance is None else length(ctx, spec.clearance, f"{pkey}.clearance")
    axis = (0.0, 0.0, 1.0) if spec.axis is None else direction(ctx, spec.axis, f"{pkey}.axis")
    lead = None if spec.lead is None else direction(ctx, spec.lead, f"{pkey}.lead")
    if lead is not None and abs(sum(a * b for a, b in zip(axis, lead))) > 1 - 1e-6:
        raise ctx.fail(f"{pkey}.lead", "the lead direction runs along the pulley's axis: it must lie in the pulley's plane")
    fixing = None if spec.fixing is None else direction(ctx, spec.fixing, f"{pkey}.fixing")
    if fixing is not None and not spec.pin:
        raise ctx.fail(f"{pkey}.fixing", "only a cable wrapped onto a pin (pin = true) has a fixing point")
    return Pulley(radius, clearance, axis, 1 if spec.wrap == "ccw" else -1, spec.pin, lead, fixing)


#: the keys of a free-stiffness spring's design (:class:`SpringDesignOptions`); ``max_length``
#: of a direct mount is the spring's own limit (:func:`direct_mount`), not one of them
DESIGN_KEYS = ("material", "max_outer_diameter", "max_body_length", "max_length", "rate_tolerance", "min_safety_factor")


def design_options(ctx: Context, s: Any, key: str) -> SpringDesignOptions:
    """How the helical spring of a free-stiffness spring is designed (docs/springs.md)."""
    given = {k: getattr(s, k) for k in DESIGN_KEYS if getattr(s, k) is not None and not (k == "max_length" and s.mount == "direct")}
    if not given:
        return SpringDesignOptions()
    if s.slot is not None:
        raise ctx.fail(f"{key}.{next(iter(given))}", "a spring with a slot is a catalogue part; only a free-stiffness spring is designed")
    from ...springs.materials import materials  # numpy and a CSV only

    values: dict[str, Any] = {}
    if "material" in given:
        known = materials()
        if s.material not in known:
            raise ctx.fail(f"{key}.material", f"unknown spring material '{s.material}'{suggest(s.material, list(known))} (known: {', '.join(known)})")
        values["material"] = s.material
    for field in ("max_outer_diameter", "max_body_length", "max_length"):
        if field in given:
            q = ctx.literal(given[field], f"{key}.{field}")
            with ctx.at(f"{key}.{field}"):
                check_dimension(q.dimension, LENGTH, f"'{given[field]}'")
            if not (math.isfinite(q.si) and q.si > 0):
                raise ctx.fail(f"{key}.{field}", f"must be a positive length, got '{given[field]}'")
            values[field] = q.si
    if "rate_tolerance" in given:
        values["rate_tolerance"] = tolerance(ctx, given["rate_tolerance"], f"{key}.rate_tolerance")
    if "min_safety_factor" in given:
        values["min_safety_factor"] = float(given["min_safety_factor"])
    return SpringDesignOptions(**values)


def direct_mount(ctx: Context, s: Any, key: str) -> DirectMount | None:
    """The cable and the spring's own data of a directly attached spring (None: pulley)."""
    given = {k: getattr(s, k) for k in ("free_length", "initial_tension", "max_length", "cable") if getattr(s, k) is not None}
    if s.mount == "pulley":
        given.pop("max_length", None)  # a designed spring's envelope (design_options)
        if given:
            raise ctx.fail(f"{key}.{next(iter(given))}", 'only a directly attached spring (mount = "direct") has this key')
        return None
    values: dict[str, ex.Expr | None] = {}
    for field in ("free_length", "initial_tension", "max_length"):
        if s.slot is not None:
            if field in given:
                raise ctx.fail(f"{key}.{field}", "a spring with a slot takes this from its part")
            values[field] = ex.Name(f"{s.slot}:{field}")
        elif field in given:
            dimension, what = (FORCE, "a force") if field == "initial_tension" else (LENGTH, "a length")
            tree = ctx.expression(given[field], f"{key}.{field}", ctx.design_names())
            ctx.nonnegative(tree, given[field], f"{key}.{field}", dimension, what)
            values[field] = tree
        elif field == "free_length":
            raise ctx.fail(f"{key}.free_length", 'missing required key for a directly attached spring (or give a slot)')
        else:
            values[field] = ex.Num(0.0) if field == "initial_tension" else None
    cable: ex.Expr = ex.Num(0.0)
    if "cable" in given:
        cable = ctx.expression(given["cable"], f"{key}.cable", ctx.design_names())
        ctx.nonnegative(cable, given["cable"], f"{key}.cable", LENGTH, "a length")
    return DirectMount(values["free_length"], values["initial_tension"], cable, values["max_length"])  # type: ignore[arg-type]  # the required values were checked above
