"""Designed helical extension springs (counterpoise.springs; docs/springs.md).

The worked example of docs/springs.md is checked against its hand values to 3 digits; the
winding rules are checked on designs over a grid of requirements and every material; a
requirement no spring meets gives reasons, not an exception; the shipped catalogue still
comes out of the script byte for byte; and free-stiffness problems get ``kind = designed``
rows in springs.csv through the in-process command line.
"""

from __future__ import annotations

import csv
import importlib.util
import io
import math
import sys

import numpy as np
import pytest

from conftest import PROBLEMS, ROOT, solved
from counterpoise.springs import (
    Envelope,
    Requirement,
    design,
    largest_force,
    material,
    materials,
    redesign_at,
    smallest_initial_tension,
    wire_diameters,
)
from counterpoise.springs import physics as ph

# ---------------------------------------------------------------------------------------
# The worked example of docs/springs.md ("Worked example"): k = 500 N/m, working forces
# 10-60 N behind a pulley (d = 20-120 mm), music wire, the defaults: safety factor 1.2 at
# the rate's upper tolerance +10 %, slack margin 3 mm. The design's choice is d = 1.7 mm,
# D = 16.15 mm, N_b = 39.75; every value below is derived by hand in the docs from those
# three numbers:
#   d = 1.7 mm = 0.0669 in: table 10-5's 0.064-0.125 in row, G = 81.0 GPa, E = 196.5 GPa (S1)
#   C = 16.15/1.7 = 9.5;  N_a = 39.75 + 81.0/196.5 = 40.1622                      (S5)
#   k_w = 81.0e9 · (1.7e-3)^4 / (8 · (16.15e-3)^3 · 40.1622)
#       = 0.67652 / 1.35340e-3 = 499.87 N/m (−0.026 %)                            (S4)
#   wound forces k_w·d: 9.9974-59.984 N                                           (S12)
#   τ_i band 231 e^(−0.9975) ± 6.9·3 = 85.19 ± 20.70 MPa, × π d³/(8D) = 1.19464e-7 m²
#       -> F0 band 7.705-12.650 N (middle 10.18 N)                                 (S7)
#   F0 ≤ k_w (d_min − 3 mm) = 499.87 · 0.017 = 8.498 N: inside the band, so F0 = 8.498 N
#   at +10 %: 8.498 + 1.1 (59.984 − 8.498) = 65.133 N
#   Sut = 2211 / 1.7^0.145 = 2211 / 1.07998 = 2047.3 MPa; allowables 0.45/0.75/0.40 Sut
#       = 921.3 / 1535.4 / 818.9 MPa                                               (S1, S10)
#   K_B = 40/35 = 1.14286; 8 F D/(π d³) at 59.984 N = 502.12 MPa; τ = 573.8 MPa   (S2, S3)
#   (K)_A = 350.5/323 = 1.08514; σ_A = 59.984 (1.08514·1.67416e7 + 4.40571e5) = 1116.2 MPa (S8)
#   τ_B = 1.25 · 502.12 = 627.6 MPa                                                (S9)
#   max force = 59.984 · 818.9/627.6 = 78.26 N (hook torsion binds)              (S10)
#   safety 78.26/59.984 = 1.3047 nominal, 78.26/65.133 = 1.2016 at +10 %          (S10)
#   L_b = 40.75 · 1.7 = 69.275 mm; L0 = 69.275 + 2 (16.15 − 1.7) = 98.175 mm       (S6)
#   L at d_max = L0 + d_max − F0/k_w = 98.175 + 120 − 17 = 201.175 mm              (S12)
#   mass = 7850 · π·(1.7e-3)²/4 · π·16.15e-3·41.75 = 37.74 g                       (S11)
# ---------------------------------------------------------------------------------------
EXAMPLE = Requirement(rate=500.0, force_min=10.0, force_max=60.0)


@pytest.fixture(scope="module")
def example():
    return design(EXAMPLE)


