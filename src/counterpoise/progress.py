"""Progress lines of long steps (reading a large catalogue, searching many parts).

The library says what it is doing through :func:`note`; nothing is printed unless a sink
is installed (:func:`sink`): the command line installs one that prints each note as a
line on stderr, a Python user may install their own (``logging``, a GUI) or none.
A step announces itself only when it is large (:data:`LARGE_STEP` items or more), so
ordinary runs stay quiet.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

#: a step over at least this many items (catalogue rows, candidate parts) prints progress
LARGE_STEP = 20_000
#: ... and a line every this many items
PROGRESS_EVERY = 50_000
#: a phase (a part search, a verification, a payload schedule) still running after this
#: many seconds says so, and says when it ends
SLOW_PHASE_S = 2.0

_sinks: list[Callable[[str], None]] = []
#: the sinks that also want the timed notes of slow phases (:func:`phase`)
_timed: list[Callable[[str], None]] = []


@contextmanager
def sink(write: Callable[[str], None], timed: bool = False) -> Iterator[None]:
    """Within: every :func:`note` calls ``write(message)``; with ``timed``, slow phases say
    so too (:func:`phase`; the command line asks for them on a terminal, where a silent
    minute looks like a hang, not in logs, where timing-dependent lines are noise)."""
    _sinks.append(write)
    if timed:
        _timed.append(write)
    try:
        yield
    finally:
        _sinks.remove(write)
        if timed:
            _timed.remove(write)


def wants_timed_notes(stream: object) -> bool:
    """Slow-phase notes on ``stream``: on a terminal, or when COUNTERPOISE_PROGRESS=1."""
    import os

    setting = os.environ.get("COUNTERPOISE_PROGRESS", "")
    if setting in ("0", "1"):
        return setting == "1"
    isatty = getattr(stream, "isatty", None)
    return bool(isatty and isatty())


def note(message: str) -> None:
    """Tell the installed sink (the innermost) what a long step is doing."""
    if _sinks:
        _sinks[-1](message)


def counter(what: str, total: int) -> Callable[[int], None]:
    """For a step over ``total`` items: a function to call with the number done so far;
    it notes the start and every :data:`PROGRESS_EVERY` items when the step is large."""
    if total < LARGE_STEP or not _sinks:
        return lambda done: None
    note(f"{what}: {total:,} to go")
    state = {"next": PROGRESS_EVERY}

    def tick(done: int) -> None:
        if done >= state["next"]:
            note(f"{what}: {done:,} of {total:,} done")
            state["next"] = done - done % PROGRESS_EVERY + PROGRESS_EVERY

    return tick


@contextmanager
def phase(what: str, after: float = SLOW_PHASE_S) -> Iterator[None]:
    """Within: a step that stays quiet when quick; if it is still running after ``after``
    seconds, note "<what> ..." then, at its end, "<what>: done in N s". The first note comes
    from a timer thread, so it appears while the work runs (a terminal user knows it is busy)."""
    if not _timed or _timed[-1] is not (_sinks[-1] if _sinks else None):
        yield
        return
    write = _timed[-1]
    started = time.perf_counter()
    said = threading.Event()
    lock = threading.Lock()
    finished = False

    def announce() -> None:
        with lock:
            if not finished:
                said.set()
                write(f"{what} ...")

    timer = threading.Timer(after, announce)
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        with lock:
            finished = True
        timer.cancel()
        if said.is_set():
            write(f"{what}: done in {time.perf_counter() - started:.1f} s")
