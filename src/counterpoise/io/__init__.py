"""The io layer: problem files (TOML) in, typed problems out.

:mod:`.schema` checks the shape of a file (pydantic), :mod:`.resolve` its meaning, and
:mod:`.loader` ties them together; :mod:`.builder` builds the same data in Python code.
Other formats (URDF) belong here, beside TOML. :mod:`.cache` keeps loaded problems on
disk for the command line.

The names below are imported on first use (PEP 562), so that importing a module of this
package (:mod:`.cache`, :mod:`.robot`) does not import pydantic and pint with the loader.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .builder import ProblemBuilder, dh, rotate, translate
    from .loader import load_problem, load_problem_data, load_problem_text

__all__ = ["ProblemBuilder", "dh", "load_problem", "load_problem_data", "load_problem_text", "rotate", "translate"]

_WHERE = {
    "ProblemBuilder": "builder",
    "dh": "builder",
    "rotate": "builder",
    "translate": "builder",
    "load_problem": "loader",
    "load_problem_data": "loader",
    "load_problem_text": "loader",
}


def __getattr__(name: str) -> Any:
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value
