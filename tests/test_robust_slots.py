"""[robust] with catalogue slots (docs/robust.md#catalogue-parts): the chosen part's design is
judged at every corner of the tolerance box, its spring taking the part's own rate tolerance,
and the part's limits (slack, load, length) hold at every corner.

The mechanism (tests/builders.py ``slot_pendulum_toml``): a link at angle θ ∈ [−60°, 60°]
from the horizontal, mass m at r = 0.2 m, a catalogue spring from (0, h) on the ground to
b = 0.1 m along the link, h free: V = m g r sin θ − k b h sin θ, balanced when k b h = m g r.
With k = 200 N/m and m g r = 2 N·m the design is h = 0.1 m. As [robust] models a part (its
string set for the part as built, robust/limits.py), a corner with rate k(1 + δ) and mass
m(1 + δ_m) leaves the residual τ(θ) = (m g r (1 + δ_m) − k (1 + δ) b h) cos θ, and the
residual ratio max |τ| / (m g r) (the largest gravity torque, at θ = 0). The tests evaluate
that law in numpy at every corner, with the design's own h, independently of the engine.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from builders import slot_pendulum_toml
from counterpoise import design, load_problem
from counterpoise.cli import main
from counterpoise.robust.result import RobustReport
from counterpoise.solvers.base import Status

G, R, B, K = 9.81, 0.2, 0.1, 200.0
MASS = 2.0 / (G * R)  # m g r = 2 N·m: h = 2/(200 · 0.1) = 0.1 m
HEADER = "part_number,rate_N_per_m,free_length_m,initial_tension_N,max_load_N,max_length_m,outer_diameter_m,wire_diameter_m,material"
#: rate 200 N/m, L0 50 mm, F0 1 N, allowable load 50 N, longest 0.3 m: fits at every corner
#: (largest distance b·sqrt(2 + √3) = 0.193 m at θ = −60°: 1.1 · 200 · 0.193 = 42.5 N < 50 N)
PART = "P-1,200,0.05,1,50,0.3,0.01,0.001,x"


def problem_file(tmp_path: Path, rows: list[str], robust: str, header: str = HEADER) -> Path:
    (tmp_path / "parts.csv").write_text(header + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
    path = tmp_path / "pendulum.toml"
    path.write_text(slot_pendulum_toml("pendulum_catalogue", MASS) + "\n[robust]\n" + robust, encoding="utf-8")
    return path


def by_hand(h: float, rate: float, mass: float = 0.0) -> float:
    """The worst residual ratio over the corners (±rate, ±mass) by the law of the module
    docstring, on a fine grid of θ (|cos θ| peaks at θ = 0, a node)."""
    theta = np.radians(np.linspace(-60.0, 60.0, 2001))
    worst = 0.0
    for dk, dm in itertools.product((-rate, rate), (-mass, mass)):
        tau = (MASS * G * R * (1 + dm) - K * (1 + dk) * B * h) * np.cos(theta)
        worst = max(worst, float(np.abs(tau).max()) / (MASS * G * R))
    return worst


def test_the_parts_catalogue_tolerance_decides_and_matches_the_hand_evaluation(tmp_path):
    """The catalogue gives the part ±4 %, the file ±20 %: the part's 4 % is used (status.txt
    says so) and the band equals the hand evaluation at both corners (0.04: the residual is
    ±0.04 k b h cos θ = ±0.04 m g r cos θ), to 1e-9."""
    path = problem_file(tmp_path, [PART + ",0.04"], 'mode = "none"\ntolerances.rate = "20 %"\n', HEADER + ",rate_tolerance")
    result = design(load_problem(path))
    assert result.status is Status.OPTIMAL, result.message
    h = result.solution.variable_values(next(iter(result.solution.scenario_parameters)))["h"]
    report = result.extra(RobustReport)
    assert report is not None
    assert [(d.tolerance.item, d.half_width) for d in report.deviations] == [("s", 0.04)]
    band = report.bands["nominal"]["all"]
    assert band == pytest.approx(by_hand(h, 0.04), abs=1e-9)
    assert band == pytest.approx(0.04, abs=1e-9)
    assert any("the catalogue's rate_tolerance of part P-1" in t and "±4 %" in t for t in report.part_tolerances)
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stop:
        main(["solve", str(path), "--out", str(out)])
    assert stop.value.code == 0
    status = (out / "pendulum_catalogue" / "status.txt").read_text(encoding="utf-8")
    assert "robust: spring s (part P-1 of slot s): rate tolerance ±4 %, the catalogue's rate_tolerance of part P-1" in status


def test_without_a_catalogue_tolerance_the_files_then_the_slots(tmp_path):
    """No tolerance column: the file's ``tolerances.rate`` (3 %: band 0.03); with only a mass
    tolerance in the file (5 %), the slot's rate tolerance (10 %, slot_pendulum_toml's), the
    two at their adding signs: 0.15, both against the hand evaluation."""
    result = design(load_problem(problem_file(tmp_path, [PART], 'mode = "none"\ntolerances.rate = "3 %"\n')))
    assert result.status is Status.OPTIMAL, result.message
    h = result.solution.variable_values(next(iter(result.solution.scenario_parameters)))["h"]
    report = result.extra(RobustReport)
    assert report is not None and report.bands["nominal"]["all"] == pytest.approx(by_hand(h, 0.03), abs=1e-9)
    assert "the file's robust.tolerances.rate" in report.part_tolerances[0]
    result = design(load_problem(problem_file(tmp_path, [PART], 'mode = "none"\ntolerances.mass.link = "5 %"\n')))
    assert result.status is Status.OPTIMAL, result.message
    report = result.extra(RobustReport)
    assert report is not None and report.bands["nominal"]["all"] == pytest.approx(by_hand(h, 0.10, 0.05), abs=1e-9)
    assert by_hand(h, 0.10, 0.05) == pytest.approx(0.15, abs=1e-9)
    assert "slot s's rate tolerance" in report.part_tolerances[0]


def test_a_part_overloaded_at_a_corner_is_infeasible(tmp_path):
    """Allowable load 40 N: the nominal part pulls at most k·d_max = 200 · 0.1 · sqrt(2 + √3)
    = 38.64 N (it fits: without [robust] the design is optimal), at the +10 % corner
    1.1 × 38.64 = 42.50 N, 2.50 N beyond it: infeasible, never optimal, the corner and the
    limit named."""
    overloaded = "P-1,200,0.05,1,40,0.3,0.01,0.001,x"
    path = problem_file(tmp_path, [overloaded], 'mode = "none"\ntolerances.rate = "10 %"\n')
    plain = path.read_text(encoding="utf-8").split("\n[robust]\n")[0]
    (tmp_path / "plain.toml").write_text(plain, encoding="utf-8")
    assert design(load_problem(tmp_path / "plain.toml")).status is Status.OPTIMAL
    result = design(load_problem(path))
    assert result.status is Status.INFEASIBLE
    assert "corner corner_p (rate s +10 %): spring s: it is loaded beyond its allowable load by" in result.message
    excess = float(result.message.split("allowable load by ")[1].split(" N")[0])
    assert excess == pytest.approx(1.1 * K * B * np.sqrt(2 + np.sqrt(3)) - 40.0, abs=2e-3)  # the dense sample's d_max, 4 digits


@pytest.mark.parametrize(
    ("robust", "key"),
    [
        ('mode = "limit"\nlimit = 0.05\ntolerances.rate = "10 %"\n', "robust.mode"),
        ('mode = "minimise"\nweight = "10 kg"\ntolerances.rate = "10 %"\n', "robust.mode"),
        ('mode = "none"\ntune = ["h"]\ntolerances.rate = "10 %"\n', "robust.tune"),
    ],
)
def test_what_is_not_combinable_yet_is_refused(tmp_path, capsys, robust, key):
    """limit and minimise (the part search does not search for the robust design) and tune (the
    part search does not hold the tune variables): exit 2 naming the key, nothing written."""
    path = problem_file(tmp_path, [PART], robust)
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stop:
        main(["solve", str(path), "--out", str(out)])
    assert stop.value.code == 2
    assert f"{key}: not combinable yet" in capsys.readouterr().err
    assert not out.exists()


def test_a_parts_max_force_holds_at_every_corner(tmp_path):
    """``max_force = "41 N"`` on the part's spring: the nominal part pulls at most 38.64 N (the
    previous test), the +10 % corner 42.50 N: [robust] mode "none" judges the design at every
    corner (robust/constraints.py, as for a designed spring): infeasible, the corner named;
    without [robust] optimal."""
    path = problem_file(tmp_path, [PART], 'mode = "none"\ntolerances.rate = "10 %"\n')
    text = path.read_text(encoding="utf-8").replace('slot = "s"\n', 'slot = "s"\nmax_force = "41 N"\n')
    path.write_text(text, encoding="utf-8")
    (tmp_path / "plain.toml").write_text(text.split("\n[robust]\n")[0], encoding="utf-8")
    assert design(load_problem(tmp_path / "plain.toml")).status is Status.OPTIMAL
    result = design(load_problem(path))
    assert result.status is Status.INFEASIBLE
    assert "breaks a constraint at a tolerance corner" in result.message and "rate s +10 %" in result.message
    assert "with [slots] mode = \"limit\"/\"minimise\" is not combinable yet" in result.message  # not advised to use a refused mode
