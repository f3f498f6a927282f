"""Small mechanisms built in code for the tests (no paper numbers here).

They use the project's Python API (:class:`counterpoise.ProblemBuilder`), the same
validation as a problem file. Tests about the file format itself write problem-file text:
they build it here (:func:`toml_head`, :func:`one_link_toml`, :func:`counter_mass_toml`,
:func:`pendulum_toml`, :func:`slot_pendulum_toml`) and write out only the tables that are
theirs, so that one mechanism is not copied from test file to test file.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from counterpoise import ProblemBuilder, rotate, translate

G = 9.81


@dataclass
class Link:
    """A planar link: length to the next joint, a body on it, a counter-mass behind its joint."""

    length: float  # m
    mass: float  # kg, given body
    com: tuple[float, float]  # m, body position in the link frame
    arm: float  # m, counter-mass distance behind the joint (fixed)
    free_offset: bool = False  # counter-mass may also move across the link (y variable)


@dataclass
class Chain:
    links: list[Link]
    base_angle: float = 0.0  # deg, fixed rotation of the base (turns the chain w.r.t. gravity)
    spring_on_first: float | None = None  # attachment distance f (m) of a ZFL spring on link 1
    ranges: list[tuple[float, float]] = field(default_factory=list)  # deg per joint
    inertia_weight: float = 0.0
    offset_bound: float = 5.0  # m, bound on the counter-masses' y offsets
    #: the spring is ideal (the engine's exactness on the ideal model; tests/test_realisation.py
    #: builds chains of real springs): its ends meet where link 1 points up
    ideal: bool = True
    #: the spring's anchor above the base pivot, as a multiple of its attachment distance f
    #: (1: the ideal textbook spring, whose ends meet)
    anchor_ratio: float = 1.0

    def required_masses(self) -> list[float]:
        """Counter-mass of each link that moves its subtree's centre of mass onto its joint
        (no spring), from the tip inwards: M_i arm_i = m_i com_x,i + W_{i+1} L_i, where
        W_{i+1} is everything carried beyond joint i+1 (its counter-masses included)."""
        out = [0.0] * len(self.links)
        carried = 0.0
        for i in range(len(self.links) - 1, -1, -1):
            link = self.links[i]
            beyond = carried if i + 1 < len(self.links) else 0.0
            out[i] = (link.mass * link.com[0] + beyond * link.length) / link.arm
            carried = beyond + link.mass + out[i]
        return out

    def mass_bounds(self) -> list[float]:
        """Upper bounds that always leave room: four times the required mass, at least 1 kg."""
        return [max(1.0, 4.0 * m) for m in self.required_masses()]

    def builder(self) -> ProblemBuilder:
        b = ProblemBuilder("chain", gravity=f"{G} m/s^2", direction=(0, -1, 0))
        coords = {}
        for i in range(len(self.links)):
            lo, hi = self.ranges[i] if i < len(self.ranges) else (-180.0, 180.0)
            coords[f"q{i}"] = (f"{lo} deg", f"{hi} deg")
        b.subsystem("arm", **coords)
        b.frame("base", rotate("z", f"{round(self.base_angle, 3)}*pi/180"))
        parent = "base"
        for i in range(len(self.links)):
            steps = [rotate("z", f"q{i}")] if i == 0 else [translate(f"{self.links[i - 1].length} m"), rotate("z", f"q{i}")]
            b.frame(f"l{i}", *steps, parent=parent)
            parent = f"l{i}"
        for i, (link, upper) in enumerate(zip(self.links, self.mass_bounds())):
            b.body(f"b{i}", frame=f"l{i}", mass=f"{link.mass} kg", com=(f"{link.com[0]} m", f"{link.com[1]} m", 0))
            b.variable(f"M{i}", "0 kg", f"{upper} kg", initial=f"{min(1.0, upper / 2)} kg")
            y = 0
            if link.free_offset:
                b.variable(f"y{i}", f"-{self.offset_bound} m", f"{self.offset_bound} m", initial="0 m")
                y = f"y{i}"
            b.counter_mass(f"c{i}", frame=f"l{i}", mass=f"M{i}", position=(f"-{link.arm} m", y, 0))
        if self.spring_on_first is not None:
            f = self.spring_on_first
            b.variable("k", "0 N/m", "1e7 N/m", initial="100 N/m")
            # ZFL spring from a point above the base pivot (in the base frame) to link 1
            b.spring("s", "k", from_=("base", (0, f"{f * self.anchor_ratio} m", 0)), to=("l0", (f"{f} m", 0, 0)))
            if self.ideal:
                b.settings(ideal_springs=True)
        b.objective(mass_weight=1, inertia_weight=f"{self.inertia_weight} 1/m^2")
        return b

    def problem(self):
        return self.builder().build("chain.toml")


def pendulum(m: float, r: float, b_range: tuple[float, float], w: float, mass_upper: float = 100.0) -> ProblemBuilder:
    """One link with a point mass m at r and a counter-mass M at b (both M and b free)."""
    lo, hi = b_range
    b = ProblemBuilder("pendulum", gravity=f"{G} m/s^2", direction=(0, -1, 0))
    b.parameter("m", f"{m} kg").parameter("r", f"{r} m")
    b.subsystem("arm", q=("-180 deg", "180 deg"))
    b.frame("link", rotate("z", "q"))
    b.body("tip", frame="link", mass="m", com=("r", 0, 0))
    b.variable("M", "0 kg", f"{mass_upper} kg").variable("b", f"{lo} m", f"{hi} m")
    b.counter_mass("cm", frame="link", mass="M", position=("-b", 0, 0))
    return b.objective(mass_weight=1, inertia_weight=f"{w} 1/m^2")


def toml_head(name: str, parameters: str) -> str:
    """The first tables of every test problem file: [problem] ``name``, [gravity] 9.81 m/s²
    along −y, and [parameters] with the TOML lines ``parameters``."""
    return f"""
