"""``[synthesis]``: the regions, sites, candidate pairs and bounds of a superstructure
(problems/README.md, docs/synthesis.md), and the compositions it does not cover (each an
input error naming its key: "not combinable")."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from ...model.mechanism import GROUND, Frame
from ...model.synthesis import BOX, HOLES, SEGMENT, Attachment, Region, Site, SynthesisSpec, Vec
from ...model.units import LENGTH, MASS, STIFFNESS, canonical_dimension, dimension_name
from ..schema import RegionSpec
from .context import Context, suggest

#: grid points of one region at most (a spring end is taken at each)
MAX_REGION_POINTS = 10_000


def synthesis(ctx: Context, frames: Mapping[str, Frame]) -> SynthesisSpec | None:
    spec = ctx.spec.synthesis
    if spec is None:
        return None
    key = "synthesis"
    _combinable(ctx)
    attachments = []
    for name, region in spec.regions.items():
        rkey = f"{key}.regions.{name}"
        with ctx.item():
            if name != GROUND and name not in frames:
                raise ctx.fail(rkey, f"unknown frame '{name}'{suggest(name, [*frames, GROUND])} (a region is given per frame, or for the ground)")
            attachments.append(Attachment(name, _region(ctx, region, rkey, spec.points), ctx.subsystem_of(name, frames)))
    sites = []
    for name, site in spec.sites.items():
        skey = f"{key}.sites.{name}"
        with ctx.item():
            if site.frame == GROUND or site.frame not in frames:
                what = "a counter-mass on the ground does no work" if site.frame == GROUND else f"unknown frame '{site.frame}'{suggest(site.frame, list(frames))}"
                raise ctx.fail(f"{skey}.frame", what)
            sub = ctx.subsystem_of(site.frame, frames)
            if sub is None:
                raise ctx.fail(f"{skey}.frame", f"frame '{site.frame}' does not move: a counter-mass on it does no work")
            sites.append(Site(name, site.frame, _region(ctx, site, skey, spec.points), sub))
    ctx.check()
    pairs = _pairs(ctx, attachments)
    min_rate = _bound(ctx, spec.min_rate, f"{key}.min_rate", STIFFNESS, "a spring rate", 0.0)
    max_rate = _bound(ctx, spec.max_rate, f"{key}.max_rate", STIFFNESS, "a spring rate", None if pairs else 0.0)
    min_mass = _bound(ctx, spec.min_mass, f"{key}.min_mass", MASS, "a mass", 0.0)
    max_mass = _bound(ctx, spec.max_mass, f"{key}.max_mass", MASS, "a mass", None if sites else 0.0)
    if pairs and not max_rate > min_rate:
        raise ctx.fail(f"{key}.max_rate", f"must be greater than min_rate ({spec.min_rate or 0})")
    if sites and not max_mass > min_mass:
        raise ctx.fail(f"{key}.max_mass", f"must be greater than min_mass ({spec.min_mass or 0})")
    if not pairs and not sites:
        raise ctx.fail(key, "no candidate element: give regions on at least two bodies that move relative to each other (springs), or a site (counter-masses)")
    if spec.adjust and not ctx.spec.payloads:
        raise ctx.fail(f"{key}.adjust", "adjustments are made per payload: it needs a payload range ([payloads.<name>])")
    return SynthesisSpec(
        attachments=tuple(attachments),
        sites=tuple(sites),
        pairs=pairs,
        min_rate=min_rate,
        max_rate=max_rate,
        min_mass=min_mass,
        max_mass=max_mass,
        spring_cost=spec.spring_cost,
        mass_cost=spec.mass_cost,
        same_rate=spec.same_rate,
        adjust=spec.adjust,
        max_topologies=spec.max_topologies,
        time_limit=spec.time_limit,
        refine=spec.refine,
        description=spec.description,
    )


def _combinable(ctx: Context) -> None:
    """The compositions the exact conditions do not cover: input errors naming the key."""
    spec = ctx.spec
    why = "the synthesised balancer is linear in its rates and masses only when nothing else of the design is free"
    if spec.variables:
        name = next(iter(spec.variables))
        raise ctx.fail(f"variables.{name}", f"not combinable with [synthesis]: {why} (the synthesis makes its own variables; give fixed values)")
    if spec.slots:
        raise ctx.fail(f"slots.{next(iter(spec.slots))}", "not combinable with [synthesis]: catalogue parts are chosen by `solve` once the topology is known")
    if spec.robust is not None:
        raise ctx.fail("robust", "not combinable with [synthesis] (tolerances of a balancer that is not chosen yet)")
    if spec.constraints:
        raise ctx.fail(f"constraints.{next(iter(spec.constraints))}", "not combinable with [synthesis] (design constraints name elements that are not chosen yet)")
    if isinstance(spec.objective, str):
        raise ctx.fail("objective", f"not combinable with [synthesis]: '{spec.objective}' (the synthesis minimises the elements' cost, then the added mass)")
    for name, s in spec.springs.items():
        if s.mount == "direct":
            raise ctx.fail(f"springs.{name}.mount", "not combinable with [synthesis]: a directly attached spring's energy is not a trigonometric polynomial")


def _region(ctx: Context, region: RegionSpec, key: str, default_points: int) -> Region:
    given = [k for k in ("box", "segment", "holes") if getattr(region, k) is not None]
    if len(given) != 1:
        raise ctx.fail(key, "give exactly one of box, segment and holes" + (f" (got {', '.join(given)})" if given else ""))
    allowed = ctx.parameter_names()

    def point(values: Any, where: str) -> Vec:
        tree = ctx.vector(values, where, LENGTH, "a position", allowed)
        x, y, z = (ctx.finite(t, raw, f"{where}.{i}") for i, (t, raw) in enumerate(zip(tree, values)))
        return (x, y, z)

    if region.holes is not None and (region.points is not None or region.spacing is not None):
        raise ctx.fail(f"{key}.points" if region.points is not None else f"{key}.spacing", "a list of holes has no grid: its holes are the points")
    if region.holes is not None:
        if not region.holes:
            raise ctx.fail(f"{key}.holes", "must not be empty")
        holes = tuple(point(h, f"{key}.holes.{i}") for i, h in enumerate(region.holes))
        return Region(HOLES, holes[0], (), holes, (), key)
    if region.box is not None:
        lo, hi = point(region.box.lower, f"{key}.box.lower"), point(region.box.upper, f"{key}.box.upper")
        for i in range(3):
            if lo[i] > hi[i]:
                raise ctx.fail(f"{key}.box.lower.{i}", f"lower corner {region.box.lower[i]!s} is above the upper corner {region.box.upper[i]!s}")
        axes = tuple(tuple(hi[i] - lo[i] if j == i else 0.0 for j in range(3)) for i in range(3) if hi[i] > lo[i])
        kind, origin = BOX, lo
    else:
        segment = region.segment or ((0, 0, 0), (0, 0, 0))  # given: one of the three is (checked above)
        a, b = point(segment[0], f"{key}.segment.0"), point(segment[1], f"{key}.segment.1")
        if a == b:
            raise ctx.fail(f"{key}.segment", "the segment has zero length (a single point is a list of one hole: holes = [[x, y, z]])")
        axes = ((b[0] - a[0], b[1] - a[1], b[2] - a[2]),)
        kind, origin = SEGMENT, a
    points = _points(ctx, region, key, default_points, [math.sqrt(sum(c * c for c in ax)) for ax in axes])
    region_out = Region(kind, origin, tuple(axes), (), points, key)  # type: ignore[arg-type]  # each axis has three components
    count = math.prod(points) if points else 1
    if count > MAX_REGION_POINTS:
        raise ctx.fail(f"{key}.points" if region.points is not None else key, f"{count} grid points (at most {MAX_REGION_POINTS}): give fewer points or a larger spacing")
    return region_out


def _points(ctx: Context, region: RegionSpec, key: str, default_points: int, lengths: list[float]) -> tuple[int, ...]:
    if region.points is not None and region.spacing is not None:
        raise ctx.fail(f"{key}.spacing", "give points or spacing, not both")
    if region.spacing is None:
        n = region.points if region.points is not None else default_points
        return tuple(n for _ in lengths)
    q = ctx.literal(region.spacing, f"{key}.spacing")
    if q.dimension != canonical_dimension(LENGTH):
        raise ctx.fail(f"{key}.spacing", f"expected a length, got {dimension_name(q.dimension)} ('{region.spacing}')")
    if not q.si > 0:
        raise ctx.fail(f"{key}.spacing", f"must be positive, got '{region.spacing}'")
    return tuple(max(2, int(round(length / q.si)) + 1) for length in lengths)


def _pairs(ctx: Context, attachments: list[Attachment]) -> tuple[tuple[str, str], ...]:
    spec = ctx.spec.synthesis
    if spec is None:
        return ()
    by_frame = {a.frame: a for a in attachments}
    if spec.springs == "none":
        return ()
    if spec.springs == "all":
        out = []
        for i, a in enumerate(attachments):
            for b in attachments[i + 1 :]:
                if a.subsystem is None and b.subsystem is None:
                    continue  # neither moves: the spring's length never changes
                if a.subsystem is not None and b.subsystem is not None and a.subsystem != b.subsystem:
                    continue  # a spring may not join two subsystems
                out.append((a.frame, b.frame))
        return tuple(out)
    out = []
    for i, (first, second) in enumerate(spec.springs):
        pkey = f"synthesis.springs.{i}"
        for name in (first, second):
            if name not in by_frame:
                raise ctx.fail(pkey, f"'{name}' has no region (add [synthesis.regions.{name}])")
        a, b = by_frame[first], by_frame[second]
        if first == second:
            raise ctx.fail(pkey, f"a spring joins two bodies, got '{first}' twice")
        if a.subsystem is None and b.subsystem is None:
            raise ctx.fail(pkey, f"neither '{first}' nor '{second}' moves: the spring's length never changes")
        if a.subsystem is not None and b.subsystem is not None and a.subsystem != b.subsystem:
            raise ctx.fail(pkey, f"'{first}' and '{second}' belong to two subsystems ('{a.subsystem}', '{b.subsystem}'): a spring may not join them")
        if (first, second) in out or (second, first) in out:
            raise ctx.fail(pkey, f"the pair '{first}'-'{second}' is given twice")
        out.append((first, second))
    return tuple(out)


def _bound(ctx: Context, value: Any, key: str, dimension: str, what: str, default: float | None) -> float:
    if value is None:
        if default is None:
            raise ctx.fail(key, f"missing: give the largest {what.removeprefix('a ')} a candidate may have")
        return default
    q = ctx.literal(value, key)
    if q.si == 0 and q.dimension == "":
        return 0.0
    if q.dimension != canonical_dimension(dimension):
        raise ctx.fail(key, f"expected {what}, got {dimension_name(q.dimension)} ('{value}')")
    if q.si < 0 or not math.isfinite(q.si):
        raise ctx.fail(key, f"must not be negative, got '{value}'")
    return q.si
