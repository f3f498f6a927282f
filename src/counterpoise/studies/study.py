"""A parameter study: points → runner → ``results/<name>-study/study.csv``.

The folder holds ``study.csv`` (one row per point, in point order) and ``study.json``
(the problem, the varied keys, the method, the seed and the columns). Rows are written in
batches through a temporary file and a rename, so an interrupted study keeps every batch
it finished; ``resume=True`` skips the points already in the file (the plan must be the
same: same ``--vary``, method, samples and seed; a row whose varied values are not the
plan's, or that is incomplete, is computed again). A point that fails, raises or runs past
the time limit is recorded with its status and the study goes on.

One study at a time writes a folder: :func:`study_lock` holds an exclusive ``flock`` on
``.<name>-study.lock`` beside it, and a second study into it is an input error naming the
holder (pid and host). A new study (without ``resume``) into a folder that holds one keeps
that study until the new one completes: it runs in ``<name>-study.partial/``, which then
replaces the folder (:func:`_replace_folder`: the earlier study renamed aside, the new one
renamed in, the earlier one removed; safe at every instant); interrupted, it stays there and
``resume`` continues it.

``study.json`` records the problem's content key (:func:`~counterpoise.model.digest.content_key_anywhere`:
the file, the ``--set`` values, the catalogues it reads), and ``resume`` continues only a
study of the same problem: another is an input error saying what differs. None of the
folders and files a study makes beside or in its folder may be a symbolic link
(:mod:`counterpoise.nofollow`): a planted link would have it write outside ``--out``.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ProblemFileError
from ..model.problem import Problem
from ..nofollow import LinkRefused, make_folder, open_no_follow, refuse_link
from ..report.files import FLOAT_FORMAT, CsvWriter, atomic_write_text
from .runners import ERROR, TIMEOUT, PointResult, Runner, SerialRunner, StudyTask, batched
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


def partial_folder(folder: Path) -> Path:
    """Where a new study runs while the folder still holds the one it replaces."""
    return folder.with_name(f"{folder.name}.partial")


def aside_folder(folder: Path) -> Path:
    """Where the earlier study waits while a finished new one is renamed in (:func:`_replace_folder`)."""
    return folder.with_name(f".{folder.name}.old")


def lock_file(folder: Path) -> Path:
    return folder.with_name(f".{folder.name}.lock")


def study_in_progress(problem: Problem, out: str | Path) -> Path:
    """The folder an interrupted study left its finished points in (``resume`` continues it)."""
    folder = study_folder(problem, out)
    partial = partial_folder(folder)
    return partial if (partial / "study.csv").exists() else folder


#: statuses a study row may hold (the design's, and a point's own)
STATUSES = frozenset({"optimal", "infeasible", "failed", TIMEOUT, ERROR})


@contextmanager
def study_lock(folder: Path, label: str) -> Iterator[None]:
    """Hold the exclusive lock of study ``folder`` (``flock`` on ``.<name>.lock`` beside it,
    with this process's pid and host written in it); another holder is a
    :class:`ProblemFileError` naming it. The lock file is removed on release; a process that
    opened it just before then notices (its inode is no longer the path's) and tries again."""
    import socket

    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock (one study at a time is then the user's care)
        yield
        return
    lock = lock_file(folder)
    lock.parent.mkdir(parents=True, exist_ok=True)
    while True:
        try:
            fd = open_no_follow(lock, os.O_RDWR | os.O_CREAT)  # a planted link is refused, never truncated
        except LinkRefused as exc:
            raise ProblemFileError(label, "--out", str(exc)) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            try:
                holder = os.pread(fd, 200, 0).decode("utf-8", "replace").strip() or "starting"
            finally:
                os.close(fd)
            raise ProblemFileError(
                label, "--out", f"{folder} is being written by another study ({holder}): wait for it to end, or give another --out"
            ) from None
        try:
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()} on host {socket.gethostname()}\n".encode(), 0)
        yield
    finally:
        lock.unlink(missing_ok=True)
        os.close(fd)


def _replace_folder(folder: Path, new: Path) -> None:
    """Move the finished study ``new`` into ``folder``, safe at every instant: the earlier
    study is renamed aside (:func:`aside_folder`), the new one renamed in, and only then is
    the earlier one removed. SIGTERM and Ctrl-C wait until the renames are done (blocked
    meanwhile); an exception between them puts the earlier study back; a process killed
    outright between them leaves it aside, where the next study into the folder finds it
    (:func:`_recover`). The earlier study is never removed before the new one is in."""
    aside = aside_folder(folder)
    refuse_link(aside)
    with _signals_held():
        try:
            if os.path.lexists(folder):
                os.rename(folder, aside)
            os.rename(new, folder)
        except BaseException:
            _recover(folder)
            raise
        shutil.rmtree(aside, ignore_errors=True)


def _recover(folder: Path) -> None:
    """Finish or undo a replacement that stopped between its renames
    (:func:`_replace_folder`): the new study in, the earlier one aside: remove that one;
    the folder missing and the earlier study aside: put it back."""
    aside = aside_folder(folder)
    if not os.path.lexists(aside):
        return
    refuse_link(aside)
    if os.path.lexists(folder):
        shutil.rmtree(aside, ignore_errors=True)
    else:
        os.rename(aside, folder)


@contextmanager
def _signals_held() -> Iterator[None]:
    """SIGTERM and SIGINT held back within (delivered as the block ends), in the main
    thread of a POSIX process; elsewhere nothing is held."""
    import signal
    import threading

    held = {signal.SIGTERM, signal.SIGINT}
    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _number(text: str | None) -> bool:
    try:
        return text is not None and math.isfinite(float(text))
    except ValueError:
        return False


def row_is_done(row: Mapping[str, str | None], cols: list[str], expected: dict[str, str], variable_headers: list[str]) -> bool:
    """Whether a ``study.csv`` row read back is a finished point of this plan: every column
    there (no torn line), a known status and a solve time, the varied values ``expected`` (as
    this plan writes them: a row of another study is not this point), and for an optimal
    point every figure of the design."""
    if None in row or any(row.get(c) is None for c in cols):
        return False
    if row["status"] not in STATUSES or not _number(row["solve_time_s"]):
        return False
    if any(row[header] != text for header, text in expected.items()):
        return False
    if row["status"] == "optimal":
        figures = ["objective_kg", "added_mass_kg", "added_inertia_kg_m2", "residual_ratio", *variable_headers]
        return all(_number(row[c]) for c in figures)
    return True


def _varied_texts(plan: StudyPlan, index: int) -> dict[str, str]:
    return {v.header: _fmt(v.unit.from_si(plan.points[index][v.key])) for v in plan.varies}


def variable_columns(problem: Problem) -> list[tuple[str, str, float]]:
    """(result key, CSV header, SI size of the display unit) of every design-vector slot.

    An adjustable variable has a value per scenario; with a payload range, per payload: its
    columns are its settings at the lower end, the nominal and the upper end of the range
    (``b@tool_0kg``...: the payloads every design is solved on), as in the design's slots."""
    settings = [s.name for s in problem.scenarios]
    if problem.payloads:
        from ..payload.scenarios import payload_of, setting_name

        payload = payload_of(problem)
        settings = [setting_name(payload, m) for m in sorted({payload.lower, payload.nominal, payload.upper})]
    out = []
    for v in problem.variables:
        for setting in settings if v.adjustable else [None]:
            key = v.name if setting is None else f"{v.name}@{setting}"
            out.append((key, f"{key} [{v.unit.label}]", v.unit.to_si))
    return out


def part_columns(problem: Problem) -> list[tuple[str, str, str, str]]:
    """(slot, part header, rate header, force header) of every catalogue slot: the part each
    point chose, its rate and its springs' largest working force, so that a jump of the
    design between points shows which part changed."""
    return [(s.name, f"{s.name} part", f"{s.name} rate [N/mm]", f"{s.name} max force [N]") for s in problem.slots]


def text_columns(problem: Problem) -> list[str]:
    """The columns of ``study.csv`` that hold text besides the fixed ones (the part numbers)."""
    return [part for _, part, _, _ in part_columns(problem)]


def columns(problem: Problem, plan: StudyPlan) -> list[str]:
    slots = [h for _, *headers in part_columns(problem) for h in headers]
    return FIXED_BEFORE + [v.header for v in plan.varies] + FIXED_AFTER + [h for _, h, _ in variable_columns(problem)] + slots + FIXED_END


def _fmt(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return "" if value != value else FLOAT_FORMAT % value
    return str(value)


def result_row(problem: Problem, plan: StudyPlan, index: int, r: PointResult,
               variables: Sequence[tuple[str, str, float]] | None = None) -> dict[str, str]:
    """One CSV row (strings) of point ``index``: display units throughout (``variables``:
    :func:`variable_columns` of ``problem``, when the caller has them)."""
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
    for key, header, size in variable_columns(problem) if variables is None else variables:
        row[header] = _fmt(r.values[key] / size) if key in r.values else ""
    for slot, part, rate, force in part_columns(problem):
        number, k, f = r.parts.get(slot, ("", math.nan, math.nan))
        row.update({part: number, rate: _fmt(k / 1e3), force: _fmt(f)})
    return row


class _CsvLines:
    """``study.csv`` lines, each formatted once: the file is written again after every
    flush (whole, through a rename), and formatting every row each time made the
    study's own process a cost that grows with the square of the points."""

    def __init__(self, cols: list[str]) -> None:
        import io

        self.cols = cols
        self._buffer = io.StringIO()
        self._writer = CsvWriter(self._buffer)
        self.header = self._format(cols)

    def _format(self, values: Sequence[str]) -> str:
        self._buffer.seek(0)
        self._buffer.truncate()
        self._writer.writerow(values)
        return self._buffer.getvalue()

    def line(self, row: Mapping[str, str]) -> str:
        return self._format([row.get(c, "") for c in self.cols])

    def text(self, lines: Mapping[int, str]) -> str:
        return self.header + "".join(lines[i] for i in sorted(lines))


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
    overrides: Sequence[tuple[str, object]] = (),
) -> StudyOutcome:
    """Run every point of ``plan`` (minus those already done when ``resume``) and write the study.

    Finished batches are written to ``study.csv`` at most every ``flush_seconds`` (0: after
    every batch) and at the end, also when the study is interrupted. ``started(skipped)`` is called once the points already
    done are known; ``progress(results)`` after each batch. ``overrides``: the ``--set``
    values the problem was loaded with (recorded, and named when a resume is refused).
    """
    t0 = time.perf_counter()
    folder = study_folder(problem, out)
    label = problem.path or problem.name
    identity = _identity(problem, overrides)
    try:
        for path in (folder, partial_folder(folder), aside_folder(folder)):
            refuse_link(path)
        with study_lock(folder, label):
            _recover(folder)
            work, done = _prepare(problem, plan, folder, resume, label, identity)
            outcome = _run_points(problem, plan, work, done, runner, task, batch_size, flush_seconds, progress, started, identity)
            if work != folder:  # the new study is complete: it replaces the one that was there
                _replace_folder(folder, work)
    except LinkRefused as exc:
        raise ProblemFileError(label, "--out", str(exc)) from None
    outcome.folder = folder
    outcome.wall_time = time.perf_counter() - t0
    return outcome


def _identity(problem: Problem, overrides: Sequence[tuple[str, object]]) -> dict[str, object]:
    """What ``study.json`` records of the problem a study is of: its content key (wherever
    its files lie), the ``--set`` values and a digest of the problem file's text (these two
    say what differs when a resume is refused)."""
    from ..hashing import blake2b
    from ..model.digest import content_key_anywhere

    text = b""
    if problem.path:
        try:
            text = Path(problem.path).read_bytes()
        except OSError:
            pass
    return {
        "problem_key": content_key_anywhere(problem),
        "set": [[str(k), str(v)] for k, v in overrides],
        "file_digest": blake2b(text, digest_size=16).hexdigest() if text else None,
    }


def _other_problem(meta: Mapping[str, object], identity: Mapping[str, object], work: Path) -> str | None:
    """Why the study in ``work`` (its ``study.json``: ``meta``) is not of this problem, or None."""
    if meta.get("problem_key") == identity["problem_key"]:
        return None
    if "problem_key" not in meta:
        return f"{work} holds a study that does not record its problem's content (an older counterpoise), so it may be of another problem"

    def shown(values: object) -> str:
        pairs = [f"{k}={v}" for k, v in values] if isinstance(values, list) else []
        return "--set " + ", ".join(pairs) if pairs else "no --set"

    if meta.get("set") != identity["set"]:
        return f"{work} holds a study run with {shown(meta.get('set'))}, this run has {shown(identity['set'])}"
    if meta.get("file_digest") != identity["file_digest"]:
        return f"{work} holds a study of another version of the problem file (it was edited since)"
    return f"{work} holds a study of another problem content (a file the problem reads, such as a catalogue or a robot model, changed)"


def _prepare(
    problem: Problem, plan: StudyPlan, folder: Path, resume: bool, label: str, identity: Mapping[str, object]
) -> tuple[Path, dict[int, dict[str, str]]]:
    """The folder to run in and the rows already done there (``resume``).

    Resuming continues the unfinished new study (``.partial``) if there is one, else the
    folder's, if it is a study of this problem (``identity``: :func:`_identity`) and plan;
    rows that are not a finished point of this plan are dropped (computed again).
    A new study runs in the folder when it holds no study, else in ``.partial`` (emptied)."""
    partial = partial_folder(folder)
    cols = columns(problem, plan)
    if resume:
        work = partial if (partial / "study.csv").exists() else folder
        done: dict[int, dict[str, str]] = {}
        csv_path, meta_path = work / "study.csv", work / "study.json"
        refuse_link(csv_path)
        refuse_link(meta_path)
        if csv_path.exists():
            try:
                meta = json.loads(meta_path.read_text(encoding="utf-8"))
                rows = read_rows(csv_path)
            except (OSError, ValueError) as exc:
                raise ProblemFileError(label, "--resume", f"cannot read the study in {work}: {exc}") from None
            if not isinstance(meta, dict):
                raise ProblemFileError(label, "--resume", f"cannot read the study in {work}: study.json holds no table; drop --resume to start again")
            other = _other_problem(meta, identity, work)
            if other is not None:
                raise ProblemFileError(label, "--resume", f"{other}: --resume continues a study of the same problem only; run without --resume to start again")
            if meta.get("plan") != json.loads(json.dumps(plan.identity())) or meta.get("columns") != cols:
                raise ProblemFileError(label, "--resume", f"{work} holds a study with other --vary/--samples/--seed or another problem; drop --resume to start again")
            headers = [h for _, h, _ in variable_columns(problem)]
            for r in rows:
                point = r.get("point") or ""
                if point.isdigit() and int(point) < len(plan.points) and row_is_done(r, cols, _varied_texts(plan, int(point)), headers):
                    done[int(point)] = {c: r[c] for c in cols}
        return work, done
    if (folder / "study.csv").exists() or (folder / "study.json").exists():
        shutil.rmtree(partial, ignore_errors=True)
        return partial, {}
    shutil.rmtree(partial, ignore_errors=True)  # an unfinished replacement of a study since removed
    return folder, {}


def _run_points(
    problem: Problem,
    plan: StudyPlan,
    folder: Path,
    done: dict[int, dict[str, str]],
    runner: Runner | None,
    task: StudyTask | None,
    batch_size: int,
    flush_seconds: float,
    progress: Callable[[list[PointResult]], None] | None,
    started: Callable[[int], None] | None,
    identity: Mapping[str, object],
) -> StudyOutcome:
    csv_path, meta_path = folder / "study.csv", folder / "study.json"
    cols = columns(problem, plan)
    meta = {
        "problem": problem.name,
        "file": problem.path,
        **identity,
        "plan": plan.identity(),
        "points": len(plan.points),
        "columns": cols,
        "text_columns": text_columns(problem),
        "time_limit_s": task.time_limit if task else None,
    }
    make_folder(folder)
    atomic_write_text(meta_path, json.dumps(meta, indent=2) + "\n")
    todo = [i for i in range(len(plan.points)) if i not in done]
    outcome = StudyOutcome(folder, len(plan.points), len(done))
    csv_lines = _CsvLines(cols)
    lines = {i: csv_lines.line(row) for i, row in done.items()}  # each row formatted once
    atomic_write_text(csv_path, csv_lines.text(lines))
    slots = variable_columns(problem)
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
                lines[i] = csv_lines.line(result_row(problem, plan, i, r, slots))
                outcome.counts[r.status] = outcome.counts.get(r.status, 0) + 1
            if time.perf_counter() - last_flush >= flush_seconds:  # whole batches, at most once per flush_seconds
                atomic_write_text(csv_path, csv_lines.text(lines))
                last_flush = time.perf_counter()
            if progress is not None:
                progress(results)
    finally:  # also when interrupted: keep every finished batch
        atomic_write_text(csv_path, csv_lines.text(lines))
    return outcome
