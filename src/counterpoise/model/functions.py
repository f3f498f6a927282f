"""Function tables of the numeric backends: the tables that decide what the physics is computed on.

The same expression trees and kinematics run on floats, numpy arrays (real, or complex
for complex-step derivatives) and CasADi SX symbols; only the table of functions
(``sin``, ``sqrt``...) handed to them changes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

Functions = Mapping[str, Callable[..., Any]]

def _complex_safe_abs(z: Any) -> Any:
    """|x| that keeps the imaginary part of a complex-step perturbation."""
    return np.where(np.real(z) < 0, -z, z)


NUMPY_FUNCTIONS: Functions = {
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    "asin": np.arcsin,
    "acos": np.arccos,
    "atan": np.arctan,
    "sqrt": np.sqrt,
    "exp": np.exp,
    "log": np.log,
    "abs": _complex_safe_abs,
}


def casadi_functions() -> Functions:
    import casadi as ca

    return {
        "sin": ca.sin,
        "cos": ca.cos,
        "tan": ca.tan,
        "asin": ca.asin,
        "acos": ca.acos,
        "atan": ca.atan,
        "sqrt": ca.sqrt,
        "exp": ca.exp,
        "log": ca.log,
        "abs": ca.fabs,
    }
