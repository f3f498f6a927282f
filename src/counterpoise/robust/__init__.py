"""Designs that stay balanced as built: tolerances, the robust counterpart (cvxpy), tuning.

See docs/robust.md. Nothing here is imported on the plain solve path of a problem without
``[robust]`` (cvxpy costs about a second to import)."""

from __future__ import annotations

from .method import Corner, RobustMethod, RobustReport
from .perturb import Deviation, perturbed

__all__ = ["Corner", "Deviation", "RobustMethod", "RobustReport", "perturbed"]
