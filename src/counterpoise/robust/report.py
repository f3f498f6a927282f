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

from ..designer.layers import Result, Row
from .result import ON_MANIFOLD, SAMPLED_MINIMAX, RobustReport

TOLERANCE_COLUMNS = ["design", "case", "deviation", "residual_ratio", "adjusted_residual_ratio", "adjustment"]
#: report.html's caption of a [robust] problem's tolerance.csv (a catalogue's has its own)
TOLERANCE_CAPTION = (
    "tolerance.csv: the worst-case residual ratio over the whole tolerance box ([robust]) and per kind of tolerance, "
    "for the nominal and the robust design; with tune, each corner before and after tuning"
)


def _report(result: Result) -> RobustReport | None:
    return result.extra(RobustReport)


def tolerance_rows(result: Result) -> list[Row]:
    report = _report(result)
    if report is None:
        return []
    rows: list[Row] = []
    for design, band in report.bands.items():
        rows.append({"design": design, "case": "nominal", "deviation": "", "residual_ratio": band["residual"]})
        label = "" if report.exactness == "exact" else f" ({report.exactness})"
        rows.append({"design": design, "case": "band", "deviation": _box(report) + label, "residual_ratio": band["all"]})
        if design in report.worst_corner:
            rows.append({"design": design, "case": "worst_corner", "deviation": report.worst_corner[design], "residual_ratio": band["all"]})
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


def _box(report: RobustReport) -> str:
    seen: dict[str, str] = {}
    for d in report.deviations:
        t = d.tolerance
        seen.setdefault(f"{t.kind} {t.item}", f"{t.kind} {t.item} ±{100 * t.amount:g} %" if t.relative else f"{t.kind} {t.item} ±{t.amount:g} SI")
    return ", ".join(seen.values()) + (f" ({report.shape})" if report.shape != "box" else "")


def tuning_columns(result: Result) -> list[str]:
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


def tuning_rows(result: Result) -> list[Row]:
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


def design_rows(result: Result) -> list[Row]:
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


def status_lines(result: Result) -> str:
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
        at = f" at {report.worst_corner[design]}" if design in report.worst_corner else ""
        lines.append(
            f"robust: {design} design: worst-case residual ratio {band['all']:.4g}{at} ({kinds}); "
            f"added mass {report.added_mass[design]:.6g} kg, {minimised}"
        )
    shape = "box" if report.shape == "box" else "ellipsoid"
    for text in report.part_tolerances:
        lines.append(f"robust: {text}")
    if report.exactness == "exact":
        lines.append(f"robust: the worst case over the tolerance {shape} is exact")
    elif report.exactness.startswith(ON_MANIFOLD):
        lines.append(f"robust: the worst case over the tolerance {shape} is {report.exactness}")
    elif report.exactness.startswith(SAMPLED_MINIMAX):
        lines.append(f"robust: the worst case is {report.exactness}")
    else:
        lines.append(f"robust: the worst-case figures are {report.exactness}")
    for design, value in report.sampled.items():
        corners = report.bands[design]["all"]
        verdict = f"within the corners' worst case {corners:.4g}" if value <= corners * (1 + 1e-9) else f"above the corners' worst case {corners:.4g} by {value - corners:.3g}"
        lines.append(f"robust: {design} design at {report.samples} random machines inside the box: largest residual ratio {value:.4g} ({verdict})")
    for m in report.lengths:
        what = "d − c − (L0 + slack margin)" if m.limit == "slack" else "L_max − (d − c)"
        lines.append(f"robust: spring {m.spring} {what} at least {m.margin * 1e3:.4g} mm over the tolerance corners (least at {m.corner})")
    if report.lp_seconds:
        lines.append(f"robust: counterpart ({report.mode}, {report.shape}) solved by {report.solver} in {report.lp_seconds:.3g} s")
    units = {v.name: v.unit for v in result.problem.variables}
    for name, (lo, hi) in report.tuning_range.items():
        u = units[name]
        lines.append(f"tuning range {name}: {u.from_si(lo):.6g} to {u.from_si(hi):.6g} {u.label}")
    if report.corners:
        lines.append(f"tuning: {report.tuning_status}; largest residual ratio after tuning {report.tuned_residual:.3g} over {len(report.corners)} corners")
    return "".join(f"{line}\n" for line in lines)


# -- the tuning procedure (tuning.csv, report.html) -----------------------------------------------

#: tuning.csv: the numbered procedure a technician carries out (docs/robust.md, "The tuning law")
PROCEDURE_COLUMNS = ["step", "action", "where", "with", "quantity", "value", "unit", "note"]


def _nice(value: float) -> float:
    """``value`` rounded to two significant digits (a weight, a setting to read)."""
    if not value or value != value:
        return value
    from math import floor, log10

    digits = 1 - int(floor(log10(abs(value))))
    return round(value, digits)