[problem]
name = "{name}"
[gravity]
acceleration = "{G} m/s^2"
direction = [0, -1, 0]
[parameters]
{parameters.strip()}
"""


def one_link_toml(
    name: str,
    parameters: str,
    rest: str,
    *,
    coordinate: str = "q",
    joint_range: tuple[str, str] = ("-180 deg", "180 deg"),
    frame: str = "link",
    body: str = "tip",
    mass: str = "m",
    com: str = '["r", 0, 0]',
    payload: tuple[str, str] | None = None,
) -> str:
    """Problem-file text of the tests' one-link mechanism: ``frame`` turns about z at the
    ground by ``coordinate`` (subsystem ``arm``, in ``joint_range``) and carries ``body``
    (``mass`` at ``com``), under g = 9.81 m/s² along −y. ``parameters``: the lines of
    [parameters]; ``payload``: a payload range [payloads.tool] at ``com``; ``rest``: the
    other tables (variables, counter-masses, springs, scenarios, objective) as TOML text."""
    text = toml_head(name, parameters) + f"""[subsystems.arm]
coordinates.{coordinate} = {{ range = ["{joint_range[0]}", "{joint_range[1]}"] }}
[frames.{frame}]
transforms = [{{ rotate = "z", angle = "{coordinate}" }}]
[bodies.{body}]
frame = "{frame}"
mass = "{mass}"
com = {com}
"""
    if payload is not None:
        text += f'[payloads.tool]\nframe = "{frame}"\nposition = {com}\nrange = ["{payload[0]}", "{payload[1]}"]\n'
    return text + rest.lstrip("\n")


def counter_mass_toml(position: str, name: str = "cm", frame: str = "link", mass: str = "M") -> str:
    """A [counter_masses.<name>] table: ``mass`` at ``position`` (a TOML array) in ``frame``."""
    return f'[counter_masses.{name}]\nframe = "{frame}"\nmass = "{mass}"\nposition = {position}\n'


def payload_pendulum_toml(
    name: str, lever: str, lower: str, upper: str, position: str, description: str = "", mass_upper: str = "20 kg", r: str = "0.3 m"
) -> str:
    """m = 1 kg at ``r`` on one link with a payload range of 0 to 1 kg at the same point, and a
    counter-mass M (0 to ``mass_upper``) at ``position`` behind the joint, whose lever
    variable ``lever`` (in [``lower``, ``upper``]) is set per payload (adjustable)."""
    described = f'description = "{description}"\n' if description else ""
    rest = f"""
