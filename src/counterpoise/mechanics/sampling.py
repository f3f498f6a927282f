"""Sampled configurations of a subsystem: random points of its coordinate box plus its corners.

Below both :mod:`counterpoise.designer` (the minimax designer's sample rows) and
:mod:`counterpoise.verify` (the dense check), so that the two draw configurations the same way.
"""

from __future__ import annotations

import itertools

import numpy as np

from ..model.problem import Problem

#: the corners of a box are added while there are at most this many (12 coordinates)
MAX_CORNERS = 4096
#: complex step of every derivative by complex-step differentiation (the dense check, the
#: catalogue screening): any tiny value works, there is no subtractive cancellation
STEP = 1e-30


def configurations(problem: Problem, subsystem: str, samples: int, rng: np.random.Generator) -> np.ndarray:
    """``samples`` uniform random configurations of ``subsystem`` plus the corners of its
    coordinate box (when there are at most :data:`MAX_CORNERS` of them): (N, n_q)."""
    coords = problem.subsystem_coordinates(subsystem)
    lo = np.array([c.lower for c in coords])
    hi = np.array([c.upper for c in coords])
    q = lo + (hi - lo) * rng.random((samples, len(coords)))
    if 2 ** len(coords) <= MAX_CORNERS:
        q = np.vstack([q, np.array(list(itertools.product(*zip(lo, hi))), dtype=float).reshape(-1, len(coords))])
    return q