def test_worked_example_matches_its_hand_values(example):
    s = example
    assert s.ok and not s.warnings
    assert (s.wire_diameter * 1e3, s.mean_diameter * 1e3, s.body_coils) == pytest.approx((1.7, 16.15, 39.75))
    hand = {
        "index": (s.index, 9.5),
        "active coils": (s.active_coils, 40.1622),
        "wound rate N/m": (s.rate, 499.87),
        "design rate N/m": (s.design_rate, 500.0),
        "wound force min N": (s.force_min, 9.9974),
        "wound force max N": (s.force_max, 59.984),
        "allowable body MPa": (s.allowable_body * 1e-6, 921.3),
        "allowable hook bending MPa": (s.allowable_hook_bending * 1e-6, 1535.4),
        "allowable hook torsion MPa": (s.allowable_hook_torsion * 1e-6, 818.9),
        "body stress MPa": (s.body_stress * 1e-6, 573.8),
        "hook bending MPa": (s.hook_bending_stress * 1e-6, 1116.2),
        "hook torsion MPa": (s.hook_torsion_stress * 1e-6, 627.6),
        "F0 band low N": (s.initial_tension_band[0], 7.705),
        "F0 band high N": (s.initial_tension_band[1], 12.650),
        "F0 N": (s.initial_tension, 8.498),
        "force at +10 % N": (s.force_upper, 65.133),
        "body length mm": (s.body_length * 1e3, 69.275),
        "free length mm": (s.free_length * 1e3, 98.175),
        "length at 120 mm mm": (s.length_max * 1e3, 201.175),
        "max force N": (s.max_force, 78.26),
        "safety factor": (s.safety_factor, 1.3047),
        "safety factor at +10 %": (s.safety_factor_upper, 1.2016),
        "mass g": (s.mass * 1e3, 37.74),
    }
    for name, (got, want) in hand.items():
        assert got == pytest.approx(want, rel=1e-3), name
    assert s.outer_diameter * 1e3 == pytest.approx(16.15 + 1.7)
    assert s.slack_distance == pytest.approx(0.020 - 0.003)  # F0 = k_w (d_min − margin)


#: Shigley 9th ed., table 10-5 (p. 526), music wire A228, typed here from the book (not read
#: from the package's CSV): (largest diameter of the band, in; G, E in GPa)
MUSIC_WIRE_MODULI = ((0.032, 82.7, 203.4), (0.063, 81.7, 200.0), (0.125, 81.0, 196.5), (math.inf, 80.0, 193.0))


def music_wire_moduli(d):
    """G and E (Pa) of music wire of diameter d (m), the diameter to 0.001 in as the table."""
    inches = round(d / 0.0254, 3)
    return next((G * 1e9, E * 1e9) for top, G, E in MUSIC_WIRE_MODULI if inches <= top)


def test_moduli_follow_the_wire_size():
    """Table 10-5's four music-wire bands: the material gives each standard wire its band's
    G and E, and the rate (S4) and active coils (S5) use them; the other materials have one
    value for every size."""
    mat = material("music_wire")
    for d in wire_diameters(mat):
        G, E = music_wire_moduli(d)
        assert (mat.shear_modulus(d), mat.youngs_modulus(d)) == (G, E), d
        assert ph.active_coils(mat, d, 10.0) == pytest.approx(10.0 + G / E, rel=1e-15)
        assert ph.rate(mat, d, 8 * d, 12.0) == pytest.approx(G * d**4 / (8 * (8 * d) ** 3 * 12.0), rel=1e-15)
    bands = {music_wire_moduli(d) for d in wire_diameters(mat)}
    assert len(bands) == 4  # the standard series has wires in every band
    assert material("stainless_302").shear_modulus(np.array([0.3e-3, 2.5e-3])).tolist() == [69.0e9, 69.0e9]
    assert material("chrome_silicon").youngs_modulus(9.5e-3) == 203.4e9


def test_worked_example_is_the_lightest_candidate_that_keeps_the_rules(example):
    """The design is the lightest: no other wire/coil count of the enumeration that keeps
    every rule (moduli by size, safety factor 1.2 at +10 % rate, windable F0 at most
    k (d_min − 3 mm)) weighs less (checked by brute force over the same rules)."""
    mat = material("music_wire")
    k, d_min, n, tol, margin = EXAMPLE.rate, EXAMPLE.force_min / EXAMPLE.rate, 1.2, 0.1, 0.003
    for d in wire_diameters(mat):
        G, E = music_wire_moduli(d)
        for C in np.linspace(4, 12, 33):
            Nb = round((G * d / (8 * C**3 * k) - G / E) * 4) / 4
            if Nb < 3:
                continue
            Na = Nb + G / E
            D = (G * d**4 / (8 * k * Na)) ** (1 / 3)
            if not 4 <= D / d <= 12:
                continue
            low, mid = (ph.tension_of_stress(ph.initial_stress_mid(D / d) + s * ph.initial_stress_half_band(D / d), d, D) for s in (-1, 0))
            if low > k * (d_min - margin):
                continue  # would go slack within the margin
            f0 = min(k * (d_min - margin), mid)
            strong = min(0.45 / ph.shear_stress(1.0, d, D), 0.75 / ph.hook_bending_stress(1.0, d, D), 0.40 / ph.hook_torsion_stress(1.0, d, D))
            if strong * ph.tensile_strength(mat, d) < n * (f0 + (1 + tol) * (EXAMPLE.force_max - f0)):
                continue
            assert ph.mass(mat, d, D, Nb) >= example.mass * (1 - 2e-3), (d, C)


