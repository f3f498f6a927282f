"""The command line (typer), a thin layer over the library."""

from __future__ import annotations

from .app import main

__all__ = ["main"]
