"""Directly attached real springs (no pulley): the minimax designer and its dense check."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from counterpoise import design, load_problem
from counterpoise.designer.minimax import MinimaxDesign
from counterpoise.errors import ProblemFileError
from counterpoise.formulation.assumptions import check_exact_conditions
from counterpoise.solvers.base import Status

ARM = """
[problem]
name = "direct_arm"

[gravity]
acceleration = "9.81 m/s^2"
direction = [0, -1, 0]

[parameters]
m = "1 kg"
r = "0.2 m"
{stiffness_parameter}

[variables.x]
lower = "-0.1 m"
upper = "0.1 m"
initial = "0 m"
[variables.y]
lower = "0.05 m"
upper = "0.5 m"
initial = "0.2 m"
[variables.b]
lower = "0.01 m"
upper = "0.3 m"
initial = "0.1 m"
[variables.c]
lower = "0 m"
upper = "0.3 m"
initial = "0 m"

[subsystems.arm]
coordinates.phi = {{ range = ["-45 deg", "55 deg"] }}

[frames.link]
transforms = [{{ rotate = "z", angle = "phi" }}]

[bodies.link]
frame = "link"
mass = "m"
com = ["r", 0, 0]

[springs.s]
{spring}
mount = "direct"
cable = "c"
from = {{ frame = "ground", point = ["x", "y", 0] }}
to = {{ frame = "link", point = ["b", 0, 0] }}
{extra}

