"""The design of a helical extension spring for a rate and a force range (docs/springs.md).

:func:`design` takes a :class:`Requirement` (rate, smallest and largest working force, and
for a directly attached spring its initial tension and free length), a material and an
:class:`Envelope`, and returns a :class:`SpringDesign`: the lightest spring that keeps the
winding rules, or, when none does, a design whose ``reasons`` say which rule no candidate
met. :func:`largest_force` is the largest force any spring within the rules and the
envelope carries (the default force limit of a designed spring).

Candidates: every standard wire diameter of the material (:func:`.materials.wire_diameters`)
times a grid of spring indices 4-12. For each, the body-coil count for the rate is rounded
to a quarter coil, then the mean coil diameter is re-solved from the rate for that count and
rounded to 0.01 mm (0.001 mm where 0.01 mm would move the rate by more than
:data:`RATE_ROUNDING`); a candidate is kept when every rule holds on the rounded values.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace

import numpy as np

from . import physics as ph
from .materials import DEFAULT_MATERIAL, Material, material, wire_diameters

#: the spring indices tried between C_MIN and C_MAX
INDEX_STEPS = 161
#: body coils are wound to a quarter coil
COIL_STEP = 0.25
#: at least this many body coils
MIN_BODY_COILS = 3.0
#: the rounded coil count and diameter keep the rate within this share of the required rate
RATE_ROUNDING = 0.005
#: mean coil diameter rounding (m): coarse, then fine where coarse moves the rate too far
DIAMETER_STEPS = (1e-5, 1e-6)
#: the rate tolerance written into a designed spring's spec unless the file gives one
RATE_TOLERANCE = 0.10


@dataclass(frozen=True)
class Requirement:
    """What the spring must do (SI): its rate and the range of forces it works over.

    ``initial_tension`` and ``free_length``: given for a directly attached spring (the
    balance depends on them); None for a spring behind a pulley, whose initial tension the
    design chooses (at most ``force_min``, so that the cable never goes slack)."""

    rate: float  # N/m
    force_min: float  # N, smallest working force
    force_max: float  # N, largest working force
    initial_tension: float | None = None
    free_length: float | None = None


@dataclass(frozen=True)
class Envelope:
    """Optional limits on the spring's size (m; None: no limit)."""

    max_outer_diameter: float | None = None
    max_body_length: float | None = None
    max_length: float | None = None  # largest working length, hooks included

    def text(self) -> str:
        parts = [
            f"{label} ≤ {1e3 * v:.4g} mm"
            for label, v in (("outer diameter", self.max_outer_diameter), ("body length", self.max_body_length), ("working length", self.max_length))
            if v is not None
        ]
        return ", ".join(parts) or "no envelope"


@dataclass(frozen=True)
class SpringDesign:
    """A designed helical extension spring with machine hooks (SI units; NaN when ``reasons``
    says why no spring could be designed)."""

    material: Material
    requirement: Requirement
    reasons: tuple[str, ...] = ()
    #: a spring was designed, but it does not do everything asked (the cable goes slack)
    warnings: tuple[str, ...] = ()
    wire_diameter: float = math.nan
    mean_diameter: float = math.nan
    body_coils: float = math.nan
    active_coils: float = math.nan
    rate: float = math.nan  # G d⁴ / (8 D³ N_a) of the rounded design
    initial_tension: float = math.nan
    initial_tension_band: tuple[float, float] = (math.nan, math.nan)  # windable, for the index
    body_length: float = math.nan
    free_length: float = math.nan  # inside the hooks
    hook_extension: float = 0.0  # each hook longer than a machine hook by this (direct mount)
    length_min: float = math.nan  # working lengths at force_min (not below free_length), force_max
    length_max: float = math.nan
    max_force: float = math.nan  # the force at which the first allowable stress is reached
    max_length: float = math.nan  # the length at max_force
    body_stress: float = math.nan  # K_B-corrected shear at the largest working force
    hook_bending_stress: float = math.nan
    hook_torsion_stress: float = math.nan
    initial_stress: float = math.nan  # uncorrected, of the initial tension
    allowable_body: float = math.nan
    allowable_hook_bending: float = math.nan
    allowable_hook_torsion: float = math.nan
    mass: float = math.nan
    rate_tolerance: float = RATE_TOLERANCE
    candidates: int = field(default=0, compare=False)  # how many designs met every rule

    @property
    def ok(self) -> bool:
        return not self.reasons

    @property
    def index(self) -> float:
        return self.mean_diameter / self.wire_diameter

    @property
    def outer_diameter(self) -> float:
        return self.mean_diameter + self.wire_diameter

    @property
    def safety_factor(self) -> float:
        """Smallest allowable/stress over body shear, hook bending and hook torsion at the
        largest working force (= max_force / force_max: the stresses are linear in F)."""
        return min(
            self.allowable_body / self.body_stress,
            self.allowable_hook_bending / self.hook_bending_stress,
            self.allowable_hook_torsion / self.hook_torsion_stress,
        )

    @property
    def rate_error(self) -> float:
        """(rate − required rate) / required rate."""
        return self.rate / self.requirement.rate - 1.0


