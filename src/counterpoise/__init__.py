"""counterpoise: design gravity balancers for mechanisms by optimisation.

Typical use::

    from counterpoise import load_problem, design, write_reports
    result = design(load_problem("problems/yasir2019_hybrid.toml"))
    write_reports(result, "results")

Heavy dependencies (CasADi, pandas) are imported on first use, not here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

__all__ = [
    "CounterpoiseError",
    "ProblemFileError",
    "SolverError",
    "load_problem",
    "load_problem_text",
    "design",
    "Designer",
    "Status",
    "verify",
    "write_reports",
]

from .errors import CounterpoiseError, ProblemFileError, SolverError

_LAZY = {
    "load_problem": ("loader", "load_problem"),
    "load_problem_text": ("loader", "load_problem_text"),
    "design": ("design", "design"),
    "Designer": ("nlp", "Designer"),
    "Status": ("nlp", "Status"),
    "verify": ("verify", "verify"),
    "write_reports": ("report", "write_reports"),
}

if TYPE_CHECKING:  # pragma: no cover
    from .design import design
    from .loader import load_problem, load_problem_text
    from .nlp import Designer, Status
    from .report import write_reports
    from .verify import verify


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(f".{module}", __name__), attr)
    raise AttributeError(f"module 'counterpoise' has no attribute '{name}'")
