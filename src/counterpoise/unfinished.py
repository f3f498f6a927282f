"""What this process is still writing: temporary folders of :func:`counterpoise.report.files.atomic_folder`.

A pool worker (``solve --jobs``, a study's process pool) is ended by its parent with SIGTERM
when the command is interrupted or fails; its handler (:mod:`counterpoise.studies.runners`)
removes what it was writing before it goes, so an interrupted run leaves no hidden
``.<name>.*.new`` folder beside the reports (the folders already in place stay whole).
"""

from __future__ import annotations

from pathlib import Path

_PATHS: set[Path] = set()


def begin(path: Path) -> None:
    """``path`` is being written by this process (a temporary folder)."""
    _PATHS.add(path)


def end(path: Path) -> None:
    """``path`` is done with: moved into place or removed."""
    _PATHS.discard(path)


def discard_all() -> None:
    """Remove every temporary folder this process is still writing."""
    import shutil  # not at import: a solve imports this module and rarely needs shutil

    for path in list(_PATHS):
        shutil.rmtree(path, ignore_errors=True)
    _PATHS.clear()