def _round(x: np.ndarray, step: float) -> np.ndarray:
    return np.round(x / step) * step


def _frozen(**arrays: np.ndarray) -> dict[str, np.ndarray]:
    """``arrays``, each made read-only (they are kept by :func:`_grid` and shared)."""
    for a in arrays.values():
        a.flags.writeable = False
    return arrays


@functools.lru_cache(maxsize=4)
def _wires(mat: Material) -> dict[str, np.ndarray]:
    """What of the candidates depends on the material alone (kept: every design of the
    material starts from it): the (wire, index) grid as flat arrays, G·d⁴ and the
    allowable stresses of each wire."""
    d = np.asarray(wire_diameters(mat), dtype=float)
    C0 = np.linspace(ph.C_MIN, ph.C_MAX, INDEX_STEPS)
    d, C0 = (a.ravel() for a in np.meshgrid(d, C0, indexing="ij"))
    sut = ph.tensile_strength(mat, d)
    return _frozen(
        d=d,
        Gd=mat.G * d,
        C3=8.0 * C0**3,
        Gd4=mat.G * d**4,
        body=mat.body_torsion * sut,
        bend=mat.end_bending * sut,
        tors=mat.end_torsion * sut,
    )


@functools.lru_cache(maxsize=4)
def _grid(mat: Material, k: float) -> dict[str, np.ndarray]:
    """Every (wire, index) candidate for rate ``k``, rounded, as flat arrays, with what of
    them depends on the rate alone (capacity, windable initial-tension band, lengths,
    mass). Kept for the last few rates: the springs of one problem often share a rate
    (read-only arrays; at most ~2 MB each)."""
    w = _wires(mat)
    d = w["d"]
    offset = mat.G / mat.E
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        Nb = _round(w["Gd"] / (w["C3"] * k) - offset, COIL_STEP)  # N_a for D = C0 d, then rounded
        Na = ph.active_coils(mat, Nb)
        exact = (w["Gd4"] / (8.0 * k * Na)) ** (1.0 / 3.0)
        D = _round(exact, DIAMETER_STEPS[0])
        fine = np.abs(w["Gd4"] / (8.0 * D**3 * Na) / k - 1.0) > RATE_ROUNDING  # ph.rate
        D = np.where(fine, _round(exact, DIAMETER_STEPS[1]), D)
        rate = w["Gd4"] / (8.0 * D**3 * Na)  # ph.rate
        C = D / d
        a_body, a_bend, a_tors = w["body"], w["bend"], w["tors"]
        unit = (ph.shear_stress(1.0, d, D), ph.hook_bending_stress(1.0, d, D), ph.hook_torsion_stress(1.0, d, D))
        capacity = np.minimum.reduce([a / u for a, u in zip((a_body, a_bend, a_tors), unit)])  # (S10)
        mid, half = ph.initial_stress_mid(C), ph.initial_stress_half_band(C)
        t_lo, t_mid, t_hi = (ph.tension_of_stress(t, d, D) for t in (mid - half, mid, mid + half))
        L0 = ph.free_length(d, D, Nb)
        Lb = ph.body_length(d, Nb)
        index = np.isfinite(D) & (C >= ph.C_MIN - 1e-9) & (C <= ph.C_MAX + 1e-9) & (np.abs(rate / k - 1.0) <= RATE_ROUNDING)
        mass = ph.mass(mat, d, D, Nb)
    return _frozen(
        d=d, D=D, Nb=Nb, Na=Na, rate=rate, C=C, a_body=a_body, a_bend=a_bend, a_tors=a_tors, capacity=capacity,
        t_lo=t_lo, t_mid=t_mid, t_hi=t_hi, L0=L0, Lb=Lb, index=index, coils=Nb >= MIN_BODY_COILS, mass=mass,
    )  # fmt: skip


