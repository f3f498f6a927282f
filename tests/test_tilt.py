"""A tilting base ([gravity] tilt, docs/tilt.md): hand-derived arms and composition.

The arm of problems/tilt_*.toml: upper arm l1 = 0.3 m (m1 = 1.2 kg at c1 = 0.15 m), forearm
held absolute by a parallelogram (l2 = 0.25 m, m2 = 0.8 kg at c2 = 0.125 m), head m3 = 0.5 kg
at l2; counter-masses behind the shoulder (e1 = 0.1 m) and the elbow (e2 = 0.08 m); springs
from h1 = 0.15 m above the shoulder to r1 = 0.1 m on the upper arm, and from h2 = 0.1 m above
the elbow (on the parallelogram's elbow link) to r2 = 0.1 m on the forearm. g = 9.81 m/s².
"""

from __future__ import annotations

import math

import pytest

from counterpoise.io.builder import ProblemBuilder, rotate
from counterpoise.io.loader import load_problem, load_problem_text
from counterpoise.pipeline import design
from counterpoise.solvers.base import Status

from conftest import PROBLEMS, solved

G = 9.81
#: counter-masses: M2 = (m2 c2 + m3 l2)/e2, M1 = (m1 c1 + (m2 + m3 + M2) l1)/e1
M2 = (0.8 * 0.125 + 0.5 * 0.25) / 0.08
M1 = (1.2 * 0.15 + (0.8 + 0.5 + M2) * 0.3) / 0.1
#: springs, upright: k1 h1 r1 = g (m1 c1 + (m2 + m3) l1), k2 h2 r2 = g (m2 c2 + m3 l2)
K1 = G * (1.2 * 0.15 + (0.8 + 0.5) * 0.3) / (0.15 * 0.1)
K2 = G * (0.8 * 0.125 + 0.5 * 0.25) / (0.1 * 0.1)


def values(result) -> dict[str, float]:
    return {slot.variable: v for slot, v in result.solution.values.items()}


@pytest.fixture(scope="module")
def counter_mass_arm():
    return solved("tilt_counter_mass_arm")


def test_counter_mass_arm_is_tilt_proof(counter_mass_arm):
    r = counter_mass_arm
    assert r.status is Status.OPTIMAL, r.message
    assert values(r)["M1"] == pytest.approx(M1, rel=1e-9) and values(r)["M2"] == pytest.approx(M2, rel=1e-9)
    assert r.verification.residual_ratio <= 1e-12
    # the dense check drew every configuration at its own tilt, inside the ranges
    for check in r.verification.checks:
        assert len(check.worst_tilt) == 2
        assert all(abs(a) <= math.radians(15) + 1e-12 for a in check.worst_tilt)
    # one check per coordinate covers the whole tilt box (not one per node of the grid)
    assert len(r.verification.checks) == 2


def test_tilt_grid_nodes_are_the_scenarios(counter_mass_arm):
    problem = counter_mass_arm.problem
    assert len(problem.tilts) == 2 and len(problem.scenarios) == 9
    angles = sorted({round(math.degrees(a), 9) for s in problem.scenarios for a in s.tilt})
    assert angles == [-15.0, 0.0, 15.0]
    assert {s.setting for s in problem.scenarios} == {"nominal"}  # one setting: no retuning as the base tilts


def test_spring_arm_is_infeasible_and_names_the_tilt():
    r = solved("tilt_spring_arm")
    assert r.status is Status.INFEASIBLE
    assert "base tilted" in r.message and "about [0, 0, 1]" in r.message
    # an in-plane pitch of up to 15 deg leaves about 2 sin(7.5 deg) = 26 % of the torque
    # unbalanced for the upright springs; the closest design cannot be far better
    assert r.verification.residual_ratio > 0.1


def _without_tilt(name: str) -> str:
    text = (PROBLEMS / name).read_text(encoding="utf-8")
    start = text.index("tilt = [")
    end = text.index("]\n\n", start) + 2
    return text[:start] + text[end:]


def test_spring_arm_upright_is_balanced_by_the_hand_rates():
    r = design(load_problem_text(_without_tilt("tilt_spring_arm.toml"), "tilt_spring_arm.toml"))
    assert r.status is Status.OPTIMAL, r.message
    assert values(r)["k1"] == pytest.approx(K1, rel=1e-9) and values(r)["k2"] == pytest.approx(K2, rel=1e-9)


def test_a_single_tilt_out_of_the_plane_scales_the_springs_by_its_cosine():
    """A fixed roll ψ about x leaves the in-plane gravity g cos ψ: the rates scale by cos ψ."""
    text = _without_tilt("tilt_spring_arm.toml").replace(
        'direction = [0, -1, 0]                 # the arm moves in the x-y plane, y up',
        'direction = [0, -1, 0]\ntilt = [{ axis = [1, 0, 0], range = ["10 deg", "10 deg"] }]',
    )
    r = design(load_problem_text(text, "tilt_spring_arm.toml"))
    assert r.status is Status.OPTIMAL, r.message
    c = math.cos(math.radians(10))
    assert values(r)["k1"] == pytest.approx(K1 * c, rel=1e-9) and values(r)["k2"] == pytest.approx(K2 * c, rel=1e-9)


