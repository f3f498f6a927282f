"""What the parts layer found of a design: its :class:`PartsReport` (an extra of the
:class:`~counterpoise.designer.solution.Solution`, ``solution.extra(PartsReport)``).

The records only: no search, no solver is imported here, so a report or an outer layer
that reads a design's parts costs nothing when the design has none.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .results import SearchResult
    from .tolerance import ToleranceBand


@dataclass(frozen=True)
class SpringUse:
    """One spring with its part, over every checked configuration and scenario (SI)."""

    spring: str
    slot: str
    part_number: str
    distance_min: float  # between the attachment points
    distance_max: float
    length_min: float  # of the spring itself: d + L0 − F0/k
    length_max: float
    force_min: float  # k·d
    force_max: float
    free_length: float
    max_length: float
    initial_tension: float
    max_load: float
    margin_slack: float  # d_min − F0/k − slack_margin (≥ 0: the string never goes slack, by the margin)
    margin_length: float  # L_max − length_max
    margin_load: float  # F_max − force_max
    scenario: str = ""  # the scenario (payload sample) these extremes are taken in; "": every one

    @property
    def fits(self) -> bool:
        return self.margin_slack >= 0 and self.margin_length >= 0 and self.margin_load >= 0


@dataclass(frozen=True)
class BillLine:
    part_number: str
    quantity: int
    unit_price: float  # NaN if unknown
    currency: str = ""

    @property
    def price(self) -> float:
        return self.quantity * self.unit_price


@dataclass(frozen=True)
class Corner:
    """A tolerance corner: each slot's rate at nominal × (1 + sign·tolerance)."""

    deviation: tuple[tuple[str, float], ...]  # (slot, relative rate change)
    ratio: float  # residual ratio of the nominal design with these rates
    adjusted_ratio: float  # after re-solving the adjustment variables (NaN: none)
    adjustment: tuple[tuple[str, float, float], ...]  # (variable, nominal SI, adjusted SI); empty: none balances


@dataclass(frozen=True)
class PartsReport:
    search: SearchResult
    chosen: dict[str, int]  # slot -> catalogue row (empty when nothing fits and no nearest part)
    springs: tuple[SpringUse, ...]
    bill: tuple[BillLine, ...]
    tolerance: ToleranceBand | None
    corners: tuple[Corner, ...]
    #: every spring in every checked scenario (a payload range: every payload of its schedule)
    by_scenario: tuple[SpringUse, ...] = ()

    @property
    def fits(self) -> bool:
        return self.search.choice is not None and all(s.fits for s in self.springs)

    def first_misfit(self) -> SpringUse | None:
        """The first spring use (per scenario when known) outside its part's limits."""
        return next((u for u in self.by_scenario or self.springs if not u.fits), None)
