"""The hardware limits of a pulley-mounted spring as built, at a tuned tolerance corner.

A small boundary of its own (issue 31): the robust layer checks every tuned setting against
the limits a built spring has, from per-spring figures only, so that the realisation model
(counterpoise.realisation, springs/) can later be pointed at it without the robust layer
changing. All figures SI.

A pulley mount (docs/catalogues.md, "What a part must do"): a cable of length C runs from the
spring's moving end over the pulley to the link point, d from the pulley; the spring's fixed
end sits behind the pulley so that its length is L = d + L0 − F0/k (the string set for the
part as measured: step 1 of the tuning procedure), and it then pulls k·d. Over the workspace
of a tuned corner (distances d_min to d_max at the tuned settings, the corner's rate k):

| limit | condition | margin |
|---|---|---|
| ``slack``: the coils stay open (the cable taut) | d ≥ F0/k | d_min − F0/k |
| ``cable``: the spring's end stays behind the pulley | d ≤ C | C − d_max |
| ``load``: within the spring's allowable load | k·d ≤ F_max | F_max − k·d_max |
| ``length``: within its longest allowed length | d + L0 − F0/k ≤ L_max | L_max − (d_max + L0 − F0/k) |

A figure that is not known (NaN: a spring not yet designed has no F0, L0 or allowable load)
gives no margin for the limits that need it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

#: the limits, in the order they are reported
LIMITS = ("slack", "cable", "load", "length")


@dataclass(frozen=True)
class PulleySpring:
    """One pulley-mounted spring as built (SI): the part's rate and initial tension (with their
    deviations at the corner), its free length, the cable, its allowable load and length."""

    rate: float
    initial_tension: float = math.nan
    free_length: float = math.nan
    cable: float = math.nan
    max_force: float = math.nan
    max_length: float = math.nan


@dataclass(frozen=True)
class Margin:
    """How far inside one limit a spring stays over a workspace (SI: m or N; < 0 beyond it)."""

    spring: str
    limit: str
    margin: float

    @property
    def unit(self) -> str:
        return "N" if self.limit == "load" else "m"


def pulley_margins(name: str, s: PulleySpring, d_min: float, d_max: float) -> tuple[Margin, ...]:
    """The margins (module docstring) of spring ``name`` over distances ``d_min``..``d_max``."""
    k, f0, l0 = s.rate, s.initial_tension, s.free_length
    out = []
    if math.isfinite(f0) and k > 0:
        out.append(Margin(name, "slack", d_min - f0 / k))
    if math.isfinite(s.cable):
        out.append(Margin(name, "cable", s.cable - d_max))
    if math.isfinite(s.max_force):
        out.append(Margin(name, "load", s.max_force - k * d_max))
    if math.isfinite(s.max_length) and math.isfinite(f0) and math.isfinite(l0) and k > 0:
        out.append(Margin(name, "length", s.max_length - (d_max + l0 - f0 / k)))
    return tuple(out)


@dataclass(frozen=True)
class Envelope:
    """What one spring must serve over every tuned corner: the least and largest distance of
    its ends and the least and largest force k'·d (each corner's own rate), SI."""

    distance_min: float
    distance_max: float
    force_min: float
    force_max: float


def envelope(uses: Iterable[tuple[float, float, float]]) -> Envelope:
    """The envelope of (rate, d_min, d_max) at every tuned corner."""
    rows = list(uses)
    return Envelope(
        min(d for _, d, _ in rows),
        max(d for _, _, d in rows),
        min(k * d for k, d, _ in rows),
        max(k * d for k, _, d in rows),
    )


def least(margins: Sequence[Margin]) -> dict[tuple[str, str], Margin]:
    """The least margin of each (spring, limit)."""
    out: dict[tuple[str, str], Margin] = {}
    for m in margins:
        key = (m.spring, m.limit)
        if key not in out or m.margin < out[key].margin:
            out[key] = m
    return out


def breaches(margins: Mapping[str, Sequence[Margin]], tolerance: float = 1e-9) -> list[tuple[str, Margin]]:
    """(corner, margin) of every limit broken beyond ``tolerance`` (relative to 1 m or 1 N)."""
    return [(corner, m) for corner, ms in margins.items() for m in ms if m.margin < -tolerance]
