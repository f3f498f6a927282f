"""Report rows: plain dicts with units and descriptions, one list per report file.

Pure data, no pandas: the CLI writes them with the standard library (:mod:`.files`), and
:mod:`.tables` offers them as DataFrames to Python users.
"""

from __future__ import annotations

import math

from ..designer.layers import Row, layers
from ..formulation.constraints import ConstraintValue
from ..pipeline import DesignResult
from ..model.problem import Problem
from ..verify.certificate import certificate_of
from ..designer.checks import PRISMATIC, REVOLUTE, CoordinateCheck


DESIGN_COLUMNS = ["name", "kind", "scenario", "value", "unit", "lower", "upper", "active_bound", "description"]
SUMMARY_COLUMNS = [
    "problem",
    "status",
    "objective",
    "added_mass_kg",
    "added_inertia_kg_m2",
    "max_residual_N_m",
    "max_gravity_torque_N_m",
    "residual_ratio",
    "residual_ratio_as_built",  # the balancer rebuilt from build.csv with real springs (realisation/asbuilt.py)
    "spring_model",  # real, or ideal: a paper's idealised design ([settings] ideal_springs), the status refers to it
    "checked_configurations",
    "iterations",
    "solve_time_s",
    "solver",
    "max_residual_N",
    "max_gravity_force_N",
    "certificate_gap_kg",
    "starts_reaching_best",
    "worst_scenario",
    "lower_bound_ratio",
    "parts",
    "certificate",  # exact: balance proven by the certificate's coefficients; sampled: the dense check
]
VERIFICATION_COLUMNS = [
    "subsystem",
    "scenario",
    "coordinate",
    "max_residual",
    "max_gravity_torque",
    "residual_ratio",
    "unit",
    "configurations",
    "worst_configuration",
]


SUBSTITUTION_COLUMNS = ["body", "point", "frame", "scenario", "mass", "unit"]


def substitution_rows(result: DesignResult) -> list[Row]:
    """One row per substituted point mass (and scenario, when it differs between scenarios)."""
    problem = result.problem
    units = {q.name: q.unit for q in problem.report}
    rows: list[Row] = []
    for sub in problem.substitutions:
        for m in sub.masses:
            for qv in result.quantities:
                if qv.name == m.name:
                    rows.append(
                        {
                            "body": sub.body,
                            "point": m.name,
                            "frame": m.point.frame,
                            "scenario": qv.scenario or "",
                            "mass": units[m.name].from_si(qv.value),
                            "unit": units[m.name].label,
                        }
                    )
    return rows


def design_rows(result: DesignResult) -> list[Row]:
    """Every row of ``design.csv``: the design's own (:func:`core_design_rows`), then each
    registered layer's (:meth:`counterpoise.designer.layers.Layer.design_rows`: a catalogue
    part per slot, a robust counterpart's figures; a payload range's pinned adjustments)."""
    rows = core_design_rows(result)
    for layer in layers():
        rows = layer.design_rows(result, rows)
    return rows


def core_design_rows(result: DesignResult) -> list[Row]:
    """One row per design-vector slot (``variable``), per design constraint
    (``constraint``) and per report quantity (``quantity``)."""
    problem = result.problem
    rows: list[Row] = []
    for slot, value in result.solution.values.items():
        v = problem.variable[slot.variable]
        u = v.unit
        side = v.bound_side(value)
        # a value within the bound tolerance of its bound is reported as the bound itself
        # (not 2.34e-08 mm off it): "at a bound" means one thing everywhere (model.problem)
        shown = v.lower if side == "lower" else v.upper if side == "upper" else value
        rows.append(
            {
                "name": v.name,
                "kind": "variable",
                "scenario": slot.scenario or "",
                "value": u.from_si(shown),
                "unit": u.label,
                "lower": u.from_si(v.lower),
                "upper": u.from_si(v.upper),
                "active_bound": v.bound_side(value),  # a layer may say otherwise (a payload range's pinned adjustment)
                "description": v.description,
            }
        )
    rows += constraint_rows(result)
    units = {q.name: q for q in problem.report}
    for qv in result.quantities:
        q = units[qv.name]
        rows.append(
            {
                "name": qv.name,
                "kind": "quantity",
                "scenario": qv.scenario or "",
                "value": q.unit.from_si(qv.value),
                "unit": q.unit.label,
                "lower": None,
                "upper": None,
                "active_bound": "",
                "description": q.description,
            }
        )
    return rows