def test_the_slack_rule_is_tight_and_names_the_distance_it_needs(example):
    """``needed_distance`` is the shortest d_min some spring allows: a requirement with its
    ends that far apart is designed, 0.1 mm closer it is refused with a reason that gives
    the distance (never a warning). ``smallest_initial_tension`` is tight likewise: an
    allowed F0 of 1 % above it is designable, 1 % below it is not (the wound rate is
    within 0.5 % of the design rate, so the margin is 1 %)."""
    need = example.needed_distance
    assert 0.003 < need < 0.020  # the example's own spring would do at 17 + 3 mm
    at = design(Requirement(rate=500.0, force_min=500.0 * need, force_max=60.0))
    assert at.ok and at.initial_tension <= at.rate * (need - 0.003) * (1 + 1e-9)
    closer = design(Requirement(rate=500.0, force_min=500.0 * (need - 1e-4), force_max=60.0))
    assert not closer.ok and not closer.warnings
    assert "cable taut" in closer.reasons[0] and f"{1e3 * need:.4g} mm apart" in closer.reasons[0]
    assert closer.needed_distance == pytest.approx(need)
    f0 = smallest_initial_tension(500.0, 60.0)
    assert 0 < f0 < example.initial_tension
    margin0 = {"slack_margin": 0.0}
    assert design(Requirement(rate=500.0, force_min=1.01 * f0, force_max=60.0, **margin0)).ok
    below = design(Requirement(rate=500.0, force_min=0.99 * f0, force_max=60.0, **margin0))
    assert not below.ok and "cable taut" in below.reasons[0]
    assert smallest_initial_tension(500.0, 1e4) == math.inf  # no spring of that rate carries 10 kN
    with pytest.raises(ValueError):
        smallest_initial_tension(0.0, 60.0)


def test_redesign_at_keeps_the_wound_spring(example):
    """The geometry re-solved for the wound rate moves the forces a little: the same
    spring (wire, diameter, coils) is kept, with its initial tension while that keeps
    every rule; 1 mm closer it lowers F0 inside its band (still 1.2 at +10 %); 10 mm closer,
    or a stiffer rate, it fails with reasons naming the wound spring (never another spring)."""
    s = example
    kw = s.rate
    same = redesign_at(s, Requirement(rate=kw, force_min=kw * 0.0201, force_max=kw * 0.1199))
    assert same.ok and (same.wire_diameter, same.mean_diameter, same.body_coils, same.initial_tension) == (
        s.wire_diameter, s.mean_diameter, s.body_coils, s.initial_tension)  # fmt: skip
    assert same.rate == s.rate and same.rate_error == pytest.approx(0.0, abs=1e-15)
    lower = redesign_at(s, Requirement(rate=kw, force_min=kw * 0.019, force_max=kw * 0.12))
    assert lower.ok and lower.wire_diameter == s.wire_diameter and lower.body_coils == s.body_coils
    assert lower.initial_tension == pytest.approx(kw * (0.019 - 0.003)) and lower.safety_factor_upper >= 1.2
    slack = redesign_at(s, Requirement(rate=kw, force_min=kw * 0.010, force_max=kw * 0.12))
    assert not slack.ok and slack.reasons[0].startswith("the wound spring (wire 1.7 mm") and "cable taut" in slack.reasons[0]
    # this spring's own F0 (its band's bottom, 7.705 N) needs F0/k_w + 3 mm = 18.41 mm
    assert slack.needed_distance == pytest.approx(s.initial_tension_band[0] / kw + 0.003)
    stiffer = redesign_at(s, Requirement(rate=1.01 * kw, force_min=kw * 0.02, force_max=kw * 0.12))
    assert not stiffer.ok and "winds the rate" in stiffer.reasons[0]
    strong = redesign_at(s, Requirement(rate=kw, force_min=kw * 0.02, force_max=kw * 0.15))
    assert not strong.ok and "allowable stresses" in strong.reasons[0]


def test_springs_of_one_rate_share_the_kept_candidates_and_design_as_fresh_ones():
    """The (wire, index) candidates of a rate are computed once and kept (read-only); a
    design from the kept candidates is the design computed afresh, field for field, for
    two requirements of one rate (the springs of a problem often share a rate)."""
    import sys

    module = sys.modules["counterpoise.springs.design"]
    second = Requirement(rate=EXAMPLE.rate, force_min=0.5 * EXAMPLE.force_min, force_max=0.9 * EXAMPLE.force_max)
    module._grid.cache_clear()
    kept = [design(EXAMPLE), design(second)]
    assert module._grid.cache_info().misses == 1 and module._grid.cache_info().hits == 1
    grid = module._grid(material("music_wire"), EXAMPLE.rate)
    assert not any(a.flags.writeable for a in grid.values())
    fresh = []
    for r in (EXAMPLE, second):
        module._grid.cache_clear()
        module._wires.cache_clear()
        fresh.append(design(r))
    assert kept == fresh and kept[0] != kept[1]


REQUIREMENTS = [
    Requirement(rate=k, force_min=f * lo, force_max=f)
    for k in (50.0, 300.0, 2000.0, 20000.0)
    for f in (2.0, 20.0, 150.0, 600.0)
    for lo in (0.0, 0.5, 0.9)  # 0: d_min = 0, always slack (a reason)
]


