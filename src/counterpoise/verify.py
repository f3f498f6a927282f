"""Dense, independent check that a design is balanced.

For every (subsystem, scenario) the residual ∂V/∂q is evaluated on ``verify_samples``
random configurations plus every corner of the coordinate box. The derivative is taken by
complex step on the numpy backend of :class:`counterpoise.mechanics.Mechanics` — the same
energy code the NLP was built from, but neither CasADi's derivatives nor the sampled
configurations of the compression — so it is exact to rounding and catches a compression
that sampled too little.

Each residual is set against the worst gravity torque of the *unbalanced* mechanism (the
given bodies alone, without counter-masses or springs): ``residual_ratio`` is the largest
residual divided by the largest such torque.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from .mechanics import NUMPY_FUNCTIONS, Mechanics
from .nlp import Solution
from .problem import Problem

STEP = 1e-30  # complex step; any tiny value works, there is no subtractive cancellation
MAX_CORNERS = 4096


@dataclass(frozen=True)
class CoordinateCheck:
    """Verification of one coordinate's balance condition in one (subsystem, scenario)."""

    subsystem: str
    scenario: str
    coordinate: str
    max_residual: float  # N·m (N for a slider)
    max_gravity_torque: float  # of the unbalanced mechanism
    configurations: int
    worst_configuration: tuple[float, ...]  # coordinates of the subsystem, SI

    @property
    def ratio(self) -> float:
        return _ratio(self.max_residual, self.max_gravity_torque)


@dataclass(frozen=True)
class Verification:
    checks: tuple[CoordinateCheck, ...]
    tolerance: float

    @property
    def max_residual(self) -> float:
        """Largest residual (NaN if any residual is NaN)."""
        return float(np.max([c.max_residual for c in self.checks], initial=0.0))

    @property
    def max_gravity_torque(self) -> float:
        return float(np.max([c.max_gravity_torque for c in self.checks], initial=0.0))

    @property
    def residual_ratio(self) -> float:
        return _ratio(self.max_residual, self.max_gravity_torque)

    @property
    def configurations(self) -> int:
        """Configurations checked, summed over (subsystem, scenario) pairs."""
        seen: dict[tuple[str, str], int] = {}
        for c in self.checks:
            seen[(c.subsystem, c.scenario)] = c.configurations
        return sum(seen.values())

    @property
    def balanced(self) -> bool:
        return self.residual_ratio <= self.tolerance

    def unmet(self) -> list[CoordinateCheck]:
        """Conditions that fail, worst first (relative to the overall gravity torque)."""
        total = self.max_gravity_torque
        bad = [c for c in self.checks if not _ratio(c.max_residual, total) <= self.tolerance]  # NaN is unmet
        return sorted(bad, key=lambda c: -c.max_residual if not np.isnan(c.max_residual) else -np.inf)


def _ratio(residual: float, torque: float) -> float:
    if np.isnan(residual) or np.isnan(torque):
        return float("nan")
    if torque > 0:
        return residual / torque
    return 0.0 if residual == 0 else float("inf")


def configurations(problem: Problem, subsystem: str, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Random configurations of a subsystem plus the corners of its box: (N, n_q)."""
    coords = problem.subsystem_coordinates(subsystem)
    lo = np.array([c.lower for c in coords])
    hi = np.array([c.upper for c in coords])
    q = lo + (hi - lo) * rng.random((samples, len(coords)))
    if 2 ** len(coords) <= MAX_CORNERS:
        corners = np.array(list(itertools.product(*zip(lo, hi))), dtype=float).reshape(-1, len(coords))
        q = np.vstack([q, corners])
    return q


def residuals(
    problem: Problem, subsystem: str, q: np.ndarray, variables: dict[str, float], base: dict[str, float], gravity: tuple[float, float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """∂V/∂q at each row of ``q`` by complex step, for the design and for the bodies alone.

    All n_q perturbations are stacked into one array of n_q·N configurations, so the energy
    code runs once. Returns (residual, unbalanced gravity torque), each (N, n_q).
    """
    names = [c.name for c in problem.subsystem_coordinates(subsystem)]
    n, n_q = q.shape
    stacked = np.tile(q.astype(complex), (n_q, 1))  # block j perturbs coordinate j
    for j in range(n_q):
        stacked[j * n : (j + 1) * n, j] += 1j * STEP
    coords = {name: stacked[:, i] for i, name in enumerate(names)}
    mech = Mechanics(problem, base, variables, coords, gravity, NUMPY_FUNCTIONS)

    def derivative(energy: object) -> np.ndarray:
        if not np.iscomplexobj(energy):
            return np.zeros((n, n_q))
        return (np.imag(np.broadcast_to(energy, (n * n_q,))) / STEP).reshape(n_q, n).T

    bodies, balancers = mech.energy_terms(subsystem)
    return derivative(bodies + balancers), derivative(bodies)


def verify(solution: Solution, samples: int | None = None, seed: int | None = None) -> Verification:
    """Check ``solution`` on random configurations plus corners, per (subsystem, scenario)."""
    problem = solution.problem
    settings = problem.settings
    rng = np.random.default_rng(settings.seed + 1 if seed is None else seed)
    n = settings.verify_samples if samples is None else samples
    checks = []
    for scenario in problem.scenarios:
        variables = solution.variable_values(scenario.name)
        gravity, base = solution.scenario_parameters[scenario.name]
        for sub in problem.subsystems:
            q = configurations(problem, sub.name, n, rng)
            r, t = residuals(problem, sub.name, q, variables, base, gravity)
            for j, name in enumerate(sub.coordinates):
                worst = int(np.nanargmax(np.abs(r[:, j]))) if not np.isnan(r[:, j]).all() else 0
                checks.append(
                    CoordinateCheck(
                        subsystem=sub.name,
                        scenario=scenario.name,
                        coordinate=name,
                        max_residual=float(np.abs(r[:, j]).max()),  # NaN if any is NaN
                        max_gravity_torque=float(np.abs(t[:, j]).max()),
                        configurations=int(q.shape[0]),
                        worst_configuration=tuple(float(v) for v in q[worst]),
                    )
                )
    return Verification(tuple(checks), settings.verify_tolerance)
