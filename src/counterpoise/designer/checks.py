"""How balanced a design is: residuals set against the forces gravity puts on the mechanism.

Definitions (the reports and messages use these and nothing else):

- A coordinate is *revolute* (an angle: residual in N·m) or *prismatic* (a length:
  residual in N). Figures of the two kinds are never compared with each other.
- ``max_residual`` of a coordinate: the largest |∂V/∂q| of the balanced design over the
  checked configurations of its (subsystem, scenario).
- ``max_gravity_torque`` of a coordinate: the same for the *unbalanced* mechanism (the given
  bodies alone, no counter-masses or springs), taken over the whole coordinate *box*, not
  only the samples: the best sample is refined by projected Newton steps on exact
  derivatives (:class:`~.residuals.BoxMaximum`) to the box maximum (relative accuracy
  ``BOX_MAXIMUM_TOLERANCE``; a maximum inside the box is typically 0.2 % above the best of
  10,000 samples). This is done for every coordinate that may set the reference (its
  sampled value at least ``REFERENCE_CANDIDATE`` = 90 % of the largest of its kind); the
  others keep their sampled maximum, a lower bound.
- The *reference* of a kind: the largest ``max_gravity_torque`` over every coordinate of
  that kind in the problem (every subsystem and scenario). When gravity loads no
  coordinate of that kind (a yaw axis parallel to gravity, a horizontal mechanism), the
  reference is the largest generalized force the balancers alone produce there instead,
  or the ``energy_scale`` (the largest Σ |energy of each element|, per radian or per
  metre) when that is larger: a spring whose length cannot change produces only rounding
  noise, and noise measured against noise would give a ratio near 1. Gravity "loads
  nothing" when its largest torque is below NOISE_TOLERANCE × that energy scale.
- ``residual_ratio`` of a coordinate: its ``max_residual`` divided by the reference of its
  kind, and 0 when both are 0. It is finite whenever the residual can be evaluated.
- The design's ``residual_ratio``: the largest coordinate ratio. It is balanced when that
  is at most ``settings.verify_tolerance``.

These records are the data a :class:`~counterpoise.designer.solution.Solution` carries as its
``verification``; the verify layer computes them (:func:`counterpoise.verify.check.check`: the
dense check, or the exact certificate of :mod:`counterpoise.verify.certificate`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

REVOLUTE = "revolute"
PRISMATIC = "prismatic"
UNIT = {REVOLUTE: "N·m", PRISMATIC: "N"}
#: Relative size of rounding noise: a gravity torque below NOISE_TOLERANCE × energy_scale is zero.
NOISE_TOLERANCE = 1e-12
FORCE_NAME = {REVOLUTE: "gravity torque", PRISMATIC: "gravity force"}


@dataclass(frozen=True)
class CoordinateCheck:
    """Verification of one coordinate's balance condition in one (subsystem, scenario)."""

    subsystem: str
    scenario: str
    coordinate: str
    kind: str  # REVOLUTE or PRISMATIC
    max_residual: float  # N·m (N for a slider); NaN when it cannot be evaluated
    max_gravity_torque: float  # of the unbalanced mechanism
    max_balancer_force: float  # of the balancers alone (used when gravity loads nothing)
    configurations: int
    worst_configuration: tuple[float, ...]  # coordinates of the subsystem, SI
    energy_scale: float = 0.0  # largest Σ |energy of each element| of the (subsystem, scenario), J
    #: a tilting base: the tilt angles (rad) of the worst configuration (one per tilt)
    worst_tilt: tuple[float, ...] = ()

    @property
    def unit(self) -> str:
        return UNIT[self.kind]


@dataclass(frozen=True)
class Verification:
    checks: tuple[CoordinateCheck, ...]
    tolerance: float

    def reference(self, kind: str) -> float:
        """The force of ``kind`` that residuals of that kind are measured against."""
        mine = [c for c in self.checks if c.kind == kind]
        gravity = max((c.max_gravity_torque for c in mine if np.isfinite(c.max_gravity_torque)), default=0.0)
        scale = max((c.energy_scale for c in mine if np.isfinite(c.energy_scale)), default=0.0)
        if gravity > 0 and gravity > NOISE_TOLERANCE * scale:
            return gravity
        balancers = max((c.max_balancer_force for c in mine if np.isfinite(c.max_balancer_force)), default=0.0)
        return max(balancers, scale)

    def ratio(self, check: CoordinateCheck) -> float:
        """``residual_ratio`` of one coordinate (see the module's definitions)."""
        if np.isnan(check.max_residual):
            return float("nan")
        if check.max_residual == 0:
            return 0.0
        return check.max_residual / self.reference(check.kind)

    def _kind_max(self, kind: str, attribute: str) -> float | None:
        values = [getattr(c, attribute) for c in self.checks if c.kind == kind]
        return float(np.max(values)) if values else None  # NaN if any is NaN

    def max_residual(self, kind: str = REVOLUTE) -> float | None:
        """Largest residual of ``kind`` (None when the problem has no such coordinate)."""
        return self._kind_max(kind, "max_residual")

    def max_gravity_torque(self, kind: str = REVOLUTE) -> float | None:
        return self._kind_max(kind, "max_gravity_torque")

    @cached_property
    def residual_ratio(self) -> float:
        """The largest coordinate ratio (NaN if any residual cannot be evaluated); computed
        once (the checks are a tuple of frozen records: a study point asks for it several times)."""
        ratios = [self.ratio(c) for c in self.checks]
        return float(np.max(ratios)) if ratios else 0.0

    @property
    def configurations(self) -> int:
        """Configurations checked, summed over (subsystem, scenario) pairs."""
        seen: dict[tuple[str, str], int] = {}
        for c in self.checks:
            seen[(c.subsystem, c.scenario)] = c.configurations
        return sum(seen.values())

    @property
    def balanced(self) -> bool:
        return bool(self.residual_ratio <= self.tolerance)  # NaN is not balanced

    def worst(self) -> CoordinateCheck | None:
        """The check with the largest ratio (a NaN one first)."""
        if not self.checks:
            return None
        return max(self.checks, key=lambda c: np.inf if np.isnan(self.ratio(c)) else self.ratio(c))

    def unmet(self) -> list[CoordinateCheck]:
        """Conditions that fail, worst first."""
        bad = [c for c in self.checks if not self.ratio(c) <= self.tolerance]  # NaN is unmet
        return sorted(bad, key=lambda c: -np.inf if np.isnan(self.ratio(c)) else -self.ratio(c))