@pytest.mark.parametrize("key", sorted(materials()))
def test_designs_keep_the_winding_rules(key):
    """Acceptance: the wound rate k_w = G d⁴/(8 D³ N_a) (G, E of the wire's size) within
    0.5 % of the design rate, every stress within its allowable, the safety factor ≥ 1.2 at
    the wound spring's largest force F0 + 1.1 (F_max − F0) of the rate's upper tolerance,
    index 4-12, initial tension in the windable band (never 0 N) and, behind a pulley, at
    most k_w (d_min − 3 mm), at least 3 body coils, a standard wire of the material;
    otherwise reasons (never an exception, never a warning)."""
    mat = material(key)
    designed = 0
    for r in REQUIREMENTS:
        s = design(r, key)
        assert not s.warnings
        if not s.ok:
            assert s.reasons and all(isinstance(t, str) and t for t in s.reasons)
            assert math.isnan(s.wire_diameter)
            continue
        designed += 1
        d = s.wire_diameter
        G, E = mat.shear_modulus(d), mat.youngs_modulus(d)
        rate = G * d**4 / (8 * s.mean_diameter**3 * s.active_coils)
        assert rate == pytest.approx(s.rate, rel=1e-12)
        assert abs(rate / r.rate - 1) <= 0.005, r
        # behind a pulley the wound spring pulls k_w·d over the requirement's distances
        assert (s.force_min, s.force_max) == pytest.approx((r.force_min * rate / r.rate, r.force_max * rate / r.rate), rel=1e-12)
        assert s.body_stress <= s.allowable_body * (1 + 1e-12)
        assert s.hook_bending_stress <= s.allowable_hook_bending * (1 + 1e-12)
        assert s.hook_torsion_stress <= s.allowable_hook_torsion * (1 + 1e-12)
        upper = s.initial_tension + 1.1 * (s.force_max - s.initial_tension)
        assert s.max_force >= 1.2 * upper * (1 - 1e-12) and s.safety_factor_upper >= 1.2 * (1 - 1e-12)
        assert s.safety_factor == pytest.approx(s.max_force / s.force_max) and s.safety_factor > s.safety_factor_upper
        assert 4 - 1e-9 <= s.index <= 12 + 1e-9
        assert 0 < s.initial_tension_band[0] * (1 - 1e-12) <= s.initial_tension <= s.initial_tension_band[1] * (1 + 1e-12)
        assert s.initial_tension <= rate * (r.force_min / r.rate - 0.003) * (1 + 1e-12)  # never slack, 3 mm to spare
        assert s.body_coils >= 3 and s.active_coils == pytest.approx(s.body_coils + G / E)
        assert any(d == pytest.approx(w) for w in wire_diameters(mat))
        assert s.free_length <= s.length_min <= s.length_max <= s.max_length
        assert s.needed_distance <= r.force_min / r.rate * (1 + 1e-9)
    assert designed >= len(REQUIREMENTS) // 4  # the grid is not all out of reach


def test_a_force_beyond_every_spring_gives_reasons():
    limit = largest_force()
    s = design(Requirement(rate=5000.0, force_min=100.0, force_max=1.5 * limit))
    assert not s.ok and "allowable stresses" in s.reasons[0] and "upper tolerance" in s.reasons[0]
    assert largest_force(max_outer_diameter=0.003) < EXAMPLE.force_max  # so no spring within 3 mm carries 60 N
    s = design(EXAMPLE, envelope=Envelope(max_outer_diameter=0.003))
    assert not s.ok and "envelope (outer diameter ≤ 3 mm)" in s.reasons[0]
    s = design(Requirement(rate=-1.0, force_min=1.0, force_max=2.0))
    assert not s.ok and "not positive" in s.reasons[0]


def test_envelope_is_kept():
    """With the worked example's requirement and an outer diameter of at most 17.5 mm (the
    example's is 17.85 mm), a body of at most 60 mm (its is 69.3 mm) or a working length
    of at most 195 mm (its is 201.2 mm), another spring is chosen within it."""
    s = design(EXAMPLE, envelope=Envelope(max_outer_diameter=0.0175))
    assert s.ok and s.outer_diameter <= 0.0175
    s = design(EXAMPLE, envelope=Envelope(max_body_length=0.06))
    assert s.ok and s.body_length <= 0.06
    s = design(EXAMPLE, envelope=Envelope(max_length=0.195))
    assert s.ok and s.length_max <= 0.195
    s = design(EXAMPLE, envelope=Envelope(max_length=0.12))  # the stroke alone is 100 mm
    assert not s.ok and "working length ≤ 120 mm" in s.reasons[0]


