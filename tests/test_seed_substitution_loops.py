"""Mass moment substitution inside a closed loop (docs/seeds.md#substitution-points).

The four-bar of problems/fourbar_counter_mass.toml with its coupler (0.8 kg, centre of mass
midway along AB) replaced by 0.4 kg at A (carried by the crank) and 0.4 kg at B (carried by
the rocker). On the closed loop A and B are the coupler's points in every configuration, so
the substitution is exact there and the minimum counter-masses do not change. The coupler
frame is moved by dependent coordinates whose home is only approximate in the file (it picks
the branch), so the loader does not check its points at home: this must not be an error.
"""

from __future__ import annotations

import pytest

from conftest import PROBLEMS, value
from counterpoise.io.loader import load_problem_text
from counterpoise.pipeline import design

SUBSTITUTED = """
[substitutions.coupler]
points.mu_A = { at = [0, 0, 0], frame = "crank", point = ["a", 0, 0] }
points.mu_B = { at = ["b", 0, 0], frame = "rocker", point = ["c", 0, 0] }
"""


def test_coupler_substituted_onto_crank_and_rocker_keeps_the_design():
    text = (PROBLEMS / "fourbar_counter_mass.toml").read_text(encoding="utf-8")
    text = text.replace('com = ["p3", 0, 0]', 'com = ["b/2", 0, 0]')  # midway: m3/2 at A and at B
    reference = design(load_problem_text(text, "fourbar_midway"))
    result = design(load_problem_text(text + SUBSTITUTED, "fourbar_substituted"))
    assert result.status.value == "optimal", result.message
    assert result.verification.residual_ratio <= 1e-9
    assert value(result, "mu_A", "kg") == pytest.approx(0.4)
    assert value(result, "mu_B", "kg") == pytest.approx(0.4)
    names = [v.name for v in result.problem.variables]
    for name in names:
        assert value(result, name) == pytest.approx(value(reference, name), rel=1e-6)

