"""The command line: a thin layer over the library.

:func:`main` is the console-script entry point. It imports nothing heavy: ``counterpoise``
and ``counterpoise --help`` are answered from the table of commands in :mod:`.spec` (the
standard library only), and ``counterpoise solve``, ``validate`` and ``study`` are parsed
by :mod:`.light` with a parser derived from that table (it imports the library, not typer;
only a study's progress bar imports rich); every other command, and any call :mod:`.light` hands back (``--help``, a usage
error), goes to the typer app in :mod:`.app`, whose commands are built from the same
table, imported then.
When the console script runs ``solve``, ``validate`` or ``study``, the process ends with ``os._exit``
once the command has returned and stdout and stderr are flushed: every report is already
closed and renamed into place by then (:mod:`counterpoise.report.files`), and tearing down
the imported modules (numpy, CasADi, pint, pydantic) would take longer than the work.

The console script (not an in-process call) turns on the cache of :mod:`counterpoise.io.cache`
and, with it, the dataclass methods compiled once (:mod:`counterpoise.io.compiled`), whose
new codes it writes back before it exits.

Before anything is imported, the process environment gets (unless the user set them):
one BLAS thread (:mod:`counterpoise.threads`) and ``PYDANTIC_DISABLE_PLUGINS=__all__``:
pydantic otherwise scans every installed package's entry points for plugins when the
problem schema is built (~7 ms); set ``PYDANTIC_DISABLE_PLUGINS=`` to keep them.
"""

from __future__ import annotations

import os
import sys

from ..threads import limit_blas_environment
from .spec import COMMANDS, top_level_help, wants_top_level_help

__all__ = ["COMMANDS", "main"]

#: Commands after which the process may end without interpreter teardown (they write every
#: file before returning, and ``solve --jobs`` and ``study`` have shut their worker pool
#: down and joined the plot preload thread by then).
FAST_EXIT = frozenset({"solve", "validate", "study"})


def main(argv: list[str] | None = None) -> None:
    """Entry point: ``argv`` defaults to ``sys.argv[1:]``. Exits with the command's status."""
    args = list(sys.argv[1:] if argv is None else argv)
    help_status = wants_top_level_help(args)
    if help_status is not None:
        sys.stdout.write(top_level_help())
        sys.stdout.flush()
        raise SystemExit(help_status)
    limit_blas_environment()  # before numpy and CasADi load their BLAS (see counterpoise.threads)
    os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
    fast = argv is None and bool(FAST_EXIT & set(args[:1]))
    if argv is None:  # the console script: loaded problems (and the designers of solve and study) are kept on disk (counterpoise.io.cache)
        from ..io import cache

        cache.enable(built=args[:1] in (["solve"], ["study"]))
        where = cache.folder()
        if where is not None:  # dataclasses' methods compiled once (counterpoise.io.compiled)
            from ..io import compiled

            compiled.install(where)
    from . import light

    code = light.run(args, pause_gc=fast)
    if code is not None:
        _save_compiled()
        if fast:
            _fast_exit(code)
        raise SystemExit(code)
    from .app import main as app_main

    if not fast:
        try:
            app_main(args)
        finally:
            _save_compiled()
        return
    try:
        app_main(args)
        code = 0
    except SystemExit as exc:
        code = _status(exc.code)
    _save_compiled()
    _fast_exit(code)


def _save_compiled() -> None:
    """Keep the dataclass methods this process compiled (when :mod:`counterpoise.io.compiled`
    was installed: the console script with the cache on)."""
    compiled = sys.modules.get("counterpoise.io.compiled")
    if compiled is not None:
        compiled.save()


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
