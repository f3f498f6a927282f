"""[robust] keeps every design constraint and force limit at every tolerance corner (issue 31, part 1).

The robust pendulum of tests/test_robust.py (docs/robust.md#pendulum): residual
(m g l − M g b − k h a) cos θ, u = k h a/(m g l) the spring's share, v = M b/(m l) the
counter-mass's, rate ±t (t = 0.1). In ``limit`` mode (ρ = |1 − u − v| + t u ≤ ρ_max) the
lightest design for a given largest share u ≤ ρ_max/t keeps e = 1 − u − v = ρ_max − t u ≥ 0,
so v = 1 − ρ_max − (1 − t) u and M = (m l/b) v: the more spring, the less mass.

A force limit F on the spring is a limit on u at the +t corner: the spring pulls
k (1 + t) d, largest at θ = −90° where d = a + h, so k ≤ F/((1 + t)(a + h)) and
u ≤ F h a/((1 + t)(a + h) m g l).
"""

from __future__ import annotations

import pytest

from counterpoise.cli import main
from counterpoise.io.loader import load_problem
from counterpoise.pipeline import design
from counterpoise.solvers.base import Status

from conftest import PROBLEMS
from test_robust import MGL, PENDULUM
from counterpoise.robust.result import RobustReport

T, RHO = 0.1, 0.04
ML_B = 2 * 0.3 / 0.1  # m l/b = 6 kg
A = 0.2  # m


def _mass(u: float) -> float:
    """The least counter-mass of a limit-mode design with spring share u (module docstring)."""
    return ML_B * (1 - RHO - (1 - T) * u)


def _problem(folder, name: str, robust: str, h=("100 mm", "100 mm"), force: str | None = None, extra: str = ""):
    text = PENDULUM % {"robust": robust, "h_lower": h[0], "h_upper": h[1]}
    if force is not None:
        text = text.replace('[springs.s]\nstiffness = "k"', f'[springs.s]\nstiffness = "k"\nmax_force = "{force}"')
    path = folder / f"{name}.toml"
    path.write_text(text + extra, encoding="utf-8")
    return load_problem(path)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("robust_corners")


def _values(result) -> dict[str, float]:
    return {slot.variable: v for slot, v in result.solution.values.items()}


def test_force_limit_holds_at_the_worst_corner_lp(folder):
    """h = 100 mm held: k ≤ 30/(1.1 × 0.3) = 90.909 N/m, u = 0.30890 (module docstring), and
    M = 6 (0.96 − 0.9 u) = 4.0919 kg. Holding the limit at the nominal rate only would allow
    k = 100 N/m and M = 3.9251 kg: the design would pull 33 N at the +10 % corner."""
    result = design(_problem(folder, "force_lp", f'mode = "limit"\nlimit = {RHO}\ntolerances.rate = "10 %"', force="30 N"))
    assert result.optimal, result.message
    v = _values(result)
    k_max = 30 / ((1 + T) * (A + 0.1))
    assert v["k"] == pytest.approx(k_max, rel=1e-6)
    assert v["M"] == pytest.approx(_mass(k_max * 0.1 * A / MGL), rel=1e-6)
    (limit,) = result.solution.constraints
    assert limit.name == "s.max_force"
    assert limit.value == pytest.approx(30, rel=1e-6)  # at the +10 % corner, θ = −90°
    assert limit.active == "upper"
    assert limit.corner == "rate s +10 %"
    assert "at the tolerance corner rate s +10 %" in result.message


