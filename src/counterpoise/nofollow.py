"""What the tool creates under ``--out`` is never reached through a symbolic link.

A link planted where a study or a solve writes (``<problem>-study.partial``, the study's
lock ``.<problem>-study.lock``, a report folder ``<out>/<problem>``) would make it write,
truncate or delete outside ``--out``. Such a link is refused, naming the path
(:class:`LinkRefused`, which the commands turn into one line and exit status 2), and what is
created is opened with ``O_NOFOLLOW`` (a file) or made by ``mkdir`` (which never follows).
``--out`` itself may be a link: the user named it.

Standard library only (like :mod:`counterpoise.filemodes`).
"""

from __future__ import annotations

import os
from pathlib import Path

from .errors import CounterpoiseError


class LinkRefused(CounterpoiseError):
    """A path the tool would write through is a symbolic link; the message names it."""


def refuse_link(path: str | Path) -> None:
    """Raise :class:`LinkRefused` if ``path`` is a symbolic link (dangling or not)."""
    if os.path.islink(path):
        try:
            target = os.readlink(path)
        except OSError:
            target = "?"
        raise LinkRefused(f"'{path}' is a symbolic link (to '{target}'): counterpoise writes nothing through a link there; remove it, or give another --out")


def open_no_follow(path: str | Path, flags: int, mode: int = 0o666) -> int:
    """``os.open`` that never follows a link at ``path`` (``O_NOFOLLOW``): a link is
    :class:`LinkRefused`."""
    try:
        return os.open(path, flags | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0), mode)
    except OSError as exc:
        if os.path.islink(path):
            refuse_link(path)
        raise exc


def make_folder(path: str | Path) -> Path:
    """``path`` as a folder of its own: made if missing (``mkdir`` never follows a link); a
    link there, dangling or not, is :class:`LinkRefused`; the parents are made as needed."""
    path = Path(path)
    refuse_link(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        path.mkdir()
    except FileExistsError:
        refuse_link(path)  # planted since the check: refused all the same
        if not path.is_dir():
            raise
    return path
