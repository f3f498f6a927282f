"""What every solver backend promises: one call signature, the project's own statuses.

A backend is built once from a problem in standard form (scaled variables z, parameters
p, objective, constraints g with lbg ≤ g ≤ ubg) and solved many times, with bounds passed
per call (branch-and-bound nodes and schedules change them). Each backend maps its own
return codes to :class:`Status` in its own module, and nowhere else.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Protocol

import numpy as np


class Status(str, Enum):
    """Outcome of a design. ``optimal`` only once the dense verification agrees."""

    OPTIMAL = "optimal"
    INFEASIBLE = "infeasible"
    FAILED = "failed"
    #: a design that can be built but misses its tolerance: a minimax design whose worst
    #: residual ratio exceeds ``minimax_tolerance``, or a balancer that misses balance as built
    NOT_BALANCED = "not_balanced"


@dataclass(frozen=True)
class SolverOutput:
    """One backend call: the point it stopped at (scaled), its status and its own words."""

    z: np.ndarray
    status: Status
    solver_status: str  # the backend's own return code, for the report
    iterations: int
    solve_time: float  # wall seconds of this call
    solver: str  # backend name, e.g. "ipopt"
    #: the constraint rows' multipliers λ (CasADi's sign: ∇f + Jᵀλ = 0, so ∂f*/∂(bound) = −λ);
    #: None when the backend gave none
    multipliers: np.ndarray | None = None


@dataclass(frozen=True)
class Bounds:
    """Scaled variable bounds and constraint bounds of one call."""

    lbz: np.ndarray
    ubz: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray


class Backend(Protocol):
    """A solver built once for a problem in standard form and called many times."""

    name: str

    def solve(self, z0: np.ndarray, p: np.ndarray, bounds: Bounds) -> SolverOutput: ...
