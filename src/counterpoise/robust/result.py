"""What the robust layer found of a design: its :class:`RobustReport` (an extra of the
:class:`~counterpoise.designer.solution.Solution`, ``solution.extra(RobustReport)``), what
``tolerance.csv``, ``tuning.csv`` and ``tuning_corners.csv`` are written from.

The records only: nothing of the counterpart (cvxpy, the minimax NLP) is imported here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

#: how the worst case is labelled with a directly attached spring (docs/robust.md#direct-springs)
SAMPLED_MINIMAX = "a sampled minimax over the box's corners, not exact"
#: how the worst case is labelled on a closed loop (docs/robust.md#robust-loops): exact at each sampled
#: configuration of the loop's manifold, the manifold itself sampled
ON_MANIFOLD = "exact at the sampled configurations of the closed loop's manifold"

if TYPE_CHECKING:
    from .direct import LengthMargin
    from .law import Check, Law
    from .limits import Envelope as LimitEnvelope
    from .limits import Margin, PulleySpring
    from .perturb import Deviation


@dataclass(frozen=True)
class Corner:
    """One tolerance corner: its deviations, the tuning that re-balances it, residual ratios."""

    name: str
    signs: tuple[int, ...]
    deviation: str
    before: float  # worst residual ratio at this corner with the factory setting
    after: float  # after tuning (dense verification)
    settings: tuple[tuple[str, float], ...]  # (tune variable, SI value); a payload range's adjustments as "x@<setting>"
    #: a corner that cannot be re-balanced: the scenario (payload sample) where the residual stays
    scenario: str = ""


@dataclass(frozen=True)
class RobustReport:
    """What ``robust.csv``, ``tolerance.csv`` and ``tuning.csv`` are written from."""

    mode: str
    shape: str
    deviations: tuple[Deviation, ...]
    #: per design ("nominal", "robust"): {kind or "all": worst-case ratio}, "residual": nominal ratio
    bands: Mapping[str, Mapping[str, float]]
    added_mass: Mapping[str, float]  # kg, per design
    objective: Mapping[str, float]  # kg, per design
    lp_ratio: float = float("nan")  # the worst case on the LP's rows
    lp_seconds: float = 0.0
    solver: str = ""  # of the counterpart: "cvxpy/Clarabel" (LP, SOCP) or "IPOPT" (minimax NLP)
    corners: tuple[Corner, ...] = ()
    tuning_range: Mapping[str, tuple[float, float]] = field(default_factory=dict)  # SI
    tuning_status: str = ""  # "" (no tune), "balanced" or the failure
    #: how the bands are obtained: "exact" over the box, else what makes them a bound or first order
    exactness: str = "exact"
    #: minimise mode: the file's objective per design (``objective`` is it + weight × band)
    base_objective: Mapping[str, float] = field(default_factory=dict)
    weight: float = 0.0  # kg per unit of worst-case ratio (minimise)
    #: per free-stiffness pulley spring: what it must serve over every tuned corner (robust/limits.py)
    envelope: "Mapping[str, LimitEnvelope]" = field(default_factory=dict)
    #: per such spring: the spring as designed for the envelope (its F0, L0, allowable load, cable)
    springs: "Mapping[str, PulleySpring]" = field(default_factory=dict)
    #: per tuned corner: each spring's margins to its limits
    margins: "Mapping[str, tuple[Margin, ...]]" = field(default_factory=dict)
    #: the tuning law and its check at random as-built machines (robust/law.py)
    law: "Law | None" = None
    law_check: "Check | None" = None
    #: per design: the largest residual ratio at ``samples`` random machines inside the box (the
    #: check beside the corners with a directly attached spring; empty elsewhere)
    sampled: Mapping[str, float] = field(default_factory=dict)
    samples: int = 0
    #: per design: the corner (and configuration) where the worst case over the box is
    worst_corner: Mapping[str, str] = field(default_factory=dict)
    #: directly attached springs: each length limit's least margin over the corners (robust/direct.py)
    lengths: "tuple[LengthMargin, ...]" = ()
    #: catalogue parts: per spring, the rate tolerance its chosen part's corners use and where it comes from
    part_tolerances: tuple[str, ...] = ()

    @property
    def tuned_residual(self) -> float:
        return max((c.after for c in self.corners), default=float("nan"))
