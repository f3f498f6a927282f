"""Problem-file text for small mechanisms built in tests (no paper numbers here)."""

from __future__ import annotations

from dataclasses import dataclass, field


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

    def toml(self) -> str:
        n = len(self.links)
        lines = [
            '[problem]\nname = "chain"\n',
            '[gravity]\nacceleration = "9.81 m/s^2"\ndirection = [0, -1, 0]\n',
            "[subsystems.arm]",
        ]
        for i in range(n):
            lo, hi = self.ranges[i] if i < len(self.ranges) else (-180.0, 180.0)
            lines.append(f'coordinates.q{i} = {{ range = ["{lo} deg", "{hi} deg"] }}')
        lines.append(f'\n[frames.base]\ntransforms = [{{ rotate = "z", angle = "{round(self.base_angle, 3)}*pi/180" }}]')
        parent = "base"
        for i, link in enumerate(self.links):
            if i == 0:
                t = f'[{{ rotate = "z", angle = "q{i}" }}]'
            else:
                t = f'[{{ translate = ["{self.links[i-1].length} m", 0, 0] }}, {{ rotate = "z", angle = "q{i}" }}]'
            lines.append(f'[frames.l{i}]\nparent = "{parent}"\ntransforms = {t}')
            parent = f"l{i}"
        for i, link in enumerate(self.links):
            lines.append(f'[bodies.b{i}]\nframe = "l{i}"\nmass = "{link.mass} kg"\ncom = ["{link.com[0]} m", "{link.com[1]} m", 0]')
            lines.append(f'[variables.M{i}]\nlower = "0 kg"\nupper = "1000 kg"\ninitial = "1 kg"')
            y = f'"y{i}"' if link.free_offset else "0"
            if link.free_offset:
                lines.append(f'[variables.y{i}]\nlower = "-5 m"\nupper = "5 m"\ninitial = "0 m"')
            lines.append(f'[counter_masses.c{i}]\nframe = "l{i}"\nmass = "M{i}"\nposition = ["-{link.arm} m", {y}, 0]')
        if self.spring_on_first is not None:
            f = self.spring_on_first
            lines.append('[variables.k]\nlower = "0 N/m"\nupper = "1e7 N/m"\ninitial = "100 N/m"')
            # ZFL spring from a point above the base pivot (in the base frame) to link 1
            lines.append(f'[springs.s]\nstiffness = "k"\nfrom = {{ frame = "base", point = [0, "{f} m", 0] }}\nto = {{ frame = "l0", point = ["{f} m", 0, 0] }}')
        lines.append(f'[objective]\nmass_weight = 1\ninertia_weight = "{self.inertia_weight} 1/m^2"')
        return "\n".join(lines) + "\n"


def pendulum(m: float, r: float, b_range: tuple[float, float], w: float) -> str:
    """One link with a point mass m at r and a counter-mass M at b (both M and b free)."""
    lo, hi = b_range
    return f"""
[problem]
name = "pendulum"
[gravity]
acceleration = "9.81 m/s^2"
direction = [0, -1, 0]
[parameters]
m = "{m} kg"
r = "{r} m"
[subsystems.arm]
coordinates.q = {{ range = ["-180 deg", "180 deg"] }}
[frames.link]
transforms = [{{ rotate = "z", angle = "q" }}]
[bodies.tip]
frame = "link"
mass = "m"
com = ["r", 0, 0]
[variables.M]
lower = "0 kg"
upper = "100 kg"
[variables.b]
lower = "{lo} m"
upper = "{hi} m"
[counter_masses.cm]
frame = "link"
mass = "M"
position = ["-b", 0, 0]
[objective]
mass_weight = 1
inertia_weight = "{w} 1/m^2"
"""
