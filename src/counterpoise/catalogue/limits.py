"""The limits a catalogue part puts on the zero-free-length spring it realises.

A part with rate k, free length L0, initial tension F0, maximum load F_max and maximum
length L_max pulls with F = F0 + k (L − L0) at lengths L0 ≤ L ≤ L_max. Behind a string
over a pulley, set so that the spring's length is L = d + L0 − F0/k when its two
attachment points are d apart, it pulls with F = k·d: a zero-free-length spring. That
holds only while

- the coils stay open: L ≥ L0, i.e. d ≥ F0/k (below it the force is stuck at F0 or less);
- the spring is not over-stretched: d + L0 − F0/k ≤ L_max;
- the force stays within the part's rating: k·d ≤ F_max.

:func:`margins` evaluates the three margins for many parts at once (numpy broadcasting):
each is ≥ 0 when the limit holds. :func:`violation` turns them into one relative figure
for ranking the nearest parts when none fits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

LIMITS = ("initial_tension", "max_length", "max_load")
LIMIT_TEXT = {
    "initial_tension": "the string goes slack: the attachment points come closer than F0/k",
    "max_length": "the spring is stretched beyond its maximum length",
    "max_load": "the force exceeds the part's maximum load",
}


@dataclass(frozen=True)
class Margins:
    """Margins (≥ 0: the limit holds) of parts over the distances they see; arrays broadcast."""

    slack: np.ndarray  # m: d_min − F0/k
    length: np.ndarray  # m: L_max − (d_max + L0 − F0/k)
    load: np.ndarray  # N: F_max − k·d_max

    def ok(self, tolerance: float = 0.0) -> np.ndarray:
        return (self.slack >= -tolerance) & (self.length >= -tolerance) & (self.load >= -tolerance)


def margins(d_min: np.ndarray, d_max: np.ndarray, rate: ArrayLike, free_length: ArrayLike, initial_tension: ArrayLike, max_load: ArrayLike, max_length: ArrayLike) -> Margins:
    """Margins of parts (arrays of their data) for attachment distances in [d_min, d_max]."""
    k = np.asarray(rate, dtype=float)
    offset = np.asarray(initial_tension, dtype=float) / k  # F0/k: the zero-free-length point inside the spring
    return Margins(
        slack=np.asarray(d_min) - offset,
        length=np.asarray(max_length) - (np.asarray(d_max) + np.asarray(free_length) - offset),
        load=np.asarray(max_load) - k * np.asarray(d_max),
    )


def violation(m: Margins, rate: ArrayLike, free_length: ArrayLike, initial_tension: ArrayLike, max_load: ArrayLike, max_length: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(worst relative violation ≥ 0, index into :data:`LIMITS` of that limit) per part.

    Each margin is divided by the part's own scale of that limit: F0/k for the slack (its
    free length if F0 = 0), the stroke L_max − L0 for the length, F_max for the load.
    """
    k = np.asarray(rate, dtype=float)
    scale_slack = np.where(np.asarray(initial_tension) > 0, np.asarray(initial_tension) / k, np.asarray(free_length))
    rel = np.stack(
        np.broadcast_arrays(
            -m.slack / scale_slack,
            -m.length / (np.asarray(max_length) - np.asarray(free_length)),
            -m.load / np.asarray(max_load),
        )
    )
    worst = np.argmax(rel, axis=0)
    return np.maximum(np.max(rel, axis=0), 0.0), worst
