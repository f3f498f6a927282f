"""Reports of a payload-range design: ``schedule.csv`` and the lines added to ``status.txt``.

``schedule.csv`` has one row per grid payload: ``payload [<unit>]``, one column per
adjustable variable ``<name> [<unit>]`` (display units), ``residual_ratio`` (the dense
check of that payload in every working mode) and ``feasible``.
"""

from __future__ import annotations

from ..designer.layers import Result, Row
from ..model.problem import Variable
from .result import PayloadDesign


def _header(name: str, label: str) -> str:
    return f"{name} [{label}]"


def schedule_columns(result: Result) -> list[str]:
    outcome = result.extra(PayloadDesign)
    if outcome is None:  # not a payload-range design: no schedule.csv
        return []
    names = [_header("payload", outcome.payload.unit.label)]
    names += [_header(v.name, v.unit.label) for v in _adjustables(result)]
    return names + ["residual_ratio", "feasible"]


def schedule_rows(result: Result) -> list[Row]:
    """One row per grid payload of the schedule (display units)."""
    outcome = result.extra(PayloadDesign)
    if outcome is None or outcome.schedule is None:
        return []
    unit = outcome.payload.unit
    rows: list[Row] = []
    for s in outcome.schedule.rows:
        row: Row = {_header("payload", unit.label): unit.from_si(s.payload)}
        for v in _adjustables(result):
            row[_header(v.name, v.unit.label)] = v.unit.from_si(s.values[v.name])
        row["residual_ratio"] = s.residual_ratio
        row["feasible"] = "yes" if s.feasible else "no"
        rows.append(row)
    return rows


def payload_status_lines(result: Result) -> str:
    """Range, samples, the check between grid points and the linear formulas, as text."""
    outcome = result.extra(PayloadDesign)
    if outcome is None:
        return ""
    payload = outcome.payload
    unit = payload.unit
    lines = [
        f"payload: {payload.name}, declared range {payload.label(payload.lower)} to {payload.label(payload.upper)}, "
        f"nominal {payload.label(payload.nominal)}",
        "design samples: " + ", ".join(payload.label(m) for m in outcome.samples),
    ]
    plan = outcome.schedule
    if plan is not None:
        bad = [s for s in plan.between if not s.feasible]
        lines.append(
            f"schedule: {len(plan.rows)} grid payloads from {payload.label(outcome.checked[0])} to {payload.label(outcome.checked[1])}, "
            f"{len(plan.between)} more between them ({'all feasible' if not bad else f'{len(bad)} infeasible'})"
        )
        failure = plan.first_failure
        if failure is not None:
            lines.append(f"schedule: first failing payload {payload.label(failure.payload)}")
        variables = {v.name: v for v in _adjustables(result)}
        for line in plan.lines:
            v = variables[line.variable]
            slope = line.slope * unit.to_si / v.unit.to_si
            # an offset that is rounding noise of the fit (8.3e-14 mm) is shown as 0
            size = abs(line.intercept) + abs(line.slope) * max(abs(outcome.checked[0]), abs(outcome.checked[1]))
            intercept = 0.0 if abs(line.intercept) <= max(line.deviation, 1e-9 * size) else line.intercept
            lines.append(
                f"linear in the payload: {v.name} = {v.unit.from_si(intercept):.8g} {v.unit.label} + "
                f"{slope:.8g} {v.unit.label}/{unit.label} × {payload.name} (largest deviation {v.unit.from_si(line.deviation):.2g} {v.unit.label})"
            )
    if outcome.widest is not None:
        w = outcome.widest
        lines.append(f"widest payload range: {payload.label(w.lower)} to {payload.label(w.upper)} ({payload.label(w.upper - w.lower)}), {w.limit}")
        if w.lower_limit:
            lines.append(f"widest payload range: below {payload.label(w.lower)} {w.lower_limit}")
    return "\n".join(lines) + "\n"


def _adjustables(result: Result) -> list[Variable]:
    return [v for v in result.problem.variables if v.adjustable]
