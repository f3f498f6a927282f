"""Loop closures: a closed chain opened at one joint, and the joint that closes it again.

A mechanism with closed loops is modelled as a tree of frames (as every mechanism here)
plus, for each loop, the joint where the loop was cut open. Its coordinates split into
*independent* ones (with ranges: the design must balance over them) and *dependent* ones,
solved from the closure equations h(q_i, q_d) = 0 (:mod:`counterpoise.mechanics.closure`).

- ``spherical``: point ``a`` (fixed in frame a) coincides with point ``b`` (fixed in
  frame b): three equations.
- ``revolute``: the same, and the joint's axis (given in frame a) keeps its direction in
  frame b (``axis_b`` when given, else its direction at the assembled home): three more
  equations, of which two are independent.
- ``prismatic``: point ``a`` may slide along the joint's axis (given in frame a) through
  point ``b`` (three equations, (p_a − p_b) × axis = 0, two independent), and the frames keep
  their relative orientation of the assembled home (nine equations, three independent).

Closure equations may be redundant (a planar loop's in 3-D); the solver works with their
rank, never asking the user to drop equations. See docs/loops.md.
"""

from __future__ import annotations

from dataclasses import dataclass

from .mechanism import Point, Vector

REVOLUTE_JOINT = "revolute"
SPHERICAL_JOINT = "spherical"
PRISMATIC_JOINT = "prismatic"


@dataclass(frozen=True)
class Loop:
    """The joint where one loop was opened (the ``[loops.<name>]`` table)."""

    name: str
    joint: str  # REVOLUTE_JOINT, SPHERICAL_JOINT or PRISMATIC_JOINT
    a: Point
    b: Point
    axis: Vector | None  # revolute, prismatic: unit axis in frame a's coordinates
    subsystem: str  # the subsystem whose coordinates move the loop
    description: str = ""
    #: revolute: the same axis in frame b's coordinates (None: measured at the assembled home)
    axis_b: Vector | None = None
