"""Design constraints ([constraints.<name>]) and spring force limits (max_force).

Hand-derived cases (every number derived here):

**Pendulum in a housing (IPOPT).** A link of mass m = 1 kg with its centre of mass at
r = 0.2 m from a revolute joint (gravity −y, angle φ ∈ [−90°, 90°], home φ = 0), and a
counter-mass M at distance b behind the joint (variables M ∈ [0, 10] kg, b ∈ [0.05, 0.5] m).
Balance: M b = m r. Minimising M drives b up; the housing keeps the counter-mass within L of
the joint axis at home: −x_home(cm) = b ≤ L. So M* = m r / L and ∂M*/∂L = −m r / L²; with
L = 0.3 m: M* = 2/3 kg, ∂M*/∂L = −0.2/0.09 = −2.2222 kg/m.

**Spring and counter-mass at fixed geometry (LP, Clarabel).** The same link; a zero-free-
length spring k from A = (0, h) on the ground to B = a(cos φ, sin φ) on the link, a = h =
0.1 m, and M at the fixed distance b = 0.25 m behind the joint. |A − B|² = h² + a² − 2ah sin φ,
so the spring's energy is −k a h sin φ + const, and balance is m g r = k a h + M g b:
M = (m g r − 0.01 k)/(g b). Minimising M takes k as large as allowed. The spring pulls
F = k |A − B|, largest at φ = −90° where |A − B| = a + h = 0.2 m: F_max = 0.2 k. With
max_force F: k* = 5 F, M* = (m g r − 0.05 F)/(g b), ∂M*/∂F = −0.05/(g b) = −0.020387 kg/N.
For F = 15 N: k* = 75 N/m, M* = (1.962 − 0.75)/2.4525 = 0.49419 kg.
A cap M ≤ 0.3 kg then conflicts with F = 15 N (M* ≥ 0.494 kg): infeasible, both named.
"""

from __future__ import annotations

import numpy as np
import pytest

from counterpoise import ProblemBuilder, design, load_problem, rotate
from counterpoise.cli import main
from counterpoise.errors import ProblemFileError
from counterpoise.mechanics.poses import mechanics
from counterpoise.formulation.constraints import spring_force_length
from counterpoise.solvers.base import Status

from builders import counter_mass_toml, one_link_toml
from conftest import PROBLEMS, solved

G = 9.81


def housing(limit: str = "0.3 m", **constraints: dict) -> ProblemBuilder:
    b = ProblemBuilder("housing", gravity=f"{G} m/s^2", direction=(0, -1, 0))
    b.subsystem("arm", phi=("-90 deg", "90 deg"))
    b.frame("link", rotate("z", "phi"))
    b.parameter("m", "1 kg").parameter("r", "0.2 m")
    b.variable("M", "0 kg", "10 kg").variable("b", "0.05 m", "0.5 m", initial="0.2 m")
    b.body("link", "link", "m", ("r", 0, 0))
    b.counter_mass("cm", "link", "M", ("-b", 0, 0))
    b.constraint("inside", "-x_home(cm)", upper=limit, unit="mm", description="counter-mass inside the housing")
    for name, spec in constraints.items():
        b.constraint(name, **spec)
    return b


def spring_lp(max_force: str = "15 N", **constraints: dict) -> ProblemBuilder:
    b = ProblemBuilder("spring_lp", gravity=f"{G} m/s^2", direction=(0, -1, 0))
    b.subsystem("arm", phi=("-90 deg", "90 deg"))
    b.frame("link", rotate("z", "phi"))
    b.parameter("m", "1 kg").parameter("r", "0.2 m").parameter("b", "0.25 m")
    b.variable("M", "0 kg", "10 kg").variable("k", "0 N/m", "100 N/m")
    b.body("link", "link", "m", ("r", 0, 0))
    b.counter_mass("cm", "link", "M", ("-b", 0, 0))
    b.spring("s", "k", ("ground", (0, "0.1 m", 0)), ("link", ("0.1 m", 0, 0)), max_force=max_force)
    for name, spec in constraints.items():
        b.constraint(name, **spec)
    # the constraints' machinery on the textbook spring, whose ends meet at φ = 90° (ideal:
    # no realisation limits; tests/test_realisation.py holds springs as built)
    return b.settings(ideal_springs=True)


