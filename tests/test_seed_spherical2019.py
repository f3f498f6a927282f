"""Seed 002 (geometric static balancing of spherical mechanisms, 2019): spherical chain units.

The facts and their hand derivations are in docs/derivations.md, section "Spherical chains
2019"; here every one is reproduced through the general engine (problem files or TOML
texts built below), never from the paper's formulas. Tolerance 0.1 % unless stated.
"""

from __future__ import annotations

import math
import pytest

from conftest import solved as solved_as_built
from conftest import value
from counterpoise.io.loader import load_problem_text
from counterpoise.pipeline import design

G = 9.81
#: the paper's numbers are those of its idealised springs (zero free length, exactly the
#: design rate); the shipped files build real ones, wound a little off these rates, and the
#: design follows them (tests/test_build_sheet.py checks them as built)
IDEAL = (("settings.ideal_springs", "true"),)


def solved(name, overrides=()):
    return solved_as_built(name, (*overrides, *IDEAL))


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
        assert result.solution.stats.conditions == 3


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
ideal_springs = true
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
    assert result.solution.stats.conditions == 1
    assert value(result, "h", "mm") == approx(1000 * 0.25 * G / 200)  # 12.2625 mm
    assert result.verification.residual_ratio <= 1e-9


@pytest.mark.parametrize(("alpha", "a", "b"), [(35, 0, 0), (0, 40, -25)], ids=["com_on_axis", "vertical_axis"])
def test_tilted_link_degenerate_cases_balance_with_any_h(alpha, a, b):
    """a = b = 0 or α = 0: nothing moves vertically, so no condition constrains h."""
    result = tilted(alpha=alpha, a=a, b=b, h0=3.0, pinned=True)  # 3 mm is far from m g/k = 12.26 mm
    assert result.solution.stats.conditions == 0
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
ideal_springs = true
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


# --------------------------------------------------------------------------------------
# Examples 1 and 2: loops opened at one joint (problems/spherical_5r.toml,
# problems/bennett_double_spherical.toml; docs/seeds.md)
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "heights"),
    [
        # h_i = m_i g/k, k = 200 N/m: 300, 250, 200, 150 g
        ("spherical_5r", {"h1": 0.300, "h2": 0.250, "h3": 0.200, "h4": 0.150}),
        # k = 100 N/m: m = 200 g for links 1, 2, 4, 5 and m' = 150 g for link 3 (H'2)
        ("bennett_double_spherical", {"h1": 0.200, "h2": 0.200, "h3": 0.150, "h4": 0.200, "h5": 0.200}),
    ],
)
def test_opened_loop_heights(approx, name, heights):
    result = solved(name)
    assert result.status.value == "optimal"
    assert result.verification.residual_ratio <= 1e-9
    k = {"spherical_5r": 200.0, "bennett_double_spherical": 100.0}[name]
    for var, mass in heights.items():
        assert value(result, var, "mm") == approx(1000 * mass * G / k)


def test_5r_heights_are_independent_of_the_other_links():
    """Eq. (18): one condition per spring; a heavier link 3 changes h3 alone."""
    result = solved("spherical_5r", (("parameters.m3", "400 g"),))
    assert value(result, "h3", "mm") == pytest.approx(1000 * 0.4 * G / 200, rel=1e-6)
    assert value(result, "h2", "mm") == pytest.approx(1000 * 0.25 * G / 200, rel=1e-6)
    assert result.solution.stats.conditions == 4


def test_5r_with_its_loop_closed_is_balanced_by_the_paper_heights():
    """spherical_5r_closed.toml: R5 closed through the loop engine, heights pinned at m_i g/k;
    the balance is verified on the 2-DOF configuration manifold (docs/seeds.md#spherical-5r)."""
    result = solved("spherical_5r_closed")
    assert result.status.value == "optimal"
    assert result.verification.residual_ratio <= 1e-9
    assert result.verification.configurations >= 10_000


def test_5r_closed_leaves_one_height_free():
    """On the closed loop the four link terms are dependent: 3 conditions on 4 heights
    (the opened chain has 4), so the paper's heights are one balancing set among a family."""
    free = tuple((f"variables.h{i}.{end}", v) for i in (1, 2, 3, 4) for end, v in (("lower", "0 mm"), ("upper", "100 mm")))
    result = solved("spherical_5r_closed", free)
    assert result.status.value == "optimal"
    assert result.verification.residual_ratio <= 1e-9
    assert result.solution.stats.conditions == 3


def test_5r_closed_with_a_wrong_height_is_not_balanced():
    """Control: h3 = 2 m3 g/k = 19.62 mm instead of 9.81 mm leaves link 3 unbalanced."""
    pinned = (("variables.h3.lower", "19.62 mm"), ("variables.h3.upper", "19.62 mm"))
    result = solved("spherical_5r_closed", pinned)
    assert result.status.value != "optimal"
    assert result.verification.residual_ratio > 0.01


# --------------------------------------------------------------------------------------
# Example 3, the Bennett plano-spherical linkage: problems/bennett_plano_spherical.toml
# --------------------------------------------------------------------------------------


