"""Payload ranges: design for a range of payload masses, adjustment schedules, widest range.

Between :mod:`counterpoise.verify` and :mod:`counterpoise.pipeline`: payload masses become
scenarios (:mod:`.scenarios`), the designer solves them, the adjustments of the fixed
design are solved on a fine payload grid (:mod:`.schedule`), and :mod:`.design` ties it
together; :mod:`.method` is the layer's design method, :mod:`.result` what it finds
(:class:`PayloadDesign`, an extra of the design), :mod:`.layer` its entry in the registry
of layers and :mod:`.report` its report. See ``docs/payload.md``.

The names below are imported from their modules on first use: reading a design's
:class:`PayloadDesign` (:mod:`.result`) imports no solver.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .design import OperatorSettings, design_payloads, settings_for
    from .result import PayloadDesign
    from .widest import WidestRange, widest_range
    from .schedule import AdjustmentSolver, Line, Schedule, Setting, grid, schedule

#: exported name -> the module of this package that defines it (imported on first use, PEP 562)
_LAZY = {
    "OperatorSettings": "design",
    "design_payloads": "design",
    "settings_for": "design",
    "PayloadDesign": "result",
    "WidestRange": "widest",
    "widest_range": "widest",
    "AdjustmentSolver": "schedule",
    "Line": "schedule",
    "Schedule": "schedule",
    "Setting": "schedule",
    "grid": "schedule",
    "schedule": "schedule",
}

__all__ = ["AdjustmentSolver", "Line", "OperatorSettings", "PayloadDesign", "Schedule", "Setting", "WidestRange", "design_payloads", "grid", "schedule", "settings_for", "widest_range"]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
