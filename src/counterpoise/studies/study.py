"""A parameter study: points → runner → ``results/<name>-study/study.csv``.

The folder holds ``study.csv`` (one row per point, in point order) and ``study.json``
(the problem, the varied keys, the method, the seed and the columns). Rows are written in
batches through a temporary file and a rename, so an interrupted study keeps every batch
it finished; ``resume=True`` skips the points already in the file (the plan must be the
same: same ``--vary``, method, samples and seed). A point that fails, raises or runs past
the time limit is recorded with its status and the study goes on.
"""

from __future__ import annotations

import csv
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ProblemFileError
from ..model.problem import Problem
from ..report.files import FLOAT_FORMAT, atomic_write_text
from .runners import PointResult, Runner, SerialRunner, StudyTask, batched
from .spec import StudyPlan

FIXED_BEFORE = ["point"]
FIXED_AFTER = ["status", "objective_kg", "added_mass_kg", "added_inertia_kg_m2"]
FIXED_END = ["residual_ratio", "certificate", "certificate_gap_kg", "solve_time_s", "solver", "message"]


@dataclass
class StudyOutcome:
    folder: Path
    total: int
    skipped: int  # already in the file (--resume)
    counts: dict[str, int] = field(default_factory=dict)  # status -> points run now
    wall_time: float = 0.0

    @property
    def run(self) -> int:
        return sum(self.counts.values())


def study_folder(problem: Problem, out: str | Path) -> Path:
    return Path(out) / f"{problem.name}-study"


def variable_columns(problem: Problem) -> list[tuple[str, str, float]]:
    """(result key, CSV header, SI size of the display unit) of every design-vector slot."""
    out = []
    for v in problem.variables:
        for scenario in problem.scenarios if v.adjustable else [None]:
            key = v.name if scenario is None else f"{v.name}@{scenario.name}"
            out.append((key, f"{key} [{v.unit.label}]", v.unit.to_si))
    return out


def columns(problem: Problem, plan: StudyPlan) -> list[str]:
    return FIXED_BEFORE + [v.header for v in plan.varies] + FIXED_AFTER + [h for _, h, _ in variable_columns(problem)] + FIXED_END


def _fmt(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return "" if value != value else FLOAT_FORMAT % value
    return str(value)


def result_row(problem: Problem, plan: StudyPlan, index: int, r: PointResult) -> dict[str, str]:
    """One CSV row (strings) of point ``index``: display units throughout."""
    row = {"point": str(index)}
    for v in plan.varies:
        row[v.header] = _fmt(v.unit.from_si(plan.points[index][v.key]))
    row.update(
        status=r.status,
        objective_kg=_fmt(r.objective),
        added_mass_kg=_fmt(r.added_mass),
        added_inertia_kg_m2=_fmt(r.added_inertia),
        residual_ratio=_fmt(r.residual_ratio),
        certificate=r.certificate,
        certificate_gap_kg=_fmt(r.certificate_gap),
        solve_time_s=_fmt(r.solve_time),
        solver=r.solver,
        message=r.message,
    )
    for key, header, size in variable_columns(problem):
        row[header] = _fmt(r.values[key] / size) if key in r.values else ""
    return row


def _csv(rows: Sequence[dict[str, str]], cols: list[str]) -> str:
    import io

    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(cols)
    for row in rows:
        writer.writerow([row.get(c, "") for c in cols])
    return buffer.getvalue()


def read_rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8", newline="") as handle:
        return list(csv.DictReader(handle))


def run_study(
    problem: Problem,
    plan: StudyPlan,
    out: str | Path = "results",
    runner: Runner | None = None,
    *,
    task: StudyTask | None = None,
    resume: bool = False,
    batch_size: int = 16,
    flush_seconds: float = 1.0,
    progress: Callable[[list[PointResult]], None] | None = None,
    started: Callable[[int], None] | None = None,
) -> StudyOutcome:
    """Run every point of ``plan`` (minus those already done when ``resume``) and write the study.

    Finished batches are written to ``study.csv`` at most every ``flush_seconds`` (0: after
    every batch) and at the end, also when the study is interrupted. ``started(skipped)`` is called once the points already
    done are known; ``progress(results)`` after each batch.
    """
    t0 = time.perf_counter()
    folder = study_folder(problem, out)
    csv_path, meta_path = folder / "study.csv", folder / "study.json"
    cols = columns(problem, plan)
    label = problem.path or problem.name
    done: dict[int, dict[str, str]] = {}
    if resume and csv_path.exists():
        try:
            meta = json.loads(meta_path.read_text(encoding="utf-8"))
            rows = read_rows(csv_path)
        except (OSError, ValueError) as exc:
            raise ProblemFileError(label, "--resume", f"cannot read the study in {folder}: {exc}") from None
        if meta.get("plan") != json.loads(json.dumps(plan.identity())) or meta.get("columns") != cols:
            raise ProblemFileError(label, "--resume", f"{folder} holds a study with other --vary/--samples/--seed or another problem; drop --resume to start again")
        done = {int(r["point"]): r for r in rows if r.get("point", "").isdigit() and int(r["point"]) < len(plan.points)}
    meta = {
        "problem": problem.name,
        "file": problem.path,
        "plan": plan.identity(),
        "points": len(plan.points),
        "columns": cols,
        "time_limit_s": task.time_limit if task else None,
    }
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_text(meta_path, json.dumps(meta, indent=2) + "\n")
    todo = [i for i in range(len(plan.points)) if i not in done]
    outcome = StudyOutcome(folder, len(plan.points), len(done))
    rows = dict(done)
    atomic_write_text(csv_path, _csv([rows[i] for i in sorted(rows)], cols))
    task = task or StudyTask(problem)
    task.key  # the content digest, computed once here: it travels with the task to every worker
    if started is not None:
        started(len(done))
    batches = batched(todo, batch_size)
    point_batches = [[plan.points[i] for i in b] for b in batches]
    last_flush = time.perf_counter()
    try:
        for indices, results in zip(batches, (runner or SerialRunner()).map_batches(task, point_batches)):
            for i, r in zip(indices, results):
                rows[i] = result_row(problem, plan, i, r)
                outcome.counts[r.status] = outcome.counts.get(r.status, 0) + 1
            if time.perf_counter() - last_flush >= flush_seconds:  # whole batches, at most once per flush_seconds
                atomic_write_text(csv_path, _csv([rows[i] for i in sorted(rows)], cols))
                last_flush = time.perf_counter()
            if progress is not None:
                progress(results)
    finally:  # also when interrupted: keep every finished batch
        atomic_write_text(csv_path, _csv([rows[i] for i in sorted(rows)], cols))
    outcome.wall_time = time.perf_counter() - t0
    return outcome
