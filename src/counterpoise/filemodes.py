"""The mode a file written through a temporary file gets: the one an ordinary ``open`` or
``mkdir`` would give it under the process's umask.

Standard library only: :mod:`counterpoise.report.files` and the plots
(:mod:`counterpoise.plots._mpl`) use it, and the study's plot helper
(:mod:`counterpoise.plotter`) writes its PNG files without importing the report package
(which imports the pipeline, ≈ 0.15 s of CPU when the study waits for its plot).
"""

from __future__ import annotations

import os
from pathlib import Path


def umask() -> int:
    """The process's file-creation mask (read without changing it for long)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def respect_umask(path: str | Path, directory: bool = False) -> None:
    """Give a file made by :func:`tempfile.mkstemp` (0600) or a folder made by
    :func:`tempfile.mkdtemp` (0700) the mode an ordinary
    ``open``/``mkdir`` would give it."""
    os.chmod(path, (0o777 if directory else 0o666) & ~umask())
