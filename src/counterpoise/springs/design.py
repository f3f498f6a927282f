"""The design of a helical extension spring for a rate and a force range (docs/springs.md).

:func:`design` takes a :class:`Requirement` (rate, smallest and largest working force, the
slack margin, and for a directly attached spring its initial tension and free length), a
material and an :class:`Envelope`, and returns a :class:`SpringDesign`: the lightest spring
that keeps the winding rules, or, when none does, a design whose ``reasons`` say which rule
no candidate met. :func:`redesign_at` checks the same wound spring against a new
requirement (the geometry re-solved for its wound rate). :func:`smallest_initial_tension`
is the smallest windable initial tension of the springs that keep every other rule (what a
spring behind a pulley needs of its smallest distance). :func:`largest_force` is the
largest force any spring within the rules and the envelope carries (the default force
limit of a designed spring).

Candidates: every standard wire diameter of the material (:func:`.materials.wire_diameters`)
times a grid of spring indices 4-12. For each, the body-coil count for the rate is rounded
to a quarter coil, then the mean coil diameter is re-solved from the rate for that count and
rounded to 0.01 mm (0.001 mm where 0.01 mm would move the rate by more than
:data:`RATE_ROUNDING`); a candidate is kept when every rule holds on the rounded values,
with the moduli of its wire's size. The rules hold for the spring as wound: its rate (the
rate of the rounded values) pulls the forces of the requirement's geometry.
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
#: a spring whose largest working force is below this (N) is one the design does not use
#: (a stiffness at rounding level: nobody winds a spring of micro-newtons)
NEGLIGIBLE_FORCE = 1e-6
#: the rate tolerance written into a designed spring's spec unless the file gives one
RATE_TOLERANCE = 0.10
#: the smallest allowable/stress ratio at the largest working force of the rate's upper
#: tolerance, unless the file gives one (docs/springs.md: "Safety factor")
MIN_SAFETY_FACTOR = 1.2
#: behind a pulley, the spring stays this far (m) from closing at the shortest distance,
#: unless the file gives one: F0 ≤ k (d_min − slack_margin) (docs/springs.md: "Slack margin")
SLACK_MARGIN = 0.003


@dataclass(frozen=True)
class Requirement:
    """What the spring must do (SI): its rate (the design rate: the one the geometry was
    solved for) and the range of forces it works over at that rate.

    ``initial_tension`` and ``free_length``: given for a directly attached spring (the
    balance depends on them); None for a spring behind a pulley, whose initial tension the
    design chooses: it pulls F = k·d, so ``force_min``/``rate`` is the shortest distance
    d_min, and the spring must stay extended there with ``slack_margin`` (m) to spare:
    F0 ≤ k (d_min − slack_margin)."""

    rate: float  # N/m
    force_min: float  # N, smallest working force
    force_max: float  # N, largest working force
    initial_tension: float | None = None
    free_length: float | None = None
    slack_margin: float = SLACK_MARGIN  # m, behind a pulley
    #: which side of the design rate the wound rate may fall on: +1 at or above it, −1 at or
    #: below it, 0 either (a geometry held at a bound can follow a rate on one side only)
    rate_side: int = 0

    @property
    def pulley(self) -> bool:
        """Behind a pulley (the design chooses F0), not attached directly."""
        return self.initial_tension is None


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
    says why no spring could be designed).

    ``rate`` is the rate of the spring as wound (its rounded coil count and diameter, with
    the moduli of its wire's size); ``requirement.rate`` (:attr:`design_rate`) the rate
    asked for. ``force_min``/``force_max`` are the wound spring's working forces in the
    requirement's geometry: k_w·d behind a pulley, F0 + k_w·x attached directly."""

    material: Material
    requirement: Requirement
    reasons: tuple[str, ...] = ()
    #: a spring was designed, but it does not do everything asked (long hooks)
    warnings: tuple[str, ...] = ()
    wire_diameter: float = math.nan
    mean_diameter: float = math.nan
    body_coils: float = math.nan
    active_coils: float = math.nan
    rate: float = math.nan  # G d⁴ / (8 D³ N_a) of the rounded design: the wound rate
    initial_tension: float = math.nan
    initial_tension_band: tuple[float, float] = (math.nan, math.nan)  # windable, for the index
    body_length: float = math.nan
    free_length: float = math.nan  # inside the hooks
    hook_extension: float = 0.0  # each hook longer than a machine hook by this (direct mount)
    force_min: float = math.nan  # the wound spring's working forces
    force_max: float = math.nan
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
    min_safety_factor: float = MIN_SAFETY_FACTOR
    envelope: Envelope = Envelope()
    #: behind a pulley: the shortest distance between the ends that some spring keeping
    #: every other rule allows, (its smallest windable F0)/k_w + slack margin (m); NaN
    #: attached directly, or when no spring keeps the other rules
    needed_distance: float = math.nan
    candidates: int = field(default=0, compare=False)  # how many designs met every rule

    @property
    def ok(self) -> bool:
        return not self.reasons

    @property
    def design_rate(self) -> float:
        """The rate asked for (N/m): the one the requirement's geometry was solved for."""
        return self.requirement.rate

    @property
    def index(self) -> float:
        return self.mean_diameter / self.wire_diameter

    @property
    def outer_diameter(self) -> float:
        return self.mean_diameter + self.wire_diameter

    @property
    def force_upper(self) -> float:
        """The largest working force at the upper end of the rate tolerance, installed as
        specified: F0 + (1 + tol)(F_max − F0)."""
        return self.initial_tension + (1.0 + self.rate_tolerance) * (self.force_max - self.initial_tension)

    @property
    def safety_factor(self) -> float:
        """Smallest allowable/stress over body shear, hook bending and hook torsion at the
        largest working force of the nominal (wound) rate: max_force / force_max (the
        stresses are linear in F)."""
        return self.max_force / self.force_max

    @property
    def safety_factor_upper(self) -> float:
        """The same at the rate's upper tolerance: max_force / :attr:`force_upper` (the
        design keeps it ≥ ``min_safety_factor``)."""
        return self.max_force / self.force_upper

    @property
    def slack_distance(self) -> float:
        """Behind a pulley: the distance between the ends below which the spring closes
        and the cable goes slack, F0/k_w (m)."""
        return self.initial_tension / self.rate

    @property
    def rate_error(self) -> float:
        """(wound rate − design rate) / design rate."""
        return self.rate / self.requirement.rate - 1.0

    def wound_force(self, force: float) -> float:
        """The wound spring's force where the requirement's spring (at the design rate)
        pulls ``force``: behind a pulley k_w·d = force·k_w/k, attached directly
        F0 + k_w·x = F0 + (force − F0)·k_w/k."""
        scale = self.rate / self.requirement.rate
        if self.requirement.pulley:
            return force * scale
        return self.initial_tension + (force - self.initial_tension) * scale


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
    material starts from it): the (wire, index) grid as flat arrays, G·d, G·d⁴ and G/E with
    the moduli of each wire's size."""
    d = np.asarray(wire_diameters(mat), dtype=float)
    C0 = np.linspace(ph.C_MIN, ph.C_MAX, INDEX_STEPS)
    d, C0 = (a.ravel() for a in np.meshgrid(d, C0, indexing="ij"))
    G, E = mat.shear_modulus(d), mat.youngs_modulus(d)
    return _frozen(d=d, Gd=G * d, C3=8.0 * C0**3, Gd4=G * d**4, offset=G / E)