def procedure_rows(result: Result) -> list[Row]:
    """The numbered tuning procedure of a [robust] design with ``tune`` (empty without a law)."""
    report = _report(result)
    spec = result.problem.robust
    if report is None or spec is None or report.law is None:
        return []
    from ..model.robust import PITCH

    law = report.law
    problem = result.problem
    rows: list[Row] = []

    def step(action: str, where: str = "", instrument: str = "", quantity: str = "", value: float | None = None, unit: str = "", note: str = "") -> None:
        rows.append({"step": len(rows) + 1, "action": action, "where": where, "with": instrument, "quantity": quantity, "value": value, "unit": unit, "note": note})

    if problem.payloads:
        payload = problem.payloads[0]
        pinned = [(n.split("@", 1)[0], v) for c in report.corners if set(c.signs) == {0} for n, v in c.settings if "@" in n and _mass_of(result, n) == payload.nominal]
        where = ", ".join(f"{n} = {problem.variable[n].unit.from_si(v):.4g} {problem.variable[n].unit.label}" for n, v in pinned)
        step(
            f"Mount the nominal payload ({payload.name} = {payload.unit.from_si(payload.nominal):g} {payload.unit.label})"
            + (f" and set its adjustments where the design puts them: {where}" if where else ""),
            note="the tune variables are set once, here; the operator re-sets the adjustments for every other payload (schedule.csv)",
        )
    for name, s in report.springs.items():
        lo, hi = s.initial_tension, report.envelope[name].force_max if name in report.envelope else s.max_force
        w1, w2 = _nice(lo + 0.25 * (hi - lo)), _nice(lo + 0.75 * (hi - lo))
        step(
            f"Measure spring {name} before mounting it: hang W1 = {w1:g} N, then W2 = {w2:g} N from it and read its length inside the hooks, L1 and L2",
            where="on the bench",
            instrument="two weights (or a spring scale) and calipers",
            quantity="k' = (W2 - W1)/(L2 - L1); L_z = L1 - W1/k' (its zero-force length)",
            note=f"designed: k = {s.rate / 1e3:.4g} N/mm, F0 = {s.initial_tension:.4g} N, L0 = {s.free_length * 1e3:.4g} mm, so L_z = {(s.free_length - s.initial_tension / s.rate) * 1e3:.4g} mm nominally",
        )
        step(
            f"Set spring {name}'s string: its fixed end C + L_z behind the pulley along the cable's run, with the cable C from the spring's end over the pulley to {name}'s link point",
            where=f"{name}: pulley and anchor",
            instrument="rule",
            quantity="C",
            value=s.cable * 1e3,
            unit="mm",
            note="C serves every tuned setting (the longest distance over the tuning range); the spring then pulls k'·d, so its rate or initial-tension error leaves no constant force along the cable (docs/robust.md)",
        )
    pitch = dict(spec.pitch)
    # with one reading per variable (pairs), reading k + 1 is variable k's
    order = list(law.pairs) if law.pairs is not None else list(range(len(law.readings)))
    for k, t in enumerate(law.tune):
        v = problem.variable[t]
        u = v.unit
        step(f"Set {t} to its factory setting", where=t, quantity=t, value=u.from_si(law.factory[k]), unit=u.label, note=v.description)
    readings = law.readings if law.pairs is None else tuple(law.readings[i] for i in order)
    for i, r in enumerate(readings):
        pose = ", ".join(f"{n} = {problem.coordinate[n].unit.from_si(x):.4g} {problem.coordinate[n].unit.label}".rstrip() for n, x in r.pose)
        where = f"{r.body}'s mass centre, {r.lever * 1e3:.4g} mm from the {r.coordinate} axis" if r.revolute else f"along the {r.coordinate} slide"
        step(
            f"Clamp the mechanism at {pose} (every joint but {r.coordinate} held); read the holding force F{i + 1}_A of {r.coordinate}",
            where=where,
            instrument="a spring scale pulling along the direction the point moves as " + r.coordinate + " increases",
            quantity=f"F{i + 1}_A",
            unit="N",
            note="negative when the scale must pull the other way; 0 N on a balancer built to nominal",
        )
    for k, t in enumerate(law.tune):
        u = problem.variable[t].unit
        delta = law.steps[k]
        turns = f" ({abs(delta) / pitch.get(t, PITCH):.4g} turns of a {pitch.get(t, PITCH) * 1e3:g} mm pitch screw{'' if t in pitch else ', M6 coarse: set robust.pitch for yours'})" if u.dimension == "[length]" else ""
        reads = f"F{k + 1}_B" if law.pairs is not None else "every F_B"
        step(
            f"Turn {t} by {u.from_si(delta):+.4g} {u.label}{turns} and read {reads} the same way; then turn it back",
            where=t,
            quantity=t,
            value=u.from_si(law.factory[k] + delta),
            unit=u.label,
            note=f"nominally the reading changes by {law.slope[law.pairs[k], k] * delta:.4g} N" if law.pairs is not None else "",
        )
    for k, t in enumerate(law.tune):
        u = problem.variable[t].unit
        if law.pairs is not None:
            n = k + 1
            formula = f"{t} = {u.from_si(law.factory[k]):.6g} {u.label} - ({u.from_si(law.steps[k]):.4g} {u.label}) × F{n}_A/(F{n}_B - F{n}_A)"
        else:
            formula = f"{t} = t0 - S⁻¹ F_A, S[:, k] = (F_B - F_A)/Δ_k (every variable's step, docs/robust.md)"
        lo, hi = report.tuning_range.get(t, (float("nan"), float("nan")))
        step(
            f"Set {t} by the law: {formula}",
            where=t,
            quantity=t,
            unit=u.label,
            note=f"tuning range over the tolerance corners {u.from_si(lo):.4g} to {u.from_si(hi):.4g} {u.label}; bounds {u.from_si(problem.variable[t].lower):.4g} to {u.from_si(problem.variable[t].upper):.4g} {u.label}",
        )
    exact = "exact: the residual is affine in the tune variables" if law.affine else "not affine in the tune variables: repeat from step 'Clamp' until the readings are within the check"
    step(
        "Check: read the holding forces again at the same poses; each should read 0 N",
        instrument="the spring scale",
        note=exact,
    )
    return rows


