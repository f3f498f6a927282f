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

import numpy as np
import pytest

from conftest import PROBLEMS, ROOT
from counterpoise.springs import Envelope, Requirement, design, largest_force, material, materials, wire_diameters
from counterpoise.springs import physics as ph

# ---------------------------------------------------------------------------------------
# The worked example of docs/springs.md ("Worked example"): k = 500 N/m, working forces
# 10-60 N behind a pulley, music wire. The design's choice is d = 1.2 mm, D = 7.74 mm,
# N_b = 91; every value below is derived by hand in the docs from those three numbers:
#   C = 7.74/1.2 = 6.45;  N_a = 91 + 81.7/200 = 91.4085                          (S5)
#   k = 81.7e9 · (1.2e-3)^4 / (8 · (7.74e-3)^3 · 91.4085) = 499.6 N/m            (S4)
#   Sut = 2211 / 1.2^0.145 = 2153 MPa; allowables 0.45/0.75/0.40 Sut
#       = 969.0 / 1615 / 861.3 MPa                                                (S1, S10)
#   K_B = 27.8/22.8 = 1.2193; τ = K_B · 8·60·7.74e-3/(π·1.2e-3^3) = 834.4 MPa    (S2, S3)
#   (K)_A = 158.96/140.61 = 1.1305; σ_A = 60 (1.1305·2.2812e7 + 8.842e5) = 1600 MPa (S8)
#   (K)_B = 15/12 = 1.25; τ_B = 1.25 · 6.8437e8 = 855.5 MPa                      (S9)
#   τ_i band 117.35 ± 23.94 MPa -> F0 band 8.19-12.39 N; middle 10.29 N > 10 N, so
#       F0 = 10 N (the smallest working force: the cable never goes slack)        (S7)
#   L_b = 92 · 1.2 = 110.4 mm; L0 = 110.4 + 2 (7.74 − 1.2) = 123.48 mm            (S6)
#   L at 60 N = 123.48 + (60 − 10)/0.4996 = 223.55 mm
#   max force = 60 · 861.3/855.5 = 60.41 N (hook torsion binds); safety 1.0069    (S10)
#   mass = 7850 · π·(1.2e-3)²/4 · π·7.74e-3·93 = 20.08 g                          (S11)
# ---------------------------------------------------------------------------------------
EXAMPLE = Requirement(rate=500.0, force_min=10.0, force_max=60.0)


@pytest.fixture(scope="module")
def example():
    return design(EXAMPLE)


def test_worked_example_matches_its_hand_values(example):
    s = example
    assert s.ok and not s.warnings
    assert (s.wire_diameter * 1e3, s.mean_diameter * 1e3, s.body_coils) == pytest.approx((1.2, 7.74, 91.0))
    hand = {
        "index": (s.index, 6.45),
        "active coils": (s.active_coils, 91.4085),
        "rate N/m": (s.rate, 499.6),
        "allowable body MPa": (s.allowable_body * 1e-6, 969.0),
        "allowable hook bending MPa": (s.allowable_hook_bending * 1e-6, 1615.0),
        "allowable hook torsion MPa": (s.allowable_hook_torsion * 1e-6, 861.3),
        "body stress MPa": (s.body_stress * 1e-6, 834.4),
        "hook bending MPa": (s.hook_bending_stress * 1e-6, 1600.0),
        "hook torsion MPa": (s.hook_torsion_stress * 1e-6, 855.5),
        "F0 band low N": (s.initial_tension_band[0], 8.19),
        "F0 band high N": (s.initial_tension_band[1], 12.39),
        "F0 N": (s.initial_tension, 10.0),
        "body length mm": (s.body_length * 1e3, 110.4),
        "free length mm": (s.free_length * 1e3, 123.48),
        "length at 60 N mm": (s.length_max * 1e3, 223.55),
        "max force N": (s.max_force, 60.41),
        "safety factor": (s.safety_factor, 1.0069),
        "mass g": (s.mass * 1e3, 20.08),
    }
    for name, (got, want) in hand.items():
        assert got == pytest.approx(want, rel=1e-3), name
    assert s.outer_diameter * 1e3 == pytest.approx(7.74 + 1.2)


