"""``[robust]``: tolerances, mode and tuning variables (docs/robust.md)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ...model import expr as ex
from ...model.elements import CounterMass, ZeroFreeLengthSpring
from ...model.mechanism import Body
from ...model.robust import KINDS, RobustSpec, Tolerance
from ...model.units import FORCE, LENGTH, MASS, STIFFNESS, check_dimension
from .context import Context, numpy_functions, suggest
from .parts import tolerance as fraction

#: tuning enumerates 2ⁿ corners: at most this many deviations
MAX_TUNED_DEVIATIONS = 10
#: the largest ``weight`` (kg per unit of worst-case ratio): beyond it the objective's own
#: terms are lost in rounding next to weight × ρ and the solvers' scaled data overflow (a
#: weight of 1e308 made Clarabel fail and ran the minimax NLP to IPOPT's time limit); the
#: counterpart is already "ρ first" far below it (the pendulum's switch point is 60 kg)
MAX_WEIGHT = 1e9
#: an absolute length tolerance (a centre of mass, a spring end) beyond this is not a tolerance
MAX_LENGTH_TOLERANCE = 1.0  # m

#: per kind: the dimension of an absolute tolerance, whether a percentage is accepted, the elements' section
_KIND = {
    "rate": (STIFFNESS, True, "springs"),
    "initial_tension": (FORCE, False, "springs"),
    "mass": (MASS, True, "bodies"),
    "com": (LENGTH, False, "bodies"),
    "point": (LENGTH, False, "springs"),
}


def robust(
    ctx: Context,
    bodies: Sequence[Body],
    springs: Sequence[ZeroFreeLengthSpring],
    counter_masses: Sequence[CounterMass] = (),
    payloads: Sequence[str] = (),
) -> RobustSpec | None:
    """``payloads``: the names of the payload bodies (a kind-wide mass or centre-of-mass
    tolerance leaves them out: their mass is the range's)."""
    spec = ctx.spec.robust
    if spec is None:
        return None
    key = "robust"  # the tables it cannot be combined with yet are the registry's (counterpoise.registry, resolve.combinations)
    if ctx.spec.payloads and spec.mode != "none":
        raise ctx.fail(
            f"{key}.mode",
            f"not combinable yet: mode = \"{spec.mode}\" with [payloads]; a payload range is designed as usual and its tolerance corners "
            "tuned at every payload (mode = \"none\" with tune, docs/robust.md#payload-ranges)",
        )
    if ctx.spec.slots:  # catalogue parts: the chosen part's design judged at every corner (docs/robust.md#catalogue-parts)
        if spec.mode != "none":
            raise ctx.fail(
                f"{key}.mode",
                f"not combinable yet: mode = \"{spec.mode}\" with [slots]; the chosen parts' design is judged at every tolerance corner "
                "(mode = \"none\", docs/robust.md#catalogue-parts)",
            )
        if spec.tune:  # the part search designs every variable free; the tuning holds the tune ones at their factory setting
            raise ctx.fail(f"{key}.tune", "not combinable yet: tune with [slots] (the part search does not hold the tune variables; docs/robust.md#catalogue-parts)")
        if ctx.spec.payloads:
            raise ctx.fail(key, "not combinable yet: [robust] with [slots] and [payloads] (docs/robust.md#catalogue-parts)")
    if spec.tolerances == {}:
        raise ctx.fail(f"{key}.tolerances", "missing: give at least one tolerance, e.g. rate = \"10 %\"")
    # a body's or a counter-mass's name; a kind-wide value applies to every one but the payloads
    masses = [b.name for b in bodies] + [c.name for c in counter_masses]
    items = {"springs": [s.name for s in springs], "bodies": masses}
    every = {"springs": items["springs"], "bodies": [n for n in masses if n not in set(payloads)]}
    trees: dict[tuple[str, str], ex.Expr] = {("rate", s.name): s.stiffness for s in springs}
    trees.update({("mass", b.name): b.mass for b in bodies})
    trees.update({("mass", c.name): c.mass for c in counter_masses})
    direct = [s.name for s in springs if s.direct is not None]
    if direct and spec.tune:
        raise ctx.fail(
            f"{key}.tune",
            f"not combinable yet: tune with directly attached springs ('{direct[0]}': a tuned corner is not balanced exactly; docs/robust.md#not-done)",
        )
    if ctx.spec.loops:  # closed loops: the worst case along the manifold; the tuning and the rest not yet
        if spec.tune:
            raise ctx.fail(f"{key}.tune", "not combinable yet: tune with [loops] (the tuning law reads poses of an open chain; docs/robust.md#robust-loops)")
        if direct:
            raise ctx.fail(key, f"not combinable yet: [robust] with [loops] and directly attached springs ('{direct[0]}'; docs/robust.md#robust-loops)")
        if ctx.spec.payloads:
            raise ctx.fail(key, "not combinable yet: [robust] with [loops] and [payloads] (docs/robust.md#robust-loops)")
    if direct and ctx.spec.payloads:
        raise ctx.fail(key, f"not combinable yet: [robust] with [payloads] and directly attached springs ('{direct[0]}'; docs/robust.md#not-done)")
    tolerances: list[Tolerance] = []
    for kind, raw in spec.tolerances.items():
        kkey = f"{key}.tolerances.{kind}"
        if kind not in _KIND:
            raise ctx.fail(kkey, f"unknown tolerance kind '{kind}'{suggest(kind, KINDS)} (expected one of {', '.join(KINDS)})")
        section = _KIND[kind][2]
        names = items[section]
        given = raw if isinstance(raw, dict) else {name: raw for name in every[section]}
        if not given:
            raise ctx.fail(kkey, f"an empty table: name at least one of the {section}" if isinstance(raw, dict) else f"the problem has no {section} to tolerance")
        for item, value in given.items():
            ikey = f"{kkey}.{item}" if isinstance(raw, dict) else kkey
            if item not in names:
                what = "spring" if section == "springs" else "body or counter-mass"
                raise ctx.fail(ikey, f"unknown {what} '{item}'{suggest(item, names)}")
            t = _tolerance(ctx, kind, item, value, ikey)
            _check_size(ctx, t, trees.get((kind, item)), value, ikey)
            if kind == "point" and item in direct and t.amount > 0 and spec.shape != "box":
                raise ctx.fail(
                    "robust.shape",
                    f"not combinable yet: shape = \"{spec.shape}\" with a point tolerance of the directly attached spring '{item}' ({ikey}): "
                    "its residual is not affine in the deviation, and the worst case is taken over the box's corners",
                )
            tolerances.append(t)
    mode = spec.mode
    weight = limit = 0.0
    if mode == "minimise":
        if spec.weight is None:
            raise ctx.fail(f"{key}.weight", "mode = \"minimise\" needs a weight (kg per unit of worst-case residual ratio, e.g. \"2 kg\")")
        w = ctx.literal(spec.weight, f"{key}.weight")
        with ctx.at(f"{key}.weight"):
            check_dimension(w.dimension, MASS, f"'{spec.weight}'")
        if not w.si > 0:
            raise ctx.fail(f"{key}.weight", "must be positive")
        if not w.si <= MAX_WEIGHT:
            raise ctx.fail(
                f"{key}.weight",
                f"'{spec.weight}' is too large: weights above {MAX_WEIGHT:g} kg per unit of worst-case ratio overflow the solvers' scaled data "
                "and leave the objective's own terms in rounding; any weight above the design's switch point already minimises the worst case first",
            )
        weight = w.si
    elif spec.weight is not None:
        raise ctx.fail(f"{key}.weight", "a weight is only used with mode = \"minimise\"")
    if mode == "limit":
        if spec.limit is None:
            raise ctx.fail(f"{key}.limit", "mode = \"limit\" needs a limit (the largest worst-case residual ratio, e.g. 0.05)")
        limit = float(spec.limit)
    elif spec.limit is not None:
        raise ctx.fail(f"{key}.limit", "a limit is only used with mode = \"limit\"")
    for i, name in enumerate(spec.tune):
        if name in spec.tune[:i]:
            raise ctx.fail(f"{key}.tune.{i}", f"'{name}' is listed twice (first as robust.tune.{spec.tune.index(name)})")
        if ctx.symbol_kind.get(name) != "variables":
            raise ctx.fail(f"{key}.tune.{i}", f"unknown variable '{name}'{suggest(name, list(ctx.spec.variables))}")
        if ctx.spec.variables[name].adjustable:
            raise ctx.fail(f"{key}.tune.{i}", f"'{name}' is adjustable per scenario; a tuning variable must not be")
    deviations = sum({"rate": 1, "mass": 1, "com": 3, "point": 6}.get(t.kind, 0) for t in tolerances if t.amount > 0)
    if spec.tune and deviations > MAX_TUNED_DEVIATIONS:
        raise ctx.fail(
            f"{key}.tune",
            f"tuning re-balances every corner of the tolerance box: {deviations} deviations (a centre of mass counts 3, "
            f"a spring's points 6) give 2^{deviations} corners; at most {MAX_TUNED_DEVIATIONS} deviations can be tuned",
        )
    if spec.tune and all(t.kind == "initial_tension" for t in tolerances):
        raise ctx.fail(f"{key}.tune", "tuning re-balances rate, mass, centre-of-mass and point corners; only initial tensions are toleranced")
    steps = _per_tune(ctx, spec.step, spec.tune, f"{key}.step", "trial turn")
    pitch = _per_tune(ctx, spec.pitch, spec.tune, f"{key}.pitch", "screw pitch", length_only=True)
    return RobustSpec(tuple(tolerances), mode, weight, limit, spec.shape, tuple(spec.tune), spec.description, steps, pitch)


def _per_tune(ctx: Context, table: dict[str, Any], tune: Sequence[str], key: str, what: str, length_only: bool = False) -> tuple[tuple[str, float], ...]:
    """A table keyed by tune variables of quantities in each variable's unit (a pitch: a
    length, for a variable that is a length), positive and finite."""
    out = []
    for name, raw in table.items():
        k = f"{key}.{name}"
        if name not in tune:
            raise ctx.fail(k, f"'{name}' is not a tune variable{suggest(name, list(tune))} (robust.tune = [{', '.join(tune)}])")
        q = ctx.literal(raw, k)
        unit = ctx.symbol_unit[name]
        if length_only and unit.dimension != LENGTH:
            raise ctx.fail(k, f"a {what} is for a tune variable that is a length (a screw position); '{name}' is not")
        with ctx.at(k):
            check_dimension(q.dimension, unit.dimension, f"'{raw}'")
        if not (math.isfinite(q.si) and q.si > 0):
            raise ctx.fail(k, f"a {what} must be positive and finite, got '{raw}'")
        out.append((name, q.si))
    return tuple(out)


def _tolerance(ctx: Context, kind: str, item: str, value: Any, key: str) -> Tolerance:
    dimension, relative_ok, _ = _KIND[kind]
    if isinstance(value, str) and value.strip().endswith("%") or isinstance(value, (int, float)) and not isinstance(value, bool) and relative_ok:
        if not relative_ok:
            raise ctx.fail(key, f"a {kind} tolerance is a quantity (e.g. '{'0.5 N' if kind == 'initial_tension' else '1 mm'}'), not a percentage")
        amount = fraction(ctx, value, key)
        if not amount < 1:
            what = "rate" if kind == "rate" else "mass"
            raise ctx.fail(key, f"a relative tolerance must be below 100 % (at -100 % the {what} vanishes), got '{value}'")
        return Tolerance(kind, item, amount, True, key)
    q = ctx.literal(value, key)
    with ctx.at(key):
        check_dimension(q.dimension, dimension, f"'{value}'")
    if not math.isfinite(q.si):
        raise ctx.fail(key, f"a tolerance must be finite, got '{value}'")
    if not q.si >= 0:
        raise ctx.fail(key, f"a tolerance must not be negative, got '{value}'")
    if kind in ("com", "point") and not q.si <= MAX_LENGTH_TOLERANCE:
        raise ctx.fail(key, f"a {kind} tolerance of '{value}' is beyond {MAX_LENGTH_TOLERANCE:g} m: not a tolerance of a built part")
    return Tolerance(kind, item, q.si, False, key)


def _check_size(ctx: Context, t: Tolerance, tree: ex.Expr | None, raw: Any, key: str) -> None:
    """An absolute rate or mass tolerance must stay below the nominal value it scatters
    around (at −tolerance the rate or mass would vanish or turn negative): below the largest
    value the element takes within the variables' bounds (corners and random points of the
    box, as :meth:`Context.finite_everywhere` samples it)."""
    if t.relative or tree is None or t.kind not in ("rate", "mass"):
        return
    largest = _largest(ctx, tree)
    if largest is not None and not t.amount < largest:
        unit = "N/m" if t.kind == "rate" else "kg"
        raise ctx.fail(
            key,
            f"an absolute {t.kind} tolerance of '{raw}' is not below the nominal {t.kind} (at most {largest:.6g} {unit} within the bounds): "
            f"at the lower corner the {t.kind} would vanish or turn negative",
        )


def _largest(ctx: Context, tree: ex.Expr) -> float | None:
    """The largest value of ``tree`` over the box of the variables it depends on (None when it
    cannot be evaluated here)."""
    moving = sorted(n for n in ex.names(tree) if n in ctx.box)
    env: dict[str, Any] = {n: v for n, v in ctx.symbol_value.items() if ctx.symbol_kind.get(n) in ("parameters", "slots", "variables", "coordinates")}
    if moving:
        lo = np.array([ctx.box[n][0] for n in moving])
        hi = np.array([ctx.box[n][1] for n in moving])
        points = [lo + (hi - lo) * np.random.default_rng(0).random((256, len(moving)))]
        if len(moving) <= 10:
            points.insert(0, np.array(list(itertools.product(*zip(lo, hi))), dtype=float))
        q = np.vstack(points)
        env.update({n: q[:, i] for i, n in enumerate(moving)})
    with np.errstate(all="ignore"):
        try:
            values = np.asarray(ex.evaluate(tree, env, numpy_functions()), dtype=float)
        except (ArithmeticError, ValueError, TypeError, KeyError):
            return None
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else None
