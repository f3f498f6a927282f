"""matplotlib with the non-interactive Agg backend (no display needed), loaded on first use."""

from __future__ import annotations

from typing import Any


def pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def save(fig: Any, path: Any, *, tight: bool = True) -> None:
    """Write ``fig`` as PNG through a temporary file and a rename, then close it.

    ``tight``: crop the picture to what is drawn (``bbox_inches="tight"``, which draws the
    figure once more to find it); False for a figure laid out by its maker."""
    import os
    import sys
    import tempfile
    from pathlib import Path

    from ..report.files import respect_umask

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".png", dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=110, bbox_inches="tight" if tight else None)
        respect_umask(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    finally:
        if "matplotlib.pyplot" in sys.modules:  # a figure made by pyplot: forget it there; others have no pyplot state
            pyplot().close(fig)
