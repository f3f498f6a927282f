"""Nearest candidates when nothing fits: parts pruned by the rate window, with their
relative distance to it (from numbers already computed, no solve per failing part)."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from ..formulation.layout import Slot
from ..model.parts import SpringSlot
from .results import NearMiss
from .windows import WINDOW_SLACK


def rate_misses(slots: Mapping[str, SpringSlot], windows: Mapping[str, tuple[float, float]], values: Mapping[Slot, float], nearest: int) -> list[NearMiss]:
    """Up to ``nearest`` parts per slot outside its rate window, nearest first."""
    out = []
    for n, s in slots.items():
        lo, hi = windows[n]
        rates = s.catalogue.array("rate")
        if math.isnan(lo):
            target = values.get(Slot(n, None), float(np.median(rates)))
            lo = hi = target
        distance = np.where(rates < lo, (lo - rates) / lo, np.where(rates > hi, (rates - hi) / hi, 0.0))
        for i in np.argsort(distance)[:nearest]:
            if distance[i] > WINDOW_SLACK:  # within the window's stated tolerance: not outside it
                out.append(NearMiss(n, s.catalogue.part_number[int(i)], "rate", s.springs[0], float(distance[i])))
    return out
