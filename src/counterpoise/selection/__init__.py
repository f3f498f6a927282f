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
- :mod:`.parts`: the chosen parts' report (dense limit check, bill of materials, tolerance corners);
- :mod:`.result`: what the layer found (:class:`PartsReport`, an extra of the design);
  :mod:`.method` is the layer's design method, :mod:`.layer` its entry in the registry of
  layers, :mod:`.report` its report.

The names below are imported from their modules on first use: reading a design's parts
(:mod:`.result`) imports no search.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .result import BillLine, Corner, PartsReport, SpringUse
    from .parts import choose
    from .search import PartSearch
    from .results import Choice, NearMiss, SearchResult, SlotCount
    from .tolerance import ToleranceBand, tolerance_band

#: exported name -> the module of this package that defines it (imported on first use, PEP 562)
_LAZY = {
    "BillLine": "result",
    "Corner": "result",
    "PartsReport": "result",
    "SpringUse": "result",
    "choose": "parts",
    "PartSearch": "search",
    "Choice": "results",
    "NearMiss": "results",
    "SearchResult": "results",
    "SlotCount": "results",
    "ToleranceBand": "tolerance",
    "tolerance_band": "tolerance",
}

__all__ = ["BillLine", "Choice", "Corner", "NearMiss", "PartSearch", "PartsReport", "SearchResult", "SlotCount", "SpringUse", "ToleranceBand", "choose", "tolerance_band"]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
