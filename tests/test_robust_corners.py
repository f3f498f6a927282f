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
    (+10 % on its rate), the value design.csv reports."""
    text = (PROBLEMS / "lamp_robust.toml").read_text(encoding="utf-8").replace("[springs.spring_1]\n", '[springs.spring_1]\nmax_force = "10 N"\n')
    path = tmp_path / "lamp_force.toml"
    path.write_text(text, encoding="utf-8")
    result = design(load_problem(path))
    assert result.optimal, result.message
    (limit,) = result.solution.constraints
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
    band = result.solution.robust.bands["robust"]
    assert band["mass"] == pytest.approx(0.02, rel=1e-6)
    assert band["all"] == pytest.approx(0.08, rel=1e-6)


# -- issue 32, item 16 and the Tolerance caption ----------------------------------------------


def test_fully_fixed_robust_problem_is_judged_by_its_dense_check(tmp_path):
    """problems/lamp_robust.toml with every variable fixed: the rates at their balancing values
    k_1 = g (m_1 L_1/2 + (m_2 + m_head) L_1)/(h_1 a_1) = 551.8125 N/m and k_2 = g (m_2 L_2/2 +
    m_head L_2)/(h_2 a_2) = 613.125 N/m, k_2 given 1.6e-10 high (a residual ratio of about
    1e-10, within verify_tolerance 1e-8), no counter-mass, the anchors held as tune variables.
    It was "infeasible (IPOPT)" with an empty tuning table; it is the design as given, judged
    by its dense check, and tuned at the 17 corners."""
    text = (PROBLEMS / "lamp_robust.toml").read_text(encoding="utf-8")
    for old, new in [
        ('[variables.k_1]\nlower = "0 N/m"\nupper = "3000 N/m"', '[variables.k_1]\nlower = "551.8125 N/m"\nupper = "551.8125 N/m"'),
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
    report = result.solution.robust
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
