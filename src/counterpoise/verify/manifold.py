"""Dense check of a subsystem with closed loops, on its configuration manifold.

``verify_samples`` random configurations of the independent coordinates plus every corner
of their box are assembled (:mod:`counterpoise.mechanics.closure`, on the branch of home,
at the scenario's parameter values); at each, ∂V/∂q of every coordinate is taken by complex
step on the numpy energy (:class:`~.residuals.SubsystemResiduals`, not the CasADi graph the
optimiser used) and projected along the manifold:

    r_i = ∂V/∂q_i + (dq_d/dq_i)ᵀ ∂V/∂q_d.

The gravity torque of the unbalanced mechanism is projected the same way, so
``residual_ratio`` means what it means for open chains (:mod:`.checks`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..model.problem import Problem
from ..mechanics.sampling import MAX_CORNERS
from .residuals import SubsystemResiduals

if TYPE_CHECKING:
    from ..mechanics.closure import ManifoldPoints


class ManifoldResiduals:
    """The residual along the manifold of one subsystem, on fixed independent configurations.

    ``q`` holds every coordinate of the subsystem (dependent ones solved) and ``names`` the
    independent ones, whose residuals :meth:`evaluate` returns. The manifold is solved again
    when the geometry's parameters change (only then: a payload's mass
    or a spring's rate re-solves nothing).
    """

    def __init__(self, problem: Problem, subsystem: str, samples: int, rng: np.random.Generator, scenario: str) -> None:
        self.problem = problem
        self.subsystem = subsystem
        from ..mechanics.closure import closure, scenario_base  # not at import: an open chain's check needs none (~3 ms)

        c = closure(problem, subsystem, scenario_base(problem, scenario))
        n_i = len(c.independent)
        qi = c.lower + (c.upper - c.lower) * rng.random((samples, n_i))
        if 2**n_i <= MAX_CORNERS:
            qi = np.vstack([qi, c.corners()])
        self.qi = qi
        coords = problem.subsystem_coordinates(subsystem)
        self.names = [coords[i].name for i in c.independent]
        self._key: tuple[tuple[str, float], ...] | None = None
        self._points: ManifoldPoints | None = None
        self._residuals: SubsystemResiduals | None = None
        self._solve(c.base)

    def _solve(self, base: Mapping[str, float]) -> None:
        from ..mechanics.closure import closure, geometry_key

        key = geometry_key(self.problem, self.subsystem, base)
        if key == self._key:
            return
        c = closure(self.problem, self.subsystem, base)
        self._points = c.solve(self.qi)
        self._residuals = SubsystemResiduals(self.problem, self.subsystem, self._points.q)
        self._closure = c
        self._key = key

    @property
    def q(self) -> np.ndarray:
        """Every coordinate of the subsystem at the checked configurations: (N, n)."""
        return self._points.q  # type: ignore[union-attr]  # set in __init__

    @property
    def conditioning(self) -> float:
        """Smallest σ_min/σ_max of ∂h/∂q_d over the checked configurations (1: far from singular)."""
        return float(self._points.conditioning.min(initial=1.0))  # type: ignore[union-attr]  # set in __init__

    def evaluate(self, variables: Mapping[str, float], base: Mapping[str, float], gravity: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """(residual, gravity torque of the bodies alone) along the manifold: (N, n_i) each."""
        self._solve(base)
        r, t = self._residuals.evaluate(variables, base, gravity)  # type: ignore[union-attr]  # set in __init__
        c = self._closure
        tangent = self._points.tangent  # type: ignore[union-attr]  # set in __init__

        def along(g: np.ndarray) -> np.ndarray:
            g = np.asarray(g)
            return g[:, c.independent] + np.einsum("kdi,kd->ki", tangent, g[:, c.dependent])

        return along(r), along(t)