def test_force_limit_holds_at_every_corner_minimax(folder):
    """h free in [50, 150] mm (the minimax NLP): k h ≤ 30 h/(1.1 (a + h)) grows with h, so
    h = 150 mm, k h = 30 × 0.15/(1.1 × 0.35) = 11.6883 N < 11.772 N (the unlimited optimum,
    u = ρ_max/t), u = 0.397156 and M = 6 (0.96 − 0.9 u) = 3.61536 kg."""
    result = design(_problem(folder, "force_nlp", f'mode = "limit"\nlimit = {RHO}\ntolerances.rate = "10 %"', h=("50 mm", "150 mm"), force="30 N"))
    assert result.optimal, result.message
    assert "minimax NLP" in result.message
    v = _values(result)
    kh = 30 * 0.15 / ((1 + T) * (A + 0.15))
    assert v["h"] == pytest.approx(0.15, rel=1e-6)
    assert v["k"] * v["h"] == pytest.approx(kh, rel=1e-6)
    assert v["M"] == pytest.approx(_mass(kh * A / MGL), rel=1e-6)
    (limit,) = result.solution.constraints
    assert limit.value == pytest.approx(30, rel=1e-6) and limit.corner == "rate s +10 %"


def test_mode_none_names_the_corner_that_breaks_a_limit(folder):
    """The ordinary design (k = 294.3 N/m, M = 0) pulls 294.3 × 0.3 = 88.29 N at θ = −90°,
    within 90 N; at the +10 % corner 97.119 N: never "optimal" in breach."""
    result = design(_problem(folder, "force_none", 'tolerances.rate = "10 %"', force="90 N"))
    assert result.status is Status.INFEASIBLE
    assert "breaks a constraint at a tolerance corner: s.max_force" in result.message
    (limit,) = result.solution.constraints
    assert limit.value == pytest.approx(294.3 * 1.1 * 0.3, rel=1e-6)
    assert limit.active == "violated" and limit.corner == "rate s +10 %"


def test_constraint_conflict_is_named_with_its_amount(folder):
    """M ≤ 3 kg with ρ ≤ 0.04: the least mass is 3.6 kg (u = 0.4): the constraint is missed by
    0.6 kg, and the design reported is the least relaxation's."""
    extra = '\n[constraints.housing]\nexpression = "M"\nupper = "3 kg"\n'
    result = design(_problem(folder, "conflict", f'mode = "limit"\nlimit = {RHO}\ntolerances.rate = "10 %"', extra=extra))
    assert result.status is Status.INFEASIBLE
    assert "housing (missed by 0.6 kg)" in result.message
    assert _values(result)["M"] == pytest.approx(3.6, rel=1e-6)


@pytest.mark.parametrize(
    ("name", "edit", "fragment"),
    [
        ("m1cap", '\n[constraints.m1cap]\nexpression = "M_1"\nupper = "0.5 kg"\n', "m1cap (missed by"),
        ("addcap", '\n[constraints.cap]\nexpression = "added_mass()"\nupper = "1 kg"\n', "cap (missed by"),
    ],
)
def test_lamp_reproducers_are_never_optimal_in_breach(tmp_path, capsys, name, edit, fragment):
    """Issue 31's reproducers on problems/lamp_robust.toml: M_1 ≤ 0.5 kg and an added-mass cap of
    1 kg cannot hold with a worst case of 0.06 (it needs 3.14 kg, M_1 = 2.64 kg): infeasible,
    the constraint named, and design.csv shows it with its worst corner."""
    path = tmp_path / f"{name}.toml"
    path.write_text((PROBLEMS / "lamp_robust.toml").read_text(encoding="utf-8") + edit, encoding="utf-8")
    with pytest.raises(SystemExit) as stop:
        main(["solve", str(path), "--out", str(tmp_path / "out")])
    assert stop.value.code == 1
    status = (tmp_path / "out" / "lamp_robust" / "status.txt").read_text()
    assert "status: infeasible" in status and fragment in status
    rows = [line for line in (tmp_path / "out" / "lamp_robust" / "design.csv").read_text().splitlines() if ",constraint," in line]
    assert len(rows) == 1 and ",violated," in rows[0] and "worst tolerance corner" in rows[0]