def constraint_rows(result: DesignResult) -> list[Row]:
    """One ``constraint`` row per design constraint (and scenario, when there are several):
    its value at the design, its bounds, ``active_bound`` (lower, upper, violated or empty)
    and, for an active one, the sensitivity of the optimal objective to its bound."""
    problem = result.problem
    rows: list[Row] = []
    values = list(result.solution.constraints)
    by_name: dict[str, list[ConstraintValue]] = {}
    for v in values:
        by_name.setdefault(v.name, []).append(v)
    # like report quantities: one row when every scenario agrees (value and mark), else one per scenario
    shown: list[tuple[ConstraintValue, str, float]] = []
    for group in by_name.values():
        first = group[0]
        same = all(v.active == first.active and (v.value == first.value or abs(v.value - first.value) <= 1e-12 * abs(first.value)) for v in group)
        # one bound for every scenario: the objective's sensitivity to it is the sum of theirs
        total = sum(v.sensitivity for v in group)
        shown += [(first, "", total)] if same else [(v, v.scenario, v.sensitivity) for v in group]
    for v, scenario, sensitivity in shown:
        c = v.constraint
        u = c.unit
        text = c.description
        if v.active in ("lower", "upper") and sensitivity == sensitivity:
            # ∂objective/∂bound: objective units (kg) per SI unit of the constraint -> per display unit
            per = sensitivity * u.to_si
            text = f"{text}; " if text else ""
            text += f"d(objective)/d({v.active} bound) = {per:.6g} per {u.label}"
        if v.configuration:
            at = ", ".join(f"{n}={problem.coordinate[n].unit.from_si(x):.6g} {problem.coordinate[n].unit.label}".rstrip() for n, x in v.configuration.items())
            text = f"{text}; extreme at {at}" if text else f"extreme at {at}"
        if v.relaxed > 0:
            relaxed = f"relaxed by {u.from_si(v.relaxed):.4g} {u.label}".rstrip() + " in this design (the elastic design of the conflict)"
            text = f"{text}; {relaxed}" if text else relaxed
        if v.corner:  # a [robust] design: the value at the constraint's worst tolerance corner
            text = f"{text}; worst tolerance corner: {v.corner}" if text else f"worst tolerance corner: {v.corner}"
        rows.append(
            {
                "name": c.name,
                "kind": "constraint",
                "scenario": scenario,
                "value": u.from_si(v.value),
                "unit": u.label,
                "lower": u.from_si(c.lower) if c.lower is not None else None,
                "upper": u.from_si(c.upper) if c.upper is not None else None,
                "active_bound": v.active,
                "description": text,
            }
        )
    return rows


def summary_row(result: DesignResult) -> Row:
    """The one-row summary: the design's own cells (:func:`core_summary_row`), then each
    registered layer's (the parts chosen, the residual ratio as built). A cell whose column
    :data:`SUMMARY_COLUMNS` does not list is written after those (:func:`summary_columns`)."""
    row = core_summary_row(result)
    for layer in layers():
        row.update(layer.summary_cells(result))
    return row


def summary_columns(row: Row) -> list[str]:
    """The columns of ``summary.csv`` for ``row``: :data:`SUMMARY_COLUMNS`, then any a layer added."""
    return [*SUMMARY_COLUMNS, *(c for c in row if c not in SUMMARY_COLUMNS)]


def core_summary_row(result: DesignResult) -> Row:
    """The summary cells of the design itself. Revolute figures (N·m) and prismatic ones (N)
    are kept apart; a kind the problem does not have is left empty."""
    s, v = result.solution, result.verification
    stats = s.stats
    return {
        "problem": result.problem.name,
        "status": result.status.value,
        "objective": s.objective,
        "added_mass_kg": s.added_mass,
        "added_inertia_kg_m2": s.added_inertia,
        "max_residual_N_m": v.max_residual(REVOLUTE),
        "max_gravity_torque_N_m": v.max_gravity_torque(REVOLUTE),
        "residual_ratio": v.residual_ratio,
        "spring_model": "ideal" if result.problem.settings.ideal_springs else "real",
        "certificate": certificate_of(v),
        "checked_configurations": v.configurations,
        "iterations": stats.iterations,
        "solve_time_s": stats.solve_time,
        "solver": stats.solver,
        "max_residual_N": v.max_residual(PRISMATIC),
        "max_gravity_force_N": v.max_gravity_torque(PRISMATIC),
        "certificate_gap_kg": stats.certificate_gap,
        "starts_reaching_best": f"{stats.starts[0]}/{stats.starts[1]}",
        "worst_scenario": worst.scenario if (worst := v.worst()) is not None else "",
    }


def _scenario_label(problem: Problem, check: CoordinateCheck) -> str:
    """A check's scenario; on a tilting base, the working mode checked over its whole tilt box
    ('nominal (all tilts)'), since one check covers every node of its tilt grid."""
    if not check.worst_tilt:
        return check.scenario
    own = next((s for s in problem.scenarios if s.name == check.scenario), None)
    return f"{own.setting if own is not None and own.setting else check.scenario} (all tilts)"


def verification_rows(result: DesignResult) -> list[Row]:
    """One row per (subsystem, scenario, coordinate) balance condition."""
    problem = result.problem
    verification = result.verification
    rows: list[Row] = []
    for c in verification.checks:
        rows.append(
            {
                "subsystem": c.subsystem,
                "scenario": _scenario_label(problem, c),
                "coordinate": c.coordinate,
                "max_residual": c.max_residual,
                "max_gravity_torque": c.max_gravity_torque,
                "residual_ratio": verification.ratio(c),
                "unit": c.unit,
                "configurations": c.configurations,
                "worst_configuration": "; ".join(
                    f"{k.name}={k.unit.from_si(x):.6g} {k.unit.label}".rstrip()
                    for k, x in zip(problem.subsystem_coordinates(c.subsystem), c.worst_configuration)
                )
                + "".join(f"; tilt{i + 1}={math.degrees(a):.6g} deg" for i, a in enumerate(c.worst_tilt)),
            }
        )
    return rows


def status_text(result: DesignResult) -> str:
    s = result.solution
    stats = s.stats
    return (
        f"problem: {result.problem.name}\n"
        f"status: {result.status.value}\n"
        f"message: {result.message}\n"
        f"solver: {stats.solver} ({stats.solver_status}), {stats.iterations} iterations\n"
        f"balance conditions: {stats.conditions} ({stats.condition_summary})\n"
        + (f"closest design: {s.closest}\n" if result.status.value == "infeasible" and s.closest else "")
    )