def test_worked_example_is_the_lightest_candidate_that_keeps_the_rules(example):
    """The design is the lightest: no other wire/coil count of the enumeration that keeps
    every rule weighs less (checked by brute force over the same rules)."""
    mat = material("music_wire")
    for d in wire_diameters(mat):
        for C in np.linspace(4, 12, 33):
            Nb = round((mat.G * d / (8 * C**3 * EXAMPLE.rate) - mat.G / mat.E) * 4) / 4
            if Nb < 3:
                continue
            Na = Nb + mat.G / mat.E
            D = (mat.G * d**4 / (8 * EXAMPLE.rate * Na)) ** (1 / 3)
            if not 4 <= D / d <= 12:
                continue
            strong = min(0.45 / ph.shear_stress(1.0, d, D), 0.75 / ph.hook_bending_stress(1.0, d, D), 0.40 / ph.hook_torsion_stress(1.0, d, D))
            if strong * ph.tensile_strength(mat, d) < EXAMPLE.force_max:
                continue
            low = ph.tension_of_stress(ph.initial_stress_mid(D / d) - ph.initial_stress_half_band(D / d), d, D)
            if low > EXAMPLE.force_min:
                continue  # would go slack (the example's design does not)
            assert ph.mass(mat, d, D, Nb) >= example.mass * (1 - 2e-3), (d, C)


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
    for lo in (0.0, 0.5)
]


@pytest.mark.parametrize("key", sorted(materials()))
def test_designs_keep_the_winding_rules(key):
    """Acceptance: k = G d⁴/(8 D³ N_a) within 0.5 % of the required rate, every stress
    within its allowable, index 4-12, initial tension in the windable band, at least 3 body
    coils, a standard wire of the material; otherwise reasons (never an exception)."""
    mat = material(key)
    designed = 0
    for r in REQUIREMENTS:
        s = design(r, key)
        if not s.ok:
            assert s.reasons and all(isinstance(t, str) and t for t in s.reasons)
            assert math.isnan(s.wire_diameter)
            continue
        designed += 1
        rate = mat.G * s.wire_diameter**4 / (8 * s.mean_diameter**3 * s.active_coils)
        assert rate == pytest.approx(s.rate, rel=1e-12)
        assert abs(rate / r.rate - 1) <= 0.005, r
        assert s.body_stress <= s.allowable_body * (1 + 1e-12)
        assert s.hook_bending_stress <= s.allowable_hook_bending * (1 + 1e-12)
        assert s.hook_torsion_stress <= s.allowable_hook_torsion * (1 + 1e-12)
        assert s.safety_factor >= 1 - 1e-12 and s.max_force >= r.force_max * (1 - 1e-12)
        assert 4 - 1e-9 <= s.index <= 12 + 1e-9
        assert s.initial_tension_band[0] * (1 - 1e-12) <= s.initial_tension <= s.initial_tension_band[1] * (1 + 1e-12)
        assert s.body_coils >= 3 and s.active_coils == pytest.approx(s.body_coils + mat.G / mat.E)
        assert any(s.wire_diameter == pytest.approx(d) for d in wire_diameters(mat))
        assert s.free_length <= s.length_min <= s.length_max <= s.max_length
        if s.initial_tension <= r.force_min:
            assert not s.warnings
        else:  # the cable goes slack: said, and the smallest windable tension was taken
            assert "slack" in s.warnings[0]
    assert designed >= len(REQUIREMENTS) // 4  # the grid is not all out of reach


def test_a_force_beyond_every_spring_gives_reasons():
    limit = largest_force()
    s = design(Requirement(rate=5000.0, force_min=100.0, force_max=1.5 * limit))
    assert not s.ok and "allowable stresses" in s.reasons[0]
    assert largest_force(max_outer_diameter=0.003) < EXAMPLE.force_max  # so no spring within 3 mm carries 60 N
    s = design(EXAMPLE, envelope=Envelope(max_outer_diameter=0.003))
    assert not s.ok and "envelope (outer diameter ≤ 3 mm)" in s.reasons[0]
    s = design(Requirement(rate=-1.0, force_min=1.0, force_max=2.0))
    assert not s.ok and "not positive" in s.reasons[0]


def test_envelope_is_kept():
    """With the worked example's requirement and an outer diameter of at most 8 mm (the
    example's is 8.94 mm), another spring is chosen within it."""
    s = design(EXAMPLE, envelope=Envelope(max_outer_diameter=0.008))
    assert s.ok and s.outer_diameter <= 0.008
    s = design(EXAMPLE, envelope=Envelope(max_body_length=0.08))
    assert s.ok and s.body_length <= 0.08