def test_lamp_force_limit_is_kept_at_every_corner(tmp_path):
    """max_force = 10 N on spring_1 (the robust design pulled 18.1 N): kept at its worst corner
    (+10 % on its rate), the value design.csv reports. (Without the tuning: with it, a spring
    of that force range cannot be wound with an initial tension low enough to stay taut at
    every tuned corner, which the hardware check reports; tests/test_robust_tuning.py.)"""
    text = (PROBLEMS / "lamp_robust.toml").read_text(encoding="utf-8").replace("[springs.spring_1]\n", '[springs.spring_1]\nmax_force = "10 N"\n')
    text = text.replace('tune = ["h_1", "h_2"]\n', "")
    # h_1 free (no longer a tuning screw) would climb towards the cable's grip at 130 mm and
    # bring the spring's ends within its F0/k: kept below 80 mm, as a bracket would be
    text = text.replace('[variables.h_1]\nlower = "20 mm"\nupper = "120 mm"', '[variables.h_1]\nlower = "20 mm"\nupper = "80 mm"')
    assert 'upper = "80 mm"' in text
    path = tmp_path / "lamp_force.toml"
    path.write_text(text, encoding="utf-8")
    result = design(load_problem(path))
    assert result.optimal, result.message
    (limit,) = [v for v in result.solution.constraints if v.name == "spring_1.max_force"]
    assert limit.value <= 10 * (1 + 1e-7)
    assert limit.corner == "rate spring_1 +10 %"


# -- input (issue 31 part 6; issue 32 item 12) ------------------------------------------------


def test_absolute_rate_tolerance_beyond_the_nominal_is_refused(folder):
    """1e308 N/m on a rate of at most 2000 N/m (k's upper bound) gave a band of 1.7e305, exit 0."""
    from counterpoise.errors import ProblemFileError

    with pytest.raises(ProblemFileError) as error:
        _problem(folder, "huge_rate", 'tolerances.rate = "1e308 N/m"')
    assert error.value.key == "robust.tolerances.rate"
    assert "not below the nominal rate (at most 2000 N/m within the bounds)" in error.value.message


def test_counter_mass_tolerance(folder):
    """The counter-mass toleranced too (±5 %, by name): ρ = |1 − u − v| + 0.1 u + 0.05 v. On the
    balance line (e = 0) ρ = 0.05 + 0.05 u ≤ 0.08 gives u ≤ 0.6 (a positive e costs 0.95 per unit
    against u's 0.05, a negative one only lowers u), so v = 0.4: M = 2.4 kg, k = 0.6 × 294.3 =
    176.58 N/m, and the mass tolerance's share of the band is 0.05 v = 0.02."""
    result = design(_problem(folder, "cm_tolerance", 'mode = "limit"\nlimit = 0.08\ntolerances.rate = "10 %"\ntolerances.mass = { cm = "5 %" }'))
    assert result.optimal, result.message
    v = _values(result)
    assert v["M"] == pytest.approx(2.4, rel=1e-6)
    assert v["k"] == pytest.approx(0.6 * 294.3, rel=1e-6)
    band = result.solution.extra(RobustReport).bands["robust"]
    assert band["mass"] == pytest.approx(0.02, rel=1e-6)
    assert band["all"] == pytest.approx(0.08, rel=1e-6)


# -- issue 32, item 16 and the Tolerance caption ----------------------------------------------