def _candidates(mat: Material, k: float) -> dict[str, np.ndarray]:
    """Every (wire, index) candidate for rate ``k``, rounded, as flat arrays."""
    g = _grid(mat, k)
    return {name: g[name] for name in ("d", "D", "Nb", "Na", "rate", "C")}


def _capacity(mat: Material, d: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, ...]:
    """Allowable stresses (body, hook bending, hook torsion) and the largest force (S10)."""
    sut = ph.tensile_strength(mat, d)
    allow = (mat.body_torsion * sut, mat.end_bending * sut, mat.end_torsion * sut)
    unit = (ph.shear_stress(1.0, d, D), ph.hook_bending_stress(1.0, d, D), ph.hook_torsion_stress(1.0, d, D))
    force = np.minimum.reduce([a / u for a, u in zip(allow, unit)])
    return (*allow, force)


def design(
    requirement: Requirement,
    mat: "str | Material" = DEFAULT_MATERIAL,
    envelope: Envelope = Envelope(),
    rate_tolerance: float = RATE_TOLERANCE,
    min_safety_factor: float = 1.0,
) -> SpringDesign:
    """The lightest extension spring of ``mat`` for ``requirement`` within the winding rules
    and ``envelope``, with at least ``min_safety_factor`` on every allowable stress at the
    largest working force; a design with ``reasons`` when there is none (never an exception
    for a requirement no spring meets).

    Behind a pulley the initial tension is the middle of the windable band, lowered to
    ``force_min`` but not below the band; when some candidates keep F0 ≤ ``force_min``, the
    lightest of them is chosen, otherwise the one whose F0 exceeds it least, with a
    warning (the cable goes slack near the shortest distance). Attached directly, the
    candidates whose hooks need at most one coil diameter each beyond machine hooks to
    make up the given free length come first (otherwise the least excess, with a warning)."""
    m = material(mat)
    r = requirement
    k, f_lo, f_hi = r.rate, r.force_min, r.force_max

    def fail(*why: str) -> SpringDesign:
        return SpringDesign(m, r, reasons=why, rate_tolerance=rate_tolerance)

    if k == 0 or f_hi == 0:
        return fail("its stiffness is 0: the balance does not use this spring (leave it out)")
    if not (math.isfinite(k) and k > 0):
        return fail(f"its rate {k:.4g} N/m is not positive")
    if not (math.isfinite(f_hi) and f_hi > 0 and math.isfinite(f_lo)):
        return fail(f"its working force {f_lo:.4g}-{f_hi:.4g} N is not a positive range")
    g = _grid(m, k)
    d, D, Nb, Na, C, rate = g["d"], g["D"], g["Nb"], g["Na"], g["C"], g["rate"]
    a_body, a_bend, a_tors, capacity = g["a_body"], g["a_bend"], g["a_tors"], g["capacity"]
    t_lo, t_mid, t_hi, L0, Lb = g["t_lo"], g["t_mid"], g["t_hi"], g["L0"], g["Lb"]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if r.initial_tension is None:  # the middle of the band, lower down to f_lo, not below the band
            F0 = np.minimum(np.maximum(f_lo, t_lo), t_mid)
        else:
            F0 = np.full_like(d, r.initial_tension)
        free = L0 if r.free_length is None else np.full_like(d, r.free_length)
        L_hi = free + (f_hi - F0) / rate
    stages = [
        ("index", g["index"]),
        ("coils", g["coils"]),
        ("strength", capacity >= f_hi * min_safety_factor),
        ("tension", (F0 >= t_lo * (1 - 1e-12)) & (F0 <= t_hi * (1 + 1e-12)) & (F0 < f_hi)),
        ("free length", L0 <= free * (1 + 1e-12)),
        ("envelope", _fits(envelope, D + d, Lb, L_hi)),
    ]
    keep = np.ones(d.shape, dtype=bool)
    for stage, ok in stages:
        if not np.any(keep & ok):
            return fail(_reason(stage, m, r, envelope, keep, capacity / min_safety_factor, L0, F0))
        keep &= ok
    mass = g["mass"]
    slack = np.maximum(F0 - f_lo, 0.0)  # > 0: the cable goes slack at the shortest distance
    long_hooks = np.maximum((free - L0) / 2.0 - D, 0.0)  # direct mount: hooks longer than a coil diameter more
    order = np.lexsort((f_hi / capacity, np.where(keep, mass, np.inf), np.where(keep, long_hooks, np.inf), np.where(keep, slack, np.inf)))
    i = int(order[0])
    f0 = float(F0[i])
    warnings: tuple[str, ...] = ()
    if slack[i] > 0:
        warnings += (
            f"its force falls to {f_lo:.4g} N, below the smallest windable initial tension {f0:.4g} N of any spring strong "
            f"enough: the cable goes slack where the ends come closer than F0/k = {1e3 * f0 / k:.4g} mm, and the balance "
            f"is lost there (the spring pulls nothing instead of k·d < F0)",
        )
    if long_hooks[i] > 0:
        warnings += (
            f"its free length {1e3 * float(free[i]):.4g} mm leaves {1e3 * float(free[i] - L0[i]) / 2:.4g} mm per hook beyond "
            f"machine hooks on every spring strong enough: extended hooks (or a longer cable and a shorter free length)",
        )
    return SpringDesign(
        warnings=warnings,
        material=m,
        requirement=r,
        wire_diameter=float(d[i]),
        mean_diameter=float(D[i]),
        body_coils=float(Nb[i]),
        active_coils=float(Na[i]),
        rate=float(rate[i]),
        initial_tension=f0,
        initial_tension_band=(float(t_lo[i]), float(t_hi[i])),
        body_length=float(Lb[i]),
        free_length=float(free[i]),
        hook_extension=float(free[i] - L0[i]) / 2.0,
        length_min=float(free[i] + max(f_lo - f0, 0.0) / rate[i]),  # slack cable: the spring stays at L0
        length_max=float(L_hi[i]),
        max_force=float(capacity[i]),
        max_length=float(free[i] + (capacity[i] - f0) / rate[i]),
        body_stress=float(ph.shear_stress(f_hi, d[i], D[i])),
        hook_bending_stress=float(ph.hook_bending_stress(f_hi, d[i], D[i])),
        hook_torsion_stress=float(ph.hook_torsion_stress(f_hi, d[i], D[i])),
        initial_stress=float(8.0 * f0 * D[i] / (math.pi * d[i] ** 3)),
        allowable_body=float(a_body[i]),
        allowable_hook_bending=float(a_bend[i]),
        allowable_hook_torsion=float(a_tors[i]),
        mass=float(mass[i]),
        rate_tolerance=rate_tolerance,
        candidates=int(keep.sum()),
    )


