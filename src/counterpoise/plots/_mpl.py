"""matplotlib with the non-interactive Agg backend (no display needed), loaded on first use."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

#: resolution of the PNG files
DPI = 110
#: zlib level of the PNG files (lossless at any level): 3 encoded the demo's 87 PNGs in 3.0 s
#: CPU against 4.9 s at Pillow's default 6, for files 2 % larger (12.5 MB against 12.3 MB)
COMPRESS_LEVEL = 3


def pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def save(fig: Any, path: Any, crop: bool | None = None) -> None:
    """Write ``fig`` as PNG through a temporary file and a rename, then close it.

    ``crop``: cut the PNG to what is drawn (``bbox_inches="tight"``), which costs a second
    draw of the whole figure to find that box. A figure laid out by constrained layout
    fills its canvas already: with ``crop`` None it is laid out once (:func:`freeze_layout`)
    and drawn once, uncropped; any other figure (``tight_layout``) is cropped. ``False``:
    the figure is laid out by its maker (a fixed layout, or frozen by :func:`freeze_layout`):
    drawn once.
    """
    import sys

    if crop is None:
        from matplotlib.layout_engine import ConstrainedLayoutEngine

        crop = not isinstance(fig.get_layout_engine(), ConstrainedLayoutEngine)
        if not crop:
            freeze_layout(fig)
    try:
        _write(path, lambda tmp: fig.savefig(tmp, dpi=DPI, pil_kwargs={"compress_level": COMPRESS_LEVEL}, **({"bbox_inches": "tight"} if crop else {})))
    finally:
        if "matplotlib.pyplot" in sys.modules:  # a figure made by pyplot: forget it there; others have no pyplot state
            pyplot().close(fig)


def save_canvas(fig: Any, path: Any) -> None:
    """Write what is drawn on ``fig``'s Agg canvas now as PNG (the resolution and metadata
    ``savefig`` writes), through a temporary file and a rename: for a figure drawn in parts
    (``canvas.draw`` then each artist's ``draw``...), which ``savefig`` would draw again
    from scratch. An opaque canvas is written as RGB, without its alpha channel (all 255):
    the same pixels, a quarter less to filter and compress (≈ 60 ms against 87 ms for the
    7-row ``study.png`` of ``yasir2019_hybrid``)."""
    import matplotlib
    import numpy as np
    from PIL import Image, PngImagePlugin

    buffer = fig.canvas.buffer_rgba()
    rgba = np.asarray(buffer)
    image = Image.frombuffer("RGBA", (rgba.shape[1], rgba.shape[0]), buffer, "raw", "RGBA", 0, 1)  # no copy
    if (rgba[..., 3] == 255).all():
        image = image.convert("RGB")  # in Pillow's C code: 2 ms against 13 ms for numpy's slice copied
    info = PngImagePlugin.PngInfo()
    info.add_text("Software", f"Matplotlib version{matplotlib.__version__}, https://matplotlib.org/")
    _write(path, lambda tmp: image.save(tmp, format="png", dpi=(fig.dpi, fig.dpi), pnginfo=info, compress_level=COMPRESS_LEVEL))


def _write(path: Any, write: Callable[[str], object]) -> None:
    """``write(tmp)`` into a temporary file beside ``path``, then renamed to ``path``."""
    import os
    import tempfile
    from pathlib import Path

    from ..filemodes import respect_umask

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".png", dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        respect_umask(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def freeze_layout(fig: Any, axes: Sequence[Any] = ()) -> Any:
    """Lay ``fig`` out as its first draw would, without drawing it: run its layout engine
    (constrained layout), apply each axes' aspect at its final place, fix the limits of
    ``axes`` and turn the engine off, so that pixels measured now are the pixels of the
    saved picture (up to its resolution). Returns the renderer to measure text with.

    A draw does the same (``Figure.draw`` runs the engine, ``Axes.draw`` applies the aspect
    at the box its locator gives) and then rasterizes every artist, which costs as much
    again and is thrown away when the figure is saved. With no engine left, ``savefig``
    draws the figure once (with one, it runs a draw without rendering first).
    """
    renderer = fig.canvas.get_renderer()
    engine = fig.get_layout_engine()
    if engine is not None:
        engine.execute(fig)
    for ax in fig.axes:
        locator = ax.get_axes_locator()
        ax.apply_aspect(locator(ax, renderer) if locator else None)
    for ax in axes:
        ax.set_xlim(ax.get_xlim())
        ax.set_ylim(ax.get_ylim())
        ax.set_autoscale_on(False)
    import matplotlib

    # no engine at all (not the "none" placeholder, for which savefig still runs a draw without
    # rendering before the real one); None means no engine unless the rc file asks for one
    with matplotlib.rc_context({"figure.autolayout": False, "figure.constrained_layout.use": False}):
        fig.set_layout_engine(None)
    return renderer
