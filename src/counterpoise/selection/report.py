"""Reports of the parts layer: its rows of ``springs.csv`` (the catalogue parts per spring
and scenario, and the bill of materials; the file is written with the designed springs by
:mod:`counterpoise.realisation.report`), ``tolerance.csv``, the ``part`` rows of
``design.csv``, its cells of ``summary.csv`` and its lines of ``status.txt``.

- ``kind = spring``: a catalogue part (its part number, the catalogue's data);
- ``kind = bom``: the bill of materials of catalogue parts: per part the quantity and,
  where the catalogue gives one, the unit and total price.

Lengths in mm, forces in N.
"""

from __future__ import annotations

import math
from dataclasses import replace

from ..designer.layers import Result, Row
from ..model.parts import Catalogue
from ..springs.workspace import ALL
from .result import PartsReport

#: the scenario of a spring's summary row (extremes over every scenario)
ALL_SCENARIOS = ALL
TOLERANCE_COLUMNS = ["case", "deviation", "residual_ratio", "adjusted_residual_ratio", "adjustment"]


def bill_rows(result: Result) -> list[Row]:
    """``kind = bom``: per catalogue part, the quantity and (where known) the prices."""
    parts = result.extra(PartsReport)
    if parts is None:
        return []
    return [
        {
            "kind": "bom",
            "part_number": line.part_number,
            "count": line.quantity,
            "unit_price": None if math.isnan(line.unit_price) else line.unit_price,
            "price": None if math.isnan(line.unit_price) else line.price,
        }
        for line in parts.bill
    ]


def part_rows(result: Result) -> list[Row]:
    """``kind = spring``: each spring's catalogue part per scenario (and ``all``)."""
    parts = result.extra(PartsReport)
    if parts is None:
        return []
    mm = 1e3
    rows: list[Row] = []
    uses = list(parts.by_scenario or parts.springs)
    if parts.by_scenario and len(parts.by_scenario) > len(parts.springs):  # several scenarios: a summary row each
        uses += [replace(u, scenario=ALL_SCENARIOS) for u in parts.springs]
    slots = {s.name: s for s in result.problem.slots}
    for u in uses:
        slot = slots.get(u.slot)
        i = parts.chosen.get(u.slot)
        cat = slot.catalogue if slot is not None else None
        rows.append(
            {
                "kind": "spring",
                "spring": u.spring,
                "slot": u.slot,
                "part_number": u.part_number,
                "count": _count(result, u.slot, u.part_number),
                "scenario": u.scenario,
                "min_distance_mm": u.distance_min * mm,
                "max_distance_mm": u.distance_max * mm,
                "min_length_mm": u.length_min * mm,
                "max_length_mm": u.length_max * mm,
                "min_force_N": u.force_min,
                "max_force_N": u.force_max,
                "free_length_mm": u.free_length * mm,
                "part_max_length_mm": u.max_length * mm,
                "initial_tension_N": u.initial_tension,
                "part_max_load_N": u.max_load,
                "margin_slack_mm": u.margin_slack * mm,
                "margin_length_mm": u.margin_length * mm,
                "margin_load_N": u.margin_load,
                **(_catalogue_data(cat, i, slot.rate_tolerance) if cat is not None and slot is not None and i is not None else {}),
            }
        )
    return rows


def _catalogue_data(cat: Catalogue, i: int, rate_tolerance: float) -> Row:
    """What the catalogue says of its part ``i`` in the spec columns (blank when unknown)."""
    mm = 1e3

    def known(v: float, scale: float = 1.0) -> float | None:
        return None if math.isnan(v) else v * scale

    return {
        "rate_N_per_mm": cat.rate[i] / mm,
        "rate_tolerance": rate_tolerance,
        "material": cat.material[i],
        "wire_diameter_mm": known(cat.wire_diameter[i], mm),
        "outer_diameter_mm": known(cat.outer_diameter[i], mm),
        "mass_g": known(cat.mass[i], 1e3),
    }


def _count(result: Result, slot: str, part_number: str) -> int:
    """How many identical springs of the base part a spring's part is (a slot with ``count``)."""
    for s in result.problem.slots:
        if s.name == slot and part_number in s.catalogue.part_number:
            return s.catalogue.parts_in_parallel(s.catalogue.part_number.index(part_number))
    return 1


