"""Seed 001: the leg-by-leg design when the leg plane tilts (problems/yasir2019_leg_tilt.toml,
docs/seeds.md#yasir-tilt).

The paper's side leg: M_c = 293.80 g, M_b = 1649.78 g lump everything onto link a, 2388.88 g
at g_at = 133.99 mm from A0, and k f^2 = M_a g g_at with f = 78 mm (k = 0.51611 N/mm). With
the plane turned by psi about an in-plane axis at beta from the horizontal, by hand:
    V(psi, q) - V(0, q) = -M_a g g_at cos(beta) (1 - cos psi) sin(q_a - beta),
M_a g g_at = 2.38888 * 9.81 * 0.13399 = 3.1400 N*m.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import PROBLEMS, solved, value
from counterpoise.io.loader import load_problem
from counterpoise.mechanics.energy import Mechanics

G = 9.81
M_A, G_AT = 2.38888, 0.13399  # kg, m (docs/derivations.md, seed 001 side leg)


def test_vertical_tilt_axis_keeps_the_paper_design(approx):
    result = solved("yasir2019_leg_tilt")
    assert result.status.value == "optimal"
    assert result.verification.residual_ratio <= 1e-9
    assert value(result, "M_c", "g") == approx(293.80)
    assert value(result, "M_b", "g") == approx(1649.78)
    assert value(result, "k", "N/mm") == approx(0.51611)


@pytest.mark.parametrize("beta", [60.0, 30.0])
def test_inclined_tilt_axis_unbalances_the_paper_design(beta):
    """The engine's energy of the paper's design against the hand formula, on random
    configurations (the distal angles q_b, q_c drop out: the lumping holds in any plane)."""
    problem = load_problem(PROBLEMS / "yasir2019_leg_tilt.toml", {"parameters.beta": f"{beta} deg"})
    base = {p.name: p.value for p in problem.parameters if p.is_base}
    paper = {"M_b": 1.649781, "M_c": 0.2937988, "k": 516.11263}
    rng = np.random.default_rng(7)
    n = 500
    psi = np.radians(rng.uniform(-20, 20, n))
    q = {"q_a": np.radians(rng.uniform(57.2, 209.7, n)), "q_b": rng.uniform(-math.pi, math.pi, n), "q_c": rng.uniform(-math.pi, math.pi, n)}

    def energy(tilt):
        return np.asarray(Mechanics(problem, base, paper, {"psi": tilt, **q}, [0.0, -G, 0.0]).energy(), dtype=float)

    b = math.radians(beta)
    expected = -M_A * G * G_AT * math.cos(b) * (1 - np.cos(psi)) * np.sin(q["q_a"] - b)
    assert energy(psi) - energy(np.zeros(n)) == pytest.approx(expected, abs=2e-4)
    assert np.abs(expected).max() > 0.02  # N*m: clearly unbalanced at 20 deg of tilt


def test_inclined_tilt_axis_is_infeasible_for_any_design():
    result = solved("yasir2019_leg_tilt", (("parameters.beta", "60 deg"),))
    assert result.status.value == "infeasible"
    assert "coordinate 'psi'" in result.message
