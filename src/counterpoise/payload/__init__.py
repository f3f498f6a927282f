"""Payload ranges: design for a range of payload masses, adjustment schedules, widest range.

Between :mod:`counterpoise.verify` and :mod:`counterpoise.pipeline`: payload masses become
scenarios (:mod:`.scenarios`), the designer solves them, the adjustments of the fixed
design are solved on a fine payload grid (:mod:`.schedule`), and :mod:`.design` ties it
together. See ``docs/payload.md``.
"""

from __future__ import annotations

from .design import OperatorSettings, PayloadDesign, WidestRange, design_payloads, settings_for, widest_range
from .schedule import AdjustmentSolver, Line, Schedule, Setting, grid, schedule

__all__ = [
    "AdjustmentSolver",
    "Line",
    "OperatorSettings",
    "PayloadDesign",
    "Schedule",
    "Setting",
    "WidestRange",
    "design_payloads",
    "grid",
    "schedule",
    "settings_for",
    "widest_range",
]