def _value(result, name):
    return next(v for v in result.solution.constraints if v.name == name)


def _mass(result):
    return next(v for s, v in result.solution.values.items() if s.variable == "M")


# -- an active constraint and its multiplier (IPOPT) -------------------------------------


@pytest.fixture(scope="module")
def housed():
    return design(housing().build())


def test_active_constraint_optimum_by_hand(housed):
    assert housed.status is Status.OPTIMAL
    assert _mass(housed) == pytest.approx(0.2 / 0.3, rel=1e-8)
    inside = _value(housed, "inside")
    assert inside.active == "upper"
    assert inside.value == pytest.approx(0.3, rel=1e-8)
    assert "binding: inside" in housed.message


def test_multiplier_matches_finite_difference_of_the_optimum(housed):
    """The sensitivity from IPOPT's multiplier equals (M*(L+h) − M*(L−h)) / 2h and −m r / L²."""
    h = 1e-3
    up, down = (design(housing(f"{0.3 + s} m").build()) for s in (h, -h))
    fd = (_mass(up) - _mass(down)) / (2 * h)
    sensitivity = _value(housed, "inside").sensitivity
    assert sensitivity == pytest.approx(-0.2 / 0.09, rel=1e-6)
    assert sensitivity == pytest.approx(fd, rel=1e-4)  # central difference: O(h²) = 1e-5 relative


def test_inactive_constraint_has_no_mark():
    result = design(housing(heavy={"expression": "added_mass()", "upper": "1.5 kg"}).build())
    heavy = _value(result, "heavy")
    assert heavy.active == "" and heavy.value == pytest.approx(0.2 / 0.3, rel=1e-8)


def test_conflicting_constraints_are_named():
    """b ≤ 0.3 m needs M ≥ 2/3 kg: a cap of 0.5 kg conflicts with it."""
    result = design(housing(heavy={"expression": "added_mass()", "upper": "0.5 kg"}).build())
    assert result.status is Status.INFEASIBLE
    assert "heavy" in result.message and "inside" in result.message
    assert "cannot all hold" in result.message


# -- force limits on the LP path ----------------------------------------------------------


@pytest.fixture(scope="module")
def limited():
    return design(spring_lp().build())


def test_force_limit_binds_on_the_lp_path(limited):
    assert limited.status is Status.OPTIMAL and limited.solution.stats.solver == "clarabel"
    assert _mass(limited) == pytest.approx((1 * G * 0.2 - 0.75) / (G * 0.25), rel=1e-8)
    limit = _value(limited, "s.max_force")
    assert limit.active == "upper" and limit.value == pytest.approx(15.0, rel=1e-8)
    assert limit.configuration["phi"] == pytest.approx(-np.pi / 2)
    assert "s.max_force" in limited.message and "phi=-90 deg" in limited.message


def test_lp_multiplier_matches_hand_sensitivity(limited):
    """Clarabel's dual: ∂M*/∂F = −0.05/(g b)."""
    assert _value(limited, "s.max_force").sensitivity == pytest.approx(-0.05 / (G * 0.25), rel=1e-6)


def test_force_limit_conflicting_with_a_mass_cap_is_named():
    result = design(spring_lp(heavy={"expression": "added_mass()", "upper": "0.3 kg"}).build())
    assert result.status is Status.INFEASIBLE
    assert "heavy" in result.message and "s.max_force" in result.message


