"""Where many designs run: serially, on a local process pool, or (later) on Dask.

A study hands a runner a :class:`StudyTask` (a picklable description: the problem and
the solver options) and batches of points; the runner decides where they run: in this
process (:class:`SerialRunner`), on a local process pool (:class:`ProcessRunner`) or on a
Dask cluster (:class:`DaskRunner`, batches as tasks). Each worker
builds the problem's design method once from the description (CasADi objects do not
pickle; :func:`counterpoise.pipeline.build_method`: the designer, a payload range's
method, a slot problem's part search with its relaxed designer) and solves its batches
with it (:func:`counterpoise.pipeline.run`), so a batch costs one build at most per
worker, never one per point.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

from .. import unfinished
from ..kept import Kept
from ..model.problem import Problem

if TYPE_CHECKING:
    from ..designer.designer import Designer
    from ..designer.methods import DesignMethod
    from ..formulation.layout import Slot

#: One study point: values (SI) by key. A bare name is a literal parameter of the file
#: (``m_endo``); ``VAR.lower`` / ``VAR.upper`` a variable's bound; ``objective.mass_weight``
#: and ``objective.inertia_weight`` the objective's weights (see :mod:`.spec`).
Point = Mapping[str, float]
T = TypeVar("T")

#: statuses a point can end with, besides the design statuses (optimal, infeasible, failed)
TIMEOUT = "timeout"
ERROR = "error"
_TIME_CODES = ("Maximum_WallTime_Exceeded", "Maximum_CpuTime_Exceeded")


@dataclass(frozen=True)
class StudyTask:
    """What a worker needs to rebuild the designer: picklable, unlike the designer's CasADi objects.

    ``time_limit`` (seconds per point): IPOPT's ``max_wall_time`` and Clarabel's
    ``time_limit`` stop a solver that runs too long, and in a process's main thread an
    interval timer also stops Python code that hangs; such a point is recorded as ``timeout``.
    ``warm_start``: each point of a batch starts from the previous point's optimum (batches
    are the same whichever engine runs them, so the results are too).
    ``check``: how each point is verified: ``auto`` by the exact certificate where the
    residual is a trigonometric polynomial and its coefficients prove balance, else by the
    dense check; ``dense`` always by the dense check (:func:`counterpoise.verify.check.check`).
    """

    problem: Problem
    ipopt_options: Mapping[str, Any] = field(default_factory=dict)
    time_limit: float | None = None
    warm_start: bool = True
    backend: str = "auto"
    check: str = "auto"

    def designer(self, problem: Problem | None = None) -> Designer:
        from ..designer.designer import Designer

        options = dict(self.ipopt_options)
        if self.time_limit is not None:
            options["max_wall_time"] = float(self.time_limit)
        designer = Designer(problem or self.problem, options, self.backend)
        if self.time_limit is not None and designer.convex is not None:
            designer.convex.options["time_limit"] = float(self.time_limit)
        return designer

    def method(self, problem: Problem | None = None) -> DesignMethod:
        """The design method of ``problem`` (this task's by default), built once per worker.

        Where the innermost solve is the :class:`~counterpoise.designer.designer.Designer`
        of the problem itself (no payload range, no directly attached spring), it is
        :meth:`designer`'s, so the solver options and the time limit apply to it."""
        from ..designer.minimax import needs_minimax
        from ..pipeline import build_method

        problem = problem or self.problem
        inner = None if problem.payloads or needs_minimax(problem) else self.designer(problem)
        return build_method(problem, backend=self.backend, designer=inner)

    @cached_property
    def key(self) -> str:
        """Cache key of the designers built from this task: the problem's *content*
        (:func:`~counterpoise.model.digest.content_key`) and the solver options, never its
        name or path (two problems of one file with different ``--set`` values differ)."""
        from ..model.digest import content_key, digest

        return digest((content_key(self.problem), sorted((str(k), repr(v)) for k, v in self.ipopt_options.items()), self.time_limit, self.backend))


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
    solver: str = ""
    certificate_gap: float = float("nan")
    #: ``exact``: balance proven by the certificate's coefficients; ``sampled``: the dense check
    certificate: str = ""
    #: slot -> (chosen part number, its rate N/m, its springs' largest working force N)
    parts: dict[str, tuple[str, float, float]] = field(default_factory=dict)


#: design methods built in this process, per thread (a CasADi function is not safe to call
#: from two threads at once, and a Dask worker may run several task threads), least
#: recently used last; at most :data:`CACHED_METHODS` each (a weight study builds one per weight)
_WORKER = threading.local()
CACHED_METHODS = 8


class PointTimeout(Exception):
    """Raised by the interval timer when a point runs past the study's time limit."""


def method_for(task: StudyTask, weights: Mapping[str, float]) -> DesignMethod:
    """The design method of this task (and objective weights, which are built into the NLP),
    kept per worker under the problem's content (:attr:`StudyTask.key`)."""
    problem = task.problem
    key = (task.key, (weights.get("mass_weight", problem.objective.mass_weight), weights.get("inertia_weight", problem.objective.inertia_weight)))
    kept: Kept[tuple[str, tuple[float, float]], DesignMethod] = _WORKER.__dict__.setdefault("methods", Kept(CACHED_METHODS))

    def build() -> DesignMethod:
        if not weights:
            return task.method(problem)
        import dataclasses

        from ..model.problem import Objective

        return task.method(dataclasses.replace(problem, objective=Objective(*key[1])))

    return kept.get(key, build)


def split_point(point: Point) -> tuple[dict[str, float], dict[str, list[tuple[str, float]]], dict[str, float]]:
    """(parameters, bounds {variable: [(side, value), ...]}, objective weights) of a point."""
    parameters: dict[str, float] = {}
    bounds: dict[str, list[tuple[str, float]]] = {}
    weights: dict[str, float] = {}
    for key, value in point.items():
        if key.startswith("objective."):
            weights[key.removeprefix("objective.")] = float(value)
        elif key.endswith(".lower") or key.endswith(".upper"):
            name, _, side = key.rpartition(".")
            bounds.setdefault(name, []).append((side, float(value)))
        else:
            parameters[key] = float(value)
    return parameters, bounds, weights


def _bounds(problem: Problem, sides: Mapping[str, Sequence[tuple[str, float]]]) -> dict[Slot | str, tuple[float, float]]:
    out: dict[Slot | str, tuple[float, float]] = {}
    for name, items in sides.items():
        v = problem.variable[name]
        lo, hi = v.lower, v.upper
        for side, value in items:
            if side == "lower":
                lo = value
            else:
                hi = value
        out[name] = (lo, hi)
    return out


def solve_point(task: StudyTask, point: Point, initial: Mapping[Any, float] | None = None) -> tuple[PointResult, Any]:
    """Solve and verify one point; never raises for a point's own failure (it is recorded)."""
    from ..errors import CounterpoiseError
    from ..pipeline import run as run_method
    from ..verify.certificate import certificate_of

    parameters, sides, weights = split_point(point)
    t0 = time.perf_counter()
    try:
        with _time_limit(task.time_limit):
            method = method_for(task, weights)
            result = run_method(method, parameters=parameters, bounds=_bounds(task.problem, sides) or None, initial=initial, quantities=False, check=task.check)
    except PointTimeout:
        return _failed(point, TIMEOUT, f"no result within the time limit of {task.time_limit:g} s", time.perf_counter() - t0), None
    except (CounterpoiseError, ArithmeticError, ValueError, KeyError, RuntimeError) as exc:
        return _failed(point, ERROR, f"{type(exc).__name__}: {' '.join(str(exc).split())}", time.perf_counter() - t0), None
    s = result.solution
    status, message = result.status.value, result.message
    if s.stats.solver_status in _TIME_CODES:
        status, message = TIMEOUT, f"{s.stats.solver} stopped at the time limit of {task.time_limit:g} s"
    res = PointResult(
        point=dict(point),
        status=status,
        message=message,
        values={slot.variable if slot.scenario is None else f"{slot.variable}@{slot.scenario}": v for slot, v in s.values.items()},
        objective=s.objective,
        added_mass=s.added_mass,
        added_inertia=s.added_inertia,
        residual_ratio=result.verification.residual_ratio,
        solve_time=s.stats.solve_time,
        solver=s.stats.solver,
        certificate_gap=s.stats.certificate_gap,
        certificate=certificate_of(result.verification),
        parts=_chosen_parts(result),
    )
    return res, (s.values if status == "optimal" else None)


def _chosen_parts(result: Any) -> dict[str, tuple[str, float, float]]:
    """Each slot's chosen part (the nearest candidate when none fits), its rate and the
    largest force its springs pull over the checked configurations (``result``: a
    :class:`~counterpoise.pipeline.DesignResult`)."""
    from ..selection.result import PartsReport

    parts = result.extra(PartsReport)
    if parts is None:
        return {}
    out = {}
    for slot in result.problem.slots:
        row = parts.chosen.get(slot.name)
        if row is None:
            continue
        forces = [u.force_max for u in parts.springs if u.slot == slot.name]
        out[slot.name] = (slot.catalogue.part_number[row], slot.catalogue.rate[row], max(forces) if forces else float("nan"))
    return out


def _failed(point: Point, status: str, message: str, elapsed: float) -> PointResult:
    nan = float("nan")
    return PointResult(dict(point), status, message, {}, nan, nan, nan, nan, elapsed)


def solve_batch(task: StudyTask, points: Sequence[Point]) -> list[PointResult]:
    """Solve and verify each point with one design method (built once per process and task);
    with ``task.warm_start`` each point starts from the previous point's optimum."""
    out = []
    previous = None
    for point in points:
        result, values = solve_point(task, point, previous if task.warm_start else None)
        previous = values if values is not None else previous
        out.append(result)
    return out


@contextmanager
def _time_limit(seconds: float | None) -> Iterator[None]:
    """Raise :class:`PointTimeout` after ``seconds`` (main thread of a process only: POSIX
    interval timer; elsewhere the solvers' own time limits are the guard)."""
    usable = seconds is not None and hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()
    if not usable:
        yield
        return

    def _raise(signum: int, frame: Any) -> None:
        raise PointTimeout()

    previous = signal.signal(signal.SIGALRM, _raise)
    # a little slack so that the solver's own limit (a clean status) normally fires first
    signal.setitimer(signal.ITIMER_REAL, float(seconds) * 1.5 + 0.5)  # type: ignore[arg-type]  # called only with a time limit
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


class Runner(Protocol):
    """Runs ``solve_batch(task, batch)`` for every batch; yields results in batch order."""

    def map_batches(self, task: StudyTask, batches: Sequence[Sequence[Point]]) -> Iterator[list[PointResult]]: ...


class SerialRunner:
    """Everything in this process (the reference: other runners must give the same values).
    ``tune=True`` also applies the workers' allocator settings to this process."""

    def __init__(self, tune: bool = False) -> None:
        self.tune = tune

    def map_batches(self, task: StudyTask, batches: Sequence[Sequence[Point]]) -> Iterator[list[PointResult]]:
        if self.tune:
            tune_allocator()
        for batch in batches:
            yield solve_batch(task, batch)


class ProcessRunner:
    """A local process pool; ``jobs`` defaults to the number of cores."""

    def __init__(self, jobs: int | None = None) -> None:
        self.jobs = jobs or os.cpu_count() or 1

    def map_batches(self, task: StudyTask, batches: Sequence[Sequence[Point]]) -> Iterator[list[PointResult]]:
        pool = process_pool(self.jobs, task)
        finished = False
        try:
            futures = [pool.submit(solve_pool_batch, batch) for batch in batches]
            for future in futures:
                yield future.result()
            finished = True
        finally:
            stop_pool(pool, finished)


def process_pool(jobs: int, task: StudyTask | None = None) -> ProcessPoolExecutor:
    """A local pool of ``jobs`` worker processes set up by :func:`_pool_worker` (one BLAS
    thread, Ctrl-C left to the parent, ended with the parent); end it with :func:`stop_pool`.

    ``task``: the study's task, given to each worker once, when it starts (a ``fork`` worker
    inherits it, unpickled; another start method pickles it once per worker), for
    :func:`solve_pool_batch`: a batch then carries only its points (the task holds the
    problem, ~13 kB of pickle for ``yasir2019_hybrid``, once per batch before)."""
    return ProcessPoolExecutor(max_workers=jobs, initializer=_pool_worker, initargs=(task,))


#: the task this pool worker was started with (:func:`process_pool`)
_POOL_TASK: list[StudyTask] = []


def solve_pool_batch(points: Sequence[Point]) -> list[PointResult]:
    """:func:`solve_batch` of the task this pool worker was started with."""
    return solve_batch(_POOL_TASK[0], points)


def stop_pool(pool: ProcessPoolExecutor, finished: bool) -> None:
    """Shut ``pool`` down. Not ``finished`` (Ctrl-C, SIGTERM, a failure): the tasks not
    started are dropped and the running ones ended now; no worker outlives its parent's work."""
    if not finished:
        _terminate_workers(pool)
    pool.shutdown(wait=True, cancel_futures=not finished)


def _terminate_workers(pool: ProcessPoolExecutor) -> None:
    """Stop every worker process of ``pool`` (``terminate_workers`` from Python 3.14 on)."""
    terminate = getattr(pool, "terminate_workers", None)
    if terminate is not None:  # pragma: no cover - Python >= 3.14
        terminate()
        return
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        if process.is_alive():
            process.terminate()
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        process.join(WORKER_JOIN_SECONDS)


#: how long an interrupted study waits for a terminated worker to end
WORKER_JOIN_SECONDS = 5.0
#: prctl(PR_SET_PDEATHSIG): Linux sends the worker this signal when its parent dies
_PR_SET_PDEATHSIG = 1


def _single_threaded() -> None:
    """Worker set-up: one BLAS thread, and an allocator that keeps its memory (below)."""
    from ..threads import limit_blas_threads

    limit_blas_threads()
    tune_allocator()


def _pool_worker(task: StudyTask | None = None) -> None:
    """Set-up of a :class:`ProcessRunner` worker: :func:`_single_threaded`, its study's
    ``task`` kept for :func:`solve_pool_batch`, and signals.

    A pool worker leaves Ctrl-C to the study (which terminates it: a terminal sends SIGINT
    to the whole process group, and a worker's traceback would only add noise), and on
    Linux it ends when its parent does, even one killed by SIGKILL: no worker is orphaned.
    """
    _single_threaded()
    if task is not None:
        _POOL_TASK[:] = [task]
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _ended)  # not the study's handler, inherited by fork
    _die_with_parent()


