"""Designs that stay balanced as built: tolerances, the robust counterpart (cvxpy), tuning.

See docs/robust.md. Nothing here is imported on the plain solve path of a problem without
``[robust]`` (cvxpy costs about a second to import): the names below are imported from
their modules on first use, and the records of :mod:`.result` (:class:`RobustReport`, an
extra of the design) import no solver. :mod:`.method` is the layer's design method,
:mod:`.layer` its entry in the registry of layers, :mod:`.report` its report.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .result import Corner, RobustReport
    from .method import RobustMethod
    from .perturb import Deviation, perturbed

#: exported name -> the module of this package that defines it (imported on first use, PEP 562)
_LAZY = {
    "Corner": "result",
    "RobustReport": "result",
    "RobustMethod": "method",
    "Deviation": "perturb",
    "perturbed": "perturb",
}

__all__ = ["Corner", "Deviation", "RobustMethod", "RobustReport", "perturbed"]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
