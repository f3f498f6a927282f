"""Reports of springs: ``springs.csv``, ``tolerance.csv``, design rows and status lines.

``springs.csv`` has one row per spring and scenario (a payload range: one scenario per
payload of its schedule, named after its working mode and payload) and, when there are
several scenarios, a summary row per spring with ``scenario = all``: the extremes over all
of them. Each row gives the distance between the spring's attachment points, its own
length (d + L0 − F0/k behind a pulley) and its force (k·d) over every checked
configuration, its limits and the three margins (≥ 0: the limit holds).

- ``kind = spring``: a catalogue part (its part number, the catalogue's data);
- ``kind = designed``: a free-stiffness spring, with the helical extension spring designed
  for it (:mod:`counterpoise.springs`): the spec a spring maker quotes from (the wound
  rate ``rate_N_per_mm`` = ``wound_rate_N_per_mm``, the ``design_rate_N_per_mm`` the
  geometry was solved for, the rate tolerance, wire, coils, diameters, lengths, initial
  tension and its windable band, stresses and allowables, the safety factor at the nominal
  rate and at the rate's upper tolerance, mass, material); its forces and lengths are the
  wound spring's; ``note`` says why no spring could be designed, or what the design cannot
  do;
- ``kind = bom``: the bill of materials of catalogue parts: per part the quantity and,
  where the catalogue gives one, the unit and total price.

Lengths in mm, forces in N, stresses in MPa, masses in g.
"""

from __future__ import annotations

import math
from dataclasses import replace

from ..model.parts import Catalogue
from ..pipeline import DesignResult
from ..springs.workspace import ALL
from .rows import Row

SPRINGS_COLUMNS = [
    "kind",
    "spring",
    "slot",
    "part_number",
    "count",
    "scenario",
    "min_distance_mm",
    "max_distance_mm",
    "min_length_mm",
    "max_length_mm",
    "min_force_N",
    "max_force_N",
    "free_length_mm",
    "part_max_length_mm",
    "initial_tension_N",
    "part_max_load_N",
    "margin_slack_mm",
    "margin_length_mm",
    "margin_load_N",
    "unit_price",
    "price",
    "rate_N_per_mm",
    "design_rate_N_per_mm",
    "wound_rate_N_per_mm",
    "rate_tolerance",
    "material",
    "wire_diameter_mm",
    "mean_diameter_mm",
    "outer_diameter_mm",
    "spring_index",
    "body_coils",
    "active_coils",
    "body_length_mm",
    "initial_tension_band_min_N",
    "initial_tension_band_max_N",
    "body_stress_MPa",
    "hook_bending_stress_MPa",
    "hook_torsion_stress_MPa",
    "allowable_body_MPa",
    "allowable_hook_bending_MPa",
    "allowable_hook_torsion_MPa",
    "safety_factor_nominal_rate",
    "safety_factor_upper_rate",
    "mass_g",
    "note",
]
#: the scenario of a spring's summary row (extremes over every scenario)
ALL_SCENARIOS = ALL
TOLERANCE_COLUMNS = ["case", "deviation", "residual_ratio", "adjusted_residual_ratio", "adjustment"]


def springs_rows(result: DesignResult) -> list[Row]:
    """Catalogue parts per scenario (and ``all``), designed springs likewise, then the bill."""
    rows = _part_rows(result) + designed_rows(result)
    parts = result.parts
    if parts is None:
        return rows
    for line in parts.bill:
        rows.append(
            {
                "kind": "bom",
                "part_number": line.part_number,
                "count": line.quantity,
                "unit_price": None if math.isnan(line.unit_price) else line.unit_price,
                "price": None if math.isnan(line.unit_price) else line.price,
            }
        )
    return rows


def _part_rows(result: DesignResult) -> list[Row]:
    parts = result.parts
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


