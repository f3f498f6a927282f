"""Progress lines of long steps (reading a large catalogue, searching many parts).

The library says what it is doing through :func:`note`; nothing is printed unless a sink
is installed (:func:`sink`): the command line installs one that prints each note as a
line on stderr, a Python user may install their own (``logging``, a GUI) or none.
A step announces itself only when it is large (:data:`LARGE_STEP` items or more), so
ordinary runs stay quiet.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

#: a step over at least this many items (catalogue rows, candidate parts) prints progress
LARGE_STEP = 20_000
#: ... and a line every this many items
PROGRESS_EVERY = 50_000

_sinks: list[Callable[[str], None]] = []


@contextmanager
def sink(write: Callable[[str], None]) -> Iterator[None]:
    """Within: every :func:`note` calls ``write(message)``."""
    _sinks.append(write)
    try:
        yield
    finally:
        _sinks.remove(write)


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
