"""The cable of a spring over a pulley of radius r: its length and wraps, on every backend.

A pulley mount (:class:`~counterpoise.model.elements.Pulley`) has its pulley at the spring's
``from`` point A, turning about ``axis`` (in the ``from`` frame). The cable comes from the
spring, which lies behind the pulley along the *lead* direction u, wraps over the pulley in
the sense σ (+1: counter-clockwise about the axis) and runs on to the link point B (the
spring's ``to`` point). In the pulley's plane take e1 = u (made normal to the axis), e2 =
n × e1 and B − A = (b1, b2, b3) in (e1, e2, n); d = √(b1² + b2²).

- **Cable to a point** (docs/build.md#pulleys). The cable leaves the pulley on the tangent
  through B: its straight run is s = √(d² − r²) and the arc it wraps is

      θ = π + atan2(b1 r + σ b2 s, b1 s − σ b2 r)   ∈ (0, 2π],

  measured from the point where the incoming run (parallel to u) meets the pulley. The path
  from there to B is ℓ = s + r θ. With r = 0, ℓ = d and θ = π + σ·atan2(b2, b1).
- **Cable onto a pin** of the same radius at B (an open belt): the straight run is parallel
  to AB, offset by r, and exactly d long. The cable wraps θ_p = π + atan2(σ b2, b1) on the
  pulley and θ_b on the pin, up to its fixing point, in the direction f (fixed in the
  ``to`` frame): with (f1, f2) its components along (e1, e2),

      θ_b = π + atan2(−(f1 b1 + f2 b2), σ (f2 b1 − f1 b2)),

  and ℓ = d + r (θ_p + θ_b). θ_p + θ_b changes only when f turns against (e1, e2): when the
  pin's frame keeps the pulley frame's orientation the path is d plus a constant, so the
  spring pulls k·d exactly at any radius (docs/build.md derives it).

The lead u defaults to the direction from A to B at home (so θ is near π there: the cable
wraps half a turn), the pin's fixing direction to σ e2 at home (θ_b = π there). Both are
written on the build sheet. The arctangents are continuous except where a wrap reaches 0
or 2π, which the realisation limits keep away (:data:`~counterpoise.model.elements.MIN_WRAP`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .kinematics import Scalar, Vec, add, cross, dot, matvec, mul, sub, unit_vector

if TYPE_CHECKING:
    from ..model.elements import ZeroFreeLengthSpring
    from .energy import Mechanics


#: a spring's length is sqrt(d·d + LENGTH_FLOOR²) (m): differentiable where its ends meet
LENGTH_FLOOR = 1e-12


@dataclass(frozen=True)
class Cable:
    """A pulley mount's cable at the configurations evaluated (each a Scalar of the backend)."""

    path: Scalar  # from the pulley's entry point over the pulley (and pin) to B (or the pin's fixing point)
    distance: Scalar  # |B − A| in the pulley's plane (the centre distance of a pin)
    wrap: Scalar  # the arc wrapped on the pulley (rad)
    pin_wrap: Scalar | None  # the arc wrapped on the pin (rad), None without a pin
    off_plane: Scalar  # (B − A)·n: 0 when B moves in the pulley's plane


def transposed(rot: list[list[Scalar]], v: Vec) -> Vec:
    """Rᵀ v (a world vector in a frame's coordinates)."""
    return [add(add(mul(rot[0][i], v[0]), mul(rot[1][i], v[1])), mul(rot[2][i], v[2])) for i in range(3)]


def minus(a: Scalar, b: Scalar) -> Scalar:
    return add(a, mul(-1.0, b))


def home(mech: "Mechanics") -> "Mechanics":
    """``mech`` at every coordinate's home (the configuration the default lead is taken at)."""
    return mech.moved({c.name: c.home for c in mech.problem.coordinates})


def lead_local(mech: "Mechanics", spring: "ZeroFreeLengthSpring") -> Vec:
    """The lead direction u in the ``from`` frame: the file's, or from A towards B at home."""
    p = spring.pulley
    if p is not None and p.lead is not None:
        return [float(c) for c in p.lead]
    at_home = home(mech)
    a, b = spring.ends
    rot = at_home.pose(a.frame)[0]
    return transposed(rot, sub(at_home.position(b), at_home.position(a)))


def fixing_local(mech: "Mechanics", spring: "ZeroFreeLengthSpring") -> Vec:
    """A pin's fixing direction f in the ``to`` frame: σ e2 at home (θ_b = π there)."""
    p = spring.pulley
    if p is None:
        raise ValueError(f"spring {spring.name}: a direct mount has no pin")
    if p.fixing is not None:
        return [float(c) for c in p.fixing]
    at_home = home(mech)
    n, e1, e2 = plane(at_home, spring)
    rot_b = at_home.pose(spring.ends[1].frame)[0]
    return transposed(rot_b, [mul(float(p.sense), c) for c in e2])