def _ended(signum: int, frame: object) -> None:
    """SIGTERM in a pool worker (its parent ends it, or died): the report folder it was
    writing is removed (:mod:`counterpoise.unfinished`), then the worker ends at once, as
    the default action would have ended it."""
    unfinished.discard_all()
    os._exit(128 + signum)


def _die_with_parent() -> None:
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the study's own clean-up is the guard
        return
    if os.getppid() == 1:  # the parent died before prctl took effect
        os._exit(1)


#: glibc malloc settings of study workers: the dense verification allocates and frees
#: arrays of a few MB per point; with glibc's defaults each is mapped and unmapped again
#: (~6,500 page faults per hybrid point, a third of the worker's time in the kernel).
#: Keeping up to 256 MB (per worker) removes them: 16 hybrid points 0.79 s -> 0.67 s.
MALLOC_SETTINGS = {"M_TRIM_THRESHOLD": (-1, 256 << 20), "M_TOP_PAD": (-2, 64 << 20), "M_MMAP_THRESHOLD": (-3, 32 << 20)}


def tune_allocator() -> bool:
    """Apply :data:`MALLOC_SETTINGS` with glibc's ``mallopt`` (no-op elsewhere); True if applied."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    return all(mallopt(code, value) == 1 for code, value in MALLOC_SETTINGS.values())


def batched(points: Sequence[T], size: int) -> list[Sequence[T]]:
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