class TestBennettPlanoSpherical:
    """Link 2 (m, centre midway) becomes m/2 on R2 and m/2 on R3 (I3); four springs
    (docs/seeds.md#bennett-plano-spherical). m = 200 g, k = 100 N/m, L = 300 mm."""

    @pytest.fixture
    def result(self):
        return solved("bennett_plano_spherical")

    def test_balanced(self, result):
        assert result.status.value == "optimal"
        assert result.verification.residual_ratio <= 1e-9
        assert result.verification.configurations >= 10_000

    def test_substituted_masses(self, result, approx):
        assert value(result, "mu_R2", "g") == approx(100.0)
        assert value(result, "mu_R3", "g") == approx(100.0)

    def test_augmented_links_and_attachment_fractions(self, result, approx):
        # link 1: m + m/2 = 3m/2 = 300 g, centre of mass (m L/2 + m/2 L)/(3m/2) = 2L/3 = 200 mm
        assert value(result, "M1", "g") == approx(300.0)
        assert value(result, "r1", "mm") / 300.0 == approx(2 / 3)
        # link 3: m/2 + mu_R3 = m = 200 g at (m/2 L/2 + mu_R3 L)/m = 3L/4 (the top quarter)
        mu3 = value(result, "mu_R3", "g")
        assert 100.0 + mu3 == approx(200.0)
        assert (100.0 * 150.0 + mu3 * 300.0) / (100.0 + mu3) / 300.0 == approx(3 / 4)
        # links 5, 4 and augmented link 3: 200 + 200 + 200 g
        assert value(result, "M_spherical", "g") == approx(600.0)

    def test_spring_heights(self, result, approx):
        assert value(result, "h1", "mm") == approx(1000 * 3 * 0.2 * G / (2 * 100))  # 3mg/(2k) = 29.43 mm
        for name in ("h3", "h4", "h5"):
            assert value(result, name, "mm") == approx(1000 * 0.2 * G / 100)  # mg/k = 19.62 mm

    def test_attachment_elsewhere_on_the_line_changes_the_height(self, approx):
        """Appendix B: on link 3 at L/2 instead of 3L/4, h3 = m g (3L/4)/(k L/2) = 1.5 mg/k = 29.43 mm."""
        result = solved("bennett_plano_spherical", (("parameters.f3", "0.5"),))
        assert result.verification.residual_ratio <= 1e-9
        assert value(result, "h3", "mm") == approx(1.5 * 1000 * 0.2 * G / 100)

    def test_link_2_that_does_not_reach_r3_is_rejected(self):
        """Link 2's R3 point 10 mm off link 3's end at home: the linkage cannot be assembled."""
        from counterpoise.errors import ProblemFileError
        from counterpoise.io.loader import load_problem

        from conftest import PROBLEMS

        with pytest.raises(ProblemFileError) as info:
            load_problem(PROBLEMS / "bennett_plano_spherical.toml", {"parameters.p3y": "160 mm"})
        assert info.value.key == "substitutions.link2.points.mu_R3"
        assert "does not coincide" in info.value.message


# --------------------------------------------------------------------------------------
# The 3-RRS parallel mechanism (example 4): problems/rrs3_parallel.toml
# --------------------------------------------------------------------------------------


