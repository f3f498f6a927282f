"""The command line: a thin layer over the library.

:func:`main` is the console-script entry point; every command is parsed and run by the
typer app of :mod:`.app`, whose commands are built from the table of :mod:`.spec`.

The console script (not an in-process call) turns on the cache of :mod:`counterpoise.io.cache`.
When it runs ``solve``, ``validate`` or ``study``, the process ends with ``os._exit`` once
the command has returned and stdout and stderr are flushed: every report is already closed
and renamed into place by then (:mod:`counterpoise.report.files`), and tearing down the
imported modules (numpy, CasADi, pint, pydantic) would take longer than the work.

Before anything is imported, the process environment gets (unless the user set them):
one BLAS thread (:mod:`counterpoise.threads`) and ``PYDANTIC_DISABLE_PLUGINS=__all__``:
pydantic otherwise scans every installed package's entry points for plugins when the
problem schema is built (~7 ms); set ``PYDANTIC_DISABLE_PLUGINS=`` to keep them.
"""

from __future__ import annotations

import os
import sys

from ..threads import limit_blas_environment
from .spec import COMMANDS

__all__ = ["COMMANDS", "main"]

#: Commands after which the process may end without interpreter teardown (they write every
#: file before returning, and ``solve --jobs`` and ``study`` have shut their worker pool
#: down and joined the plot preload thread by then).
FAST_EXIT = frozenset({"solve", "validate", "study"})


def main(argv: list[str] | None = None) -> None:
    """Entry point: ``argv`` defaults to ``sys.argv[1:]``. Exits with the command's status."""
    args = list(sys.argv[1:] if argv is None else argv)
    limit_blas_environment()  # before numpy and CasADi load their BLAS (see counterpoise.threads)
    os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
    if argv is None:  # the console script: loaded problems (and the designers of solve and study) are kept on disk (counterpoise.io.cache)
        from ..io import cache

        cache.enable(built=args[:1] in (["solve"], ["study"]))
    from .app import main as app_main

    if argv is not None or not FAST_EXIT & set(args[:1]):
        app_main(args)
        return
    try:
        app_main(args)
        code = 0
    except SystemExit as exc:
        code = _status(exc.code)
    _fast_exit(code)


def _status(code: object) -> int:
    if code is None:
        return 0
    if isinstance(code, int):
        return code
    print(code, file=sys.stderr)
    return 1


def _fast_exit(code: int) -> None:
    """End the process now: flush the standard streams, skip interpreter teardown."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # closed pipe: nothing more can be said
            pass
    os._exit(code)
