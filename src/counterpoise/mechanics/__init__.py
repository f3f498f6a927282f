"""The mechanics layer: kinematics and potential energy, written once for every backend."""

from __future__ import annotations

from ..model.functions import NUMPY_FUNCTIONS, Functions, casadi_functions
from .energy import Mechanics

__all__ = ["NUMPY_FUNCTIONS", "Functions", "Mechanics", "casadi_functions"]
