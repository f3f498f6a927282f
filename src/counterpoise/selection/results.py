"""What a part search returns: the choice, per-slot counts, near misses and the evidence."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..catalogue.limits import LIMIT_TEXT
from ..formulation.layout import Slot

#: objectives within this relative amount count as tied (the preference then decides)
TIE = 1e-9


@dataclass(frozen=True)
class NearMiss:
    """A part that does not fit, and why (for the report when none fits)."""

    slot: str
    part_number: str
    limit: str  # one of catalogue.limits.LIMITS, or 'rate'
    spring: str
    violation: float  # relative amount by which the limit is exceeded
    rates: tuple[tuple[str, float], ...] = ()  # slot rates of its design (when it was solved)

    def text(self) -> str:
        if self.limit == "rate":
            return f"{self.part_number} (slot {self.slot}): no balanced design within the bounds uses its rate ({100 * self.violation:.3g} % outside the balanceable range)"
        return f"{self.part_number} (slot {self.slot}, spring {self.spring}): {LIMIT_TEXT[self.limit]} ({100 * self.violation:.3g} % beyond)"


@dataclass
class SlotCount:
    """How a slot's parts fared."""

    slot: str
    parts: int
    window: tuple[float, float]  # balanceable rate range (N/m)
    pruned: int = 0  # outside the window: pruned before any per-part solve
    rates_solved: int = 0  # distinct rates whose design was solved
    failed_limits: int = 0  # solved, but a limit does not hold
    fitting: int = 0
    failed_by: dict[str, int] = field(default_factory=dict)  # limit -> parts failing it (and no other design fits them)


@dataclass
class Choice:
    parts: dict[str, int]  # slot -> row of its catalogue
    rates: dict[str, float]
    objective: float
    price: float
    robust: float = math.nan  # worst-case residual ratio over the tolerance band
    #: the design found with these parts (directly attached slots: a start for the final solve)
    values: dict[Slot, float] | None = None


@dataclass
class SearchResult:
    choice: Choice | None
    counts: list[SlotCount]
    groups: list[tuple[str, ...]]
    methods: list[str]
    nearest: list[NearMiss]
    solves: int
    seconds: float
    message: str = ""
    candidates: list[Choice] = field(default_factory=list)  # every fitting combination found, best first
    #: a lower bound on the best worst-case residual ratio reachable with the catalogues (NaN: none)
    lower_bound_ratio: float = math.nan
    #: lines of evidence of the search (screening, pruning per limit, bound), for status.txt
    evidence: tuple[str, ...] = ()

    def text(self) -> str:
        """The search's evidence, one line each (empty when there is none)."""
        return "\n".join(self.evidence)
