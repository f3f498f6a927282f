"""The problem-file schema: what a TOML problem file may contain, checked by pydantic.

This layer only checks *shape* (known keys, required sections, types). Units, names,
expressions and the frame graph are checked when the loader resolves the file into a
:class:`counterpoise.problem.Problem`. Every table forbids unknown keys, so a typo such as
``uper = "1 kg"`` is an error, not a silently ignored line.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, Union

from pydantic import BaseModel, BeforeValidator, ConfigDict, Discriminator, Field, Tag


def _value(v: Any) -> Any:
    if isinstance(v, bool) or not isinstance(v, (str, int, float)):
        raise ValueError("expected a quantity such as '135 mm', a number or an expression")
    if isinstance(v, int):
        _float(v)
    if isinstance(v, float) and not math.isfinite(v):
        raise ValueError(f"value must be finite, got {v}")
    return v


def _float(v: int) -> float:
    """A TOML integer as a float; Python integers have no size limit, floats do."""
    try:
        return float(v)
    except OverflowError:
        raise ValueError(f"number too large ({len(str(abs(v)))} digits)") from None


def _finite_number(v: Any) -> Any:
    """A plain number (``mass_weight``, ``verify_tolerance``) must be finite; said before
    any range check, which would call NaN 'not greater than 0'."""
    if isinstance(v, bool):
        return v  # pydantic rejects it with its own message
    if isinstance(v, int):
        _float(v)
    elif isinstance(v, (str, float)):
        try:
            x = float(v)
        except ValueError:
            return v  # not a number at all: pydantic says so
        if not math.isfinite(x):
            raise ValueError(f"must be a finite number, got {v!r}")
    return v


FiniteFloat = Annotated[float, BeforeValidator(_finite_number)]


#: A quantity literal ("135 mm"), a number, or an expression ("r_a + b_b").
Value = Annotated[Union[str, int, float], BeforeValidator(_value)]
Vec3 = tuple[Value, Value, Value]
Name = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$")]


class _Table(BaseModel):
    #: ``defer_build``: a model's validator is built when it first validates, not when its
    #: class is defined. Only :class:`ProblemFile` validates, and building its schema once
    #: (the nested tables with it) costs a little less than building every table's schema
    #: at import (~10–20 ms per process); the validation is the same.
    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True, defer_build=True)


class ProblemMeta(_Table):
    #: it names the report folders (``<name>``, ``<name>-study`` and their temporary
    #: siblings): at most 128 characters, well within a file name's 255 bytes
    name: Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$", max_length=128)]
    title: str = ""
    source: str = ""
    description: str = ""


class GravitySpec(_Table):
    acceleration: Value
    direction: tuple[FiniteFloat, FiniteFloat, FiniteFloat]


class TiltSpec(_Table):
    """A continuous range of base tilts about one axis of the base (``[gravity] tilt``)."""

    axis: tuple[FiniteFloat, FiniteFloat, FiniteFloat]
    range: tuple[Value, Value]
    description: str = ""


class TiltingGravitySpec(GravitySpec):
    """The file's ``[gravity]``: a direction, and optionally tilts of the base it must hold for."""

    tilt: list[TiltSpec] = Field(default_factory=list)


class ParameterSpec(_Table):
    value: Value
    description: str = ""


ParameterEntry = Annotated[
    Union[Annotated[Value, Tag("value")], Annotated[ParameterSpec, Tag("table")]],
    Discriminator(lambda v: "table" if isinstance(v, (dict, ParameterSpec)) else "value"),
]


class CoordinateSpec(_Table):
    range: tuple[Value, Value] | None = None  # required unless dependent
    home: Value | None = None
    #: solved from the loop closures ([loops]); its home picks the assembly branch
    dependent: bool = False
    description: str = ""


class SubsystemSpec(_Table):
    description: str = ""
    coordinates: Annotated[dict[Name, CoordinateSpec], Field(min_length=1)]
    #: coupled coordinates: names for expressions of this subsystem's coordinates (a
    #: parallelogram's opposite link, a five-bar's passive joints), usable in frames
    coupled: dict[Name, Value] = Field(default_factory=dict)


class RotateSpec(_Table):
    rotate: Union[Literal["x", "y", "z"], Vec3]
    angle: Value


class TranslateSpec(_Table):
    translate: Vec3


class DHRow(_Table):
    """Modified (Craig) Denavit-Hartenberg: Rot_x(alpha) Trans_x(a) Rot_z(theta) Trans_z(d)."""

    a: Value
    alpha: Value
    d: Value
    theta: Value


