"""IPOPT through CasADi's ``nlpsol``: built once, called many times; statuses mapped here."""

from __future__ import annotations

import contextlib
import io
import sys
import time
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from ..numeric import NumericFunction
from .base import Bounds, SolverOutput, Status

#: Options the designs rely on: tight tolerances, no bound relaxation (a variable on its
#: bound stays exactly on it), quiet output.
IPOPT_DEFAULTS: Mapping[str, Any] = {
    "print_level": 0,
    "sb": "yes",
    "tol": 1e-10,
    "constr_viol_tol": 1e-12,
    "acceptable_tol": 1e-8,
    "bound_relax_factor": 0.0,
    "honor_original_bounds": "yes",
    "mu_strategy": "adaptive",
    "max_wall_time": 120.0,  # seconds per solve: no input keeps a solve running for ever (Ipopt status Maximum_WallTime_Exceeded)
}

#: IPOPT return codes and what they mean for a design.
STATUS_MAP: Mapping[str, Status] = {
    "Solve_Succeeded": Status.OPTIMAL,
    "Solved_To_Acceptable_Level": Status.OPTIMAL,
    "Infeasible_Problem_Detected": Status.INFEASIBLE,
    "Restoration_Failed": Status.INFEASIBLE,
    "Not_Enough_Degrees_Of_Freedom": Status.INFEASIBLE,
}


#: CasADi warnings (written to Python's stderr) that would be stray lines for a user: a
#: variable whose bounds are equal counts as an equality, so a fixed variable plus a square
#: system of balance conditions "overconstrains" the NLP although IPOPT simply removes it;
#: an inf or NaN in an evaluation ends as IPOPT's Invalid_Number_Detected, which the
#: design's status and message already report.
QUIET_WARNINGS = ("NLP is overconstrained", "Inf detected for output", "NaN detected for output")


@contextlib.contextmanager
def _quiet_warnings() -> Iterator[None]:
    buffer = io.StringIO()
    try:
        with contextlib.redirect_stderr(buffer):
            yield
    finally:
        for line in buffer.getvalue().splitlines(keepends=True):
            if not any(w in line for w in QUIET_WARNINGS):
                sys.stderr.write(line)


def map_status(return_status: str) -> Status:
    """The project's status for an IPOPT return code (anything unlisted is a failure)."""
    return STATUS_MAP.get(return_status, Status.FAILED)


class IpoptBackend:
    """``nlp`` is CasADi's dict {x, p, f, g} of SX expressions; the solver is built once,
    on the first call (:attr:`solver`): a designer that solves its problem as an LP never
    calls IPOPT, and building it loads the IPOPT plugin (~8 ms for the hybrid)."""

    name = "ipopt"

    def __init__(self, nlp: Mapping[str, Any], options: Mapping[str, Any], label: str = "design") -> None:
        self.options = dict(options)
        self.label = label
        self._nlp = dict(nlp)
        self._solver: Any = None
        self._evaluate: NumericFunction | None = None

    @property
    def solver(self) -> Any:
        """CasADi's ``nlpsol`` for this NLP, built on first use."""
        if self._solver is None:
            import casadi as ca

            self._solver = ca.nlpsol(self.label, "ipopt", self._nlp, {"print_time": False, "ipopt": self.options})
        return self._solver

    def solve(self, z0: np.ndarray, p: np.ndarray, bounds: Bounds) -> SolverOutput:
        """IPOPT from ``z0`` with parameters ``p`` within ``bounds``, through the solver's
        buffers (:class:`~counterpoise.numeric.NumericFunction`: no ``DM`` conversions, the
        same solve bit for bit); the initial multipliers are 0, as the ordinary call's."""
        if self._evaluate is None:
            self._evaluate = NumericFunction(self.solver)
        evaluate = self._evaluate
        n, m = int(np.size(bounds.lbz)), int(np.size(bounds.lbg))
        t0 = time.perf_counter()
        with _quiet_warnings():
            x, _, _, _, lam_g, _ = evaluate(z0, p, bounds.lbz, bounds.ubz, bounds.lbg, bounds.ubg, np.zeros(n), np.zeros(m))
        elapsed = time.perf_counter() - t0
        stats = evaluate.stats()
        code = str(stats.get("return_status", "unknown"))
        return SolverOutput(
            z=x.reshape(-1),
            status=map_status(code),
            solver_status=code,
            iterations=int(stats.get("iter_count", 0)),
            solve_time=elapsed,
            solver=self.name,
            multipliers=lam_g.reshape(-1),
        )
