"""Choosing bought parts: one catalogue spring per slot, the continuous design re-solved for it.

- :mod:`.search`: pruning, independent slot groups, enumeration or branch and bound;
- :mod:`.geometry`: spring lengths over configurations for many designs at once;
- :mod:`.tolerance`: worst-case residual over the parts' tolerance band;
- :mod:`.parts`: the chosen parts' report (dense limit check, bill of materials, tolerance corners).
"""

from __future__ import annotations

from .parts import BillLine, Corner, PartsReport, SpringUse, choose, report
from .search import Choice, NearMiss, PartSearch, SearchResult, SlotCount
from .tolerance import ToleranceBand, tolerance_band

__all__ = [
    "BillLine",
    "Choice",
    "Corner",
    "NearMiss",
    "PartSearch",
    "PartsReport",
    "SearchResult",
    "SlotCount",
    "SpringUse",
    "ToleranceBand",
    "choose",
    "report",
    "tolerance_band",
]