def spring_and_counter_mass(**constraints: dict) -> ProblemBuilder:
    """The pendulum with both a free counter-mass (M, b) and a free zero-free-length spring k
    (a = h = 0.1 m, as in :func:`spring_lp`): balance is m g r = k a h + M g b."""
    b = ProblemBuilder("conflict", gravity=f"{G} m/s^2", direction=(0, -1, 0))
    b.subsystem("arm", phi=("-90 deg", "90 deg"))
    b.frame("link", rotate("z", "phi"))
    b.parameter("m", "1 kg").parameter("r", "0.2 m").parameter("a", "0.1 m").parameter("h", "0.1 m")
    b.variable("M", "0 kg", "10 kg").variable("b", "0.05 m", "0.5 m", initial="0.2 m").variable("k", "0 N/m", "1000 N/m")
    b.body("link", "link", "m", ("r", 0, 0))
    b.counter_mass("cm", "link", "M", ("-b", 0, 0))
    b.spring("s", "k", ("ground", (0, "h", 0)), ("link", ("a", 0, 0)))
    for name, spec in constraints.items():
        b.constraint(name, **spec)
    return b


def test_an_infeasible_design_is_the_elastic_design_its_message_describes():
    """Issue 32 item 6. No counter moment (M b ≤ 0) and a spring moment k a h ≤ 0.5 N·m
    cannot hold with the balance m g r = k a h + M g b = 1.962 N·m: the smallest relaxation
    keeps the spring at its limit (k = 0.5/(a h) = 50 N/m) and misses counter_moment by
    (m g r − 0.5)/g = 1.462/9.81 = 0.14903 kg·m. The design reported is that one (balanced,
    spring_moment at its bound, M b = 0.14903), not IPOPT's last iterate (k = 80 N/m, both
    constraints beyond their bounds)."""
    from counterpoise.report.rows import constraint_rows

    result = design(spring_and_counter_mass(
        counter_moment={"expression": "M * b", "upper": "0 kg m"},
        spring_moment={"expression": "k * a * h", "upper": "0.5 N m"},
    ).build())
    assert result.status is Status.INFEASIBLE
    missed = (1 * G * 0.2 - 0.5) / G
    assert "counter_moment (missed by 0.149 kg m)" in result.message and "binding: spring_moment = 0.5 N m at its upper bound" in result.message
    values = {slot.variable: v for slot, v in result.solution.values.items()}
    assert values["k"] == pytest.approx(0.5 / (0.1 * 0.1), rel=1e-6)
    assert values["M"] * values["b"] == pytest.approx(missed, rel=1e-6)
    assert result.verification.balanced
    moment, spring = _value(result, "counter_moment"), _value(result, "spring_moment")
    assert moment.active == "violated" and moment.value == pytest.approx(missed, rel=1e-6) and moment.relaxed == pytest.approx(missed, rel=1e-6)
    assert spring.active == "upper" and spring.relaxed == 0.0
    rows = {r["name"]: r for r in constraint_rows(result)}  # design.csv's constraint rows
    assert rows["spring_moment"]["active_bound"] == "upper" and rows["spring_moment"]["value"] == pytest.approx(0.5, rel=1e-6)
    assert "relaxed by 0.149 kg m" in rows["counter_moment"]["description"]


def spring_only(max_force: str) -> ProblemBuilder:
    """The pendulum held by a zero-free-length spring alone: k and the anchor a on the link
    free (an NLP), h = 0.1 m. Balance k a h = m g r; the pull k|A − B| is largest at
    φ = −90° (|A − B| = a + h), so F_max = m g r (a + h)/(a h) = m g r (1/h + 1/a), least at
    the largest a = 0.3 m: 1.962 × (10 + 10/3) = 26.16 N."""
    b = ProblemBuilder("spring_only", gravity=f"{G} m/s^2", direction=(0, -1, 0))
    b.subsystem("arm", phi=("-90 deg", "90 deg"))
    b.frame("link", rotate("z", "phi"))
    b.parameter("m", "1 kg").parameter("r", "0.2 m").parameter("h", "0.1 m")
    b.variable("a", "0.01 m", "0.3 m").variable("k", "0 N/m", "10000 N/m")
    b.body("link", "link", "m", ("r", 0, 0))
    b.spring("s", "k", ("ground", (0, "h", 0)), ("link", ("a", 0, 0)), max_force=max_force)
    return b


