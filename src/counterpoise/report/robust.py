"""Reports of a ``[robust]`` design: ``tolerance.csv``, ``tuning.csv``, design rows, status lines.

``tolerance.csv`` (robust problems): per design (``nominal``: the ordinary design;
``robust``: the robust counterpart's), the nominal residual ratio (``case = nominal``), the
worst case over the whole tolerance box (``band``) and over each tolerance kind alone
(``band_rate``, ``band_mass``, ``band_com``, ``band_point``, ``band_initial_tension``); with
``tune``, one ``corner`` row per corner of the box (the untuned worst case at that corner,
the residual ratio after tuning and the tuning) and ``band_after_tuning``, the largest
residual ratio left after tuning. ``tuning.csv``: the tuning table, one row per corner: the
deviation of each toleranced quantity (fractions for relative tolerances, SI otherwise),
the setting of each tune variable (its display unit) and the ratios before and after.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..pipeline import DesignResult
from .rows import Row

if TYPE_CHECKING:
    from ..robust.method import RobustReport

TOLERANCE_COLUMNS = ["design", "case", "deviation", "residual_ratio", "adjusted_residual_ratio", "adjustment"]
#: report.html's caption of a [robust] problem's tolerance.csv (a catalogue's has its own)
TOLERANCE_CAPTION = (
    "tolerance.csv: the worst-case residual ratio over the whole tolerance box ([robust]) and per kind of tolerance, "
    "for the nominal and the robust design; with tune, each corner before and after tuning"
)


def is_robust_tolerance(text: str) -> bool:
    """Whether a tolerance.csv text is a [robust] problem's (its header), not a catalogue's."""
    return text.split("\n", 1)[0].strip() == ",".join(TOLERANCE_COLUMNS)


def _report(result: DesignResult) -> "RobustReport | None":
    report: RobustReport | None = getattr(result.solution, "robust", None)
    return report


def tolerance_rows(result: DesignResult) -> list[Row]:
    report = _report(result)
    if report is None:
        return []
    rows: list[Row] = []
    for design, band in report.bands.items():
        rows.append({"design": design, "case": "nominal", "deviation": "", "residual_ratio": band["residual"]})
        label = "" if report.exactness == "exact" else f" ({report.exactness})"
        rows.append({"design": design, "case": "band", "deviation": _box(report) + label, "residual_ratio": band["all"]})
        for kind, value in band.items():
            if kind not in ("residual", "all"):
                rows.append({"design": design, "case": f"band_{kind}", "deviation": f"{kind} tolerances only", "residual_ratio": value})
    design = "robust" if "robust" in report.bands else "nominal"
    units = {v.name: v.unit for v in result.problem.variables}
    for c in report.corners:
        rows.append(
            {
                "design": design,
                "case": "corner",
                "deviation": c.deviation,
                "residual_ratio": c.before,
                "adjusted_residual_ratio": c.after,
                "adjustment": "; ".join(f"{t} {units[_variable(t)].from_si(v):.6g} {units[_variable(t)].label}" for t, v in c.settings),
            }
        )
    if report.corners:
        rows.append({"design": design, "case": "band_after_tuning", "deviation": report.tuning_status, "residual_ratio": report.tuned_residual})
    return rows


def _box(report: "RobustReport") -> str:
    seen: dict[str, str] = {}
    for d in report.deviations:
        t = d.tolerance
        seen.setdefault(f"{t.kind} {t.item}", f"{t.kind} {t.item} ±{100 * t.amount:g} %" if t.relative else f"{t.kind} {t.item} ±{t.amount:g} SI")
    return ", ".join(seen.values()) + (f" ({report.shape})" if report.shape != "box" else "")


def tuning_columns(result: DesignResult) -> list[str]:
    report = _report(result)
    if report is None:
        return []
    units = {v.name: v.unit for v in result.problem.variables}
    devs = [d.parameter.split(":", 1)[1] for d in report.deviations]
    names = [t for t, _ in report.corners[0].settings] if report.corners else list(result.problem.robust.tune)  # type: ignore[union-attr]  # called only for a [robust] problem
    tune = [f"{t} [{units[_variable(t)].label}]" for t in names]
    return ["corner", *devs, *tune, "residual_ratio_before", "residual_ratio_after"]


def _variable(name: str) -> str:
    """The variable of a tuning column: 'h', or 'x' of a payload's adjustment 'x@camera_8kg'."""
    return name.split("@", 1)[0]


def tuning_rows(result: DesignResult) -> list[Row]:
    report = _report(result)
    if report is None:
        return []
    units = {v.name: v.unit for v in result.problem.variables}
    columns = tuning_columns(result)
    rows: list[Row] = []
    for c in report.corners:
        row: Row = {"corner": c.name, "residual_ratio_before": c.before, "residual_ratio_after": c.after}
        for d, sign, column in zip(report.deviations, c.signs, columns[1:]):
            row[column] = sign * d.half_width
        for (t, v), column in zip(c.settings, columns[1 + len(report.deviations) :]):
            row[column] = units[_variable(t)].from_si(v)
        rows.append(row)
    return rows


def design_rows(result: DesignResult) -> list[Row]:
    """One ``tuning_range`` row per tune variable for design.csv (lower/upper: the range)."""
    report = _report(result)
    if report is None:
        return []
    rows: list[Row] = []
    for name, (lo, hi) in report.tuning_range.items():
        v = result.problem.variable[name]
        rows.append(
            {
                "name": name,
                "kind": "tuning_range",
                "scenario": "",
                "value": v.unit.from_si(hi - lo),
                "unit": v.unit.label,
                "lower": v.unit.from_si(lo),
                "upper": v.unit.from_si(hi),
                "active_bound": "",
                "description": f"settings of {name} that re-balance every tolerance corner (value: the span)",
            }
        )
    return rows


def status_lines(result: DesignResult) -> str:
    report = _report(result)
    if report is None:
        return ""
    lines = []
    for design, band in report.bands.items():
        kinds = ", ".join(f"{k} {v:.4g}" for k, v in band.items() if k not in ("residual", "all"))
        if report.mode == "minimise":
            minimised = (
                f"objective minimised {report.objective[design]:.6g} kg = {report.base_objective.get(design, 0.0):.6g} kg "
                f"+ weight × worst case ({report.weight:.6g} kg × {band['all']:.4g})"
            )
        else:
            minimised = f"objective {report.objective[design]:.6g} kg"
        lines.append(
            f"robust: {design} design: worst-case residual ratio {band['all']:.4g} ({kinds}); "
            f"added mass {report.added_mass[design]:.6g} kg, {minimised}"
        )
    shape = "box" if report.shape == "box" else "ellipsoid"
    lines.append(f"robust: the worst case over the tolerance {shape} is {report.exactness}" if report.exactness == "exact" else f"robust: the worst-case figures are {report.exactness}")
    if report.lp_seconds:
        lines.append(f"robust: counterpart ({report.mode}, {report.shape}) solved by {report.solver} in {report.lp_seconds:.3g} s")
    units = {v.name: v.unit for v in result.problem.variables}
    for name, (lo, hi) in report.tuning_range.items():
        u = units[name]
        lines.append(f"tuning range {name}: {u.from_si(lo):.6g} to {u.from_si(hi):.6g} {u.label}")
    if report.corners:
        lines.append(f"tuning: {report.tuning_status}; largest residual ratio after tuning {report.tuned_residual:.3g} over {len(report.corners)} corners")
    return "".join(f"{line}\n" for line in lines)
