"""The plot helper of a pool study: a process forked when the study command starts, which
draws ``study.png`` (and ``pareto.png``) beside the study (issue 19).

A study with a process pool spends its first second in its own process alone (loading the
file, building the design method before the pool forks): one core is idle. Forked then,
the helper imports matplotlib meanwhile, prepares the figure once it is sent the study's
layout (:meth:`PlotProcess.prepare`, :func:`counterpoise.plots.study.prepare`), and draws the
results when it is sent the finished study's folder (:meth:`PlotProcess.plot`). The study's
process never imports matplotlib.

This module imports only the standard library: the command imports it before anything
else, to fork a small process early. The helper ignores Ctrl-C (the study handles it and
ends the helper), writes nothing to the terminal, and ends when its study ends (it reads
end-of-file then) or is ended by it; should it fail or die, :meth:`PlotProcess.plot`
returns None and the study draws its plots itself, where an error is reported as for any
plot.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path
from threading import active_count
from typing import Any


#: how long the study waits for the helper's plots once its points are done (a 1000-point
#: study's take ~0.3 s); beyond it the helper is ended and the study draws them itself
PLOT_SECONDS = 120.0


class PlotProcess:
    """The plot helper, forked on construction (see the module)."""

    def __init__(self) -> None:
        import multiprocessing

        context = multiprocessing.get_context("fork")
        self._conn, child = context.Pipe()
        self._process = context.Process(target=_serve, args=(child, self._conn), name="study-plot", daemon=True)
        self._process.start()
        child.close()

    @classmethod
    def fork_if_useful(cls, plot: bool, jobs: int | None, scheduler: str | None) -> PlotProcess | None:
        """A helper for a study plotted (``plot``) with a local process pool (``jobs`` other
        than 1, no Dask ``scheduler``, whose client runs threads), where ``fork`` exists
        and this process runs no other thread (a forked child would inherit their locks
        held); else None (the plot is drawn in the study's process)."""
        import multiprocessing

        if not plot or scheduler is not None or (jobs or os.cpu_count() or 1) < 2:
            return None
        if "fork" not in multiprocessing.get_all_start_methods() or active_count() > 1:
            return None
        return cls()

    def prepare(self, meta: dict[str, Any], xs: list[list[float]]) -> None:
        """Send the study's layout (:func:`counterpoise.plots.study.prepare`'s arguments)."""
        self._send(("prepare", meta, xs))

    def plot(self, folder: Path) -> list[Path] | None:
        """The plots of the finished study in ``folder``, written by the helper; None if the
        helper failed (then nothing is left of its work: its files are written atomically)."""
        reply = None
        if self._send(("plot", str(folder))):
            try:
                if self._conn.poll(PLOT_SECONDS):  # a helper that hangs is ended, and the study draws the plot
                    reply = self._conn.recv()
            except (OSError, EOFError):  # the helper ended without an answer
                reply = None
        self.close()
        return [Path(p) for p in reply] if isinstance(reply, list) else None

    def close(self) -> None:
        """End the helper (at once if it still works) and reap it."""
        self._conn.close()  # its next read ends (end of file)
        if self._process.is_alive():
            self._process.join(0.05)
        if self._process.is_alive():
            self._process.terminate()
        self._process.join()

    def _send(self, message: tuple[Any, ...]) -> bool:
        try:
            self._conn.send(message)
        except (OSError, ValueError):  # the helper is gone, or closed
            return False
        return True


def _serve(conn: Any, parent_end: Any) -> None:
    """The helper: import matplotlib, prepare the figure it is sent, plot the folder it is sent."""
    parent_end.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _ended)  # ended by the study: a PNG being written is removed (plots/_mpl)
    devnull = os.open(os.devnull, os.O_WRONLY)  # a failure is redone, and reported, by the study's process
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    from .plots.study import load, prepare, study_plots

    load()
    figure = None
    while True:
        try:
            message = conn.recv()
        except EOFError:  # the study ended without a plot
            return
        if message[0] == "prepare":
            figure = prepare(message[1], message[2])
        else:
            conn.send([str(p) for p in study_plots(message[1], figure)])
            return


def _ended(signum: int, frame: Any) -> None:
    """SIGTERM in the helper (the study ends it): leave through ``SystemExit``, so a PNG's
    temporary file is removed by its writer's clean-up (the default action would leave it)."""
    raise SystemExit(128 + signum)
