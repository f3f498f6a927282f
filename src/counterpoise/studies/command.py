"""``counterpoise study``: from command-line options to a finished study (the CLI stays thin).

Bad input (``--vary``, ``--samples``, ``--scheduler``...) raises a one-line
:class:`~counterpoise.errors.ProblemFileError` before anything is written; the CLI prints
it and exits 2. A finished study exits 0 whatever its points' statuses (they are data).
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import ProblemFileError
from ..io.cache import keep_no_built
from ..model.problem import Problem
from .runners import PointResult, ProcessRunner, Runner, SerialRunner, StudyTask
from .spec import StudyPlan, plan_study
from .study import StudyOutcome, run_study

if TYPE_CHECKING:
    from ..plotter import PlotProcess


@dataclass(frozen=True)
class StudyOptions:
    vary: tuple[str, ...]
    samples: int | None = None
    method: str | None = None
    seed: int | None = None
    out: Path = Path("results")
    jobs: int | None = None
    scheduler: str | None = None
    scheduler_timeout: float = 10.0
    resume: bool = False
    time_limit: float | None = None
    batch_size: int = 16
    plot: bool = True
    progress: bool = True
    #: the --set overrides the problem was loaded with (varied values are checked with them)
    overrides: tuple[tuple[str, Any], ...] = ()
    check: str = "auto"  # auto: the exact certificate where it applies; dense: the dense check


def make_runner(options: StudyOptions, label: str) -> Runner:
    """The engine: in-process (``--jobs 1``), a process pool, or Dask (``--scheduler``)."""
    jobs = options.jobs
    if jobs is not None and jobs < 1:
        raise ProblemFileError(label, "--jobs", f"must be at least 1, got {jobs}")
    if options.scheduler is not None:
        from .cluster import DaskRunner, SchedulerError

        address = options.scheduler.strip()
        if address != "local" and "://" not in address:
            raise ProblemFileError(label, "--scheduler", f"expected tcp://HOST:PORT or local, got '{address}'")
        runner = DaskRunner(address, jobs, options.scheduler_timeout)
        try:
            runner.connect()
        except SchedulerError as exc:
            raise ProblemFileError(label, "--scheduler", str(exc)) from None
        return runner
    jobs = jobs or os.cpu_count() or 1
    return SerialRunner(tune=True) if jobs == 1 else ProcessRunner(jobs)


def override_key(key: str) -> str:
    """The problem-file key (for ``--set``) of a study point key."""
    if key.startswith("objective."):
        return key
    if key.endswith((".lower", ".upper")):
        return f"variables.{key}"
    return f"parameters.{key}"


def check_varied_values(problem: Problem, plan: StudyPlan, overrides: dict[str, Any]) -> None:
    """Both ends of every ``--vary`` range pass the checks a problem file gets: the file is
    loaded again with each end as a ``--set`` override (a negative mass, an inverted bound
    or a weight of the wrong sign is an input error naming the --vary key, before any
    work). Points lie between the ends, and what the checks reject (a negative mass, a
    bound outside another) is a bound on the value, so the ends stand for the range.
    Problems not read from a file (the Python API) are not re-read. The console script
    reads each end from its cache of loaded problems (:mod:`counterpoise.io.cache`, keyed on
    the file's content and the overrides) when the same study ran before, as it reads the
    problem itself: a repeated study then imports neither pint nor pydantic for them."""
    from ..io.cache import load as load_problem  # the loader itself when the cache is off

    label = problem.path or problem.name
    if not problem.path or not Path(problem.path).is_file():
        return
    for v in plan.varies:
        ends = [t.strip() for t in v.text.partition("=")[2].split(":")[:2]]
        for text in dict.fromkeys(ends):
            if text in ("0", "0.0") and v.unit.symbol:  # a bare 0 is 0 in the range's unit (docs/studies.md)
                text = f"0 {v.unit.symbol}"
            try:
                load_problem(problem.path, {**overrides, override_key(v.key): text})
            except ProblemFileError as exc:
                raise ProblemFileError(label, f"--vary {v.key}", f"'{text}' is not allowed: {exc.key}: {exc.message}") from None


def build_before_fork(task: StudyTask, plan: StudyPlan, runner: Runner) -> bool:
    """Build the design method (and the certificate) of ``task`` in this process before a
    process pool forks its workers, which then inherit it instead of each building its own
    (≈ 0.15 s of CPU per worker for ``yasir2019_hybrid``): the same construction from the
    same problem, kept under the same key (:func:`.runners.method_for`), so the workers'
    results are those they would have had. Only for a ``fork`` pool, and only when the
    points keep the file's objective weights (a weight study builds one per weight in the
    workers). True if built."""
    import multiprocessing

    if not isinstance(runner, ProcessRunner) or multiprocessing.get_start_method() != "fork":
        return False
    if any(key.startswith("objective.") for point in plan.points for key in point):
        return False
    from .runners import method_for

    method = method_for(task, {})
    if task.check == "auto":
        from ..verify.certificate import certificate

        certificate(getattr(method, "problem", task.problem))
    return True


class StudyTerminated(KeyboardInterrupt):
    """SIGTERM during a study: handled like Ctrl-C (workers stopped, finished batches kept)."""


@contextmanager
def terminate_as_interrupt() -> Iterator[None]:
    """Within: SIGTERM raises :class:`StudyTerminated` in the main thread, so the study's
    clean-up runs (workers terminated, finished rows written) instead of the process
    vanishing and leaving its pool workers orphaned."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def _raise(signum: int, frame: Any) -> None:
        raise StudyTerminated()

    previous = signal.signal(signal.SIGTERM, _raise)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def run_study_command(problem: Problem, options: StudyOptions, console: Any, plotter: PlotProcess | None = None) -> StudyOutcome:
    """Plan, run (with a progress bar on ``console``), and plot a study.

    ``plotter``: a plot helper forked by the command before the file was loaded
    (:mod:`counterpoise.plotter`); this function ends it. Ctrl-C (KeyboardInterrupt) and
    SIGTERM (:class:`StudyTerminated`, a KeyboardInterrupt) propagate after the clean-up:
    every finished batch is in ``study.csv`` and no worker or helper is left running;
    ``--resume`` continues."""
    try:
        label = problem.path or problem.name
        plan = plan_study(problem, list(options.vary), label, options.samples, options.method, options.seed)
        if plotter is not None and options.plot:  # the helper lays the figure out while this process goes on
            plotter.prepare(*plot_inputs(problem, plan))
        check_varied_values(problem, plan, dict(options.overrides))
        if options.time_limit is not None and not options.time_limit > 0:
            raise ProblemFileError(label, "--time-limit", f"must be positive, got {options.time_limit}")
        if options.batch_size < 1:
            raise ProblemFileError(label, "--batch-size", f"must be at least 1, got {options.batch_size}")
        runner = make_runner(options, label)
        task = StudyTask(problem, time_limit=options.time_limit, check=options.check)
        preload = plot_preload(options, runner, problem, plan, plotter)
        plotter = None  # the preload ends it
        try:
            build_before_fork(task, plan, runner)
            keep_no_built()  # the designer built before the fork is kept (under the console script); none built later
            try:
                with terminate_as_interrupt():
                    outcome = _run(problem, plan, options, runner, task, console, preload)
            finally:
                close = getattr(runner, "close", None)
                if close is not None:
                    close()
            if options.plot:
                preload.plot(outcome.folder)
        finally:
            preload.close()
    finally:
        if plotter is not None:
            plotter.close()
    return outcome