def test_default_envelope_refuses_a_spring_longer_than_twice_the_mechanism():
    """A soft spring for a 1 m mechanism (k = 0.0273 N/m, d = 0.9-1 m): without an
    envelope the lightest spring is thousands of coils of 0.1 mm wire, 2.4 m long; the
    default envelope of a 1 m mechanism (working length ≤ 2 m, outer diameter ≤ 100 mm)
    refuses it, and no spring of that rate fits."""
    from counterpoise.model.elements import SpringDesignOptions
    from counterpoise.springs.workspace import envelope

    need = Requirement(rate=0.0273, force_min=0.0273 * 0.9, force_max=0.0273)
    free = design(need)
    assert free.ok and free.body_coils > 10_000 and free.length_max > 2.0
    default = envelope(SpringDesignOptions(), 1.0)
    assert default == Envelope(max_outer_diameter=0.1, max_body_length=None, max_length=2.0)
    s = design(need, envelope=default)
    assert not s.ok and "envelope (outer diameter ≤ 100 mm, working length ≤ 2000 mm)" in s.reasons[0]
    # the file's limits replace the defaults one by one; a direct mount's own max_length is its limit
    given = envelope(SpringDesignOptions(max_outer_diameter=0.02, max_body_length=0.3), 1.0)
    assert given == Envelope(max_outer_diameter=0.02, max_body_length=0.3, max_length=2.0)
    assert envelope(SpringDesignOptions(max_length=0.5), 1.0, direct_max_length=0.6).max_length == 0.5
    assert envelope(SpringDesignOptions(), 1.0, direct_max_length=0.6).max_length == 0.6
    assert envelope(SpringDesignOptions(), 0.0) == Envelope()


def test_direct_mount_keeps_the_given_initial_tension_and_free_length():
    """A directly attached spring: F0 and L0 are the file's; the hooks take up the length
    the body leaves, and a F0 outside the windable band is a reason."""
    r = Requirement(rate=500.0, force_min=10.0, force_max=60.0, initial_tension=10.0, free_length=0.2)
    s = design(r)
    assert s.ok and s.initial_tension == 10.0 and s.free_length == 0.2 and s.hook_extension >= 0
    assert s.length_max == pytest.approx(0.2 + 50.0 / 500.0)  # the geometry sets it: L0 + (F_max − F0)/k
    s = design(Requirement(rate=500.0, force_min=0.0, force_max=60.0, initial_tension=0.0, free_length=0.2))
    assert not s.ok and "initial tension 0 N is outside the windable band" in s.reasons[0]
    # the text gives the span of the bands of the springs that wind the rate
    grid = sys.modules["counterpoise.springs.design"]._grid(material("music_wire"), 500.0)
    ok = grid["index"] & grid["coils"]
    span = f"these bands span {grid['t_lo'][ok].min():.4g}-{grid['t_hi'][ok].max():.4g} N"
    assert span in s.reasons[0] and grid["t_lo"][ok].min() > 0


def test_directly_attached_free_stiffness_spring_is_designed_with_the_files_tension_and_length(tmp_path):
    """The arm of tests/test_direct_springs.py with a free-stiffness spring attached
    directly (L0 = 300 mm, F0 = 10 N): the designed spring keeps that F0 (inside its band)
    and that L0 (the hooks take up what the body leaves); its length is d − cable and its
    force F0 + k (d − cable − L0) over the checked configurations."""
    from test_direct_springs import arm

    from counterpoise.pipeline import design as solve

    problem = arm(tmp_path, 'stiffness = "k"\nfree_length = "300 mm"\ninitial_tension = "10 N"\nmax_length = "0.6 m"')
    (u,) = solve(problem).springs
    s = u.design
    assert u.mount == "direct" and s.ok, s.reasons
    assert s.initial_tension == 10.0 and s.initial_tension_band[0] <= 10.0 <= s.initial_tension_band[1]
    assert s.free_length == pytest.approx(0.3) and s.body_length + 2 * (s.mean_diameter - s.wire_diameter) <= 0.3
    assert s.hook_extension == pytest.approx((0.3 - s.body_length - 2 * (s.mean_diameter - s.wire_diameter)) / 2)
    assert u.length_min == pytest.approx(max(u.distance_min - u.cable, 0.3))
    # the wound spring's force: F0 + k_w (d − cable − L0), k_w within 0.5 % of k = 200 N/m (the arm's file)
    assert u.force_max == pytest.approx(10.0 + s.rate * (u.distance_max - u.cable - 0.3))
    assert s.design_rate == 200.0 and abs(s.rate / 200.0 - 1) <= 0.005
    assert s.max_force >= u.force_max


SPRING_ARM = """
[problem]
name = "spring_arm"

[gravity]
acceleration = "9.81 m/s^2"
direction = [0, -1, 0]

[parameters]
m = "1 kg"
r = "0.3 m"
h = "0.4 m"
b = "0.3 m"

[variables.k]
lower = "0 N/m"
upper = "1000 N/m"
initial = "10 N/m"

[subsystems.arm]
coordinates.phi = {{ range = ["-45 deg", "55 deg"], home = "0 deg" }}

[frames.link]
transforms = [{{ rotate = "z", angle = "phi" }}]

[bodies.link]
frame = "link"
mass = "m"
com = ["r", 0, 0]

[springs.s]
stiffness = "k"
from = {{ frame = "ground", point = [0, "h", 0] }}
to = {{ frame = "link", point = ["b", 0, 0] }}
{extra}
"""


