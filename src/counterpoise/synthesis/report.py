"""The synthesis's files: ``<out>/<problem>-synthesis/`` with ``synthesis.csv`` (the
minimal topologies, ranked, and the Pareto front), ``elements.csv`` (each topology's grid
design), ``terms.csv`` (the coefficient structure: each balance term and the classes that
can produce it), ``status.txt`` (what is proven), and per topology its problem file
``<problem>_tN.toml`` and the engine's reports of its verified design in
``<problem>_tN/`` (report.html among them). Written whole or not at all."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ..report.files import atomic_folder, csv_text, write_reports
from .run import INFEASIBLE, SynthesisResult, element_rows

SYNTHESIS_COLUMNS = (
    "kind",
    "rank",
    "topology",
    "elements",
    "cost",
    "grid_added_mass_kg",
    "added_mass_kg",
    "added_inertia_kg_m2",
    "objective_kg",
    "design",
    "status",
    "residual_ratio",
    "proof",
    "problem_file",
    "report",
)
ELEMENT_COLUMNS = ("rank", "topology", "kind", "name", "value", "unit", "points_mm")
TERM_COLUMNS = ("term", "mechanism_J", "produced_by")


def folder_name(result: SynthesisResult) -> str:
    return f"{result.problem.name}-synthesis"


def synthesis_rows(result: SynthesisResult) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    proof = result.proof
    for t in result.topologies:
        s = t.result.solution
        rows.append({
            "kind": "minimal",
            "rank": t.rank,
            "topology": "; ".join(t.labels),
            "elements": len(t.labels),
            "cost": t.grid.cost,
            "grid_added_mass_kg": t.grid.added_mass,
            "added_mass_kg": s.added_mass,
            "added_inertia_kg_m2": s.added_inertia,
            "objective_kg": s.objective,
            "design": "refined" if t.form == "free" else "grid",
            "status": t.result.status.value,
            "residual_ratio": t.result.verification.residual_ratio,
            "proof": proof + ("" if result.complete else "; the enumeration stopped before the last topology"),
            "problem_file": f"{t.name}.toml",
            "report": f"{t.name}/report.html",
        })
    for p in result.pareto:
        rows.append({"kind": "pareto", "topology": "; ".join(p.labels), "elements": len(p.labels), "cost": p.cost, "grid_added_mass_kg": p.added_mass,
                     "proof": "the least added mass on the grid at this cost; the least cost on the grid for less added mass than the previous point"})
    if result.status == INFEASIBLE:
        rows.append({"kind": "infeasible", "status": result.status, "proof": proof, "topology": "; ".join(f"{n} {v:+.6g} J" for n, v in result.unbalanced)})
    return rows


def status_text(result: SynthesisResult) -> str:
    lines = [
        f"synthesis of {result.problem.name}: {result.status}",
        result.message,
        f"proof: {result.proof}",
    ]
    if not math.isnan(result.cost):
        lines.append(f"least cost on the grid: {result.cost:g} (proven lower bound {result.grid_bound:g}); grid-independent lower bound {result.relaxation_bound:g}")
    lines.append(f"enumeration: {'complete: every minimal topology on the grid is listed' if result.complete else 'not complete'}")
    if result.conditions_exact:
        lines.append(f"conditions: exact ({result.rows} trigonometric coefficients of the energy, every configuration)")
    else:
        lines.append(f"conditions: sampled ({result.rows} rows; exact at the samples, not a proof between them): " + "; ".join(result.sampled_reasons))
    lines.append(f"search: {result.candidates} candidates, {result.master_solves} master and {result.grid_solves} grid solves, {result.seconds:.2f} s"
                 + (f"; {result.rejected} solution(s) balanced only to the solver's tolerance were excluded" if result.rejected else "")
                 + (f"; {result.timed_out} grid solve(s) hit the time limit (not proven)" if result.timed_out else ""))
    for n, v in result.unbalanced:
        lines.append(f"unbalanced: {n}: {v:+.6g} J")
    for t in result.topologies:
        lines.append(f"topology {t.rank}: {', '.join(t.labels)}: {t.result.status.value}, residual ratio {t.result.verification.residual_ratio:.2e}; {t.note}")
        if not t.verified:
            lines.append(f"  {t.result.message}")
    for p in result.pareto:
        lines.append(f"pareto: cost {p.cost:g}, added mass {p.added_mass:.6g} kg: {', '.join(p.labels)}")
    lines += [f"warning: {w}" for w in result.warnings]
    return "\n".join(lines) + "\n"


def write_synthesis(result: SynthesisResult, out_dir: str | Path, html: bool = True) -> Path:
    """Write the synthesis's files into ``out_dir/<problem>-synthesis/`` (see the module)."""
    texts = {
        "synthesis.csv": csv_text(synthesis_rows(result), SYNTHESIS_COLUMNS),
        "elements.csv": csv_text([{"rank": t.rank, "topology": "; ".join(t.labels), **row} for t in result.topologies for row in element_rows(t, result.classes)], ELEMENT_COLUMNS),
        "terms.csv": csv_text(list(result.terms), TERM_COLUMNS),
        "status.txt": status_text(result),
    }

    def fill(temp: Path) -> None:
        for name, text in texts.items():
            (temp / name).write_text(text, encoding="utf-8")
        for t in result.topologies:
            (temp / f"{t.name}.toml").write_text(t.text, encoding="utf-8")
            write_reports(t.result, temp, html=html)

    return atomic_folder(Path(out_dir) / folder_name(result), fill)