def designed_rows(result: DesignResult) -> list[Row]:
    """``kind = designed``: each free-stiffness spring's designed helical spring, per
    scenario and (several scenarios) over ``all`` of them."""
    mm, mpa = 1e3, 1e-6
    rows: list[Row] = []
    several = any(u.scenario == ALL_SCENARIOS for u in result.springs)
    for u in result.springs:
        s = u.design
        row: Row = {
            "kind": "designed",
            "spring": u.spring,
            "count": 1,
            "scenario": u.scenario,
            "min_distance_mm": u.distance_min * mm,
            "max_distance_mm": u.distance_max * mm,
            "min_force_N": u.force_min,
            "max_force_N": u.force_max,
            "design_rate_N_per_mm": s.design_rate / mm,
            "rate_tolerance": s.rate_tolerance,
            "material": s.material.name,
            "note": "; ".join(s.reasons + s.warnings) if not several or u.scenario == ALL_SCENARIOS else "",  # once per spring
        }
        if s.ok:
            row.update(
                {
                    "min_length_mm": u.length_min * mm,
                    "max_length_mm": u.length_max * mm,
                    "free_length_mm": s.free_length * mm,
                    "part_max_length_mm": s.max_length * mm,
                    "initial_tension_N": s.initial_tension,
                    "part_max_load_N": s.max_force,
                    "margin_slack_mm": u.margin_slack * mm,
                    "margin_length_mm": u.margin_length * mm,
                    "margin_load_N": u.margin_load,
                    "rate_N_per_mm": s.rate / mm,  # the wound rate
                    "wound_rate_N_per_mm": s.rate / mm,
                    "wire_diameter_mm": s.wire_diameter * mm,
                    "mean_diameter_mm": s.mean_diameter * mm,
                    "outer_diameter_mm": s.outer_diameter * mm,
                    "spring_index": s.index,
                    "body_coils": s.body_coils,
                    "active_coils": s.active_coils,
                    "body_length_mm": s.body_length * mm,
                    "initial_tension_band_min_N": s.initial_tension_band[0],
                    "initial_tension_band_max_N": s.initial_tension_band[1],
                    "body_stress_MPa": s.body_stress * mpa,
                    "hook_bending_stress_MPa": s.hook_bending_stress * mpa,
                    "hook_torsion_stress_MPa": s.hook_torsion_stress * mpa,
                    "allowable_body_MPa": s.allowable_body * mpa,
                    "allowable_hook_bending_MPa": s.allowable_hook_bending * mpa,
                    "allowable_hook_torsion_MPa": s.allowable_hook_torsion * mpa,
                    "safety_factor_nominal_rate": s.safety_factor,
                    "safety_factor_upper_rate": s.safety_factor_upper,
                    "mass_g": s.mass * 1e3,
                }
            )
        rows.append(row)
    return rows


def designed_status(result: DesignResult) -> str:
    """One status line per designed spring (the ``all`` design when there are several
    scenarios): what was designed, or why nothing could be, and what it cannot do."""
    several = any(u.scenario == ALL_SCENARIOS for u in result.springs)
    lines = []
    for u in result.springs:
        if several and u.scenario != ALL_SCENARIOS:
            continue
        s = u.design
        if not s.ok:
            lines.append(f"designed spring {u.spring}: none within the rules: {'; '.join(s.reasons)}")
            continue
        lines.append(
            f"designed spring {u.spring}: {s.material.name}, wire {1e3 * s.wire_diameter:.4g} mm, outer diameter "
            f"{1e3 * s.outer_diameter:.4g} mm, {s.body_coils:g} body coils, free length {1e3 * s.free_length:.4g} mm, "
            f"rate {s.rate / 1e3:.4g} N/mm as wound ({s.design_rate / 1e3:.4g} N/mm designed) ±{100 * s.rate_tolerance:g} %, "
            f"initial tension {s.initial_tension:.4g} N, {u.force_min:.4g}-{u.force_max:.4g} N, safety factor "
            f"{s.safety_factor:.3g} ({s.safety_factor_upper:.3g} at +{100 * s.rate_tolerance:g} % rate), {1e3 * s.mass:.3g} g"
        )
        lines += [f"warning: designed spring {u.spring}: {w}" for w in s.warnings]
    return "".join(f"{line}\n" for line in lines)


def _count(result: DesignResult, slot: str, part_number: str) -> int:
    """How many identical springs of the base part a spring's part is (a slot with ``count``)."""
    for s in result.problem.slots:
        if s.name == slot and part_number in s.catalogue.part_number:
            return s.catalogue.parts_in_parallel(s.catalogue.part_number.index(part_number))
    return 1


def tolerance_rows(result: DesignResult) -> list[Row]:
    parts = result.parts
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


def part_design_rows(result: DesignResult) -> list[Row]:
    """One ``part`` row per slot for design.csv: the part number, its rate in the description."""
    parts = result.parts
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


def parts_status(result: DesignResult) -> str:
    parts = result.parts
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
