"""``[synthesis]``: the superstructure a balancer is chosen from (docs/synthesis.md).

A problem file with a ``[synthesis]`` table says which balancing elements *may* be added:
zero-free-length springs between every pair of bodies that has an attachment region (the
ground, links, reference links), and counter-masses at sites on given links; each with a
cost, and rates and masses within bounds. :mod:`counterpoise.synthesis` chooses the
fewest (cheapest) of them that balance exactly. Everything here is SI and resolved: the
regions' points are numbers in their frame (they may be written with parameters, which
take the file's values).
"""

from __future__ import annotations

from dataclasses import dataclass

from .mechanism import GROUND

Vec = tuple[float, float, float]

#: region kinds: a box and a segment are convex (a point anywhere in them), holes a list of points
BOX, SEGMENT, HOLES = "box", "segment", "holes"


@dataclass(frozen=True)
class Region:
    """Where an attachment point (or a counter-mass) may be, in its frame: the points
    ``origin + Σ_i u_i axes[i]`` with every u_i in [0, 1] (a box: one axis per side of
    non-zero length; a segment: one axis), or one of ``holes``. ``points``: grid points per
    axis where a spring's end is taken on a grid (docs/synthesis.md)."""

    kind: str
    origin: Vec
    axes: tuple[Vec, ...]
    holes: tuple[Vec, ...] = ()
    points: tuple[int, ...] = ()
    key: str = ""  # the file key, for messages

    @property
    def convex(self) -> bool:
        return self.kind != HOLES

    def grid(self) -> tuple[Vec, ...]:
        """The grid points of the region (its holes for a list of holes), in its frame."""
        if self.kind == HOLES:
            return self.holes
        out: list[Vec] = [self.origin]
        for axis, n in zip(self.axes, self.points):
            steps = [i / (n - 1) for i in range(n)] if n > 1 else [0.5]
            out = [(p[0] + u * axis[0], p[1] + u * axis[1], p[2] + u * axis[2]) for p in out for u in steps]
        return tuple(out)

    def corners(self) -> tuple[Vec, ...]:
        """The vertices of the region (its holes for a list of holes)."""
        if self.kind == HOLES:
            return self.holes
        out: list[Vec] = [self.origin]
        for axis in self.axes:
            out = out + [(p[0] + axis[0], p[1] + axis[1], p[2] + axis[2]) for p in out]
        return tuple(out)


@dataclass(frozen=True)
class Attachment:
    """A body springs may be attached to: a frame (or the ground) and its region."""

    frame: str
    region: Region
    subsystem: str | None  # None: fixed to the ground


@dataclass(frozen=True)
class Site:
    """A place for one counter-mass: a frame and its region."""

    name: str
    frame: str
    region: Region
    subsystem: str | None


@dataclass(frozen=True)
class SynthesisSpec:
    """The resolved ``[synthesis]`` table (see problems/README.md)."""

    attachments: tuple[Attachment, ...]
    sites: tuple[Site, ...]
    #: candidate springs: pairs of attachment frames (each pair within one subsystem, or
    #: with the ground), in the file's order
    pairs: tuple[tuple[str, str], ...]
    min_rate: float = 0.0  # N/m
    max_rate: float = 0.0
    min_mass: float = 0.0  # kg
    max_mass: float = 0.0
    spring_cost: float = 1.0
    mass_cost: float = 1.0
    #: every chosen spring has the same rate (one part for all: "the same spring for all legs")
    same_rate: bool = False
    #: with a payload range: the free ends and counter-mass positions are re-set per payload
    adjust: bool = False
    max_topologies: int = 20
    #: seconds per mixed-integer solve (HiGHS's time limit)
    time_limit: float = 120.0
    #: free the attachment points in their regions and re-solve each topology (the NLP)
    refine: bool = True
    description: str = ""

    def attachment(self, frame: str) -> Attachment:
        for a in self.attachments:
            if a.frame == frame:
                return a
        raise KeyError(frame)


def pair_label(pair: tuple[str, str]) -> str:
    """'ground-link_a': how a pair is named in reports."""
    return f"{pair[0]}-{pair[1]}"


__all__ = ["BOX", "GROUND", "HOLES", "SEGMENT", "Attachment", "Region", "Site", "SynthesisSpec", "pair_label"]