SMALLEST_LARGEST_FORCE = 1 * G * 0.2 * (1 / 0.1 + 1 / 0.3)  # N, see spring_only


def test_a_tiny_force_limit_is_named_with_how_far_it_is_missed():
    """Issue 32 item 14: max_force = 1e-12 N. The elastic problem's rows are divided by the
    bound (1e-12): from a slack of 1 IPOPT's restoration got stuck and the message was only
    'IPOPT declared a balanceable problem infeasible'. It names the limit and its miss now."""
    result = design(spring_only("1e-12 N").build())
    assert result.status is Status.INFEASIBLE
    assert f"s.max_force (missed by {SMALLEST_LARGEST_FORCE:.4g} N)" in result.message, result.message
    assert _value(result, "s.max_force").value == pytest.approx(SMALLEST_LARGEST_FORCE, rel=1e-6)


def test_an_absurdly_small_force_limit_names_the_limit_the_design_misses():
    """max_force = 1e-300 N: the rows (divided by the bound) are ~1e301 and no solve settles
    it; the message still names the limit, the spring's pull at the design reported and
    by how much it is over."""
    result = design(spring_only("1e-300 N").build())
    assert result.status is not Status.OPTIMAL
    values = {slot.variable: v for slot, v in result.solution.values.items()}
    pull = values["k"] * (values["a"] + 0.1)  # at φ = −90°
    assert "it misses s.max_force (springs.s.max_force): spring s pulls" in result.message, result.message
    assert f"pulls {pull:.6g} N against its max_force 1e-300 N, {pull:.4g} N over (at phi=-90 deg)" in result.message


@pytest.mark.parametrize(
    ("expression", "fragment"),
    [
        # b → 0.5 m (its upper bound) minimises M; the root's argument reaches 0 at b = 0.45 m
        ("sqrt(0.45 - b/(1 m)) * 1 m", "= 0 m has no finite derivative"),
        # the initial b = 0.2 m divides by zero
        ("1 m^2/(b - 0.2 m)", "has no finite value"),
    ],
)
def test_a_constraint_that_is_not_a_finite_number_is_named(expression, fragment):
    """Issue 32 item 13: IPOPT's Invalid_Number_Detected names the constraint and its key."""
    result = design(housing("0.5 m", root={"expression": expression, "upper": "10 m"}).build())
    assert result.status is Status.FAILED
    assert "Invalid_Number_Detected: root (constraints.root.expression)" in result.message, result.message
    assert fragment in result.message and "at the solver's point (M=" in result.message


def test_nonlinear_constraint_moves_an_lp_to_the_nlp():
    """M² ≤ 0.3 kg² (M ≤ 0.5477 kg) is not linear: IPOPT solves it, and says why."""
    result = design(spring_lp(square={"expression": "M**2", "upper": "0.3 kg^2"}).build())
    assert result.status is Status.OPTIMAL and result.solution.stats.solver == "ipopt"
    assert "square" in result.message and "made this LP problem an NLP" in result.message
    assert _mass(result) == pytest.approx((1 * G * 0.2 - 0.75) / (G * 0.25), rel=1e-6)


SPRING_LP_TOML = one_link_toml(
    "spring_lp",
    'm = "1 kg"\nr = "0.2 m"\nb = "0.25 m"',
    """
[variables.M]
lower = "0 kg"
upper = "10 kg"
[variables.k]
lower = "0 N/m"
upper = "100 N/m"
""" + counter_mass_toml('["-b", 0, 0]') + """[springs.s]
stiffness = "k"
max_force = "15 N"
from = { frame = "ground", point = [0, "0.1 m", 0] }
to = { frame = "link", point = ["0.1 m", 0, 0] }
[settings]
ideal_springs = true
""",
    coordinate="phi",
    joint_range=("-90 deg", "90 deg"),
    body="link",
)