def test_hybrid_arm_needs_the_full_counter_masses_on_a_tilting_base():
    r = solved("tilt_hybrid_arm")
    assert r.status is Status.OPTIMAL, r.message
    v = values(r)
    assert v["M1"] == pytest.approx(M1, rel=1e-7) and v["M2"] == pytest.approx(M2, rel=1e-7)
    assert v["k1"] == pytest.approx(0, abs=1e-6) and v["k2"] == pytest.approx(0, abs=1e-6)
    upright = design(load_problem_text(_without_tilt("tilt_hybrid_arm.toml"), "tilt_hybrid_arm.toml"))
    assert upright.status is Status.OPTIMAL
    assert sum(values(upright)[n] for n in ("M1", "M2")) == pytest.approx(0, abs=1e-6)  # springs alone, upright


def _pendulum(tilt: bool = True) -> ProblemBuilder:
    """m = 1 kg at r = 0.2 m; a counter-mass M at b = 0.1 m behind the pivot balances it for
    any gravity direction: M = m r / b = 2 kg."""
    b = ProblemBuilder("tilt_pendulum", direction=(0, -1, 0))
    b.parameter("m", "1 kg").parameter("r", "0.2 m").parameter("b", "0.1 m")
    b.subsystem("arm", q=("-180 deg", "180 deg"))
    b.frame("link", rotate("z", "q"))
    b.body("tip", frame="link", mass="m", com=("r", 0, 0))
    b.variable("M", "0 kg", "10 kg")
    b.counter_mass("cm", frame="link", mass="M", position=("-b", 0, 0))
    if tilt:
        b.tilt((1, 0, 0), "-20 deg", "20 deg").tilt((0, 0, 1), "-10 deg", "30 deg")
    return b


def test_tilt_composes_with_working_modes():
    b = _pendulum()
    b.scenario("light", {"m": "1 kg"}).scenario("heavy", {"m": "1.5 kg"})
    b.variable("M", "0 kg", "10 kg", adjustable=True)
    r = design(b.build())
    assert r.status is Status.OPTIMAL, r.message
    assert len(r.problem.scenarios) == 2 * 9
    settings = {s.setting for s in r.problem.scenarios}
    assert settings == {"light", "heavy"}  # the counterweight is set per mode, not per tilt
    by_setting = {slot.scenario: v for slot, v in r.solution.values.items()}
    assert by_setting == pytest.approx({"light": 2.0, "heavy": 3.0}, rel=1e-9)


def test_tilt_composes_with_a_payload_range():
    b = _pendulum()
    b.payload("load", frame="link", range=("0 kg", "0.5 kg"), position=("r", 0, 0))
    b.variable("b_adj", "0.05 m", "0.5 m", adjustable=True)
    b.counter_mass("cm", frame="link", mass="M", position=("-b_adj", 0, 0))
    r = design(b.build())
    assert r.status is Status.OPTIMAL, r.message
    assert r.verification.residual_ratio <= 1e-9
    assert all(len(c.worst_tilt) == 2 for c in r.verification.checks)


def test_tilt_composes_with_a_catalogue_slot():
    """A roll fixed at 10° about x: a spring from the shipped catalogue, its lever free."""
    b = ProblemBuilder("tilt_slot", direction=(0, -1, 0))
    b.parameter("m", "1 kg").parameter("r", "0.2 m").parameter("h", "0.1 m")
    b.subsystem("arm", q=("-180 deg", "180 deg"))
    b.frame("link", rotate("z", "q"))
    b.body("tip", frame="link", mass="m", com=("r", 0, 0))
    b.variable("a", "0.01 m", "0.3 m")
    b._data.setdefault("catalogues", {})["stock"] = {"file": "shipped"}
    b._data.setdefault("slots", {})["s"] = {"catalogue": "stock"}
    b._data.setdefault("springs", {})["sp"] = {"slot": "s", "from": {"frame": "ground", "point": [0, "h", 0]}, "to": {"frame": "link", "point": ["a", 0, 0]}}
    b.tilt((1, 0, 0), "10 deg", "10 deg")
    r = design(b.build())
    assert r.status is Status.OPTIMAL, r.message
    slot = r.problem.slots[0]
    k = slot.catalogue.rate[r.parts.chosen["s"]]
    # the part's rate k and the lever a: k h a = m g r cos 10°
    assert k * 0.1 * values(r)["a"] == pytest.approx(1 * G * 0.2 * math.cos(math.radians(10)), rel=1e-6)
