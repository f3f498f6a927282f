"""A balancing problem: the mechanism, what may be added, what must hold, what to minimise.

Variables, parameters and scenarios are first-class named objects. A *scenario* is a
working condition the one shared design must balance (its own gravity vector, its own
parameter values); a variable marked ``adjustable`` takes its own value in each scenario
(a counterweight lever reset for each payload), every other variable is shared.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

from .constraints import Constraint
from .elements import CounterMass, ZeroFreeLengthSpring
from .expr import Expr
from .mechanism import Body, Coordinate, Frame, Subsystem
from .substitution import Substitution
from .tilt import Tilt
from .payload import MIN_ADDED, Payload
from .parts import SelectionSettings, SpringSlot
from .units import DisplayUnit

if TYPE_CHECKING:  # annotations only: a problem without loops or [robust] never needs them (pickle imports them for one with)
    from .loops import Loop
    from .robust import RobustSpec
    from .synthesis import SynthesisSpec


@dataclass(frozen=True)
class Parameter:
    """A fixed value. Either a literal (``value``) or an expression of other parameters."""

    name: str
    unit: DisplayUnit
    value: float | None = None  # SI, for literals
    expr: Expr | None = None  # for derived parameters
    description: str = ""

    @property
    def is_base(self) -> bool:
        return self.expr is None


#: A value counts as sitting on a bound when it is within BOUND_TOLERANCE × (upper − lower)
#: of it. The designer moves such values exactly onto the bound, and reports use the same
#: rule, so "at a bound" means one thing everywhere. It is relative to the span, not to
#: the bounds' size: 0.05 kg in [0, 50 t] is not at its lower bound.
BOUND_TOLERANCE = 1e-7


def bound_side(value: float, lower: float, upper: float, tolerance: float = BOUND_TOLERANCE) -> str:
    """'lower', 'upper' or '': which bound ``value`` sits on (see :data:`BOUND_TOLERANCE`)."""
    if not upper > lower:
        return ""
    band = tolerance * (upper - lower)
    if value - lower <= band:
        return "lower"
    if upper - value <= band:
        return "upper"
    return ""


@dataclass(frozen=True)
class Variable:
    """A design variable with bounds and initial guess (SI)."""

    name: str
    lower: float
    upper: float
    initial: float
    unit: DisplayUnit
    adjustable: bool = False
    description: str = ""
    #: payload problems: the setting at the nominal payload (None: chosen by the designer)
    nominal: float | None = None
    #: payload problems: the largest distance from ``nominal`` the adjustment may travel
    travel: float | None = None

    def adjusted_bounds(self) -> tuple[float, float]:
        """Bounds of the adjustment at any payload: the bounds, narrowed by the travel."""
        lo, hi = self.lower, self.upper
        if self.nominal is not None and self.travel is not None:
            lo, hi = max(lo, self.nominal - self.travel), min(hi, self.nominal + self.travel)
        return lo, hi

    def bound_side(self, value: float) -> str:
        """'lower', 'upper' or '': which bound ``value`` (SI) sits on."""
        return bound_side(value, self.lower, self.upper)


@dataclass(frozen=True)
class Gravity:
    """Gravity: its acceleration and its unit direction."""

    acceleration: float  # m/s^2
    direction: tuple[float, float, float]  # unit vector

    @property
    def vector(self) -> tuple[float, float, float]:
        x, y, z = self.direction
        return (self.acceleration * x, self.acceleration * y, self.acceleration * z)


@dataclass(frozen=True)
class Scenario:
    """A working condition: gravity and base-parameter values (SI) for this scenario."""

    name: str
    gravity: Gravity
    parameters: Mapping[str, float]
    description: str = ""
    #: adjustable variables take one value per *setting*; scenarios that name the same
    #: setting share it (the working modes at one payload). None: the scenario's own.
    setting: str | None = None
    #: problems with a tilting base: the tilt angles (rad) of this scenario's gravity, one per
    #: :class:`Tilt` of the problem, and the gravity of the untilted base (its working mode's)
    tilt: tuple[float, ...] = ()
    upright: Gravity | None = None


@dataclass(frozen=True)
class Objective:
    """minimise mass_weight * added_mass + inertia_weight * added_inertia
    + stiffness_weight * added_stiffness (in kg).

    added_mass = Σ M_j, added_inertia = Σ M_j d_j² over counter-masses, added_stiffness
    = Σ k_s over springs; with several scenarios each is averaged over scenarios.
    """

    mass_weight: float = 1.0
    inertia_weight: float = 0.0  # 1/m^2
    stiffness_weight: float = 0.0  # kg per N/m (s^2 in SI)
    goal: str = MIN_ADDED  # or MAX_PAYLOAD_RANGE (counterpoise.model.payload)


@dataclass(frozen=True)
class ReportQuantity:
    """A quantity the report evaluates at the design (``[report.<name>]``, and substituted masses)."""

    name: str
    expr: Expr
    unit: DisplayUnit
    description: str = ""


@dataclass(frozen=True)
class Settings:
    """Numerical settings (all have defaults; the file's ``[settings]`` may change them)."""

    verify_samples: int = 10_000  # random configurations per (subsystem, scenario)
    verify_tolerance: float = 1e-8  # largest residual_ratio accepted as balanced
    seed: int = 20190101  # random sampling is reproducible
    max_iterations: int = 500
    schedule_points: int = 51  # payload problems: at least this many schedule rows
    #: the springs are ideal (a paper's idealised design): no realisation limits, and the
    #: status refers to the ideal model (the as-built figure is reported beside it)
    ideal_springs: bool = False
    #: a minimax design whose worst residual ratio exceeds this is "not balanced"
    minimax_tolerance: float = 0.05


@dataclass(frozen=True)
class Problem:
    """A resolved problem: the mechanism, its elements, parameters and settings, in SI.

    (A docstring of its own also spares :mod:`dataclasses` computing one from the
    signature of ``__init__`` at import.)
    """

    name: str
    title: str
    source: str
    description: str
    path: str
    parameters: tuple[Parameter, ...]
    variables: tuple[Variable, ...]
    subsystems: tuple[Subsystem, ...]
    coordinates: tuple[Coordinate, ...]
    frames: tuple[Frame, ...]  # parents before children
    bodies: tuple[Body, ...]
    counter_masses: tuple[CounterMass, ...]
    springs: tuple[ZeroFreeLengthSpring, ...]
    scenarios: tuple[Scenario, ...]
    objective: Objective
    report: tuple[ReportQuantity, ...]
    settings: Settings = field(default_factory=Settings)
    substitutions: tuple[Substitution, ...] = ()  # bodies replaced by point masses (already in ``bodies``)
    payloads: tuple[Payload, ...] = ()
    slots: tuple[SpringSlot, ...] = ()  # catalogue slots (their names are base parameters: the rates)
    selection: SelectionSettings = field(default_factory=SelectionSettings)
    loops: tuple[Loop, ...] = ()  # closures of closed chains (counterpoise.model.loops)
    #: design constraints: the file's [constraints] and the springs' force limits (model.constraints)
    constraints: tuple[Constraint, ...] = ()
    #: a tilting base: the balance must hold for every tilt in these ranges ([gravity] tilt);
    #: each scenario then stands for one node of the tilt grid (:func:`~.tilt.tilt_nodes`)
    tilts: tuple[Tilt, ...] = ()
    robust: RobustSpec | None = None  # [robust]: tolerances, robust design, tuning (counterpoise.robust)
    #: [synthesis]: the elements a balancer may be chosen from (counterpoise.synthesis); `solve` ignores it
    synthesis: SynthesisSpec | None = None

    @cached_property
    def frame(self) -> Mapping[str, Frame]:
        return {f.name: f for f in self.frames}

    @cached_property
    def variable(self) -> Mapping[str, Variable]:
        return {v.name: v for v in self.variables}

    @cached_property
    def coordinate(self) -> Mapping[str, Coordinate]:
        return {c.name: c for c in self.coordinates}

    @cached_property
    def base_parameters(self) -> tuple[Parameter, ...]:
        return tuple(p for p in self.parameters if p.is_base)

    def setting(self, scenario: str) -> str:
        """The setting (adjustable-variable slot) that ``scenario`` uses."""
        for s in self.scenarios:
            if s.name == scenario:
                return s.setting or s.name
        raise KeyError(scenario)

    def subsystem_coordinates(self, subsystem: str) -> tuple[Coordinate, ...]:
        return tuple(c for c in self.coordinates if c.subsystem == subsystem)

    def subsystem_loops(self, subsystem: str) -> tuple[Loop, ...]:
        """The loops closed by ``subsystem``'s coordinates (empty: an open chain)."""
        return tuple(loop for loop in self.loops if loop.subsystem == subsystem)