def test_design_csv_and_status_name_the_binding_limit(tmp_path, capsys):
    """The same problem as :func:`spring_lp`, as a file through the CLI."""
    path = tmp_path / "p.toml"
    path.write_text(SPRING_LP_TOML, encoding="utf-8")
    with pytest.raises(SystemExit) as exc:
        main(["solve", str(path), "--out", str(tmp_path / "out")])
    assert exc.value.code == 0
    text = next((tmp_path / "out").rglob("design.csv")).read_text(encoding="utf-8")
    row = next(line for line in text.splitlines() if line.startswith("s.max_force,"))
    assert ",constraint," in row and ",upper," in row and "d(objective)/d(upper bound)" in row
    status = next((tmp_path / "out").rglob("status.txt")).read_text(encoding="utf-8")
    assert "binding: s.max_force: spring s pulls 15 N, its largest force (at phi=-90 deg)" in status


# -- input errors -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("spec", "key", "fragment"),
    [
        ({"expression": "force_max(s)", "lower": "1 N"}, "constraints.c.lower", "may only have an upper bound"),
        ({"expression": "-force_max(s)", "upper": "1 N"}, "constraints.c.upper", "may only have a lower bound"),
        ({"expression": "force_max(s) + length_min(s) * 1 N/m", "upper": "1 N"}, "constraints.c.expression", "one workspace extreme"),
        ({"expression": "force_max(s)**2", "upper": "1 N^2"}, "constraints.c.expression", "must enter linearly"),
        ({"expression": "force_home(q)", "upper": "1 N"}, "constraints.c.expression", "unknown spring 'q'"),
        ({"expression": "force_home(s)", "upper": "1 kg"}, "constraints.c.upper", "is a mass but 'force_home(s)' is a force"),
    ],
)
def test_bad_constraints_name_the_key(spec, key, fragment):
    with pytest.raises(ProblemFileError) as exc:
        spring_lp(c=spec).build()
    assert exc.value.key == key and fragment in exc.value.message


@pytest.mark.parametrize("bound", [0.5, "0.5", " 5e-1 "])
def test_a_dimensionless_bound_is_a_plain_number(bound):
    """Issue 32 item 15: the bound of a dimensionless expression is a plain number, in TOML
    as a number or a string ("0.5" said "expected a quantity such as '135 mm'")."""
    built = spring_lp(ratio={"expression": "M / (1 kg)", "upper": bound}).build()
    assert next(c for c in built.constraints if c.name == "ratio").upper == 0.5


def test_max_force_must_be_a_positive_force():
    for value, fragment in (("2 kg", "expected a force"), ("0 N", "must be positive")):
        with pytest.raises(ProblemFileError) as exc:
            spring_lp(max_force=value).build()
        assert exc.value.key == "springs.s.max_force" and fragment in exc.value.message


# -- the small arm (issue 20): a direct free-stiffness spring under a force limit ---------


@pytest.fixture(scope="module")
def so_arm(tmp_path_factory):
    out = tmp_path_factory.mktemp("so_arm")
    with pytest.raises(SystemExit) as exc:
        main(["solve", str(PROBLEMS / "so_arm100_direct.toml"), "--out", str(out)])
    return exc.value.code, out


