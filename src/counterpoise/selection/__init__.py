"""Choosing bought parts: one catalogue spring per slot, the continuous design re-solved for it.

- :mod:`.search`: the search for zero-free-length slots, step by step, using
  :mod:`.windows` (relaxed problem, rate windows), :mod:`.groups` (independent slot groups),
  :mod:`.candidates` (enumeration, branch and bound), :mod:`.limits` (vectorised limit
  checks), :mod:`.ranking` (preferences) and :mod:`.nearest` (nearest candidates);
- :mod:`.direct`: the search for directly attached springs, with :mod:`.screening`
  (all parts on a geometry grid at once, bounds, most promising first);
- :mod:`.results`: the types a search returns;
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