class DHSpec(_Table):
    dh: DHRow


def _transform_tag(v: Any) -> str:
    for tag, spec in (("rotate", RotateSpec), ("dh", DHSpec)):
        if (isinstance(v, dict) and tag in v) or isinstance(v, spec):
            return tag
    return "translate"


TransformEntry = Annotated[
    Union[Annotated[RotateSpec, Tag("rotate")], Annotated[TranslateSpec, Tag("translate")], Annotated[DHSpec, Tag("dh")]],
    Discriminator(_transform_tag),
]


class FrameSpec(_Table):
    parent: str = "ground"
    transforms: tuple[TransformEntry, ...] = ()
    #: keep the orientation of this frame (a parallelogram's or belt's reference link):
    #: the origin follows ``parent`` and ``transforms``, the axes stay those of the named frame
    orientation: str | None = None
    description: str = ""


class BodySpec(_Table):
    frame: str
    mass: Value
    com: Vec3
    description: str = ""


class CounterMassSpec(_Table):
    frame: str
    mass: Value
    position: Vec3
    joint: str | None = None
    description: str = ""


class PointSpec(_Table):
    frame: str
    point: Vec3


class PulleySpec(_Table):
    """A pulley mount's pulley (docs/build.md#pulleys): radius, clearance, axis and wrap."""

    radius: Value | None = None  # a length; default 0 (a point pulley)
    clearance: Value | None = None  # a length; default PULLEY_CLEARANCE
    axis: Vec3 | None = None  # in the from frame; default [0, 0, 1]
    wrap: Literal["ccw", "cw"] = "ccw"
    pin: bool = False
    lead: Vec3 | None = None  # from frame: where the spring lies behind the pulley
    fixing: Vec3 | None = None  # to frame: where the cable's end is fixed on the pin
    description: str = ""


class SpringSpec(_Table):
    stiffness: Value | None = None  # or a slot: the rate of the catalogue part chosen for it
    slot: Name | None = None
    mount: Literal["pulley", "direct"] = "pulley"  # direct: a real spring through a cable
    free_length: Value | None = None  # direct mount only (from the part with a slot)
    initial_tension: Value | None = None
    max_length: Value | None = None  # direct: the part's limit; pulley, free stiffness: the designed spring's envelope
    cable: Value | None = None
    max_force: Value | None = None  # the spring's largest force (a limit of the design)
    pulley: PulleySpec | None = None  # mount = "pulley": its radius, clearance, axis, wrap
    slack_margin: Value | None = None  # the extension kept beyond the free length (a length)
    # free-stiffness springs: the designed helical spring (docs/springs.md)
    material: str | None = None  # a key of counterpoise/data/spring_materials.csv
    max_outer_diameter: Value | None = None
    max_body_length: Value | None = None
    rate_tolerance: Value | None = None  # of the spring maker's spec: 0.1 or "10 %"
    min_safety_factor: Annotated[FiniteFloat, Field(ge=1, le=100)] | None = None
    from_: PointSpec = Field(alias="from")
    to: PointSpec
    description: str = ""


class SubstitutionPointSpec(_Table):
    at: Vec3  # the point in the substituted body's frame
    frame: str  # the frame that receives the point mass
    point: Vec3  # the same point in that frame
    description: str = ""


class SubstitutionSpec(_Table):
    description: str = ""
    points: Annotated[dict[Name, SubstitutionPointSpec], Field(min_length=1)]


class LoopSpec(_Table):
    """A closed loop, opened at one joint: the two points that the joint keeps together
    (a revolute or prismatic joint: its axis in frame a's coordinates; a revolute joint may
    give the same axis in frame b's coordinates, ``axis_b``). See docs/loops.md."""

    joint: Literal["revolute", "spherical", "prismatic"]
    a: PointSpec
    b: PointSpec
    axis: Vec3 | None = None
    axis_b: Vec3 | None = None
    description: str = ""


class VariableSpec(_Table):
    lower: Value
    upper: Value
    initial: Value | None = None
    unit: str | None = None
    adjustable: bool = False
    nominal: Value | None = None
    travel: Value | None = None
    description: str = ""


class ObjectiveSpec(_Table):
    mass_weight: Annotated[FiniteFloat, Field(ge=0)] = 1.0
    inertia_weight: Value = 0
    stiffness_weight: Value = 0