def _mass_of(result: Result, column: str) -> float | None:
    """The payload mass (SI) of an adjustment column 'x@camera_5kg' (its setting's scenario)."""
    setting = column.split("@", 1)[1]
    payload = result.problem.payloads[0] if result.problem.payloads else None
    if payload is None:
        return None
    for sc in result.solution.problem.scenarios:
        if sc.setting == setting and payload.name in sc.parameters:
            return sc.parameters[payload.name]
    return None


def law_status_lines(result: Result) -> str:
    """status.txt: the tuning law, its check at random as-built machines, the hardware envelope."""
    report = _report(result)
    if report is None:
        return ""
    lines = []
    problem = result.problem
    law = report.law
    if law is not None:
        parts = []
        for k, t in enumerate(law.tune):
            if law.pairs is None:
                break
            r = law.readings[law.pairs[k]]
            pose = ", ".join(f"{n}={problem.coordinate[n].unit.from_si(x):.4g} {problem.coordinate[n].unit.label}".rstrip() for n, x in r.pose)
            parts.append(f"{t} from the holding force of {r.coordinate} at {pose} (scale at {r.body or 'the slide'})")
        how = "; ".join(parts) or f"{', '.join(law.tune)} from {len(law.readings)} holding forces (coupled: the secant matrix)"
        lines.append(f"tuning law: {how}; {'exact (the residual is affine in the tune variables)' if law.affine else 'not exact (the residual is not affine in the tune variables): repeat it'}")
    check = report.law_check
    if check is not None:
        text = f"tuning law check at {check.samples} random as-built machines: largest residual ratio {check.ideal:.3g} after the law (each spring's string set for its part as measured)"
        if check.real == check.real:
            text += f"; {check.real:.3g} with the strings left set for the nominal parts ({check.real_samples} machines: a rate error times F0/k is a constant force along the cable)"
        lines.append(text)
    for name, env in report.envelope.items():
        s = report.springs.get(name)
        text = f"hardware: spring {name} over every tuned corner: distances {env.distance_min * 1e3:.4g} to {env.distance_max * 1e3:.4g} mm, forces {env.force_min:.4g} to {env.force_max:.4g} N"
        if s is not None:
            text += f"; designed for them: F0 {s.initial_tension:.4g} N, allowable {s.max_force:.4g} N, cable {s.cable * 1e3:.4g} mm"
        least: dict[str, tuple[float, str]] = {}
        for corner, margins in report.margins.items():
            for m in margins:
                if m.spring == name and (m.limit not in least or m.margin < least[m.limit][0]):
                    least[m.limit] = (m.margin, corner)
        if least:
            text += "; least margins: " + ", ".join(f"{limit} {v * (1 if limit == 'load' else 1e3):.4g} {'N' if limit == 'load' else 'mm'} ({c})" for limit, (v, c) in least.items())
        lines.append(text)
    return "".join(f"{line}\n" for line in lines)


def procedure_html(text: str) -> str:
    """report.html's tuning section: the procedure of tuning.csv as a numbered list."""
    import csv
    import html
    import io

    rows = list(csv.DictReader(io.StringIO(text)))
    items = []
    for r in rows:
        value = f" <strong>{html.escape(r.get('value', ''))} {html.escape(r.get('unit', ''))}</strong>" if r.get("value") else ""
        extra = "; ".join(html.escape(r[c]) for c in ("where", "with", "quantity") if r.get(c))
        note = f'<br><span class="note">{html.escape(r["note"])}</span>' if r.get("note") else ""
        items.append(f"<li>{html.escape(r.get('action', ''))}{value}{' (' + extra + ')' if extra else ''}{note}</li>")
    return '<p class="note">tuning.csv: what to measure, where and with what; what to turn and by how much.</p><ol>' + "".join(items) + "</ol>"
