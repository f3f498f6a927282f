"""Catalogues, spring slots and the selection settings of a problem file."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ...catalogue import SHIPPED, CatalogueError, mapping_from, read_catalogue
from ...catalogue.reader import CatalogueUnitsError
from ...model.parts import Catalogue, SelectionSettings, SpringSlot
from ...model.problem import Parameter
from ...model.units import display_unit
from .context import Context, suggest

#: used when neither the slot, the catalogue table nor the file gives a tolerance
DEFAULT_RATE_TOLERANCE = 0.10
DEFAULT_INITIAL_TENSION_TOLERANCE = 0.20


def tolerance(ctx: Context, raw: Any, key: str) -> float:
    """A tolerance: a fraction (0.1) or a percentage ('10 %'), between 0 and 100 %."""
    if raw is None:
        return math.nan
    text = str(raw).strip()
    try:
        value = float(text[:-1]) / 100 if text.endswith("%") else float(text)
    except ValueError:
        raise ctx.fail(key, f"expected a fraction (0.1) or a percentage ('10 %'), got '{raw}'") from None
    if not (math.isfinite(value) and 0 <= value <= 1):
        raise ctx.fail(key, f"a tolerance must be between 0 and 100 %, got '{raw}'")
    return value


def catalogues(ctx: Context) -> dict[str, Catalogue]:
    out = {}
    base = Path(ctx.label).parent if Path(ctx.label).is_file() else Path.cwd()
    for name, c in ctx.spec.catalogues.items():
        key = f"catalogues.{name}"
        try:
            mapping = mapping_from(c.columns, c.units)
        except ValueError as exc:
            raise ctx.fail(f"{key}.columns" if "unit system" not in str(exc) else f"{key}.units", str(exc)) from None
        rate_tol = tolerance(ctx, c.rate_tolerance, f"{key}.rate_tolerance")
        tension_tol = tolerance(ctx, c.initial_tension_tolerance, f"{key}.initial_tension_tolerance")
        path: Path | str = c.file if c.file == SHIPPED else (base / c.file)
        try:
            out[name] = read_catalogue(path, mapping, name, rate_tol, tension_tol)
        except CatalogueUnitsError as exc:
            raise ctx.fail(f"{key}.units", f"{Path(exc.file).name}: {exc.message}") from None
        except CatalogueError as exc:
            raise ctx.fail(f"{key}.file", str(exc)) from None
    return out


def slot_parameters(ctx: Context, found: dict[str, Catalogue]) -> tuple[Parameter, ...]:
    """One literal parameter per slot, named like it: the rate of its part (N/mm for display).

    Its value is the median rate of the catalogue: a representative value for building the
    solver; the designer passes each candidate's rate instead.
    """
    out = []
    unit = display_unit("N/mm")
    for name, s in ctx.spec.slots.items():
        if s.catalogue not in found:
            raise ctx.fail(f"slots.{name}.catalogue", f"unknown catalogue '{s.catalogue}'{suggest(s.catalogue, list(found))}")
        rate = float(np.median(found[s.catalogue].array("rate")))
        ctx.symbol_unit[name] = unit
        ctx.symbol_value[name] = rate
        out.append(Parameter(name, unit, value=rate, description=f"rate of the part chosen for slot {name}"))
        # the part's other data, for directly attached springs (names no expression can write)
        for field, shown in (("free_length", "mm"), ("initial_tension", "N"), ("max_length", "mm")):
            value = float(np.median(found[s.catalogue].array(field)))
            out.append(Parameter(slot_parameter(name, field), display_unit(shown), value=value, description=f"{field} of the part of slot {name}"))
    return tuple(out)


def slot_parameter(slot: str, field: str) -> str:
    """Name of the parameter holding a field of the part chosen for ``slot``."""
    return f"{slot}:{field}"


def slots(ctx: Context, found: dict[str, Catalogue], springs: dict[str, list[str]]) -> tuple[SpringSlot, ...]:
    out = []
    for name, s in ctx.spec.slots.items():
        key = f"slots.{name}"
        catalogue = found[s.catalogue]
        if not springs.get(name):
            raise ctx.fail(key, f"no spring uses slot '{name}' (give a spring slot = \"{name}\")")
        rate_tol = tolerance(ctx, s.rate_tolerance, f"{key}.rate_tolerance")
        tension_tol = tolerance(ctx, s.initial_tension_tolerance, f"{key}.initial_tension_tolerance")
        if math.isnan(rate_tol):
            column = catalogue.array("rate_tolerance")
            rate_tol = float(np.nanmax(column)) if np.isfinite(column).any() else DEFAULT_RATE_TOLERANCE
        if math.isnan(tension_tol):
            column = catalogue.array("initial_tension_tolerance")
            tension_tol = float(np.nanmax(column)) if np.isfinite(column).any() else DEFAULT_INITIAL_TENSION_TOLERANCE
        if s.count is not None:
            if s.count.min > s.count.max:
                raise ctx.fail(f"{key}.count", f"min {s.count.min} is greater than max {s.count.max}")
            catalogue = catalogue.parallel(s.count.min, s.count.max)
        out.append(SpringSlot(name, catalogue, tuple(springs[name]), rate_tol, tension_tol, s.description))
    return tuple(out)


def selection(ctx: Context) -> SelectionSettings:
    sel = ctx.spec.selection
    for i, name in enumerate(sel.adjust):
        if ctx.symbol_kind.get(name) != "variables":
            raise ctx.fail(f"selection.adjust.{i}", f"unknown variable '{name}'{suggest(name, list(ctx.spec.variables))}")
    if (sel.adjust or sel.prefer != "objective") and not ctx.spec.slots:
        raise ctx.fail("selection", "the problem has no spring slots to choose parts for")
    return SelectionSettings(sel.prefer, tuple(sel.adjust), sel.max_enumeration, sel.limit_samples, sel.nearest)