def plot_preload(options: StudyOptions, runner: Runner, problem: Problem, plan: StudyPlan, plotter: PlotProcess | None = None) -> PlotPreload:
    """How ``study.png`` is prepared while the points are solved: by the plot helper
    ``plotter`` forked by the command, or one forked now (:mod:`counterpoise.plotter`) for
    a local process pool, by a :class:`PlotPreload` thread for a Dask scheduler (whose
    client runs threads: no fork then), not at all for a study run in this process or
    ``--no-plot`` (the plot, if any, drawn at the end)."""
    from ..plotter import PlotProcess

    if not options.plot or isinstance(runner, SerialRunner):
        if plotter is not None:
            plotter.close()
        return PlotPreload(False)
    if plotter is not None:  # sent the layout by run_study_command
        return HelperPreload(plotter)
    meta, xs = plot_inputs(problem, plan)
    if isinstance(runner, ProcessRunner) and (plotter := PlotProcess.fork_if_useful(True, runner.jobs, None)) is not None:
        plotter.prepare(meta, xs)
        return HelperPreload(plotter)
    return PlotPreload(True, meta, xs)


def plot_inputs(problem: Problem, plan: StudyPlan) -> tuple[dict[str, Any], list[list[float]]]:
    """What ``study.png`` is laid out from before the points are solved
    (:func:`counterpoise.plots.study.prepare`): the study's ``study.json`` content that the
    plot reads (problem, plan, columns), and each varied key's least and greatest finite
    value over the points as ``study.csv`` will hold them (display unit, the file's number
    format): all the layout reads of them, and a message of the same size to the plot
    helper however many points the study has."""
    import json
    import math

    from ..report.files import FLOAT_FORMAT
    from .study import columns, text_columns

    meta = {"problem": problem.name, "plan": json.loads(json.dumps(plan.identity())), "columns": columns(problem, plan), "text_columns": text_columns(problem)}
    xs = []
    for v in plan.varies:
        finite = [x for point in plan.points if math.isfinite(x := float(FLOAT_FORMAT % v.unit.from_si(point[v.key])))]
        xs.append([min(finite), max(finite)] if finite else [])
    return meta, xs