def _fits(envelope: Envelope, outer: np.ndarray, body: np.ndarray, longest: np.ndarray) -> np.ndarray:
    ok = np.ones(outer.shape, dtype=bool)
    for limit, value in ((envelope.max_outer_diameter, outer), (envelope.max_body_length, body), (envelope.max_length, longest)):
        if limit is not None:
            ok &= value <= limit * (1 + 1e-12)
    return ok


def _reason(stage: str, m: Material, r: Requirement, envelope: Envelope, keep: np.ndarray, capacity: np.ndarray, L0: np.ndarray, F0: np.ndarray) -> str:
    """Why no candidate passed ``stage`` (``keep``: those that passed the stages before)."""
    wires = f"{m.name} wire {1e3 * m.d_min:g}-{1e3 * m.d_max:g} mm"
    if stage == "index":
        return f"no standard {wires} winds the rate {r.rate:.4g} N/m at a spring index 4-12"
    if stage == "coils":
        return f"the rate {r.rate:.4g} N/m is too stiff for {wires}: fewer than {MIN_BODY_COILS:g} body coils at every index 4-12"
    if stage == "strength":
        return (
            f"its largest force {r.force_max:.4g} N is more than any spring of that rate carries within the allowable stresses "
            f"({wires}, index 4-12: at most {float(np.max(np.where(keep, capacity, 0.0))):.4g} N)"
        )
    if stage == "tension" and r.initial_tension is not None:  # direct mount: the file's initial tension
        return f"its initial tension {r.initial_tension:.4g} N is outside the windable band of every spring strong enough, or not below its largest force"
    if stage == "tension":
        return (
            f"its largest force {r.force_max:.4g} N is below the smallest windable initial tension of any spring strong enough "
            f"({float(np.min(np.where(keep, F0, np.inf))):.4g} N): the spring would never extend"
        )
    if stage == "free length":
        return f"its free length {1e3 * (r.free_length or 0.0):.4g} mm is shorter than any strong enough spring with machine hooks ({1e3 * float(np.min(np.where(keep, L0, np.inf))):.4g} mm)"
    return f"no spring strong enough fits the envelope ({envelope.text()})"