def spring_arm(tmp_path, extra=""):
    """A 1R arm (1 kg at r = 0.3 m) balanced by a spring from h = 0.4 m above the pivot to
    b = 0.3 m along the link: k = m g r/(h b) = 24.525 N/m; d = √(h² + b² − 2hb sin φ)
    over φ −45°..55°: 231.1-647.8 mm. Solved, with the spring designed after the solve."""
    from counterpoise.io.loader import load_problem
    from counterpoise.pipeline import design as solve

    path = tmp_path / "spring_arm.toml"
    path.write_text(SPRING_ARM.format(extra=extra), encoding="utf-8")
    result = solve(load_problem(path))
    (u,) = result.springs
    return result, u


def test_mechanism_size_and_the_default_envelope(tmp_path):
    """At home (φ = 0) the arm's points are the pivot (0, 0), the centre of mass (0.3, 0),
    and the spring's ends (0, 0.4) and (0.3, 0): its size is their largest distance,
    √(0.3² + 0.4²) = 0.5 m, so the default envelope is a working length ≤ 1 m and an outer
    diameter ≤ 50 mm, and the spring designed within it keeps every rule."""
    from counterpoise.mechanics import Mechanics
    from counterpoise.springs.workspace import mechanism_size

    result, u = spring_arm(tmp_path)
    problem = result.problem
    mech = Mechanics(problem, {p.name: p.value for p in problem.parameters if p.is_base}, {"k": 24.525}, {"phi": 0.0}, [0.0, -9.81, 0.0])
    assert mechanism_size(problem, mech) == pytest.approx(0.5, rel=1e-12)
    s = u.design
    assert s.envelope == Envelope(max_outer_diameter=0.05, max_body_length=None, max_length=1.0)
    assert s.ok and s.outer_diameter <= 0.05 and s.length_max <= 1.0
    assert s.design_rate == pytest.approx(9.81 * 0.3 / (0.4 * 0.3))
    assert u.distance_min == pytest.approx(math.sqrt(0.25 - 0.24 * math.sin(math.radians(55))), rel=1e-6)
    assert u.margin_slack >= 0.003 * (1 - 1e-9) and s.safety_factor_upper >= 1.2


def test_the_files_envelope_slack_margin_and_safety_factor_reach_the_design(tmp_path):
    """``max_length`` behind a pulley (the stroke alone is 647.8 − 231.1 = 417 mm, so no
    spring works within 400 mm), ``slack_margin`` (240 mm: more than d_min, no initial
    tension keeps the spring extended) and ``min_safety_factor`` from [springs.<name>]."""
    _, short = spring_arm(tmp_path, 'max_length = "400 mm"')
    assert not short.ok and "envelope (outer diameter ≤ 50 mm, working length ≤ 400 mm)" in short.design.reasons[0]
    _, margin = spring_arm(tmp_path, 'slack_margin = "240 mm"')
    assert not margin.ok and "closer than the slack margin 240 mm" in margin.design.reasons[0]
    assert margin.design.needed_distance > 0.24 and margin.design.requirement.slack_margin == 0.24
    _, safe = spring_arm(tmp_path, "min_safety_factor = 2")
    assert safe.ok and safe.design.safety_factor_upper >= 2 and safe.design.min_safety_factor == 2


def test_the_lamps_springs_keep_every_rule_in_the_default_envelope():
    """problems/lamp_robust.toml: both designed springs keep every rule within the default
    envelope of the lamp's size (working length ≤ 2 s, outer diameter ≤ 0.1 s)."""
    from conftest import solved

    result = solved("lamp_robust")
    for u in result.springs:
        s = u.design
        assert s.ok, (u.spring, s.reasons)
        size = s.envelope.max_length / 2.0
        assert s.envelope.max_outer_diameter == pytest.approx(0.1 * size) and 0.3 < size < 1.5  # a desk lamp
        assert s.length_max <= 2.0 * size and s.outer_diameter <= 0.1 * size
        assert s.safety_factor_upper >= 1.2 and u.margin_slack >= 0.003 * (1 - 1e-9)