def plane(mech: "Mechanics", spring: "ZeroFreeLengthSpring") -> tuple[Vec, Vec, Vec]:
    """(n, e1, e2) in the world: the pulley's axis and its plane's axes (e1 along the lead)."""
    p = spring.pulley
    if p is None:
        raise ValueError(f"spring {spring.name}: a direct mount has no pulley")
    fn = mech.functions
    rot = mech.pose(spring.ends[0].frame)[0]
    n = matvec(rot, [float(c) for c in p.axis])
    u = matvec(rot, lead_local(mech, spring))
    along = dot(u, n)
    e1 = unit_vector([minus(u[i], mul(along, n[i])) for i in range(3)], fn)
    return n, e1, cross(n, e1)


def cable(mech: "Mechanics", spring: "ZeroFreeLengthSpring", fixing: Vec | None = None) -> Cable:
    """The cable of ``spring`` (a pulley mount) at ``mech``'s configurations. ``fixing``: a
    pin's fixing direction in the ``to`` frame (default :func:`fixing_local`)."""
    p = spring.pulley
    if p is None:
        raise ValueError(f"spring {spring.name}: a direct mount has no pulley")
    fn = mech.functions
    n, e1, e2 = plane(mech, spring)
    a, b = (mech.position(point) for point in spring.ends)
    rel = sub(b, a)
    b1, b2, b3 = dot(rel, e1), dot(rel, e2), dot(rel, n)
    r, sigma = float(p.radius), float(p.sense)
    d = fn["sqrt"](add(mul(b1, b1), mul(b2, b2)))
    if p.pin:
        wrap = add(math.pi, fn["atan2"](mul(sigma, b2), b1))
        f = matvec(mech.pose(spring.ends[1].frame)[0], fixing if fixing is not None else fixing_local(mech, spring))
        f1, f2 = dot(f, e1), dot(f, e2)
        along = add(mul(f1, b1), mul(f2, b2))
        across = minus(mul(f2, b1), mul(f1, b2))
        pin_wrap = add(math.pi, fn["atan2"](mul(-1.0, along), mul(sigma, across)))
        return Cable(add(d, mul(r, add(wrap, pin_wrap))), d, wrap, pin_wrap, b3)
    if r == 0.0:
        return Cable(d, d, add(math.pi, mul(sigma, fn["atan2"](b2, b1))), None, b3)
    s = fn["sqrt"](add(mul(d, d), -r * r))
    wrap = add(math.pi, fn["atan2"](add(mul(r, b1), mul(sigma, mul(b2, s))), add(mul(b1, s), mul(-sigma * r, b2))))
    return Cable(add(s, mul(r, wrap)), d, wrap, None, b3)


def spring_quantities(mech: "Mechanics", spring: "ZeroFreeLengthSpring") -> dict[str, Scalar]:
    """A spring's quantities at ``mech``'s configurations, in the design model: ``force``
    (its pull: k·d behind a pulley that pulls k·d, k·(ℓ − ℓ*) over a pulley of radius > 0,
    F0 + k·(d − cable − L0) attached directly), ``length`` (the distance ``|a − b|`` between its
    ends), ``path`` (what its extension follows: the cable's path over a pulley of radius
    > 0, else the distance) and ``wrap`` (the arc wrapped on a pulley of radius > 0, on the
    pulley for a pin; π where there is no such pulley)."""
    fn = mech.functions
    d = sub(mech.position(spring.ends[0]), mech.position(spring.ends[1]))
    # + LENGTH_FLOOR²: a finite derivative where the ends meet (a length error ≤ 1e-12 m)
    length = fn["sqrt"](add(dot(d, d), LENGTH_FLOOR**2))
    k = mech.value(spring.stiffness)
    p = spring.pulley
    if spring.direct is not None or p is None:
        m = spring.direct
        if m is None:
            return {"force": mul(k, length), "length": length, "path": length, "wrap": math.pi}
        stretch = add(add(length, mul(-1.0, mech.value(m.cable))), mul(-1.0, mech.value(m.free_length)))
        return {"force": add(mech.value(m.initial_tension), mul(k, stretch)), "length": length, "path": length, "wrap": math.pi}
    if p.radius == 0.0:
        return {"force": mul(k, length), "length": length, "path": length, "wrap": math.pi}
    c = cable(mech, spring)
    if p.exact or p.zero_length is None:
        return {"force": mul(k, length), "length": length, "path": c.path, "wrap": c.wrap}
    return {"force": mul(k, add(c.path, mul(-1.0, mech.env[p.zero_length]))), "length": length, "path": c.path, "wrap": c.wrap}
