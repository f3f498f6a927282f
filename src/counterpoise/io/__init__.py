"""The io layer: problem files (TOML) in, typed problems out.

:mod:`.schema` checks the shape of a file (pydantic), :mod:`.resolve` its meaning, and
:mod:`.loader` ties them together; :mod:`.builder` builds the same data in Python code.
Other formats (URDF) belong here, beside TOML.
"""

from __future__ import annotations

from .builder import ProblemBuilder, dh, rotate, translate
from .loader import load_problem, load_problem_data, load_problem_text

__all__ = ["ProblemBuilder", "dh", "load_problem", "load_problem_data", "load_problem_text", "rotate", "translate"]
