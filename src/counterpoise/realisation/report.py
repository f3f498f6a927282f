"""Reports of the realisation layer: ``springs.csv`` (every spring: catalogue parts and designed
springs), ``build.csv`` (:mod:`.sheet`), its cell of ``summary.csv`` and its lines of
``status.txt`` (the designed springs; the balancer as built, the limits not met, the
constraints added, the wound rates).

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

from typing import Any

from ..designer.layers import Result, Row
from ..springs.workspace import ALL
from .result import BuildCheck, RealisationReport

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


def _springs(result: Result) -> tuple[Any, ...]:
    """The designed springs of ``result`` (:class:`~counterpoise.springs.workspace.DesignedSpring`; none: ())."""
    report = result.extra(RealisationReport)
    return report.springs if report is not None else ()


def springs_rows(result: Result) -> list[Row]:
    """Catalogue parts per scenario (and ``all``), designed springs likewise, then the bill."""
    from ..selection.report import bill_rows, part_rows  # the parts layer's rows of this file

    return part_rows(result) + designed_rows(result) + bill_rows(result)


def designed_rows(result: Result) -> list[Row]:
    """``kind = designed``: each free-stiffness spring's designed helical spring, per
    scenario and (several scenarios) over ``all`` of them."""
    mm, mpa = 1e3, 1e-6
    rows: list[Row] = []
    several = any(u.scenario == ALL_SCENARIOS for u in _springs(result))
    for u in _springs(result):
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


def designed_status(result: Result) -> str:
    """One status line per designed spring (the ``all`` design when there are several
    scenarios): what was designed, or why nothing could be, and what it cannot do."""
    several = any(u.scenario == ALL_SCENARIOS for u in _springs(result))
    lines = []
    for u in _springs(result):
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


def realisation_status(result: Result) -> str:
    """status.txt's lines on the springs as built: the as-built residual ratio, every
    realisation limit that is not met, the realisation constraints added and the wound rates."""
    lines = []
    built = result.extra(BuildCheck)
    as_built = built.as_built if built is not None else None
    if as_built is not None:
        ratio = as_built.residual_ratio
        line = f"as built (rebuilt from build.csv with real springs): residual ratio {ratio:.3g}" if ratio == ratio else "as built: " + "; ".join(as_built.notes)
        if ratio == ratio and as_built.verification is not None and not as_built.balanced:
            # unbalanced as built (a slack spring makes the residual kink): a sampled maximum,
            # which a local search from the worst samples may raise by a few per cent
            line += f" (the largest on {as_built.verification.configurations} sampled configurations)"
        lines.append(line)
        for name, share in as_built.slack.items():
            if share > 0:
                lines.append(f"as built: spring {name} is slack on {100 * share:.3g} % of the checked configurations")
    report = result.extra(RealisationReport)
    if report is not None:
        if report.ideal:
            lines.append("springs: IDEAL (settings.ideal_springs): the status refers to the ideal model; realisation limits are reported, not enforced")
        for lim in report.violated:
            lines.append(f"realisation limit: {lim.text(result.problem)}")
        if report.added:
            lines.append(f"realisation constraints added ({report.rounds} round{'s' if report.rounds != 1 else ''}): {', '.join(report.added)}")
        lines += list(report.notes)
        for name, (design, wound) in report.wound.items():
            lines.append(f"spring {name}: designed for {design / 1e3:.6g} N/mm, wound to {wound / 1e3:.6g} N/mm; the design was solved again for the wound rate")
    return "".join(f"{line}\n" for line in lines)
