"""Where many designs run: serially, on a local process pool, or (later) on Dask.

A study hands a runner a :class:`StudyTask` (a picklable description: the problem and
the solver options) and batches of points; the runner decides where they run. Each worker
builds the designer once from the description (CasADi objects do not pickle) and solves
its batches with it, so a batch costs one build at most per worker, never one per point.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Any, Protocol

from ..model.problem import Problem

Point = Mapping[str, float]  # base-parameter overrides (SI) of one study point


@dataclass(frozen=True)
class StudyTask:
    """What a worker needs to rebuild the designer: picklable, unlike the designer's CasADi objects."""

    problem: Problem
    ipopt_options: Mapping[str, Any] = field(default_factory=dict)

    def designer(self) -> Any:
        from ..designer.designer import Designer

        return Designer(self.problem, self.ipopt_options)


@dataclass(frozen=True)
class PointResult:
    """The outcome of one point, small enough to send back from a worker."""

    point: dict[str, float]
    status: str
    message: str
    values: dict[str, float]  # variable (or variable@scenario) -> SI value
    objective: float
    added_mass: float
    added_inertia: float
    residual_ratio: float
    solve_time: float


_WORKER: dict[int, Any] = {}  # id(task) in this process -> designer, built once per worker


def solve_batch(task: StudyTask, points: Sequence[Point]) -> list[PointResult]:
    """Solve and verify each point with one designer (built once per process and task)."""
    from ..pipeline import design

    key = hash((task.problem.name, task.problem.path, tuple(sorted(task.ipopt_options.items()))))
    designer = _WORKER.get(key)
    if designer is None:
        designer = _WORKER[key] = task.designer()
    out = []
    for point in points:
        result = design(task.problem, designer, parameters=dict(point))
        s = result.solution
        out.append(
            PointResult(
                point=dict(point),
                status=result.status.value,
                message=result.message,
                values={slot.variable if slot.scenario is None else f"{slot.variable}@{slot.scenario}": v for slot, v in s.values.items()},
                objective=s.objective,
                added_mass=s.added_mass,
                added_inertia=s.added_inertia,
                residual_ratio=result.verification.residual_ratio,
                solve_time=s.solve_time,
            )
        )
    return out


class Runner(Protocol):
    """Runs ``solve_batch(task, batch)`` for every batch; yields results in batch order."""

    def map_batches(self, task: StudyTask, batches: Sequence[Sequence[Point]]) -> Iterator[list[PointResult]]: ...


class SerialRunner:
    """Everything in this process (the reference: other runners must give the same values)."""

    def map_batches(self, task: StudyTask, batches: Sequence[Sequence[Point]]) -> Iterator[list[PointResult]]:
        for batch in batches:
            yield solve_batch(task, batch)


class ProcessRunner:
    """A local process pool; ``jobs`` defaults to the number of cores."""

    def __init__(self, jobs: int | None = None) -> None:
        self.jobs = jobs or os.cpu_count() or 1

    def map_batches(self, task: StudyTask, batches: Sequence[Sequence[Point]]) -> Iterator[list[PointResult]]:
        with ProcessPoolExecutor(max_workers=self.jobs, initializer=_single_threaded) as pool:
            yield from pool.map(solve_batch, [task] * len(batches), batches)


def _single_threaded() -> None:
    from ..threads import limit_blas_threads

    limit_blas_threads()


def batched(points: Sequence[Point], size: int) -> list[Sequence[Point]]:
    """Consecutive batches of at most ``size`` points."""
    if size < 1:
        raise ValueError("batch size must be at least 1")
    return [points[i : i + size] for i in range(0, len(points), size)]


def run(task: StudyTask, points: Sequence[Point], runner: Runner | None = None, batch_size: int = 32,
        progress: Callable[[int], None] | None = None) -> list[PointResult]:
    """Solve every point with ``runner`` (serial by default); results in the points' order."""
    out: list[PointResult] = []
    for results in (runner or SerialRunner()).map_batches(task, batched(points, batch_size)):
        out.extend(results)
        if progress is not None:
            progress(len(results))
    return out
