"""Design reports: tidy tables with units and descriptions, written atomically as CSV.

``results/<problem>/`` receives

- ``design.csv``: one row per design variable (kind ``variable``) and per report quantity
  (kind ``quantity``), values in the file's display units;
- ``summary.csv``: one row with the status, objective and verification figures;
- ``verification.csv``: one row per (subsystem, scenario, coordinate) balance condition;
- ``status.txt``: the status and the message explaining it.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from .design import DesignResult, active_bound

if TYPE_CHECKING:
    import pandas as pd

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
    "checked_configurations",
    "iterations",
    "solve_time_s",
    "solver",
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
FLOAT_FORMAT = "%.10g"


def design_table(result: DesignResult) -> "pd.DataFrame":
    import pandas as pd

    problem = result.problem
    rows = []
    for slot, value in result.solution.values.items():
        v = problem.variable[slot.variable]
        u = v.unit
        rows.append(
            {
                "name": v.name,
                "kind": "variable",
                "scenario": slot.scenario or "",
                "value": u.from_si(value),
                "unit": u.label,
                "lower": u.from_si(v.lower),
                "upper": u.from_si(v.upper),
                "active_bound": active_bound(value, v.lower, v.upper),
                "description": v.description,
            }
        )
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
    return pd.DataFrame(rows, columns=DESIGN_COLUMNS)


def summary_row(result: DesignResult) -> dict[str, object]:
    s, v = result.solution, result.verification
    return {
        "problem": result.problem.name,
        "status": result.status.value,
        "objective": s.objective,
        "added_mass_kg": s.added_mass,
        "added_inertia_kg_m2": s.added_inertia,
        "max_residual_N_m": v.max_residual,
        "max_gravity_torque_N_m": v.max_gravity_torque,
        "residual_ratio": v.residual_ratio,
        "checked_configurations": v.configurations,
        "iterations": s.iterations,
        "solve_time_s": s.solve_time,
        "solver": s.solver,
    }


def summary_table(results: list[DesignResult]) -> "pd.DataFrame":
    import pandas as pd

    return pd.DataFrame([summary_row(r) for r in results], columns=SUMMARY_COLUMNS)


def verification_table(result: DesignResult) -> "pd.DataFrame":
    import pandas as pd

    problem = result.problem
    rows = []
    for c in result.verification.checks:
        unit = problem.coordinate[c.coordinate].unit
        rows.append(
            {
                "subsystem": c.subsystem,
                "scenario": c.scenario,
                "coordinate": c.coordinate,
                "max_residual": c.max_residual,
                "max_gravity_torque": c.max_gravity_torque,
                "residual_ratio": c.ratio,
                "unit": "N·m" if unit.dimension == "" else "N",
                "configurations": c.configurations,
                "worst_configuration": " ".join(
                    f"{k.unit.from_si(x):.6g}" for k, x in zip(problem.subsystem_coordinates(c.subsystem), c.worst_configuration)
                ),
            }
        )
    return pd.DataFrame(rows, columns=VERIFICATION_COLUMNS)


def status_text(result: DesignResult) -> str:
    s = result.solution
    return (
        f"problem: {result.problem.name}\n"
        f"status: {result.status.value}\n"
        f"message: {result.message}\n"
        f"solver: {s.solver} ({s.solver_status}), {s.iterations} iterations\n"
        f"balance conditions: {s.conditions} ({s.condition_summary})\n"
    )


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_reports(result: DesignResult, out_dir: str | Path) -> Path:
    """Write every report of ``result`` into ``out_dir/<problem name>/``; returns that folder."""
    folder = Path(out_dir) / result.problem.name
    tables = {
        "design.csv": design_table(result),
        "summary.csv": summary_table([result]),
        "verification.csv": verification_table(result),
    }
    texts = {name: df.to_csv(index=False, float_format=FLOAT_FORMAT, lineterminator="\n") for name, df in tables.items()}
    texts["status.txt"] = status_text(result)
    for name, text in texts.items():
        atomic_write_text(folder / name, text)
    return folder