def test_largest_force_is_monotone_in_the_envelope_and_cheap():
    """A bigger envelope carries more; the no-envelope value for music wire is the
    capacity of its thickest standard wire (6.5 mm) at index 4."""
    full = largest_force()
    assert largest_force(max_outer_diameter=0.02) < full
    assert largest_force(max_outer_diameter=0.01) < largest_force(max_outer_diameter=0.02)
    assert largest_force(max_body_length=0.01) < full
    # the defaults: safety factor 1.2 at the rate's upper tolerance +10 %
    assert largest_force(min_safety_factor=2.4) == pytest.approx(full / 2)
    capacity = largest_force(min_safety_factor=1.0, rate_tolerance=0.0)
    assert full == pytest.approx(capacity / (1.2 * 1.1))
    assert largest_force(max_outer_diameter=1e-4) == 0.0
    # a spring's options from the problem file give the same limit
    from counterpoise.model.elements import SpringDesignOptions
    from counterpoise.springs import force_limit

    options = SpringDesignOptions(material="stainless_302", max_outer_diameter=0.01, min_safety_factor=1.5, rate_tolerance=0.05)
    assert force_limit(options) == largest_force("stainless_302", 0.01, None, 1.5, 0.05)
    assert force_limit(SpringDesignOptions()) == full
    mat = material("music_wire")
    d = 6.5e-3
    D = 4 * d
    thickest = ph.tensile_strength(mat, d) * min(0.45 / ph.shear_stress(1.0, d, D), 0.75 / ph.hook_bending_stress(1.0, d, D), 0.40 / ph.hook_torsion_stress(1.0, d, D))
    assert capacity == pytest.approx(thickest, rel=1e-9)
    # every material: a spring just below its limit is designable at a rate of that scale
    for key in materials():
        f = largest_force(key, max_outer_diameter=0.03)
        assert f > 0
        s = design(Requirement(rate=f / 0.1, force_min=0.5 * f, force_max=0.95 * f), key, Envelope(max_outer_diameter=0.03))
        assert s.ok or "allowable" not in s.reasons[0], s.reasons