def test_fully_fixed_robust_problem_is_judged_by_its_dense_check(tmp_path):
    """problems/lamp_robust.toml with every variable fixed: the rates at their balancing values
    k_1 = g (m_1 L_1/2 + (m_2 + m_head) L_1)/(h_1 a_1) = 9.81 × 0.27/(0.06 × 0.13) = 339.57692307692 N/m
    (to rounding: a residual ratio of about 1e-14) and k_2 = g (m_2 L_2/2 +
    m_head L_2)/(h_2 a_2) = 613.125 N/m, k_2 given 1.6e-10 high (a residual ratio of about
    1e-10, within verify_tolerance 1e-8), no counter-mass, the anchors held as tune variables.
    It was "infeasible (IPOPT)" with an empty tuning table; it is the design as given, judged
    by its dense check, and tuned at the 17 corners."""
    text = (PROBLEMS / "lamp_robust.toml").read_text(encoding="utf-8")
    for old, new in [
        ('[variables.k_1]\nlower = "0 N/m"\nupper = "3000 N/m"', '[variables.k_1]\nlower = "339.57692307692 N/m"\nupper = "339.57692307692 N/m"'),
        ('[variables.k_2]\nlower = "0 N/m"\nupper = "3000 N/m"', '[variables.k_2]\nlower = "613.1250001 N/m"\nupper = "613.1250001 N/m"'),
        ('[variables.M_1]\nlower = "0 kg"\nupper = "5 kg"', '[variables.M_1]\nlower = "0 kg"\nupper = "0 kg"'),
        ('[variables.M_2]\nlower = "0 kg"\nupper = "5 kg"', '[variables.M_2]\nlower = "0 kg"\nupper = "0 kg"'),
        ('mode = "limit"\nlimit = 0.06\n', ""),
    ]:
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "fixed.toml"
    path.write_text(text, encoding="utf-8")
    result = design(load_problem(path))
    assert result.optimal, result.message
    assert 0 < result.verification.residual_ratio <= 1e-8
    report = result.solution.extra(RobustReport)
    assert len(report.corners) == 17 and report.tuning_status == "balanced"


def test_robust_tolerance_section_has_its_own_caption(folder, capsys):
    path = folder / "caption.toml"
    path.write_text(PENDULUM % {"robust": 'tolerances.rate = "10 %"', "h_lower": "100 mm", "h_upper": "100 mm"}, encoding="utf-8")
    with pytest.raises(SystemExit) as stop:
        main(["solve", str(path), "--out", str(folder / "caption_out")])
    assert stop.value.code == 0, capsys.readouterr()
    page = (folder / "caption_out" / "robust_pendulum" / "report.html").read_text()
    assert "worst-case residual ratio over the whole tolerance box ([robust])" in page
    assert "the parts&#x27; rates and initial tensions" not in page and "the parts' rates and initial tensions" not in page


# -- exactness (issue 31 part 4) --------------------------------------------------------------


def test_mass_and_centre_of_mass_together_equal_vertex_enumeration(folder):
    """Acceptance: the worst case with a body's mass and centre of mass toleranced together
    (their product δ_m·δ_c is not first order) equals an exact enumeration of the 16 vertices
    of (δ_k, δ_m, δ_x, δ_y) on the same configurations (θ on a grid of 10,001 nodes over
    [−180°, 180°]: affine.grid for one coordinate): the residual of the nominal design
    (M = 0, k h a = m g l) is m g (1 + δ_m)((l + δ_x) cos θ − δ_y sin θ) − k (1 + δ_k) a h cos θ."""
    import itertools

    import numpy as np

    robust = 'tolerances.rate = "10 %"\ntolerances.mass = { bob = "5 %" }\ntolerances.com = { bob = "1 mm" }'
    band = design(_problem(folder, "mass_com", robust)).solution.extra(RobustReport).bands["nominal"]
    m, g, l = 2.0, 9.81, 0.3
    theta = np.linspace(-np.pi, np.pi, 10_001)
    worst = 0.0
    for dk, dm, dx, dy in itertools.product((-0.1, 0.1), (-0.05, 0.05), (-1e-3, 1e-3), (-1e-3, 1e-3)):
        r = m * g * (1 + dm) * ((l + dx) * np.cos(theta) - dy * np.sin(theta)) - m * g * l * (1 + dk) * np.cos(theta)
        worst = max(worst, float(np.abs(r).max()))
    assert band["all"] == pytest.approx(worst / (m * g * l), abs=1e-9)
    # the first-order sum misses the product term 0.05 × 1 mm/l cos θ at θ = 0 (1.7e-4)
    assert band["all"] > 0.1 + 0.05 + 1e-3 / l + 1e-4


