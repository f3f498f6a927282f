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


def _complex_safe_atan2(y: Any, x: Any) -> Any:
    """atan2(y, x) that carries a complex-step perturbation of y and x: its derivative
    (x dy − y dx)/(x² + y²) times the imaginary parts (numpy's arctan2 takes no complex)."""
    if not (np.iscomplexobj(y) or np.iscomplexobj(x)):
        return np.arctan2(y, x)
    yr, xr = np.real(y), np.real(x)
    return np.arctan2(yr, xr) + 1j * ((xr * np.imag(y) - yr * np.imag(x)) / (xr * xr + yr * yr))


def _where_positive(x: Any, value: Any) -> Any:
    """``value`` where x > 0 (its real part), else 0: a real spring pulls only while stretched."""
    return np.where(np.real(x) > 0, value, 0.0 * value)


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
    # the physics' own (not callable from a problem file's expressions: model.expr.MATH_FUNCTIONS)
    "atan2": _complex_safe_atan2,
    "where_positive": _where_positive,
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
        "atan2": ca.atan2,
        "where_positive": lambda x, value: ca.if_else(x > 0, value, 0),
    }