class TestRRS3:
    """Three legs with their own centres O_i on a circle of radius 150 mm (no common point);
    platform 900 g, m1 = 150 g, m2 = 120 g, k = 200 N/m (docs/seeds.md#rrs3)."""

    def test_paper_spring_heights(self, approx):
        """h_i1 = m1 g/k = 7.3575 mm; h_i2 = (m2 + m_u/3) g/k = 0.42 * 9.81/200 = 20.601 mm."""
        result = solved("rrs3_parallel")
        for i in (1, 2, 3):
            assert value(result, f"h{i}_1", "mm") == approx(1000 * 0.150 * G / 200)
            assert value(result, f"h{i}_2", "mm") == approx(1000 * (0.120 + 0.300) * G / 200)

    def test_leg_centres_are_not_concurrent(self):
        """The paper's 3-RRS has no common point of its axes: each leg's two axes meet at its
        own O_i, 150 mm from the centre, 260 mm from the next leg's."""
        import numpy as np

        from counterpoise.io.loader import load_problem
        from counterpoise.mechanics.energy import Mechanics

        from conftest import PROBLEMS

        problem = load_problem(PROBLEMS / "rrs3_parallel.toml")
        base = {p.name: p.value for p in problem.parameters if p.is_base}
        home = {c.name: c.home for c in problem.coordinates}
        mech = Mechanics(problem, base, {v.name: v.initial for v in problem.variables}, home, [0.0, 0.0, -G])
        centres = [np.array(mech.pose(f"leg{i}_1")[1], dtype=float) for i in (1, 2, 3)]
        for i in range(3):
            assert np.linalg.norm(centres[i]) == pytest.approx(0.150)
            assert np.linalg.norm(centres[i] - centres[(i + 1) % 3]) == pytest.approx(0.150 * math.sqrt(3))

    def test_legs_turning_about_one_point_are_rejected(self):
        """The former file: every leg about O, S point of link 2 at (0, 90, 110) mm, 142.13 mm
        from O, while the platform's S points are 156.2 mm from O."""
        from counterpoise.errors import ProblemFileError
        from counterpoise.io.loader import load_problem

        from conftest import PROBLEMS

        overrides = {"parameters.R_b": "0 mm", "parameters.s_x": "0 mm", "parameters.s_y": "90 mm", "parameters.s_z": "110 mm"}
        with pytest.raises(ProblemFileError) as info:
            load_problem(PROBLEMS / "rrs3_parallel.toml", overrides)
        assert info.value.key == "substitutions.platform.points.m_u1"
        assert "does not coincide with the point of frame 'leg1_2'" in info.value.message

    def test_symmetric_platform_splits_in_thirds(self, approx):
        result = solved("rrs3_parallel")
        assert result.status.value == "optimal"
        assert result.verification.residual_ratio <= 1e-9
        for name in ("m_u1", "m_u2", "m_u3"):
            assert value(result, name, "g") == approx(900.0 / 3)

    def test_off_centre_platform_splits_unequally_and_still_balances(self, approx):
        result = solved("rrs3_parallel", (("parameters.u_x", "20 mm"), ("parameters.u_y", "-10 mm")))
        assert result.status.value == "optimal"
        assert result.verification.residual_ratio <= 1e-9
        mu = [value(result, f"m_u{i}", "g") for i in (1, 2, 3)]
        assert max(mu) - min(mu) > 100  # clearly unequal
        for i, m in zip((1, 2, 3), mu):  # each link 2 carries its own share: h_i2 = (m2 + mu_i) g/k
            assert value(result, f"h{i}_2", "mm") == approx((120.0 + m) * G / 200)
        # mass and first moment are kept: Σμ = m_u, Σμ s = m_u c (S joints at r = 100 mm, 30/150/270 deg)
        assert sum(mu) == approx(900.0)
        phis = [math.radians(a) for a in (30, 150, 270)]
        assert sum(m * 100 * math.cos(p) for m, p in zip(mu, phis)) == pytest.approx(900 * 20, rel=1e-6)
        assert sum(m * 100 * math.sin(p) for m, p in zip(mu, phis)) == pytest.approx(900 * -10, rel=1e-6)

    def test_substitution_report_file(self, tmp_path):
        from counterpoise.report import write_reports

        folder = write_reports(solved("rrs3_parallel"), tmp_path)
        lines = (folder / "substitution.csv").read_text().splitlines()
        assert lines[0] == "body,point,frame,scenario,mass,unit"
        assert [line.split(",")[1] for line in lines[1:]] == ["m_u1", "m_u2", "m_u3"]
        assert all(line.endswith(",300,g") for line in lines[1:])

    def test_a_scenario_cannot_move_the_substitution_points(self):
        """The split is solved once, at the file's values: a scenario changing r is an error."""
        from counterpoise.errors import ProblemFileError
        from counterpoise.io.loader import load_problem

        from conftest import PROBLEMS

        with pytest.raises(ProblemFileError) as info:
            load_problem(PROBLEMS / "rrs3_parallel.toml", {"scenarios.wide.parameters.r": "120 mm"})
        assert info.value.key == "scenarios.wide.parameters.r"
        assert "substitution points of body 'platform'" in info.value.message

    def test_centre_of_mass_off_the_plane_has_no_substitution(self):
        from counterpoise.errors import ProblemFileError
        from counterpoise.io.loader import load_problem

        from conftest import PROBLEMS

        with pytest.raises(ProblemFileError) as info:
            load_problem(PROBLEMS / "rrs3_parallel.toml", {"parameters.u_z": "100 mm"})
        assert info.value.key == "substitutions.platform"
        assert "no substitution exists for body 'platform'" in info.value.message


# --------------------------------------------------------------------------------------
# The linear system itself: exact, least-norm, impossible
# --------------------------------------------------------------------------------------


def test_substitution_matrix_exact_and_least_norm():
    import numpy as np

    from counterpoise.model.substitution import substitution_gap, substitution_matrix

    # two points, centre of mass on their line at 1/4: exact, 3/4 and 1/4 of the mass
    two = np.array([[0.0, 0.0, 0.0], [0.4, 0.0, 0.0]])
    mu = substitution_matrix(two) @ np.array([2.0, 2.0 * 0.1, 0.0, 0.0])
    assert mu == pytest.approx([1.5, 0.5])
    assert substitution_gap(two, np.array([0.1, 0.0, 0.0])) == pytest.approx(0.0, abs=1e-12)
    # off the line: no substitution
    assert substitution_gap(two, np.array([0.1, 0.05, 0.0])) > 1e-3
    # four coplanar points (a square), centre of mass at its centre: under-determined, and
    # the least-norm solution is the equal split
    square = np.array([[1.0, 1.0, 0.0], [-1.0, 1.0, 0.0], [-1.0, -1.0, 0.0], [1.0, -1.0, 0.0]])
    mu = substitution_matrix(square) @ np.array([4.0, 0.0, 0.0, 0.0])
    assert mu == pytest.approx([1.0, 1.0, 1.0, 1.0])