def test_catalogue_script_uses_the_package_and_its_output_is_unchanged():
    """scripts/make_spring_catalogue.py computes with counterpoise.springs; the shipped
    catalogue is still exactly what it generates (--check writes nothing)."""
    spec = importlib.util.spec_from_file_location("make_spring_catalogue", ROOT / "scripts" / "make_spring_catalogue.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    assert script.ph is ph and script.MUSIC_WIRE is material("music_wire")
    assert script.main(["--check"]) == 0


@pytest.mark.parametrize("name", ["yasir2019_hybrid", "fourbar_springs"])
def test_designed_springs_are_sized_on_the_sample_catalogue_parts_are_checked_on(name):
    """The after-solve sample (drawn from the mechanics layer, without importing the part
    search) is the catalogue check's, draw for draw: an open chain and a closed loop."""
    from counterpoise.io.loader import load_problem
    from counterpoise.mechanics.closure import scenario_base
    from counterpoise.selection.geometry import sample_configurations
    from counterpoise.springs.workspace import SEED_OFFSET, sample

    problem = load_problem(PROBLEMS / f"{name}.toml", {"settings.verify_samples": 500})
    seed = problem.settings.seed + SEED_OFFSET
    theirs = sample_configurations(problem, 500, seed)
    mine = sample(problem, scenario_base(problem, problem.scenarios[0].name), 500, seed)
    assert theirs.keys() == mine.keys()
    for key in theirs:
        np.testing.assert_array_equal(theirs[key], mine[key])


def _rows(capsys, tmp_path, name):
    """springs.csv and status.txt of problems/<name>.toml as ``counterpoise solve`` writes
    them, from the design the test run shares (``conftest.solved``: the shipped file is not
    designed again here)."""
    from counterpoise.report.files import write_reports

    result = solved(name)
    assert result.optimal, result.message  # what exit status 0 of the solve says
    folder = write_reports(result, tmp_path)
    rows = list(csv.DictReader(io.StringIO((folder / "springs.csv").read_text())))
    return rows, (folder / "status.txt").read_text()


def test_free_stiffness_problems_get_designed_spring_rows(capsys, tmp_path):
    """problems/fourbar_springs.toml (two free-stiffness springs behind pulleys): one
    ``designed`` row each with the maker's spec, and a status line per spring. A spring
    whose ends come closer than any windable spring allows (the rocker's, where the solve
    does not keep its distance: that is the realisation layer's constraint) is refused with
    the distance it needs, not designed with a warning."""
    rows, status = _rows(capsys, tmp_path, "fourbar_springs")
    designed = {r["spring"]: r for r in rows if r["kind"] == "designed"}
    assert set(designed) == {"crank_spring", "rocker_spring"}
    refused = {name: r for name, r in designed.items() if r["note"]}
    assert "crank_spring" not in refused
    for name, r in refused.items():
        assert f"designed spring {name}: none within the rules: no windable spring strong enough keeps its cable taut" in status
        needed = float(r["note"].split("must stay at least ")[1].split(" mm")[0])
        assert needed > float(r["min_distance_mm"]) + 3.0 and r["wire_diameter_mm"] == ""
    for name, r in designed.items():
        if name in refused:
            continue
        assert f"designed spring {name}: music wire ASTM A228" in status
        assert r["material"] == "music wire ASTM A228" and float(r["rate_tolerance"]) == 0.1
        assert 4 <= float(r["spring_index"]) <= 12
        assert float(r["body_stress_MPa"]) <= float(r["allowable_body_MPa"])
        assert float(r["max_force_N"]) <= float(r["part_max_load_N"])
        # behind a pulley the wound spring pulls k_w·d: its largest force is the wound rate
        # × the largest distance; the wound rate is within 0.5 % of the design rate
        wound, designed = float(r["wound_rate_N_per_mm"]), float(r["design_rate_N_per_mm"])
        assert float(r["rate_N_per_mm"]) == wound and abs(wound / designed - 1) <= 0.005
        assert float(r["max_force_N"]) == pytest.approx(float(r["max_distance_mm"]) * wound, rel=1e-9)
        # safety factor 1.2 at the upper rate tolerance: F0 + 1.1 (F_max − F0)
        f0, f_max, capacity = float(r["initial_tension_N"]), float(r["max_force_N"]), float(r["part_max_load_N"])
        assert float(r["safety_factor_upper_rate"]) == pytest.approx(capacity / (f0 + 1.1 * (f_max - f0)), rel=1e-5)
        assert float(r["safety_factor_upper_rate"]) >= 1.2 and float(r["safety_factor_nominal_rate"]) > float(r["safety_factor_upper_rate"])
        assert float(r["margin_slack_mm"]) >= 3.0 * (1 - 1e-6)  # never slack, the default margin to spare
        for column in ("wire_diameter_mm", "outer_diameter_mm", "body_length_mm", "free_length_mm", "initial_tension_N", "mass_g"):
            assert float(r[column]) > 0, column


def test_payload_problem_gets_a_summary_row_per_spring(capsys, tmp_path):
    """problems/woo2019_springs.toml (a payload range, free stiffnesses): a row per payload
    of the schedule and one ``all`` row per spring with the extremes over all of them."""
    rows, _ = _rows(capsys, tmp_path, "woo2019_springs")
    designed = [r for r in rows if r["kind"] == "designed"]
    for spring in ("k1", "k2"):
        mine = [r for r in designed if r["spring"] == spring]
        summary = [r for r in mine if r["scenario"] == "all"]
        assert len(summary) == 1 and len(mine) > 2
        rest = [r for r in mine if r["scenario"] != "all"]
        assert float(summary[0]["max_force_N"]) == max(float(r["max_force_N"]) for r in rest)
        assert float(summary[0]["min_distance_mm"]) == min(float(r["min_distance_mm"]) for r in rest)
        assert len({r["wire_diameter_mm"] for r in mine}) == 1  # one spring is made for every payload


def test_design_options_from_the_problem_file(capsys, tmp_path):
    """material, max_outer_diameter and rate_tolerance on [springs.<name>] reach the design."""
    text = (PROBLEMS / "fourbar_springs.toml").read_text()
    text = text.replace('[springs.crank_spring]\n', '[springs.crank_spring]\nmaterial = "stainless_302"\nmax_outer_diameter = "4 mm"\nrate_tolerance = "5 %"\n', 1)
    assert "stainless_302" in text
    path = tmp_path / "fourbar_springs.toml"
    path.write_text(text)
    from counterpoise.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["solve", str(path), "--out", str(tmp_path / "out")])
    # a spring that cannot be made within these options makes the design infeasible (exit 1)
    assert exit_.value.code in (0, 1)
    capsys.readouterr()
    rows = list(csv.DictReader(io.StringIO((tmp_path / "out" / "fourbar_springs" / "springs.csv").read_text())))
    crank = next(r for r in rows if r["spring"] == "crank_spring")
    if exit_.value.code == 1:
        assert crank["note"] and "crank_spring" in (tmp_path / "out" / "fourbar_springs" / "status.txt").read_text()
    assert crank["material"] == "stainless steel 302" and float(crank["rate_tolerance"]) == 0.05
    assert crank["note"] or float(crank["outer_diameter_mm"]) <= 4.0


def test_design_option_defaults_are_the_designs():
    """SpringDesignOptions (the model layer, which imports no spring code) and the design's
    defaults agree: safety factor 1.2, slack margin 3 mm, rate tolerance 10 %."""
    from counterpoise.model.elements import SLACK_MARGIN as SPRING_SLACK_MARGIN
    from counterpoise.model.elements import SpringDesignOptions
    from counterpoise.springs import MIN_SAFETY_FACTOR, RATE_TOLERANCE, SLACK_MARGIN

    o = SpringDesignOptions()
    assert (o.min_safety_factor, SPRING_SLACK_MARGIN, o.rate_tolerance) == (MIN_SAFETY_FACTOR, SLACK_MARGIN, RATE_TOLERANCE) == (1.2, 0.003, 0.1)
    assert (o.max_length, o.max_outer_diameter, o.max_body_length) == (None, None, None)
