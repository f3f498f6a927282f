"""The verify layer: a dense check of a design, independent of the NLP's derivatives and samples."""

from __future__ import annotations

from .check import verify
from ..designer.checks import PRISMATIC, REVOLUTE, CoordinateCheck, Verification
from .judge import judge

__all__ = ["PRISMATIC", "REVOLUTE", "CoordinateCheck", "Verification", "judge", "verify"]