# the minimax engine on a direct spring of given rate, free length and tension (ideal: no
# realisation limits; a 200 N/m spring carrying ~100 N cannot be wound within the rules,
# tests/test_realisation.py holds springs as built)
[settings]
ideal_springs = true
"""


def arm(tmp_path: Path, spring: str, extra: str = "", stiffness_parameter: str = 'k = "200 N/m"'):
    path = tmp_path / "arm.toml"
    path.write_text(ARM.format(spring=spring, extra=extra, stiffness_parameter=stiffness_parameter), encoding="utf-8")
    return load_problem(path)


def independent_ratio(result, k, free_length, tension, n=20001):
    """Net torque of the arm by hand: gravity -m g r cos(phi), spring F/d · (P × A)_z with
    F = F0 + k (d − c − L0), P = b (cos, sin), A = (x, y); ratio to max |m g r cos(phi)|."""
    v = {s.variable: x for s, x in result.solution.values.items()}
    phi = np.radians(np.linspace(-45, 55, n))
    px, py = v["b"] * np.cos(phi), v["b"] * np.sin(phi)
    d = np.hypot(v["x"] - px, v["y"] - py)
    force = tension + k * (d - v["c"] - free_length)
    tau = -1 * 9.81 * 0.2 * np.cos(phi) + force / d * (px * v["y"] - py * v["x"])
    return np.abs(tau).max() / (9.81 * 0.2)


def test_zero_free_length_limit_balances_exactly(tmp_path):
    """L0 = 0, F0 = 0, no cable: the direct spring is a zero-free-length spring and the
    minimax design reaches exact balance (k b y = m g r with x = 0)."""
    problem = arm(tmp_path, 'stiffness = "k"\nfree_length = "0 m"\ninitial_tension = "0 N"')
    result = design(problem)
    assert result.status is Status.OPTIMAL, result.message
    assert result.verification.residual_ratio < 1e-6
    assert independent_ratio(result, 200.0, 0.0, 0.0) < 1e-6


def test_real_spring_minimax_and_dense_check_agree(tmp_path):
    """L0 = 50 mm, F0 = 2 N: no exact balance. The sampled worst ratio (the NLP's t), the
    dense check and an independent hand computation of the torque agree."""
    problem = arm(tmp_path, 'stiffness = "k"\nfree_length = "50 mm"\ninitial_tension = "2 N"\nmax_length = "0.6 m"')
    with pytest.raises(ProblemFileError, match="no exact balance conditions"):
        check_exact_conditions(problem)
    result = design(problem)
    assert result.status is Status.OPTIMAL, result.message
    t = result.solution.extra(MinimaxDesign).sampled_ratio
    dense = result.verification.residual_ratio
    assert 0 < t <= dense <= 1.05 * t
    assert independent_ratio(result, 200.0, 0.05, 2.0) == pytest.approx(dense, rel=2e-3)
    # the spring stays within its lengths on the samples: d − c ≥ L0
    assert "dense check: worst residual ratio" in result.message


def test_direct_slot_picks_the_part_with_the_smallest_worst_ratio(tmp_path):
    """Three parts; each is designed by the minimax designer; the chosen one has the
    smallest worst ratio of the three, and springs.csv reports its length d − c and force."""
    rows = [
        "A,200,0.05,2,60,0.6,0.01,0.001,x",
        "B,300,0.02,0.5,80,0.6,0.01,0.001,x",
        "C,150,0.08,4,60,0.6,0.01,0.001,x",
    ]
    (tmp_path / "parts.csv").write_text(
        "part_number,rate_N_per_m,free_length_m,initial_tension_N,max_load_N,max_length_m,outer_diameter_m,wire_diameter_m,material\n"
        + "\n".join(rows)
        + "\n",
        encoding="utf-8",
    )
    extra = '[catalogues.parts]\nfile = "parts.csv"\n[slots.s]\ncatalogue = "parts"\n'
    problem = arm(tmp_path, 'slot = "s"', extra, stiffness_parameter="")
    result = design(problem)
    assert result.status is Status.OPTIMAL, result.message
    ratios = {problem.slots[0].catalogue.part_number[c.parts["s"]]: c.robust for c in result.parts.search.candidates}
    assert set(ratios) <= {"A", "B", "C"} and len(ratios) >= 2
    chosen = result.parts.springs[0]
    assert chosen.part_number == min(ratios, key=ratios.get)
    cat = problem.slots[0].catalogue
    i = cat.part_number.index(chosen.part_number)
    assert independent_ratio(result, cat.rate[i], cat.free_length[i], cat.initial_tension[i]) == pytest.approx(
        result.verification.residual_ratio, rel=2e-3
    )
    assert chosen.length_min >= cat.free_length[i] - 1e-6  # tension only: d − c ≥ L0
    assert chosen.force_min == pytest.approx(cat.initial_tension[i] + cat.rate[i] * (chosen.length_min - cat.free_length[i]))


@pytest.mark.parametrize(
    "spring, key, fragment",
    [
        ('stiffness = "k"\nfree_length = "5 cm"', "springs.s.free_length", 'only a directly attached spring (mount = "direct") has this key'),
        ('stiffness = "k"\nmount = "direct"', "springs.s.free_length", "missing required key for a directly attached spring"),
        ('stiffness = "k"\nmount = "direct"\nfree_length = "2 N"', "springs.s.free_length", "expected a length"),
        ('stiffness = "k"\nmount = "direct"\nfree_length = "5 cm"\ninitial_tension = "-1 N"', "springs.s.initial_tension", "must not be negative"),
    ],
)
def test_direct_mount_keys_are_checked(tmp_path, spring, key, fragment):
    text = ARM.format(spring=spring, extra="", stiffness_parameter='k = "200 N/m"').replace('mount = "direct"\ncable = "c"\n', "", 1)
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ProblemFileError) as info:
        load_problem(path)
    assert info.value.key == key
    assert fragment in info.value.message


PEER_ARM = """
[problem]
name = "peer_arm"

[gravity]
acceleration = "9.81 m/s^2"
direction = [0, -1, 0]

[parameters]
L = "0.409 m"
m_beam = "0.467 kg"
m_end = "0.3272 kg"
k = "{k} N/m"
L0 = "{L0} m"
F0 = "{F0} N"
c = "{c} m"
r = "{r} m"
x = "{x} m"
y = "{y} m"

[subsystems.arm]
coordinates.phi = {{ range = ["-43.4 deg", "53.6 deg"] }}

[frames.arm]
transforms = [{{ rotate = "z", angle = "phi" }}]

[bodies.beams]
frame = "arm"
mass = "m_beam"
com = ["L/2", 0, 0]
[bodies.end]
frame = "arm"
mass = "m_end"
com = ["L", 0, 0]

[springs.s]
stiffness = "k"
mount = "direct"
free_length = "L0"
initial_tension = "F0"
cable = "c"
from = {{ frame = "ground", point = ["x", "y", 0] }}
to = {{ frame = "arm", point = ["r", 0, 0] }}
"""


def test_engine_and_peer_benchmark_agree_on_the_torque(tmp_path):
    """The peer benchmark's closed-form net torque (benchmarks/peer_1r_arm.py, with the
    virtual offset t = c + L0 - F0/k) and the engine's complex-step residual dV/dphi of the
    same arm with a directly attached spring are the same function with opposite signs
    (residual = -net torque), for an arbitrary spring and geometry."""
    import importlib.util

    from counterpoise.verify.residuals import residuals

    spec = importlib.util.spec_from_file_location("peer", Path(__file__).resolve().parent.parent / "benchmarks" / "peer_1r_arm.py")
    peer = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(peer)
    k, L0, F0, c, r, x, y = 350.0, 0.04, 3.0, 0.06, 0.03, -0.05, 0.21
    path = tmp_path / "peer.toml"
    path.write_text(PEER_ARM.format(k=k, L0=L0, F0=F0, c=c, r=r, x=x, y=y), encoding="utf-8")
    problem = load_problem(path)
    phi = np.linspace(problem.coordinates[0].lower, problem.coordinates[0].upper, 301)
    base = {p.name: p.value for p in problem.base_parameters}
    residual, _ = residuals(problem, "arm", phi[:, None], {}, base, (0.0, -9.81, 0.0))
    tau = peer.net_torque(np.array([k]), np.array([[[r, x, y, c + L0 - F0 / k]]]), np.cos(phi), np.sin(phi))[0]
    assert np.abs(residual[:, 0] + tau).max() < 1e-12 * np.abs(tau).max() + 1e-14