def tolerance_rows(result: Result) -> list[Row]:
    parts = result.extra(PartsReport)
    if parts is None or parts.tolerance is None:
        return []
    t = parts.tolerance
    slots = result.problem.slots
    band = ", ".join(f"{s.name}: rate ±{100 * s.rate_tolerance:g} %, F0 ±{100 * s.initial_tension_tolerance:g} %" for s in slots)
    rows: list[Row] = [
        {"case": "nominal", "deviation": "", "residual_ratio": t.nominal},
        {"case": "band", "deviation": band, "residual_ratio": t.worst},
        {"case": "band_rate", "deviation": "rates only", "residual_ratio": t.worst_rate},
        {"case": "band_initial_tension", "deviation": "initial tensions only", "residual_ratio": t.worst_tension},
    ]
    units = {v.name: v.unit for v in result.problem.variables}
    for c in parts.corners:
        changes = []
        for name, nominal, adjusted in c.adjustment:
            u = units[name.split("@")[0]]
            changes.append(f"{name} {u.from_si(nominal):.6g} -> {u.from_si(adjusted):.6g} {u.label}")
        rows.append(
            {
                "case": "corner",
                "deviation": " ".join(f"{slot} {100 * d:+g} %" for slot, d in c.deviation),
                "residual_ratio": c.ratio,
                "adjusted_residual_ratio": c.adjusted_ratio,
                "adjustment": "; ".join(changes) if changes or not result.problem.selection.adjust else "no adjustment within the bounds balances",
            }
        )
    return rows


def part_design_rows(result: Result) -> list[Row]:
    """One ``part`` row per slot for design.csv: the part number, its rate in the description."""
    parts = result.extra(PartsReport)
    if parts is None:
        return []
    rows: list[Row] = []
    for slot in result.problem.slots:
        i = parts.chosen.get(slot.name)
        if i is None:
            continue
        cat = slot.catalogue
        rows.append(
            {
                "name": slot.name,
                "kind": "part",
                "scenario": "",
                "value": cat.part_number[i],
                "unit": "",
                "lower": None,
                "upper": None,
                "active_bound": "",
                "description": f"catalogue {cat.name}: rate {cat.rate[i] / 1e3:.6g} N/mm, free length {cat.free_length[i] * 1e3:.6g} mm, "
                f"initial tension {cat.initial_tension[i]:.6g} N; springs {' '.join(slot.springs)}",
            }
        )
    return rows


def parts_status(result: Result) -> str:
    parts = result.extra(PartsReport)
    if parts is None:
        return ""
    s = parts.search
    lines = [f"part search: {s.solves} NLP solves in {s.seconds:.3g} s; slot groups searched separately: {len(s.groups)}"]
    if s.evidence:  # the search's own account (groups, pruning per limit, coverage): once
        for c in s.counts:
            if not math.isnan(c.window[0]):
                lines.append(f"  slot {c.slot}: balanceable rates {c.window[0] / 1e3:.6g}-{c.window[1] / 1e3:.6g} N/mm")
        lines += [f"  {line}" for line in s.evidence]
    else:
        for group, method in zip(s.groups, s.methods):
            lines.append(f"  group {' '.join(group)}: {method}")
        for c in s.counts:
            lines.append(
                f"  slot {c.slot}: {c.parts} parts, {c.pruned} pruned before any per-part solve ("
                + (f"balanceable rates {c.window[0] / 1e3:.6g}-{c.window[1] / 1e3:.6g} N/mm" if not math.isnan(c.window[0]) else "no grid geometry within their lengths")
                + f"), {c.rates_solved} rates solved, "
                f"{c.failed_limits} failing a limit, {c.fitting} fitting"
            )
    if s.choice is None and s.nearest:
        lines.append("nearest candidates:")
        lines += [f"  {m.text()}" for m in s.nearest]
    if parts.tolerance is not None:
        lines.append(f"tolerance band: worst-case residual_ratio {parts.tolerance.worst:.3g} (nominal {parts.tolerance.nominal:.3g})")
    return "\n".join(lines) + "\n"


def chosen_parts(result: Result) -> str:
    """The catalogue parts chosen, 'slot: part number' per slot ('' without slots)."""
    parts = result.extra(PartsReport)
    if parts is None or not result.problem.slots:
        return ""
    by_name = {slot.name: slot for slot in result.problem.slots}
    return "; ".join(f"{name}: {by_name[name].catalogue.part_number[row]}" for name, row in parts.chosen.items() if name in by_name)