def _springs(mat: Material, k: float, d: np.ndarray, D: np.ndarray, Nb: np.ndarray) -> dict[str, np.ndarray]:
    """Everything of the springs (d, D, N_b) that does not depend on the forces: wound
    rate, index, allowables and capacity (S10), windable initial-tension band (S7),
    lengths (S6), mass (S11), and whether they keep the index, rate and coil rules for the
    rate ``k``."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        Na = ph.active_coils(mat, d, Nb)
        rate = ph.rate(mat, d, D, Na)
        C = D / d
        sut = ph.tensile_strength(mat, d)
        a_body, a_bend, a_tors = mat.body_torsion * sut, mat.end_bending * sut, mat.end_torsion * sut
        unit = (ph.shear_stress(1.0, d, D), ph.hook_bending_stress(1.0, d, D), ph.hook_torsion_stress(1.0, d, D))
        capacity = np.minimum.reduce([a / u for a, u in zip((a_body, a_bend, a_tors), unit)])  # (S10)
        mid, half = ph.initial_stress_mid(C), ph.initial_stress_half_band(C)
        t_lo, t_mid, t_hi = (ph.tension_of_stress(t, d, D) for t in (mid - half, mid, mid + half))
        index = np.isfinite(D) & (C >= ph.C_MIN - 1e-9) & (C <= ph.C_MAX + 1e-9) & (np.abs(rate / k - 1.0) <= RATE_ROUNDING)
        return dict(
            d=d, D=D, Nb=Nb, Na=Na, rate=rate, C=C, a_body=a_body, a_bend=a_bend, a_tors=a_tors, capacity=capacity,
            t_lo=t_lo, t_mid=t_mid, t_hi=t_hi, L0=ph.free_length(d, D, Nb), Lb=ph.body_length(d, Nb), index=index,
            coils=Nb >= MIN_BODY_COILS, mass=ph.mass(mat, d, D, Nb),
        )  # fmt: skip


@functools.lru_cache(maxsize=4)
def _grid(mat: Material, k: float) -> dict[str, np.ndarray]:
    """Every (wire, index) candidate for rate ``k``, rounded, as flat arrays, with what of
    them depends on the rate alone (:func:`_springs`). Kept for the last few rates: the
    springs of one problem often share a rate (read-only arrays; at most ~2 MB each)."""
    w = _wires(mat)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        Nb = _round(w["Gd"] / (w["C3"] * k) - w["offset"], COIL_STEP)  # N_a for D = C0 d, then rounded
        Na = Nb + w["offset"]  # ph.active_coils
        exact = (w["Gd4"] / (8.0 * k * Na)) ** (1.0 / 3.0)
        D = _round(exact, DIAMETER_STEPS[0])
        fine = np.abs(w["Gd4"] / (8.0 * D**3 * Na) / k - 1.0) > RATE_ROUNDING  # ph.rate
        D = np.where(fine, _round(exact, DIAMETER_STEPS[1]), D)
    return _frozen(**_springs(mat, k, w["d"], D, Nb))


def _candidates(mat: Material, k: float) -> dict[str, np.ndarray]:
    """Every (wire, index) candidate for rate ``k``, rounded, as flat arrays."""
    g = _grid(mat, k)
    return {name: g[name] for name in ("d", "D", "Nb", "Na", "rate", "C")}


@dataclass(frozen=True)
class _Rules:
    """What a design is asked beyond its requirement."""

    envelope: Envelope
    rate_tolerance: float
    min_safety_factor: float


def _forces(g: dict[str, np.ndarray], r: Requirement, F0: np.ndarray) -> dict[str, np.ndarray]:
    """The wound springs' working forces in the requirement's geometry (k_w·d behind a
    pulley, F0 + k_w·x attached directly), the largest one at the rate's upper tolerance
    (F0 + (1 + tol)(F_max − F0) with tol applied later), the free length it works from and
    its longest working length."""
    rate = g["rate"]
    scale = rate / r.rate
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if r.pulley:
            lo, hi = r.force_min * scale, r.force_max * scale
            free = g["L0"]
        else:
            lo, hi = F0 + (r.force_min - F0) * scale, F0 + (r.force_max - F0) * scale
            free = np.full_like(rate, r.free_length if r.free_length is not None else math.nan)
        return {"lo": lo, "hi": hi, "free": free, "L_hi": free + (hi - F0) / rate}


def _stages(g: dict[str, np.ndarray], r: Requirement, F0: np.ndarray, rules: _Rules, slack: bool = True) -> list[tuple[str, np.ndarray]]:
    """The rules, in the order their reasons are given, each as a mask over the candidates
    (``slack``: with the pulley's slack rule, the last)."""
    f = _forces(g, r, F0)
    tol, n = rules.rate_tolerance, rules.min_safety_factor
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        upper = F0 + (1.0 + tol) * (f["hi"] - F0)
        side = np.sign(g["rate"] - r.rate) * r.rate_side >= 0 if r.rate_side else np.ones(F0.shape, dtype=bool)
        stages = [
            ("index", g["index"] & side),
            ("coils", g["coils"]),
            ("tension", (F0 >= g["t_lo"] * (1 - 1e-12)) & (F0 <= g["t_hi"] * (1 + 1e-12)) & (F0 < f["hi"])),
            ("strength", g["capacity"] >= n * upper * (1 - 1e-12)),
            ("free length", g["L0"] <= f["free"] * (1 + 1e-12) if not r.pulley else np.ones(F0.shape, dtype=bool)),
            ("envelope", _fits(rules.envelope, g["D"] + g["d"], g["Lb"], f["L_hi"])),
        ]
        if slack and r.pulley:  # k_w (d_min − margin) with d_min = F_min/k: F0 ≤ F_min,w − k_w·margin
            stages.append(("slack", F0 <= (f["lo"] - g["rate"] * r.slack_margin) * (1 + 1e-12)))
    return stages


def _initial_tension(g: dict[str, np.ndarray], r: Requirement) -> np.ndarray:
    """Behind a pulley, the middle of the windable band, lowered to k_w (d_min − margin)
    but not below the band; attached directly, the requirement's."""
    if not r.pulley:
        return np.full_like(g["rate"], r.initial_tension)
    cap = _forces(g, r, g["t_lo"])["lo"] - g["rate"] * r.slack_margin
    return np.minimum(np.maximum(cap, g["t_lo"]), g["t_mid"])


def _smallest_tension(g: dict[str, np.ndarray], r: Requirement, rules: _Rules) -> np.ndarray:
    """Which candidates keep every rule but the slack rule with their smallest windable
    initial tension (the bottom of the band: the most demanding for strength and length)."""
    keep = np.ones(g["d"].shape, dtype=bool)
    for _, ok in _stages(g, r, np.asarray(g["t_lo"]), rules, slack=False):
        keep &= ok
    return keep


def _needed(g: dict[str, np.ndarray], r: Requirement, rules: _Rules) -> float:
    """Behind a pulley: the smallest F0/k_w + slack margin of the candidates that keep every
    other rule (m; NaN when none does, or attached directly)."""
    if not r.pulley:
        return math.nan
    keep = _smallest_tension(g, r, rules)
    if not np.any(keep):
        return math.nan
    return float(np.min(np.where(keep, g["t_lo"] / g["rate"], np.inf))) + r.slack_margin


def _invalid(r: Requirement) -> str | None:
    """Why the requirement asks for no spring (None: it asks for one)."""
    k, f_lo, f_hi = r.rate, r.force_min, r.force_max
    if k == 0 or f_hi == 0 or (math.isfinite(f_hi) and abs(f_hi) < NEGLIGIBLE_FORCE):
        return "its stiffness is 0: the balance does not use this spring (leave it out)"
    if not (math.isfinite(k) and k > 0):
        return f"its rate {k:.4g} N/m is not positive"
    if not (math.isfinite(f_hi) and f_hi > 0 and math.isfinite(f_lo)):
        return f"its working force {f_lo:.4g}-{f_hi:.4g} N is not a positive range"
    if not (math.isfinite(r.slack_margin) and r.slack_margin >= 0):
        return f"its slack margin {1e3 * r.slack_margin:.4g} mm is not a length ≥ 0"
    return None


def design(
    requirement: Requirement,
    mat: "str | Material" = DEFAULT_MATERIAL,
    envelope: Envelope = Envelope(),
    rate_tolerance: float = RATE_TOLERANCE,
    min_safety_factor: float = MIN_SAFETY_FACTOR,
) -> SpringDesign:
    """The lightest extension spring of ``mat`` for ``requirement`` within the winding rules
    and ``envelope``, with at least ``min_safety_factor`` on every allowable stress at the
    largest working force of the rate's upper tolerance; a design with ``reasons`` when
    there is none (never an exception for a requirement no spring meets).

    Behind a pulley the initial tension is the middle of the windable band, lowered to
    k_w (d_min − slack margin) but not below the band; a spring whose band lies above that
    is refused (the cable would go slack), and when every spring is, the reason says so and
    ``needed_distance`` gives the shortest distance some spring would allow. Attached
    directly, the candidates whose hooks need at most one coil diameter each beyond machine
    hooks to make up the given free length come first (otherwise the least excess, with a
    warning)."""
    m = material(mat)
    rules = _Rules(envelope, rate_tolerance, min_safety_factor)
    why = _invalid(requirement)
    if why is not None:
        return _failed(m, requirement, rules, (why,))
    g = _grid(m, requirement.rate)
    return _choose(m, requirement, g, rules, _initial_tension(g, requirement))


def redesign_at(made: SpringDesign, requirement: Requirement) -> SpringDesign:
    """The same wound spring (wire, mean diameter, body coils) checked against
    ``requirement``, with the material, envelope, rate tolerance and safety factor it was
    designed with: the geometry re-solved for its wound rate moves the working forces a
    little, and the spring must not change then. Behind a pulley it keeps its initial
    tension when that still keeps every rule, else takes it by the rule of :func:`design`.
    A design with ``reasons`` when the spring no longer keeps the rules (or ``made`` has
    none)."""
    m = made.material
    rules = _Rules(made.envelope, made.rate_tolerance, made.min_safety_factor)
    why = _invalid(requirement) or ("; ".join(made.reasons) if not made.ok else None)
    if why is not None:
        return _failed(m, requirement, rules, (why,))
    one = np.array([made.wire_diameter]), np.array([made.mean_diameter]), np.array([made.body_coils])
    g = _springs(m, requirement.rate, *one)
    if requirement.pulley:
        same = np.array([made.initial_tension])
        if all(bool(ok[0]) for _, ok in _stages(g, requirement, same, rules)):
            return _choose(m, requirement, g, rules, same)
    again = _choose(m, requirement, g, rules, _initial_tension(g, requirement))
    if again.ok:
        return again
    spring = f"the wound spring (wire {1e3 * made.wire_diameter:g} mm, mean diameter {1e3 * made.mean_diameter:g} mm, {made.body_coils:g} body coils)"
    return replace(again, reasons=tuple(f"{spring}: {why}" for why in again.reasons))


def redesign_on_side(made: SpringDesign, side: int) -> SpringDesign:
    """The lightest spring for ``made``'s requirement, with its material, envelope, rate
    tolerance and safety factor, wound to a rate on ``side`` of the design rate (+1 at or
    above, −1 at or below)."""
    return design(replace(made.requirement, rate_side=side), made.material, made.envelope, made.rate_tolerance, made.min_safety_factor)


def _failed(m: Material, r: Requirement, rules: _Rules, reasons: tuple[str, ...], needed: float = math.nan) -> SpringDesign:
    return SpringDesign(
        m, r, reasons=reasons, rate_tolerance=rules.rate_tolerance, min_safety_factor=rules.min_safety_factor, envelope=rules.envelope, needed_distance=needed
    )


def _choose(m: Material, r: Requirement, g: dict[str, np.ndarray], rules: _Rules, F0: np.ndarray) -> SpringDesign:
    """The lightest candidate of ``g`` with initial tensions ``F0`` that keeps every rule,
    or the reason of the first rule none keeps."""
    d, D, rate = g["d"], g["D"], g["rate"]
    capacity = g["capacity"]
    keep = np.ones(d.shape, dtype=bool)
    for stage, ok in _stages(g, r, F0, rules):
        if not np.any(keep & ok):
            needed = _needed(g, r, rules)
            return _failed(m, r, rules, (_reason(stage, m, r, g, rules, keep, F0, needed),), needed)
        keep &= ok
    f = _forces(g, r, F0)
    lo, hi, free, L_hi = f["lo"], f["hi"], f["free"], f["L_hi"]
    mass, L0 = g["mass"], g["L0"]
    long_hooks = np.maximum((free - L0) / 2.0 - D, 0.0) if not r.pulley else np.zeros(d.shape)
    order = np.lexsort((hi / capacity, np.where(keep, mass, np.inf), np.where(keep, long_hooks, np.inf)))
    i = int(order[0])
    f0 = float(F0[i])
    warnings: tuple[str, ...] = ()
    if long_hooks[i] > 0:
        warnings += (
            f"its free length {1e3 * float(free[i]):.4g} mm leaves {1e3 * float(free[i] - L0[i]) / 2:.4g} mm per hook beyond "
            f"machine hooks on every spring strong enough: extended hooks (or a longer cable and a shorter free length)",
        )
    f_hi = float(hi[i])
    return SpringDesign(
        warnings=warnings,
        material=m,
        requirement=r,
        wire_diameter=float(d[i]),
        mean_diameter=float(D[i]),
        body_coils=float(g["Nb"][i]),
        active_coils=float(g["Na"][i]),
        rate=float(rate[i]),
        initial_tension=f0,
        initial_tension_band=(float(g["t_lo"][i]), float(g["t_hi"][i])),
        body_length=float(g["Lb"][i]),
        free_length=float(free[i]),
        hook_extension=float(free[i] - L0[i]) / 2.0,
        force_min=float(lo[i]),
        force_max=f_hi,
        length_min=float(free[i] + max(float(lo[i]) - f0, 0.0) / rate[i]),  # attached directly: not below L0
        length_max=float(L_hi[i]),
        max_force=float(capacity[i]),
        max_length=float(free[i] + (capacity[i] - f0) / rate[i]),
        body_stress=float(ph.shear_stress(f_hi, d[i], D[i])),
        hook_bending_stress=float(ph.hook_bending_stress(f_hi, d[i], D[i])),
        hook_torsion_stress=float(ph.hook_torsion_stress(f_hi, d[i], D[i])),
        initial_stress=float(8.0 * f0 * D[i] / (math.pi * d[i] ** 3)),
        allowable_body=float(g["a_body"][i]),
        allowable_hook_bending=float(g["a_bend"][i]),
        allowable_hook_torsion=float(g["a_tors"][i]),
        mass=float(mass[i]),
        rate_tolerance=rules.rate_tolerance,
        min_safety_factor=rules.min_safety_factor,
        envelope=rules.envelope,
        needed_distance=_needed(g, r, rules),
        candidates=int(keep.sum()),
    )


def _fits(envelope: Envelope, outer: np.ndarray, body: np.ndarray, longest: np.ndarray) -> np.ndarray:
    ok = np.ones(outer.shape, dtype=bool)
    for limit, value in ((envelope.max_outer_diameter, outer), (envelope.max_body_length, body), (envelope.max_length, longest)):
        if limit is not None:
            ok &= value <= limit * (1 + 1e-12)
    return ok


def _reason(stage: str, m: Material, r: Requirement, g: dict[str, np.ndarray], rules: _Rules, keep: np.ndarray, F0: np.ndarray, needed: float) -> str:
    """Why no candidate passed ``stage`` (``keep``: those that passed the stages before)."""
    wires = f"{m.name} wire {1e3 * m.d_min:g}-{1e3 * m.d_max:g} mm"

    def least(a: np.ndarray) -> float:
        return float(np.min(np.where(keep, a, np.inf)))

    def most(a: np.ndarray) -> float:
        return float(np.max(np.where(keep, a, -np.inf)))

    tol, n = rules.rate_tolerance, rules.min_safety_factor
    if stage == "index":
        side = {1: " at or above", -1: " at or below"}.get(r.rate_side, "")
        return f"no standard {wires} winds the rate{side} {r.rate:.4g} N/m (within {100 * RATE_ROUNDING:g} %) at a spring index 4-12"
    if stage == "coils":
        return f"the rate {r.rate:.4g} N/m is too stiff for {wires}: fewer than {MIN_BODY_COILS:g} body coils at every index 4-12"
    if stage == "tension" and not r.pulley:  # direct mount: the file's initial tension
        lo, hi = least(g["t_lo"]), most(g["t_hi"])
        inside = keep & (F0 >= g["t_lo"] * (1 - 1e-12)) & (F0 <= g["t_hi"] * (1 + 1e-12))
        if np.any(inside):
            return f"its initial tension {r.initial_tension:.4g} N is not below its largest force {r.force_max:.4g} N: the spring would never extend"
        return (
            f"its initial tension {r.initial_tension:.4g} N is outside the windable band (S7) of every spring that winds the rate "
            f"{r.rate:.4g} N/m ({wires}, index 4-12): a spring can be wound only with an initial tension inside the band of its "
            f"own wire and index, and these bands span {lo:.4g}-{hi:.4g} N"
        )
    if stage == "tension":
        return (
            f"its largest force {r.force_max:.4g} N is below the smallest windable initial tension of any spring that winds the rate "
            f"({least(g['t_lo']):.4g} N): the spring would never extend"
        )
    if stage == "strength":
        f = _forces(g, r, F0)
        need = n * (F0 + (1.0 + tol) * (f["hi"] - F0))
        return (
            f"its largest force {r.force_max:.4g} N needs a spring that carries at least {least(need):.4g} N (safety factor {n:g} at the "
            f"rate's upper tolerance +{100 * tol:g} %), more than any spring of that rate carries within the allowable stresses "
            f"({wires}, index 4-12: at most {most(g['capacity']):.4g} N)"
        )
    if stage == "free length":
        return f"its free length {1e3 * (r.free_length or 0.0):.4g} mm is shorter than any strong enough spring with machine hooks ({1e3 * least(g['L0']):.4g} mm)"
    if stage == "envelope":
        return f"no spring strong enough fits the envelope ({rules.envelope.text()})"
    d_min = r.force_min / r.rate
    allowed = r.force_min - r.rate * r.slack_margin
    limit = (
        f"with the slack margin {1e3 * r.slack_margin:.4g} mm its initial tension must be at most {allowed:.4g} N"
        if allowed > 0
        else f"closer than the slack margin {1e3 * r.slack_margin:.4g} mm, where no initial tension keeps it extended"
    )
    others = _smallest_tension(g, r, rules)
    i = int(np.argmin(np.where(others, g["t_lo"] / g["rate"], np.inf)))
    return (
        f"no windable spring strong enough keeps its cable taut: behind a pulley it pulls k·d only while d ≥ F0/k, and the ends "
        f"come within {1e3 * d_min:.4g} mm, {limit}; the spring of the smallest F0/k that keeps every other rule needs "
        f"F0 ≥ {float(g['t_lo'][i]):.4g} N to be windable, so the ends must stay at least {1e3 * needed:.4g} mm apart "
        f"(F0/k + slack margin)"
    )


def smallest_initial_tension(
    rate: float,
    force_max: float,
    mat: "str | Material" = DEFAULT_MATERIAL,
    envelope: Envelope = Envelope(),
    rate_tolerance: float = RATE_TOLERANCE,
    min_safety_factor: float = MIN_SAFETY_FACTOR,
) -> float:
    """The smallest windable initial tension (N) of the springs of ``mat`` behind a pulley
    that wind ``rate`` (N/m) and keep every rule but the slack rule for a largest working
    force ``force_max`` (N) within ``envelope``: with it, such a spring stays extended
    where the ends are at least F0/rate + slack margin apart. ``math.inf`` when no spring
    keeps the other rules; a ``ValueError`` for a rate or force that is not positive."""
    if not (math.isfinite(rate) and rate > 0 and math.isfinite(force_max) and force_max > 0):
        raise ValueError(f"rate {rate!r} N/m and force_max {force_max!r} N must be positive")
    g = _grid(material(mat), float(rate))
    r = Requirement(rate=float(rate), force_min=float(force_max), force_max=float(force_max))
    keep = _smallest_tension(g, r, _Rules(envelope, rate_tolerance, min_safety_factor))
    return float(np.min(g["t_lo"][keep])) if np.any(keep) else math.inf


@functools.lru_cache(maxsize=256)
def _largest(key: str, max_outer_diameter: float | None, max_body_length: float | None, min_safety_factor: float, rate_tolerance: float) -> float:
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
    force = _springs(m, 1.0, d, D, np.full(d.shape, MIN_BODY_COILS))["capacity"]
    return float(np.max(force[ok])) / (min_safety_factor * (1.0 + rate_tolerance)) if np.any(ok) else 0.0


def largest_force(
    mat: "str | Material" = DEFAULT_MATERIAL,
    max_outer_diameter: float | None = None,
    max_body_length: float | None = None,
    min_safety_factor: float = MIN_SAFETY_FACTOR,
    rate_tolerance: float = RATE_TOLERANCE,
) -> float:
    """The largest working force (N) a spring of ``mat`` designable within the rules
    (standard wire of the material, index 4-12, at least :data:`MIN_BODY_COILS` body coils)
    and the envelope (m; None: no limit) may have: the largest capacity (force at the first
    allowable stress) divided by ``min_safety_factor`` × (1 + ``rate_tolerance``), so that
    the force at the rate's upper tolerance keeps the safety factor whatever the initial
    tension (a positive one allows a little more: F0 + (1 + tol)(F − F0) < (1 + tol) F).
    Pure and cached (some 10,000 candidates the first time, a dictionary look-up after).
    0.0 when no standard wire fits the envelope."""
    key = material(mat).key
    return _largest(key, max_outer_diameter, max_body_length, float(min_safety_factor), float(rate_tolerance))


def force_limit(options: object) -> float:
    """The default force limit (N) of a designed spring: :func:`largest_force` for a
    spring's design options (``ZeroFreeLengthSpring.design``: material, envelope, smallest
    safety factor, rate tolerance)."""
    return largest_force(
        getattr(options, "material", DEFAULT_MATERIAL),
        getattr(options, "max_outer_diameter", None),
        getattr(options, "max_body_length", None),
        getattr(options, "min_safety_factor", MIN_SAFETY_FACTOR),
        getattr(options, "rate_tolerance", RATE_TOLERANCE),
    )

