"""counterpoise: design gravity balancers for mechanisms by optimisation.

Typical use::

    from counterpoise import load_problem, design, write_reports
    result = design(load_problem("problems/yasir2019_hybrid.toml"))
    write_reports(result, "results")

or build the problem in code with :class:`~counterpoise.io.builder.ProblemBuilder`. Heavy dependencies (CasADi,
pandas, pydantic) are imported on first use, not here.

Layers, each a subpackage with one job, in the order ``tests/test_api.py`` enforces (a layer
imports only from those before it): ``model`` (typed problem) → ``catalogue`` (spring
catalogues) → ``mechanics`` (kinematics, energy) → ``io`` (files) → ``formulation``
(symbols, exact conditions) → ``solvers`` (one backend per module) → ``designer`` →
``verify`` (dense check) → ``selection`` (catalogue parts) → ``payload`` (payload ranges,
schedules) → ``robust`` (tolerances) → ``realisation`` (the springs as built) → ``pipeline``
(solve, verify, judge) → ``report``
(CSV, HTML) → ``plots`` (PNG, matplotlib) → ``synthesis`` (the fewest elements that
balance) → ``studies`` (many designs) → ``cli``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.2.0"

__all__ = [
    "CounterpoiseError",
    "ProblemFileError",
    "SolverError",
    "ProblemBuilder",
    "rotate",
    "translate",
    "dh",
    "load_problem",
    "load_problem_text",
    "load_problem_data",
    "design",
    "Designer",
    "DesignResult",
    "Status",
    "verify_design",
    "write_reports",
]

from .errors import CounterpoiseError, ProblemFileError, SolverError

_LAZY = {
    "ProblemBuilder": ("io.builder", "ProblemBuilder"),
    "rotate": ("io.builder", "rotate"),
    "translate": ("io.builder", "translate"),
    "dh": ("io.builder", "dh"),
    "load_problem": ("io.loader", "load_problem"),
    "load_problem_text": ("io.loader", "load_problem_text"),
    "load_problem_data": ("io.loader", "load_problem_data"),
    "design": ("pipeline", "design"),
    "DesignResult": ("pipeline", "DesignResult"),
    "Designer": ("designer.designer", "Designer"),
    "Status": ("solvers.base", "Status"),
    # not "verify": that name is the subpackage once it is imported
    "verify_design": ("verify.check", "verify"),
    "write_reports": ("report.files", "write_reports"),
}

if TYPE_CHECKING:  # pragma: no cover
    from .designer.designer import Designer
    from .io.loader import load_problem, load_problem_data, load_problem_text
    from .io.builder import ProblemBuilder, dh, rotate, translate
    from .pipeline import DesignResult, design
    from .report.files import write_reports
    from .solvers.base import Status
    from .verify.check import verify as verify_design


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(f".{module}", __name__), attr)
    raise AttributeError(f"module 'counterpoise' has no attribute '{name}'")
