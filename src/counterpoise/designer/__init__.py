"""The design layer: formulation + exact conditions + a solver backend -> a Solution."""

from __future__ import annotations

from .designer import Designer
from .quantities import QuantityValue, evaluate_quantities
from .solution import Solution

__all__ = ["Designer", "QuantityValue", "Solution", "evaluate_quantities"]
