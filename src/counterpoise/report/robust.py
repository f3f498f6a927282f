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

from ..pipeline import DesignResult
from .rows import Row

TOLERANCE_COLUMNS = ["design", "case", "deviation", "residual_ratio", "adjusted_residual_ratio", "adjustment"]


def _report(result: DesignResult) -> object | None:
    return getattr(result.solution, "robust", None)


def tolerance_rows(result: DesignResult) -> list[Row]:
    report = _report(result)
    if report is None:
        return []
    rows: list[Row] = []
    for design, band in report.bands.items():  # type: ignore[attr-defined]
        rows.append({"design": design, "case": "nominal", "deviation": "", "residual_ratio": band["residual"]})
        rows.append({"design": design, "case": "band", "deviation": _box(report), "residual_ratio": band["all"]})
        for kind, value in band.items():
            if kind not in ("residual", "all"):
                rows.append({"design": design, "case": f"band_{kind}", "deviation": f"{kind} tolerances only", "residual_ratio": value})
    design = "robust" if "robust" in report.bands else "nominal"  # type: ignore[attr-defined]
    units = {v.name: v.unit for v in result.problem.variables}
    for c in report.corners:  # type: ignore[attr-defined]
        rows.append(
            {
                "design": design,
                "case": "corner",
                "deviation": c.deviation,
                "residual_ratio": c.before,
                "adjusted_residual_ratio": c.after,
                "adjustment": "; ".join(f"{t} {units[t].from_si(v):.6g} {units[t].label}" for t, v in c.settings),
            }
        )
    if report.corners:  # type: ignore[attr-defined]
        rows.append({"design": design, "case": "band_after_tuning", "deviation": report.tuning_status, "residual_ratio": report.tuned_residual})  # type: ignore[attr-defined]
    return rows


def _box(report: object) -> str:
    seen: dict[str, str] = {}
    for d in report.deviations:  # type: ignore[attr-defined]
        t = d.tolerance
        seen.setdefault(f"{t.kind} {t.item}", f"{t.kind} {t.item} ±{100 * t.amount:g} %" if t.relative else f"{t.kind} {t.item} ±{t.amount:g} SI")
    return ", ".join(seen.values()) + (f" ({report.shape})" if report.shape != "box" else "")  # type: ignore[attr-defined]


def tuning_columns(result: DesignResult) -> list[str]:
    report = _report(result)
    if report is None:
        return []
    units = {v.name: v.unit for v in result.problem.variables}
    devs = [d.parameter.split(":", 1)[1] for d in report.deviations]  # type: ignore[attr-defined]
    tune = [f"{t} [{units[t].label}]" for t in result.problem.robust.tune]  # type: ignore[union-attr]
    return ["corner", *devs, *tune, "residual_ratio_before", "residual_ratio_after"]


def tuning_rows(result: DesignResult) -> list[Row]:
    report = _report(result)
    if report is None:
        return []
    units = {v.name: v.unit for v in result.problem.variables}
    columns = tuning_columns(result)
    rows: list[Row] = []
    for c in report.corners:  # type: ignore[attr-defined]
        row: Row = {"corner": c.name, "residual_ratio_before": c.before, "residual_ratio_after": c.after}
        for d, sign, column in zip(report.deviations, c.signs, columns[1:]):  # type: ignore[attr-defined]
            row[column] = sign * d.half_width
        for (t, v), column in zip(c.settings, columns[1 + len(report.deviations) :]):  # type: ignore[attr-defined]
            row[column] = units[t].from_si(v)
        rows.append(row)
    return rows


def design_rows(result: DesignResult) -> list[Row]:
    """One ``tuning_range`` row per tune variable for design.csv (lower/upper: the range)."""
    report = _report(result)
    if report is None:
        return []
    rows: list[Row] = []
    for name, (lo, hi) in report.tuning_range.items():  # type: ignore[attr-defined]
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
    for design, band in report.bands.items():  # type: ignore[attr-defined]
        kinds = ", ".join(f"{k} {v:.4g}" for k, v in band.items() if k not in ("residual", "all"))
        lines.append(
            f"robust: {design} design: worst-case residual ratio {band['all']:.4g} ({kinds}); "
            f"added mass {report.added_mass[design]:.6g} kg, objective {report.objective[design]:.6g} kg"  # type: ignore[attr-defined]
        )
    if report.lp_seconds:  # type: ignore[attr-defined]
        lines.append(f"robust: counterpart ({report.mode}, {report.shape}) solved by {report.solver} in {report.lp_seconds:.3g} s")  # type: ignore[attr-defined]
    units = {v.name: v.unit for v in result.problem.variables}
    for name, (lo, hi) in report.tuning_range.items():  # type: ignore[attr-defined]
        u = units[name]
        lines.append(f"tuning range {name}: {u.from_si(lo):.6g} to {u.from_si(hi):.6g} {u.label}")
    if report.corners:  # type: ignore[attr-defined]
        lines.append(f"tuning: {report.tuning_status}; largest residual ratio after tuning {report.tuned_residual:.3g} over {len(report.corners)} corners")  # type: ignore[attr-defined]
    return "".join(f"{line}\n" for line in lines)