CATALOGUE = """part_number,rate_N_per_m,free_length_m,initial_tension_N,max_load_N,max_length_m,outer_diameter_m,wire_diameter_m,material,mass_kg,price_eur,rate_tolerance,initial_tension_tolerance
T-200,200,0.05,2,80,0.5,0.012,0.0015,music wire,0.01,1.5,0.1,0.2
"""


def test_catalogue_band_has_the_initial_tension_share_of_a_rate_error(folder):
    """The pendulum balanced by one catalogue part behind a pulley (k = 200 N/m, F0 = 2 N, rate
    ±10 %, initial tension ±20 %), no counter-mass, h = m g l/(k a) = 147.15 mm. The string is
    set for the nominal part, so a part k + Δk, F0 + ΔF0 pulls k d + Δk (d − F0/k) + ΔF0 and
    (∂d/∂θ = −a h cos θ/d) the rate alone leaves t_k a h |cos θ| (k − F0/d): evaluated here on a
    fine grid of θ (about 0.0960 of m g l, not 0.1: the −Δk·F0/k term); the initial tension alone
    t_F F0 a h |cos θ|/d, largest where sin θ = h/a, equal to t_F F0 h: ratio 0.01 exactly."""
    import numpy as np

    (folder / "parts.csv").write_text(CATALOGUE, encoding="utf-8")
    text = PENDULUM % {"robust": "", "h_lower": "50 mm", "h_upper": "150 mm"}
    text = text.replace("[robust]\n", "").replace('upper = "10 kg"', 'upper = "0 kg"').replace('stiffness = "k"', 'slot = "s"')
    text = text.replace('[variables.k]\nlower = "0 N/m"\nupper = "2000 N/m"\n', '[catalogues.mine]\nfile = "parts.csv"\n\n[slots.s]\ncatalogue = "mine"\n')
    path = folder / "part_band.toml"
    path.write_text(text, encoding="utf-8")
    result = design(load_problem(path))
    assert result.optimal, result.message
    k, f0, a, mgl = 200.0, 2.0, A, MGL
    h = mgl / (k * a)
    assert _values(result)["h"] == pytest.approx(h, rel=1e-9)
    theta = np.linspace(-np.pi, np.pi, 2_000_001)
    d = np.sqrt(a**2 + h**2 - 2 * a * h * np.sin(theta))
    rate = 0.1 * a * h * np.abs(np.cos(theta)) * (k - f0 / d)
    tension = 0.2 * f0 * a * h * np.abs(np.cos(theta)) / d
    band = result.parts.tolerance
    assert band.worst_rate == pytest.approx(rate.max() / mgl, rel=1e-6)
    assert band.worst_rate < 0.0961  # the rate alone used to be reported as 0.1
    assert band.worst_tension == pytest.approx(0.01, rel=1e-6)
    assert band.worst == pytest.approx((rate + tension).max() / mgl, rel=1e-6)


def test_ellipsoid_with_products_is_labelled_a_bound(folder):
    """Over the ellipsoid Σ (δ_i/t_i)² ≤ 1 the product δ_m·δ_x is bounded, not exact: the figure
    is labelled a bound. Its first-order part at θ is m g l ‖(0.1 cos θ, 0.05 cos θ,
    (1 mm/l) cos θ, (1 mm/l) sin θ)‖ = m g l √(0.0125 cos² θ + (1 mm/l)²); the products
    δ_m (δ_x cos θ − δ_y sin θ) are bounded by their largest value over the box,
    0.05 × 1 mm/l × (|cos θ| + |sin θ|): the figure is the largest sum over θ. The bound holds:
    it is at least the residual at 2,000 random points of the ellipsoid's surface."""
    import numpy as np

    robust = 'shape = "ellipsoid"\ntolerances.rate = "10 %"\ntolerances.mass = { bob = "5 %" }\ntolerances.com = { bob = "1 mm" }'
    result = design(_problem(folder, "ellipse_bound", robust))
    report = result.solution.extra(RobustReport)
    assert report.exactness.startswith("a bound over the ellipsoid")
    assert "(a bound) over the tolerance ellipsoid" in result.message
    m, g, l = 2.0, 9.81, 0.3
    theta = np.linspace(-np.pi, np.pi, 10_001)
    rng = np.random.default_rng(1)
    u = rng.normal(size=(2_000, 4))
    u /= np.linalg.norm(u, axis=1)[:, None]
    dk, dm, dx, dy = (u * np.array([0.1, 0.05, 1e-3, 1e-3])).T
    c, s = np.cos(theta), np.sin(theta)
    near = np.abs(theta) <= 0.2  # the worst lies near θ = 0 (the rate and mass terms peak there)
    r = m * g * (1 + dm[:, None]) * ((l + dx[:, None]) * c[near] - dy[:, None] * s[near]) - m * g * l * (1 + dk[:, None]) * c[near]
    sampled = float(np.abs(r).max()) / (m * g * l)
    figure = np.sqrt(0.0125 * c**2 + (1e-3 / l) ** 2) + 0.05 * 1e-3 / l * (np.abs(c) + np.abs(s))
    assert report.bands["nominal"]["all"] == pytest.approx(float(figure.max()), rel=1e-9)
    assert sampled <= report.bands["nominal"]["all"]