[variables.M]
lower = "0 kg"
upper = "{mass_upper}"
[variables.{lever}]
{described}lower = "{lower}"
upper = "{upper}"
adjustable = true
""" + counter_mass_toml(position)
    return one_link_toml(name, f'm = "1 kg"\nr = "{r}"', rest, payload=("0 kg", "1 kg"))


def slot_pendulum_toml(
    name: str,
    mass: float,
    r: float = 0.2,
    b: float = 0.1,
    catalogue: str = "parts.csv",
    rate_tolerance: str = "10 %",
    tension_tolerance: str = "20 %",
    h_upper: str = "0.3 m",
    joint_range: tuple[float, float] = (-60.0, 60.0),
) -> str:
    """A pendulum (mass ``mass`` kg at ``r`` m on a link at angle theta) with a catalogue
    spring (slot ``s`` of catalogue ``catalogue``) from (0, h) on the ground to ``b`` m
    along the link, h free in [0.02 m, ``h_upper``]: V = m g r sin(theta) − k b h sin(theta),
    balanced when k b h = m g r."""
    rest = f"""
[catalogues.parts]
file = "{catalogue}"
[slots.s]
catalogue = "parts"
rate_tolerance = "{rate_tolerance}"
initial_tension_tolerance = "{tension_tolerance}"
[variables.h]
lower = "0.02 m"
upper = "{h_upper}"
initial = "0.15 m"
[springs.s]
slot = "s"
from = {{ frame = "ground", point = [0, "h", 0] }}
to = {{ frame = "link", point = ["b", 0, 0] }}
"""
    lo, hi = joint_range
    parameters = f'm = "{mass} kg"\nr = "{r} m"\nb = "{b} m"'
    return one_link_toml(name, parameters, rest, coordinate="theta", joint_range=(f"{lo} deg", f"{hi} deg"), body="link")


def pendulum_toml(m: float, r: float, b_range: tuple[float, float] | float, w: float, mass_upper: float = 100.0, name: str = "pendulum") -> str:
    """The same pendulum as :func:`pendulum`, as problem-file text, for tests of the file
    format itself. A number for ``b_range``: the lever b is that fixed parameter (m), not a
    variable (the design is then linear in M: an LP)."""
    if isinstance(b_range, tuple):
        parameters, lever = f'm = "{m} kg"\nr = "{r} m"', f'[variables.b]\nlower = "{b_range[0]} m"\nupper = "{b_range[1]} m"\n'
    else:
        parameters, lever = f'm = "{m} kg"\nr = "{r} m"\nb = "{b_range} m"', ""
    rest = f"""
[variables.M]
lower = "0 kg"
upper = "{mass_upper} kg"
{lever}{counter_mass_toml('["-b", 0, 0]')}[objective]
mass_weight = 1
inertia_weight = "{w} 1/m^2"
"""
    return one_link_toml(name, parameters, rest)


#: A counter-mass whose x position scales with its own mass: its x-moment is quadratic in M,
#: its y-moment linear, so two independent balance conditions for one variable (the
#: over-determined path of the designer: balanced only at M = M0).
OVERDETERMINED_TOML = one_link_toml(
    "overdetermined",
    'M0 = "1 kg"\nd0 = "0.1 m"',
    '[variables.M]\nlower = "0.2 kg"\nupper = "3 kg"\n' + counter_mass_toml('["-d0 * M / M0", "-d0", 0]'),
    mass="1 kg",
    com='["0.1 m", "0.1 m", 0]',
)