def test_so_arm100_spring_stays_within_its_limit(so_arm):
    """Optimal or infeasible with the limit named, never beyond it: the spring's pull on a
    fine grid of the shoulder lift's range (independent of the designer's samples)."""
    code, out = so_arm
    status = next(out.rglob("status.txt")).read_text(encoding="utf-8")
    assert code in (0, 1)
    if "status: optimal" in status:
        assert "binding: lift.max_force" in status and "shoulder_lift=" in status
    else:  # infeasible: the binding limit, or the spring that cannot be made, is named
        assert "lift.max_force" in status or "spring lift" in status
    problem = load_problem(PROBLEMS / "so_arm100_direct.toml")
    rows = next(out.rglob("design.csv")).read_text(encoding="utf-8").splitlines()[1:]
    assert any(line.startswith("lift.max_force,constraint,") for line in rows)  # its value at the design, in design.csv
    values = {}
    for line in rows:
        name, kind, _, value, *_ = line.split(",")
        if kind == "variable":
            values[name] = float(value) * problem.variable[name].unit.to_si
    lift = problem.coordinate["shoulder_lift"]
    q = np.linspace(lift.lower, lift.upper, 20001)
    coords = {c.name: c.home for c in problem.coordinates} | {"shoulder_lift": q}
    force, _ = spring_force_length(mechanics(problem, coords, values), problem.springs[0])
    assert np.max(force) <= 25.0 * (1 + 1e-6)
    assert np.max(force) > 1.0  # the spring does carry the arm


def test_verification_round_adds_the_extreme_between_samples():
    """With φ ∈ [−120°, 60°] the spring's longest stretch (φ = −90°, |A − B| = 0.2 m) lies
    inside the range, between the sampled configurations: the sampled rows alone would allow
    k a little above 75 N/m. The dense check (its best sample polished by a pattern search)
    finds φ = −90° where the limit is exceeded, adds it and solves again: k* = 75 N/m to
    rounding, and the pull at exactly −90°, 0.2 k, is 15 N."""
    from counterpoise.designer.designer import Designer

    builder = spring_lp()
    builder.subsystem("arm", phi=("-120 deg", "60 deg"))
    problem = builder.build()
    designer = Designer(problem)
    result = design(problem, designer=designer)
    assert designer._refined is not None  # at least one verification round
    k = next(v for s, v in result.solution.values.items() if s.variable == "k")
    assert 0.2 * k <= 15.0 * (1 + 1e-9)
    assert k == pytest.approx(75.0, rel=1e-9)
    limit = _value(result, "s.max_force")
    assert limit.active == "upper" and limit.configuration["phi"] == pytest.approx(-np.pi / 2, abs=1e-5)


def test_shipped_problem_with_an_active_constraint():
    """problems/ur5_counter_mass_inertia_cap.toml: minimising the added mass alone would run
    both extensions to their 500 mm bounds; the cap ΣM b² ≤ 3 kg m² binds instead, the
    design balances, and raising the cap can only lower the mass (sensitivity < 0)."""
    result = solved("ur5_counter_mass_inertia_cap")
    assert result.status is Status.OPTIMAL
    cap = _value(result, "inertia_cap")
    assert cap.active == "upper" and cap.value <= 3.0 * (1 + 1e-9)
    assert result.solution.added_inertia == pytest.approx(cap.value, rel=1e-12)
    assert cap.sensitivity < 0
    extensions = [v for s, v in result.solution.values.items() if s.variable in ("b_u", "b_f")]
    assert min(extensions) < 0.5  # at least one extension pulled in from its bound


DIRECT = one_link_toml(
    "direct_arm",
    'm = "1 kg"\nr = "0.2 m"',
    """
[variables.k]
lower = "0 N/m"
upper = "2000 N/m"
initial = "200 N/m"
[variables.y]
lower = "0.05 m"
upper = "0.5 m"
initial = "0.2 m"
[variables.b]
lower = "0.01 m"
upper = "0.3 m"
initial = "0.1 m"
[springs.s]
stiffness = "k"
mount = "direct"
free_length = "5 cm"
max_force = "25 N"
from = { frame = "ground", point = [0, "y", 0] }
to = { frame = "link", point = ["b", 0, 0] }
[constraints.strong_at_home]
expression = "force_home(s)"
lower = "30 N"
""",
    coordinate="phi",
    joint_range=("-45 deg", "55 deg"),
    body="link",
)


