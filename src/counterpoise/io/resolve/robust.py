"""``[robust]``: tolerances, mode and tuning variables (docs/robust.md)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from ...model.elements import ZeroFreeLengthSpring
from ...model.mechanism import Body
from ...model.robust import KINDS, RobustSpec, Tolerance
from ...model.units import FORCE, LENGTH, MASS, STIFFNESS, check_dimension
from .context import Context, suggest
from .parts import tolerance as fraction

#: tuning enumerates 2ⁿ corners: at most this many deviations
MAX_TUNED_DEVIATIONS = 10

#: per kind: the dimension of an absolute tolerance, whether a percentage is accepted, the elements' section
_KIND = {
    "rate": (STIFFNESS, True, "springs"),
    "initial_tension": (FORCE, False, "springs"),
    "mass": (MASS, True, "bodies"),
    "com": (LENGTH, False, "bodies"),
    "point": (LENGTH, False, "springs"),
}


def robust(ctx: Context, bodies: Sequence[Body], springs: Sequence[ZeroFreeLengthSpring]) -> RobustSpec | None:
    spec = ctx.spec.robust
    if spec is None:
        return None
    key = "robust"
    for section in ("payloads", "slots", "loops"):
        if getattr(ctx.spec, section):
            raise ctx.fail(key, f"[robust] cannot be combined with [{section}] yet (docs/robust.md)")
    if spec.tolerances == {}:
        raise ctx.fail(f"{key}.tolerances", "missing: give at least one tolerance, e.g. rate = \"10 %\"")
    items = {"springs": [s.name for s in springs], "bodies": [b.name for b in bodies]}
    direct = [s.name for s in springs if s.direct is not None]
    if direct:
        raise ctx.fail(key, f"[robust] needs pulley-mounted springs; '{direct[0]}' is attached directly")
    tolerances: list[Tolerance] = []
    for kind, raw in spec.tolerances.items():
        kkey = f"{key}.tolerances.{kind}"
        if kind not in _KIND:
            raise ctx.fail(kkey, f"unknown tolerance kind '{kind}'{suggest(kind, KINDS)} (expected one of {', '.join(KINDS)})")
        section = _KIND[kind][2]
        names = items[section]
        given = raw if isinstance(raw, dict) else {name: raw for name in names}
        if not given:
            raise ctx.fail(kkey, f"an empty table: name at least one of the {section}" if isinstance(raw, dict) else f"the problem has no {section} to tolerance")
        for item, value in given.items():
            ikey = f"{kkey}.{item}" if isinstance(raw, dict) else kkey
            if item not in names:
                raise ctx.fail(ikey, f"unknown {'spring' if section == 'springs' else 'body'} '{item}'{suggest(item, names)}")
            tolerances.append(_tolerance(ctx, kind, item, value, ikey))
    mode = spec.mode
    weight = limit = 0.0
    if mode == "minimise":
        if spec.weight is None:
            raise ctx.fail(f"{key}.weight", "mode = \"minimise\" needs a weight (kg per unit of worst-case residual ratio, e.g. \"2 kg\")")
        w = ctx.literal(spec.weight, f"{key}.weight")
        with ctx.at(f"{key}.weight"):
            check_dimension(w.dimension, MASS, f"'{spec.weight}'")
        if w.si <= 0:
            raise ctx.fail(f"{key}.weight", "must be positive")
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
    return RobustSpec(tuple(tolerances), mode, weight, limit, spec.shape, tuple(spec.tune), spec.description)


def _tolerance(ctx: Context, kind: str, item: str, value: Any, key: str) -> Tolerance:
    dimension, relative_ok, _ = _KIND[kind]
    if isinstance(value, str) and value.strip().endswith("%"):
        if not relative_ok:
            raise ctx.fail(key, f"a {kind} tolerance is a quantity (e.g. '{'0.5 N' if kind == 'initial_tension' else '1 mm'}'), not a percentage")
        return Tolerance(kind, item, fraction(ctx, value, key), True, key)
    if isinstance(value, (int, float)) and not isinstance(value, bool) and relative_ok:
        return Tolerance(kind, item, fraction(ctx, value, key), True, key)
    q = ctx.literal(value, key)
    with ctx.at(key):
        check_dimension(q.dimension, dimension, f"'{value}'")
    if not q.si >= 0:
        raise ctx.fail(key, f"a tolerance must not be negative, got '{value}'")
    return Tolerance(kind, item, q.si, False, key)