#: ``objective = "max_payload_range"`` instead of an ``[objective]`` table
ObjectiveEntry = Annotated[
    Union[Annotated[ObjectiveSpec, Tag("table")], Annotated[Literal["max_payload_range"], Tag("goal")]],
    Discriminator(lambda v: "goal" if isinstance(v, str) else "table"),
]


class PayloadSpec(_Table):
    frame: str
    position: Vec3 = (0, 0, 0)
    range: tuple[Value, Value]
    nominal: Value | None = None
    description: str = ""


class ReportSpec(_Table):
    expression: str
    unit: str = ""
    description: str = ""


# -- constraints (engineer "constraints"; kept in one block) ---------------------------
class ConstraintSpec(_Table):
    """``lower ≤ expression ≤ upper`` on the design (see problems/README.md, docs/constraints.md)."""

    expression: str
    lower: Value | None = None
    upper: Value | None = None
    unit: str | None = None  # display unit of design.csv (default: the bounds' unit)
    description: str = ""


# -- end constraints -------------------------------------------------------------------


class ScenarioSpec(_Table):
    description: str = ""
    gravity: GravitySpec | None = None
    parameters: dict[str, Value] = Field(default_factory=dict)


class SettingsSpec(_Table):
    verify_samples: Annotated[int, Field(ge=100, le=10_000_000)] = 10_000
    verify_tolerance: Annotated[FiniteFloat, Field(gt=0, lt=1)] = 1e-8
    seed: Annotated[int, Field(ge=0, lt=2**63)] = 20190101
    max_iterations: Annotated[int, Field(ge=1, le=1_000_000)] = 500
    schedule_points: Annotated[int, Field(ge=50, le=100_000)] = 51
    #: the springs are ideal (a paper's idealised design): the status refers to the ideal model
    ideal_springs: bool = False
    #: a minimax design (real springs: directly attached, or behind a pulley of radius > 0)
    #: whose worst residual ratio exceeds this is "not balanced"
    minimax_tolerance: Annotated[FiniteFloat, Field(gt=0, lt=1)] = 0.05


class CatalogueSpec(_Table):
    """A spring catalogue (CSV) and how to read it (see docs/catalogues.md)."""

    file: str  # path relative to the problem file, or "shipped"
    columns: Union[str, dict[str, str]] = "counterpoise"  # a preset or field = "column"
    units: str | None = None  # "SI", "N-mm" or "inch" (default: the preset's)
    rate_tolerance: Value | None = None  # where the file has no tolerance column
    initial_tension_tolerance: Value | None = None
    description: str = ""


class CountSpec(_Table):
    """How many identical springs of the chosen part may work in parallel in a slot."""

    min: Annotated[int, Field(ge=1, le=10)] = 1
    max: Annotated[int, Field(ge=1, le=10)] = 1


class SlotSpec(_Table):
    """A place for one catalogue part; springs name it with ``slot = "<name>"``."""

    catalogue: str
    count: CountSpec | None = None  # n identical springs in parallel, n chosen with the part
    rate_tolerance: Value | None = None  # overrides the catalogue's
    initial_tension_tolerance: Value | None = None
    description: str = ""


class SelectionSpec(_Table):
    prefer: Literal["objective", "robust", "price"] = "objective"
    adjust: tuple[Name, ...] = ()
    max_enumeration: Annotated[int, Field(ge=1, le=1_000_000)] = 400
    limit_samples: Annotated[int, Field(ge=16, le=1_000_000)] = 512
    nearest: Annotated[int, Field(ge=1, le=100)] = 5


#: a tolerance: "10 %" (of the nominal value) or a quantity ("0.5 mm", "20 N/m")
ToleranceValue = Union[Value, dict[str, Value]]


class RobustSpec(_Table):
    """``[robust]``: tolerances of the built balancer and what the design does about them
    (docs/robust.md)."""

    mode: Literal["minimise", "limit", "none"] = "none"
    weight: Value | None = None  # minimise: kg per unit of worst-case residual ratio
    limit: Annotated[FiniteFloat, Field(gt=0, lt=1)] | None = None  # limit: the worst-case ratio allowed
    shape: Literal["box", "ellipsoid"] = "box"
    #: kind = value (every item of the kind) or kind = { item = value }
    tolerances: dict[str, ToleranceValue] = Field(default_factory=dict)
    tune: tuple[Name, ...] = ()
    #: the tuning law's trial turn per tune variable, and the screw pitch (length per turn)
    step: dict[str, Value] = Field(default_factory=dict)
    pitch: dict[str, Value] = Field(default_factory=dict)
    description: str = ""