def _run(problem: Problem, plan: Any, options: StudyOptions, runner: Runner, task: StudyTask, console: Any, preload: PlotPreload) -> StudyOutcome:
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    columns = (
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("[red]{task.fields[failed]} not optimal[/red]"),
        TextColumn("{task.fields[rate]}"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    )
    # the bar is shown once the study has started: a study refused before (its folder in use,
    # a --resume of another plan) is one line on stderr, with no bar drawn
    bar = Progress(*columns, console=console, disable=not options.progress)
    t0 = time.perf_counter()
    state = {"done": 0, "failed": 0}
    total = len(plan.points)
    job = bar.add_task(f"{problem.name}", total=total, failed=0, rate="")

    def started(skipped: int) -> None:
        bar.update(job, completed=skipped)
        bar.start()

    def progress(results: list[PointResult]) -> None:
        preload.start()  # every worker process exists once a batch came back
        state["done"] += len(results)
        state["failed"] += sum(r.status != "optimal" for r in results)
        rate = state["done"] / max(time.perf_counter() - t0, 1e-9)
        bar.update(job, advance=len(results), failed=state["failed"], rate=f"{rate:.1f} points/s")

    try:
        outcome = run_study(problem, plan, options.out, runner, task=task, resume=options.resume, batch_size=options.batch_size,
                            progress=progress, started=started, overrides=options.overrides)
        bar.update(job, completed=total)
    finally:
        if bar.live.is_started:
            bar.stop()
        preload.join()
    return outcome


class PlotPreload:
    """Imports matplotlib (≈ 0.5 s of CPU) and draws ``study.png`` up to the points' results
    (:func:`counterpoise.plots.study.prepare`: the figure, its axes, x axes and labels, for
    the layout of a study whose points all end optimal) in a thread of this process while
    worker processes solve the points, instead of after them: the study's own process only
    waits for results meanwhile, and the plot at the end (:meth:`plot`) draws what the
    results decide. Started after the first batch came back, when every worker process has
    been forked (a fork during an import would leave the child a module lock held by a
    thread it does not have). Not enabled: nothing prepared, :meth:`plot` draws it all.
    ``meta``, ``xs``: :func:`plot_inputs`."""

    def __init__(self, enabled: bool, meta: dict[str, Any] | None = None, xs: list[list[float]] | None = None) -> None:
        self.enabled = enabled
        self.meta, self.xs = meta, xs or []
        self.figure: Any = None  # the prepared StudyFigure, once joined
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        if self.enabled and self._thread is None:
            self._thread = threading.Thread(target=self._prepare, name="plot-preload", daemon=True)
            self._thread.start()

    def join(self) -> None:
        if self._thread is not None:
            self._thread.join()

    def plot(self, folder: Path) -> list[Path]:
        """Write the plots of the finished study in ``folder``."""
        from ..plots.study import study_plots

        self.join()
        return study_plots(folder, self.figure)

    def close(self) -> None:
        """Nothing left running (the thread, a daemon, ends with its preparation)."""

    def _prepare(self) -> None:
        try:
            from ..plots.study import prepare

            if self.meta is not None:
                self.figure = prepare(self.meta, self.xs)
        except ImportError:  # pragma: no cover - the plot itself reports it
            pass


class HelperPreload(PlotPreload):
    """The plots drawn by a :class:`counterpoise.plotter.PlotProcess` (prepared there while
    the study runs), or here if the helper failed."""

    def __init__(self, helper: PlotProcess) -> None:
        super().__init__(False)
        self.helper = helper

    def plot(self, folder: Path) -> list[Path]:
        paths = self.helper.plot(folder)
        return super().plot(folder) if paths is None else paths

    def close(self) -> None:
        self.helper.close()
