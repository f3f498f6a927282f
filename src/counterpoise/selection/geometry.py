"""Spring lengths over configurations, for many designs at once (numpy broadcasting).

Designs run along axis 0 (values of shape (n_designs, 1)), configurations along axis 1
(shape (1, n_configurations)); the energy code of :class:`~counterpoise.mechanics.Mechanics`
broadcasts, so one evaluation covers every candidate part.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..mechanics import NUMPY_FUNCTIONS, Mechanics
from ..mechanics.kinematics import dot, sub
from ..model.problem import Problem
from ..errors import ProblemFileError
from ..mechanics.closure import geometry_key, manifold_configurations, scenario_base
from ..mechanics.sampling import STEP, configurations

Gravity3 = tuple[float, float, float]


def sample_configurations(problem: Problem, samples: int, seed: int) -> dict[str, np.ndarray]:
    """Per subsystem: ``samples`` random configurations plus the corners of its box.

    A subsystem with closed loops is sampled on its configuration manifold (random values
    of its independent coordinates plus the corners of their box, the dependent ones
    solved on the branch of home), so spring lengths and limits are those of assembled
    configurations. Its manifold must be the same in every scenario (the sample serves
    them all): a scenario that changes a loop's geometry is an input error here.
    """
    rng = np.random.default_rng(seed)
    out = {}
    for s in problem.subsystems:
        if not problem.subsystem_loops(s.name):
            out[s.name] = configurations(problem, s.name, samples, rng)
            continue
        bases = [scenario_base(problem, sc.name) for sc in problem.scenarios]
        keys = {geometry_key(problem, s.name, b) for b in bases}
        if len(keys) > 1:
            changed = sorted({n for key in keys for n, v in key} - {n for n, v in set.intersection(*(set(k) for k in keys))})
            raise ProblemFileError(
                problem.path,
                "scenarios",
                f"the scenarios change parameter '{changed[0]}' of the closed loop of subsystem '{s.name}'; catalogue parts "
                "are checked on one manifold shared by every scenario (give each geometry its own file)",
            )
        out[s.name] = manifold_configurations(problem, s.name, samples, rng, bases[0]).q
    return out


def spring_lengths(
    problem: Problem,
    springs: Sequence[str],
    q: Mapping[str, np.ndarray],
    variables: Mapping[str, np.ndarray],
    base: Mapping[str, float | np.ndarray],
    gravity: Gravity3,
) -> dict[str, np.ndarray]:
    """Distance between the two ends of each spring: (n_designs, n_configurations) arrays.

    ``q`` holds every subsystem's configurations (``sample_configurations``); a spring fixed
    to ground at both ends gets one column.
    """
    by_name = {s.name: s for s in problem.springs}
    out: dict[str, np.ndarray] = {}
    for name in springs:
        spring = by_name[name]
        coords: dict[str, np.ndarray] = {}
        if spring.subsystem is not None:
            sub_q = q[spring.subsystem]
            for i, c in enumerate(problem.subsystem_coordinates(spring.subsystem)):
                coords[c.name] = sub_q[None, :, i]
        else:
            coords = {c.name: np.array([[c.home]]) for c in problem.coordinates}
        mech = Mechanics(problem, base, variables, coords, gravity, NUMPY_FUNCTIONS)
        d = sub(mech.position(spring.ends[0]), mech.position(spring.ends[1]))
        squared = np.asarray(dot(d, d), dtype=float)
        out[name] = np.sqrt(np.maximum(np.atleast_2d(squared), 0.0))
    return out


def spring_length_gradients(
    problem: Problem,
    subsystem: str,
    q: np.ndarray,
    variables: Mapping[str, float],
    base: Mapping[str, float],
    gravity: Gravity3,
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """For each spring of ``subsystem``: (length d (N,), ∂(d²)/∂q (N, n_q)) by complex step."""
    names = [c.name for c in problem.subsystem_coordinates(subsystem)]
    n, n_q = q.shape
    stacked = np.tile(q.astype(complex), (n_q, 1))
    for j in range(n_q):
        stacked[j * n : (j + 1) * n, j] += 1j * STEP
    coords = {name: stacked[:, i] for i, name in enumerate(names)}
    mech = Mechanics(problem, base, variables, coords, gravity, NUMPY_FUNCTIONS)
    out = {}
    for spring in problem.springs:
        if spring.subsystem != subsystem:
            continue
        d = sub(mech.position(spring.ends[0]), mech.position(spring.ends[1]))
        squared = np.broadcast_to(np.asarray(dot(d, d), dtype=complex), (n * n_q,))
        length = np.sqrt(np.maximum(squared.real[:n], 0.0))
        grad = (squared.imag / STEP).reshape(n_q, n).T
        out[spring.name] = (length, grad)
    return out
