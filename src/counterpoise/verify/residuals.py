"""Generalized balance residuals ∂V/∂q by complex step, on the numpy backend.

The derivative is taken by complex step on :class:`counterpoise.mechanics.Mechanics` — the
same energy code the NLP was built from, but neither CasADi's derivatives nor the sampled
configurations of the compression — so it is exact to rounding and catches a compression
that sampled too little.
"""

from __future__ import annotations

import itertools

import numpy as np

from ..mechanics import NUMPY_FUNCTIONS, Mechanics
from ..model.problem import Problem

STEP = 1e-30  # complex step; any tiny value works, there is no subtractive cancellation
MAX_CORNERS = 4096


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




def energy_scale(
    problem: Problem, subsystem: str, q: np.ndarray, variables: dict[str, float], base: dict[str, float], gravity: tuple[float, float, float]
) -> float:
    """Largest Σ |energy of each element| of the subsystem over the rows of ``q`` (J): the
    size of the terms whose rounding noise a residual that is zero in exact arithmetic keeps."""
    names = [c.name for c in problem.subsystem_coordinates(subsystem)]
    coords = {name: q[:, i].astype(float) for i, name in enumerate(names)}
    with np.errstate(all="ignore"):
        values = np.abs(np.asarray(Mechanics(problem, base, variables, coords, gravity, NUMPY_FUNCTIONS).energy_magnitude(subsystem), dtype=float))
    finite = values[np.isfinite(values)]
    return float(finite.max(initial=0.0))
