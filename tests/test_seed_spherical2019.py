"""Seed 002 (geometric static balancing of spherical mechanisms, 2019): spherical chain units.

The facts and their hand derivations are in docs/derivations.md, section "Spherical chains
2019"; here every one is reproduced through the general engine (problem files or TOML
texts built below), never from the paper's formulas. Tolerance 0.1 % unless stated.
"""

from __future__ import annotations

import math

import pytest

from conftest import solved, value
from counterpoise.io.loader import load_problem_text
from counterpoise.pipeline import design

G = 9.81


# --------------------------------------------------------------------------------------
# The serial chain (eqs. 11-18): problems/spherical_chain_3r.toml
# --------------------------------------------------------------------------------------


class TestSphericalChain3R:
    """Three links on axes through O; h_i = m_i g / k_i balances each link on its own."""

    @pytest.fixture
    def result(self):
        return solved("spherical_chain_3r")

    def test_optimal_and_verified(self, result):
        assert result.status.value == "optimal"
        assert result.verification.residual_ratio <= 1e-9
        assert result.verification.configurations >= 10_000

    @pytest.mark.parametrize(
        ("name", "mass", "stiffness"),
        [("h_1", 0.30, 400.0), ("h_2", 0.20, 250.0), ("h_3", 0.10, 50.0)],
    )
    def test_heights(self, result, approx, name, mass, stiffness):
        # h = m g / k: 0.30·9.81/400 = 7.3575 mm, 0.20·9.81/250 = 7.848 mm, 0.10·9.81/50 = 19.62 mm
        assert value(result, name, "mm") == approx(1000 * mass * G / stiffness)

    def test_each_link_balanced_alone(self, result):
        """Eq. (18): the conditions are per link, three of them, one per unknown height."""
        assert result.solution.conditions == 3


# --------------------------------------------------------------------------------------
# One link on a tilted revolute joint (eqs. 7-10)
# --------------------------------------------------------------------------------------

TILTED = """
[problem]
name = "tilted_link"
[gravity]
acceleration = "9.81 m/s^2"
direction = [0, 0, -1]
[parameters]
alpha = "{alpha} deg"
t = "30 mm"
m = "0.25 kg"
k = "200 N/m"
[subsystems.link]
coordinates.theta = {{ range = ["-180 deg", "180 deg"] }}
[frames.axis]
transforms = [{{ rotate = "x", angle = "alpha" }}]
[frames.link]
parent = "axis"
transforms = [{{ rotate = "z", angle = "theta" }}]
[bodies.link]
frame = "link"
mass = "m"
com = ["{a} mm", "{b} mm", "70 mm"]
[variables.h]
lower = "0 mm"
upper = "100 mm"
initial = "{h0} mm"
# H: height h straight above T, the point of the (tilted) axis at distance t from O
[springs.s]
stiffness = "k"
from = {{ frame = "ground", point = ["0 mm", "-t*sin(alpha)", "t*cos(alpha) + h"] }}
to = {{ frame = "link", point = ["{a} mm", "{b} mm", "70 mm"] }}
[settings]
verify_tolerance = 1e-9
"""


def tilted(alpha: float, a: float, b: float, h0: float = 50.0, pinned: bool = False):
    """The tilted link; ``pinned`` fixes h at ``h0`` (lower = upper bound)."""
    text = TILTED.format(alpha=alpha, a=a, b=b, h0=h0)
    if pinned:
        text = text.replace('lower = "0 mm"', f'lower = "{h0} mm"').replace('upper = "100 mm"', f'upper = "{h0} mm"')
    return design(load_problem_text(text, "tilted_link"))


def test_tilted_link_needs_h_equal_mg_over_k(approx):
    """V = const + (m g − k h) sin α (b cos θ + a sin θ): one condition, h = m g/k."""
    result = tilted(alpha=35, a=40, b=-25)
    assert result.status.value == "optimal"
    assert result.solution.conditions == 1
    assert value(result, "h", "mm") == approx(1000 * 0.25 * G / 200)  # 12.2625 mm
    assert result.verification.residual_ratio <= 1e-9


@pytest.mark.parametrize(("alpha", "a", "b"), [(35, 0, 0), (0, 40, -25)], ids=["com_on_axis", "vertical_axis"])
def test_tilted_link_degenerate_cases_balance_with_any_h(alpha, a, b):
    """a = b = 0 or α = 0: nothing moves vertically, so no condition constrains h."""
    result = tilted(alpha=alpha, a=a, b=b, h0=3.0, pinned=True)  # 3 mm is far from m g/k = 12.26 mm
    assert result.solution.conditions == 0
    assert value(result, "h", "mm") == pytest.approx(3.0)
    assert result.status.value == "optimal"
    assert result.verification.residual_ratio <= 1e-9


def test_tilted_link_with_another_height_is_not_balanced():
    """Control for the test above: the same h = 3 mm on the non-degenerate link fails."""
    result = tilted(alpha=35, a=40, b=-25, h0=3.0, pinned=True)
    assert result.status.value != "optimal"
    assert result.verification.residual_ratio > 0.5


# --------------------------------------------------------------------------------------
# Appendix B: the attachment may slide along the line from an axis point through the CoM
# --------------------------------------------------------------------------------------

APPENDIX_B = """
[problem]
name = "appendix_b"
[gravity]
acceleration = "9.81 m/s^2"
direction = [0, 0, -1]
[parameters]
m = "0.4 kg"
k = "300 N/m"
px = "15 mm"
py = "48 mm"
pz = "36 mm"
tT = "-20 mm"
qx = "55 mm"
b = "{b} mm"
r = "sqrt(px**2 + py**2)"
[subsystems.link]
coordinates.theta = {{ range = ["-180 deg", "180 deg"] }}
# the joint axis is world x; in the link frame it is z, T = (0, 0, tT) lies on it
[frames.link]
transforms = [{{ rotate = "y", angle = "90 deg" }}, {{ rotate = "z", angle = "theta" }}]
[bodies.link]
frame = "link"
mass = "m"
com = ["px", "py", "pz"]
[variables.h]
lower = "0 mm"
upper = "500 mm"
# H above Q = (qx, 0, 0), another point of the axis; B on the line T -> P with TB = (b/r) TP
[springs.s]
stiffness = "k"
from = {{ frame = "ground", point = ["qx", "0 mm", "h"] }}
to = {{ frame = "link", point = ["b/r*px", "b/r*py", "tT + b/r*(pz - tT)"] }}
[settings]
verify_tolerance = 1e-9
"""


@pytest.mark.parametrize("b", [20.0, 50.4, 90.0])
def test_appendix_b_attachment_on_the_line_through_the_com(approx, b):
    """V = const − (k b h − m g r) sin θ  ⇒  h = m g r/(k b), wherever B sits on the line."""
    result = design(load_problem_text(APPENDIX_B.format(b=b), "appendix_b"))
    assert result.status.value == "optimal"
    r = math.hypot(15.0, 48.0)  # mm
    assert value(result, "h", "mm") == approx(0.4 * G * r / (300 * b) * 1000)
    assert result.verification.residual_ratio <= 1e-9