def test_direct_mount_keeps_the_given_initial_tension_and_free_length():
    """A directly attached spring: F0 and L0 are the file's; the hooks take up the length
    the body leaves, and a F0 outside the windable band is a reason."""
    r = Requirement(rate=500.0, force_min=10.0, force_max=60.0, initial_tension=10.0, free_length=0.2)
    s = design(r)
    assert s.ok and s.initial_tension == 10.0 and s.free_length == 0.2 and s.hook_extension >= 0
    assert s.length_max == pytest.approx(0.2 + 50.0 / s.rate)
    s = design(Requirement(rate=500.0, force_min=0.0, force_max=60.0, initial_tension=0.0, free_length=0.2))
    assert not s.ok and "windable band" in s.reasons[0]


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
    assert u.force_max == pytest.approx(10.0 + 200.0 * (u.distance_max - u.cable - 0.3))  # k = 200 N/m in the arm's file
    assert s.max_force >= u.force_max


def test_largest_force_is_monotone_in_the_envelope_and_cheap():
    """A bigger envelope carries more; the no-envelope value for music wire is the
    capacity of its thickest standard wire (6.5 mm) at index 4."""
    full = largest_force()
    assert largest_force(max_outer_diameter=0.02) < full
    assert largest_force(max_outer_diameter=0.01) < largest_force(max_outer_diameter=0.02)
    assert largest_force(max_body_length=0.01) < full
    assert largest_force(min_safety_factor=2.0) == pytest.approx(full / 2)
    assert largest_force(max_outer_diameter=1e-4) == 0.0
    # a spring's options from the problem file give the same limit
    from counterpoise.model.elements import SpringDesignOptions
    from counterpoise.springs import force_limit

    options = SpringDesignOptions(material="stainless_302", max_outer_diameter=0.01, min_safety_factor=1.5)
    assert force_limit(options) == largest_force("stainless_302", 0.01, None, 1.5)
    assert force_limit(SpringDesignOptions()) == full
    mat = material("music_wire")
    d = 6.5e-3
    D = 4 * d
    thickest = ph.tensile_strength(mat, d) * min(0.45 / ph.shear_stress(1.0, d, D), 0.75 / ph.hook_bending_stress(1.0, d, D), 0.40 / ph.hook_torsion_stress(1.0, d, D))
    assert full == pytest.approx(thickest, rel=1e-9)
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
    from counterpoise.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["solve", str(PROBLEMS / f"{name}.toml"), "--out", str(tmp_path)])
    assert exit_.value.code == 0
    capsys.readouterr()
    folder = tmp_path / name
    rows = list(csv.DictReader(io.StringIO((folder / "springs.csv").read_text())))
    return rows, (folder / "status.txt").read_text()


def test_free_stiffness_problems_get_designed_spring_rows(capsys, tmp_path):
    """problems/fourbar_springs.toml (two free-stiffness springs behind pulleys): one
    ``designed`` row each with the maker's spec, and a status line per spring."""
    rows, status = _rows(capsys, tmp_path, "fourbar_springs")
    designed = {r["spring"]: r for r in rows if r["kind"] == "designed"}
    assert set(designed) == {"crank_spring", "rocker_spring"}
    for name, r in designed.items():
        assert f"designed spring {name}: music wire ASTM A228" in status
        assert r["material"] == "music wire ASTM A228" and float(r["rate_tolerance"]) == 0.1
        assert 4 <= float(r["spring_index"]) <= 12
        assert float(r["body_stress_MPa"]) <= float(r["allowable_body_MPa"])
        assert float(r["max_force_N"]) <= float(r["part_max_load_N"])
        # behind a pulley the spring pulls k·d: its largest force is rate × largest distance
        assert float(r["max_force_N"]) == pytest.approx(float(r["max_distance_mm"]) * float(r["rate_N_per_mm"]), rel=0.006)
        for column in ("wire_diameter_mm", "outer_diameter_mm", "body_length_mm", "free_length_mm", "initial_tension_N", "safety_factor", "mass_g"):
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
    assert exit_.value.code == 0
    capsys.readouterr()
    rows = list(csv.DictReader(io.StringIO((tmp_path / "out" / "fourbar_springs" / "springs.csv").read_text())))
    crank = next(r for r in rows if r["spring"] == "crank_spring")
    assert crank["material"] == "stainless steel 302" and float(crank["rate_tolerance"]) == 0.05
    assert crank["note"] or float(crank["outer_diameter_mm"]) <= 4.0