class BoxSpec(_Table):
    """A box of a synthesis region: its lower and upper corners, in the frame."""

    lower: Vec3
    upper: Vec3


class RegionSpec(_Table):
    """Where a spring may be attached on a body, or a counter-mass placed
    (``[synthesis.regions.<frame>]``, ``[synthesis.sites.<name>]``): one of ``box``,
    ``segment`` and ``holes``; ``points`` or ``spacing`` sets the grid (docs/synthesis.md)."""

    box: BoxSpec | None = None
    segment: tuple[Vec3, Vec3] | None = None
    holes: tuple[Vec3, ...] | None = None
    points: Annotated[int, Field(ge=1, le=1000)] | None = None
    spacing: Value | None = None
    description: str = ""


class SiteSpec(RegionSpec):
    frame: str


class SynthesisFileSpec(_Table):
    """``[synthesis]``: the elements a balancer may be made of (docs/synthesis.md)."""

    #: "all": a candidate spring between every pair of bodies with a region; "none"; or the pairs
    springs: Union[Literal["all", "none"], tuple[tuple[Name, Name], ...]] = "all"
    regions: dict[Name, RegionSpec] = Field(default_factory=dict)
    sites: dict[Name, SiteSpec] = Field(default_factory=dict)
    min_rate: Value | None = None
    max_rate: Value | None = None
    min_mass: Value | None = None
    max_mass: Value | None = None
    spring_cost: Annotated[FiniteFloat, Field(gt=0, le=1e9)] = 1.0
    mass_cost: Annotated[FiniteFloat, Field(gt=0, le=1e9)] = 1.0
    points: Annotated[int, Field(ge=1, le=1000)] = 5
    same_rate: bool = False
    adjust: bool = False
    max_topologies: Annotated[int, Field(ge=1, le=1000)] = 20
    time_limit: Annotated[FiniteFloat, Field(gt=0, le=1e6)] = 120.0
    refine: bool = True
    description: str = ""


class RobotJointSpec(_Table):
    """A joint of a robot model that moves: it becomes a coordinate of the robot's subsystem."""

    range: tuple[Value, Value]
    home: Value | None = None
    description: str = ""


class RobotSpec(_Table):
    """A robot model (URDF or MJCF): every link a frame and a body (docs/robots.md)."""

    urdf: str | None = None  # path relative to the problem file, or absolute
    mjcf: str | None = None
    subsystem: Name = "robot"
    description: str = ""
    joints: dict[str, RobotJointSpec] = Field(default_factory=dict)
    locked: dict[str, Value] = Field(default_factory=dict)


class ProblemFile(_Table):
    problem: ProblemMeta
    gravity: TiltingGravitySpec
    parameters: dict[Name, ParameterEntry] = Field(default_factory=dict)
    #: at least one, or a [robot] (checked when resolving)
    subsystems: dict[Name, SubsystemSpec] = Field(default_factory=dict)
    robot: RobotSpec | None = None
    frames: dict[Name, FrameSpec] = Field(default_factory=dict)
    bodies: dict[Name, BodySpec] = Field(default_factory=dict)
    counter_masses: dict[Name, CounterMassSpec] = Field(default_factory=dict)
    springs: dict[Name, SpringSpec] = Field(default_factory=dict)
    substitutions: dict[Name, SubstitutionSpec] = Field(default_factory=dict)
    loops: dict[Name, LoopSpec] = Field(default_factory=dict)
    variables: dict[Name, VariableSpec] = Field(default_factory=dict)
    objective: ObjectiveEntry = Field(default_factory=ObjectiveSpec)
    report: dict[Name, ReportSpec] = Field(default_factory=dict)
    constraints: dict[Name, ConstraintSpec] = Field(default_factory=dict)
    scenarios: dict[Name, ScenarioSpec] = Field(default_factory=dict)
    payloads: dict[Name, PayloadSpec] = Field(default_factory=dict)
    settings: SettingsSpec = Field(default_factory=SettingsSpec)
    catalogues: dict[Name, CatalogueSpec] = Field(default_factory=dict)
    slots: dict[Name, SlotSpec] = Field(default_factory=dict)
    selection: SelectionSpec = Field(default_factory=SelectionSpec)
    robust: RobustSpec | None = None
    synthesis: SynthesisFileSpec | None = None