@functools.lru_cache(maxsize=256)
def _largest(key: str, max_outer_diameter: float | None, max_body_length: float | None, min_safety_factor: float) -> float:
    m = material(key)
    d = np.asarray(wire_diameters(m), dtype=float)
    C = np.linspace(ph.C_MIN, ph.C_MAX, INDEX_STEPS)
    d, C = (a.ravel() for a in np.meshgrid(d, C, indexing="ij"))
    D = C * d
    ok = np.ones(d.shape, dtype=bool)
    if max_outer_diameter is not None:
        ok &= D + d <= max_outer_diameter * (1 + 1e-12)
    if max_body_length is not None:
        ok &= ph.body_length(d, MIN_BODY_COILS) <= max_body_length * (1 + 1e-12)
    force = _capacity(m, d, D)[3]
    return float(np.max(force[ok])) / min_safety_factor if np.any(ok) else 0.0


def largest_force(
    mat: "str | Material" = DEFAULT_MATERIAL,
    max_outer_diameter: float | None = None,
    max_body_length: float | None = None,
    min_safety_factor: float = 1.0,
) -> float:
    """The largest force (N) a spring of ``mat`` designable within the rules (standard
    wire of the material, index 4-12, at least :data:`MIN_BODY_COILS` body coils) and the
    envelope (m; None: no limit) carries within its allowable stresses divided by
    ``min_safety_factor``. Pure and cached (some 10,000 candidates the first time, a
    dictionary look-up after). 0.0 when no standard wire fits the envelope."""
    key = material(mat).key
    return _largest(key, max_outer_diameter, max_body_length, float(min_safety_factor))


def force_limit(options: object) -> float:
    """The default force limit (N) of a designed spring: :func:`largest_force` for a
    spring's design options (``ZeroFreeLengthSpring.design``: material, envelope, smallest
    safety factor)."""
    return largest_force(
        getattr(options, "material", DEFAULT_MATERIAL),
        getattr(options, "max_outer_diameter", None),
        getattr(options, "max_body_length", None),
        getattr(options, "min_safety_factor", 1.0),
    )


def redesign_at(made: SpringDesign, requirement: Requirement) -> SpringDesign:
    """The same wound spring as ``made`` (wire, diameter, coils, initial tension, free
    length) against a new ``requirement`` (its working forces after the geometry was solved
    again for its wound rate): its lengths and stresses at the new forces, with a reason
    when its strength no longer covers them."""
    if not made.ok:
        return made
    f0, k = made.initial_tension, made.rate
    f_hi = requirement.force_max
    reasons: tuple[str, ...] = ()
    if made.max_force < f_hi:
        reasons = (f"its largest force {f_hi:.4g} N is more than the wound spring carries within the allowable stresses ({made.max_force:.4g} N)",)
    return replace(
        made,
        requirement=requirement,
        reasons=reasons,
        length_min=made.free_length + max(requirement.force_min - f0, 0.0) / k,
        length_max=made.free_length + (f_hi - f0) / k,
        body_stress=float(ph.shear_stress(f_hi, made.wire_diameter, made.mean_diameter)),
        hook_bending_stress=float(ph.hook_bending_stress(f_hi, made.wire_diameter, made.mean_diameter)),
        hook_torsion_stress=float(ph.hook_torsion_stress(f_hi, made.wire_diameter, made.mean_diameter)),
    )