def test_minimax_conflicting_constraints_are_named(tmp_path):
    """A directly attached spring (minimax designer): pulling ≥ 30 N at home and at most
    25 N anywhere cannot both hold (the pull at home is one of the pulls over the range)."""
    path = tmp_path / "direct.toml"
    path.write_text(DIRECT, encoding="utf-8")
    result = design(load_problem(path))
    assert result.status is Status.INFEASIBLE
    assert "strong_at_home" in result.message or "s.max_force" in result.message


def test_named_quantities_by_hand(limited):
    """At the LP design (k = 75 N/m, M = 0.49419 kg), home φ = 0 (the middle of the range):
    B = (0.1, 0) m, A = (0, 0.1) m, so length_home = 0.1·√2 m and force_home = k·0.1·√2;
    over φ ∈ [−90°, 90°], |A − B|² = 0.02 − 0.02 sin φ: length_max = 0.2 m (φ = −90°) and
    length_min = 0 (φ = 90°, the ends meet), force_min = 0; the counter-mass sits at
    (−0.25, 0, 0) m at home; a report quantity M·b = 0.25 M kg m."""
    b = spring_lp(
        lh={"expression": "length_home(s)", "upper": "1 m"},
        fh={"expression": "force_home(s)", "upper": "100 N"},
        lx={"expression": "length_max(s)", "upper": "1 m"},
        ln={"expression": "length_min(s)", "lower": "-1 m"},
        fn={"expression": "force_min(s)", "lower": "-1 N"},
        xh={"expression": "x_home(cm)", "lower": "-1 m"},
        yh={"expression": "y_home(cm) + z_home(cm)", "lower": "-1 m"},
        mo={"expression": "moment", "upper": "1 kg*m"},
        am={"expression": "added_mass()", "upper": "1 kg"},
    )
    b.report("moment", "M * b", unit="kg*m")
    result = design(b.build())
    k = next(v for s, v in result.solution.values.items() if s.variable == "k")
    M = _mass(result)
    assert k == pytest.approx(75.0, rel=1e-9)
    expected = {
        "lh": 0.1 * np.sqrt(2), "fh": k * 0.1 * np.sqrt(2), "lx": 0.2, "ln": 0.0, "fn": 0.0,
        "xh": -0.25, "yh": 0.0, "mo": 0.25 * M, "am": M,
    }
    for name, value in expected.items():
        assert _value(result, name).value == pytest.approx(value, rel=1e-9, abs=1e-9), name
        assert _value(result, name).active == "", name


def test_two_scenarios_share_one_constraint_row(tmp_path):
    """M adjustable per scenario (m = 1 kg and 1.5 kg), b shared and ≤ 0.3 m: M_s = m_s r / b,
    the objective is the scenarios' average added mass (1.25 × 0.2 / b), so b* = 0.3 m and
    ∂(objective)/∂L = −1.25 · 0.2 / 0.09 = −2.7778 kg/m, the sum of both scenarios' shares.
    The constraint's value is the same in both: one design.csv row."""
    from counterpoise.pipeline import design as run_design
    from counterpoise.report.rows import design_rows

    b = housing()
    b.variable("M", "0 kg", "10 kg", adjustable=True)
    b.scenario("light", {"m": "1 kg"}).scenario("heavy", {"m": "1.5 kg"})
    result = run_design(b.build())
    assert result.status is Status.OPTIMAL
    rows = [r for r in design_rows(result) if r["kind"] == "constraint"]
    assert len(rows) == 1 and rows[0]["scenario"] == "" and rows[0]["active_bound"] == "upper"
    total = sum(v.sensitivity for v in result.solution.constraints)
    assert total == pytest.approx(-1.25 * 0.2 / 0.09, rel=1e-6)
    assert f"{total * 1e-3:.6g} per mm" in rows[0]["description"]