# -- the objective minimised and the free-geometry ellipsoid (issue 31 part 5) -------------------


@pytest.mark.parametrize(("weight", "mass", "band"), [(30.0, 0.0, 0.1), (100.0, 6.0, 0.0)])
def test_minimise_mode_reports_the_objective_it_minimised(folder, weight, mass, band):
    """minimise mode minimises M + W ρ (docs/robust.md#pendulum: the spring alone, ρ = t = 0.1,
    below W* = 60 kg; the mass alone, M = 6 kg and ρ = 0, above it): the objective reported is
    M + W ρ = 3 kg and 6 kg, not the added mass alone."""
    result = design(_problem(folder, f"objective_{weight:g}", f'mode = "minimise"\nweight = "{weight:g} kg"\ntolerances.rate = "10 %"'))
    assert result.optimal, result.message
    assert result.solution.objective == pytest.approx(mass + weight * band, abs=1e-6)
    report = result.solution.extra(RobustReport)
    assert report.objective["robust"] == pytest.approx(mass + weight * band, abs=1e-6)
    assert report.base_objective["robust"] == pytest.approx(mass, abs=1e-6)
    # the nominal design (spring alone) under the same criterion: 0 + W × 0.1
    assert report.objective["nominal"] == pytest.approx(weight * 0.1, rel=1e-6)


def test_free_geometry_ellipsoid_is_the_ellipsoid_not_its_box(folder):
    """Rate ±10 % and the bob's mass ±5 % over the ellipsoid: ρ = |e| + √((0.1 u)² + 0.05²)
    (the mass scales the whole gravity torque). With ρ ≤ 0.08 every unit of budget is best
    spent on u (its cost 0.01 u/√(…) < 1 of e's), so e = 0, u = √(0.08² − 0.05²)/0.1 = 0.62450,
    M = 6 (1 − u) = 2.2530 kg, whether h is held (the SOCP) or free (the minimax NLP, k h only
    matters). Treating the ellipsoid as its box gave 0.1 u + 0.05 ≤ 0.08, u = 0.3, M = 4.2 kg."""
    import math

    robust = 'mode = "limit"\nlimit = 0.08\nshape = "ellipsoid"\ntolerances.rate = "10 %"\ntolerances.mass = { bob = "5 %" }'
    u = math.sqrt(0.08**2 - 0.05**2) / 0.1
    for name, h in (("ellipse_socp", ("100 mm", "100 mm")), ("ellipse_nlp", ("50 mm", "150 mm"))):
        result = design(_problem(folder, name, robust, h=h))
        assert result.optimal, result.message
        assert _values(result)["M"] == pytest.approx(ML_B * (1 - u), rel=1e-6), name
        assert result.solution.extra(RobustReport).bands["robust"]["all"] == pytest.approx(0.08, rel=1e-6)
    assert "minimax NLP over the tolerance ellipsoid" in result.message
