"""Spring catalogues: reading and validation, part choice (pruning, groups, branch and
bound, limits), the tolerance report, and the diagnosis when no part fits."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from builders import counter_mass_toml, one_link_toml, slot_pendulum_toml
from counterpoise import design, load_problem
from counterpoise.catalogue import CatalogueError, mapping_from, read_catalogue
from counterpoise.catalogue.limits import margins
from counterpoise.designer import Designer
from counterpoise.selection import PartSearch
from counterpoise.selection.geometry import sample_configurations, spring_lengths
from counterpoise.solvers.base import Status
from counterpoise.verify import verify

HEADER = "part_number,rate_N_per_m,free_length_m,initial_tension_N,max_load_N,max_length_m,outer_diameter_m,wire_diameter_m,material"


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


# --------------------------------------------------------------------------------------
# Reading and validation
# --------------------------------------------------------------------------------------


def test_shipped_catalogue_reads_and_is_consistent():
    c = read_catalogue("shipped")
    assert len(c) == 572
    a = c.arrays
    assert (a["rate"] > 0).all() and (a["max_load"] > a["initial_tension"]).all() and (a["max_length"] > a["free_length"]).all()
    # L_max = L0 + (F_max - F0)/k, to the CSV's 6 significant digits (docs/spring-catalogue.md)
    assert np.allclose(a["max_length"], a["free_length"] + (a["max_load"] - a["initial_tension"]) / a["rate"], rtol=1e-4)


def test_vendor_mapping_si_and_inch(tmp_path):
    """The vendor column names, in SI and in inch units, land on the same SI numbers."""
    si = write(
        tmp_path / "si.csv",
        "length_natural,od,wire_dia,length_max,load_min,load_max,stiffness,material,pkg_qty,part_number,pkg_cost\n"
        "0.0254,0.00508,0.000508,0.0508,4.4482216152605,44.482216152605,1751.268352464764,Music-Wire Steel,5,V1,10.00\n",
    )
    inch = write(
        tmp_path / "inch.csv",
        "length_natural,od,wire_dia,length_max,load_min,load_max,stiffness,material,pkg_qty,part_number,pkg_cost\n"
        "1,0.2,0.02,2,1,10,10,Music-Wire Steel,5,V1,10.00\n",
    )
    a = read_catalogue(si, mapping_from("vendor"))
    b = read_catalogue(inch, mapping_from("vendor_inch"))
    for field in ("rate", "free_length", "initial_tension", "max_load", "max_length", "outer_diameter", "wire_diameter"):
        assert getattr(a, field)[0] == pytest.approx(getattr(b, field)[0], rel=1e-12), field
    assert a.rate[0] == pytest.approx(1751.268352464764)  # 10 lbf/in in N/m
    assert a.price[0] == pytest.approx(2.0)  # package of 5 for 10.00


LBF, INCH = 4.4482216152605, 0.0254


def _inch_file(path: Path, a: dict, rows) -> Path:  # noqa: ANN001 - rows: indices of the shipped catalogue
    """Rows of the shipped catalogue written in lbf/in, in and lbf, without diameter columns."""
    lines = ["part_number,rate_lbf_per_in,free_length_in,initial_tension_lbf,max_load_lbf,max_length_in"]
    for i in rows:
        lines.append(
            f"P{i},{a['rate'][i] * INCH / LBF:.6g},{a['free_length'][i] / INCH:.6g},{a['initial_tension'][i] / LBF:.6g},"
            f"{a['max_load'][i] / LBF:.6g},{a['max_length'][i] / INCH:.6g}"
        )
    return write(path, "\n".join(lines) + "\n")


def test_every_shipped_part_is_a_possible_spring_and_none_is_in_lbf_read_as_n_mm():
    """Issue 32 item 8: catalogue/physics.py bounds what a steel extension spring of a rate
    and free length can carry. A bound, not a fit: every part of the shipped catalogue (made
    by Shigley's formulas, docs/spring-catalogue.md) is within it (≤ 1); written in lbf/in,
    in and lbf and read as N/mm, mm and N (force per area 145 times too high), every one is
    beyond it, while read as SI from N-mm numbers (lengths 1000 times too long) they are
    springs again: the bound catches what shrinks a spring, the median bands the rest."""
    from counterpoise.catalogue.physics import implausibility

    a = read_catalogue("shipped").arrays
    assert implausibility(a["rate"], a["free_length"], a["initial_tension"], a["max_load"]).max() <= 1
    misread = implausibility(a["rate"] * INCH / LBF * 1e3, a["free_length"] / INCH * 1e-3, a["initial_tension"] / LBF, a["max_load"] / LBF)
    assert misread.min() > 1


def test_any_two_shipped_parts_in_lbf_declared_n_mm_are_refused_naming_inch(tmp_path):
    """Issue 32 item 8, in general: two parts drawn at random from the shipped catalogue,
    written in lbf and inch without diameter columns, declared N-mm: refused, the line names
    inch; declared inch: read."""
    a = read_catalogue("shipped").arrays
    columns = dict(zip(("part_number", "rate", "free_length", "initial_tension", "max_load", "max_length"),
                       ("part_number", "rate_lbf_per_in", "free_length_in", "initial_tension_lbf", "max_load_lbf", "max_length_in")))
    rng = np.random.default_rng(32)
    for trial in range(20):
        path = _inch_file(tmp_path / f"two_{trial}.csv", a, rng.choice(len(a["rate"]), 2, replace=False))
        with pytest.raises(CatalogueError) as info:
            read_catalogue(path, mapping_from(columns, "N-mm"))
        assert info.value.key == "units" and 'set units = "inch"' in info.value.message, info.value.message
        assert len(read_catalogue(path, mapping_from(columns, "inch"))) == 2


@pytest.mark.parametrize(
    "row, where, fragment",
    [
        ("P-2,-5,0.05,1,40,0.12,0.01,0.001,x", "row 2 (line 3), column rate_N_per_m", "the rate must be positive"),
        ("P-2,500,0.05,1,40,0.04,0.01,0.001,x", "row 2 (line 3), column max_length_m", "must be above the free length"),
        ("P-2,500,0.05,50,40,0.12,0.01,0.001,x", "row 2 (line 3), column max_load_N", "must be above the initial tension"),
        ("P-2,500,nan,1,40,0.12,0.01,0.001,x", "row 2 (line 3), column free_length_m", "must be finite"),
        ("P-2,500,0.05,1,40,abc,0.01,0.001,x", "row 2 (line 3), column max_length_m", "expected a number, got 'abc'"),
        ("P-1,500,0.05,1,40,0.12,0.01,0.001,x", "row 2 (line 3), column part_number", "duplicate part number 'P-1'"),
        ("P-2,500,0.05,1,40,0.12,0.01", "row 2 (line 3)", "expected 9 cells, got 7"),
    ],
)
def test_row_errors_name_file_row_and_column(tmp_path, row, where, fragment):
    path = write(tmp_path / "parts.csv", f"{HEADER}\nP-1,500,0.05,1,40,0.12,0.01,0.001,x\n{row}\n")
    with pytest.raises(CatalogueError) as info:
        read_catalogue(path)
    assert info.value.file == str(path)
    assert info.value.key == where
    assert fragment in info.value.message
    assert "\n" not in str(info.value)


def test_missing_column_and_bad_tolerance_column(tmp_path):
    path = write(tmp_path / "parts.csv", "part_number,rate_N_per_m\nP-1,500\n")
    with pytest.raises(CatalogueError, match="header: missing column 'free_length_m'"):
        read_catalogue(path)
    path = write(tmp_path / "tol.csv", f"{HEADER},rate_tolerance\nP-1,500,0.05,1,40,0.12,0.01,0.001,x,1.5\n")
    with pytest.raises(CatalogueError, match="column rate_tolerance: a tolerance is a fraction between 0 and 1"):
        read_catalogue(path)


def test_unknown_preset_and_field():
    with pytest.raises(ValueError, match="unknown column preset 'mcmaster'"):
        mapping_from("mcmaster")
    with pytest.raises(ValueError, match="unknown catalogue field 'stiffnes'"):
        mapping_from({"stiffnes": "k"})
    with pytest.raises(ValueError, match="must name a column for"):
        mapping_from({"rate": "k"})


# --------------------------------------------------------------------------------------
# A pendulum with catalogue springs: the tolerance report by hand
# --------------------------------------------------------------------------------------

def pendulum(tmp_path: Path, rows: list[str], mass: float, rate_tol: str = "10 %", tension_tol: str = "20 %", extra: str = ""):
    catalogue = write(tmp_path / "parts.csv", HEADER + "\n" + "\n".join(rows) + "\n")
    text = slot_pendulum_toml("pendulum_catalogue", mass, catalogue=catalogue.name, rate_tolerance=rate_tol, tension_tolerance=tension_tol) + extra
    return load_problem(write(tmp_path / "pendulum.toml", text))


def test_tolerance_report_matches_the_hand_computation(tmp_path):
    """Pendulum: mass m at r on a link at angle theta in [-60, 60] deg from the horizontal;
    a spring from (0, h) to b along the link. V = m g r sin(theta) - k b h sin(theta), so
    balance is k b h = m g r. With k = 200 N/m, b = 0.1 m, m g r = k b^2 = 2 N·m the
    design is h = b = 0.1 m (m = 2/(9.81·0.2) kg).

    Rate off by ±10 %: the string is set for the nominal part (F0 = 1 N), so the rate error acts
    on d − F0/k (docs/catalogues.md): residual 0.1·(k d − F0)|∂d/∂theta| with
    |∂d/∂theta| = b h cos(theta)/d, d = b sqrt(2 - 2 sin(theta)) (b = h): 0.1 b h cos(theta)
    (k − F0/d), gravity torque at most m g r; its largest ratio over theta (about 0.0965, not
    0.1: the −Δk·F0/k term, issue 31) evaluated on a fine grid. Initial tension off by
    ΔF0 = 0.2·1 N: residual ΔF0·|∂d/∂theta| = ΔF0 b sqrt((1 + sin(theta))/2), largest at
    60 deg: 0.2·0.1·cos(15 deg); ratio 0.02·cos(15°)/2 = 0.0096593. Together
    b h cos(theta) (0.1 k + (0.2 − 0.1) F0/d).
    """
    mass = 2.0 / (9.81 * 0.2)
    problem = pendulum(tmp_path, ["P-1,200,0.05,1,50,0.3,0.01,0.001,x"], mass)
    result = design(problem)
    assert result.status is Status.OPTIMAL, result.message
    assert result.solution.values[next(iter(result.solution.values))] == pytest.approx(0.1, rel=1e-9)
    band = result.parts.tolerance
    assert band.nominal < 1e-12
    theta = np.radians(np.linspace(-60, 60, 200001))
    d = 0.1 * np.sqrt(2 - 2 * np.sin(theta))
    rate = 0.1 * 0.01 * np.cos(theta) * (200 - 1 / d) / 2
    assert band.worst_rate == pytest.approx(rate.max(), rel=1e-6)  # sampled max near its peak
    assert band.worst_rate < 0.0966
    assert band.worst_tension == pytest.approx(0.02 * math.cos(math.radians(15)) / 2, rel=1e-3)  # sampled max near 60 deg
    combined = 0.01 * np.cos(theta) * (0.1 * 200 + 0.1 * 1 / d) / 2
    assert band.worst == pytest.approx(combined.max(), rel=1e-3)
    # the rate corners: ±10 % leaves exactly 10 % of the gravity torque
    assert [c.ratio for c in result.parts.corners] == pytest.approx([0.1, 0.1], rel=1e-6)


def test_adjustment_per_tolerance_corner(tmp_path):
    """Re-setting h for each rate corner: k(1 ± 0.1)·b·h = m g r gives h = 0.1/(1 ± 0.1) m."""
    mass = 2.0 / (9.81 * 0.2)
    problem = pendulum(tmp_path, ["P-1,200,0.05,1,50,0.3,0.01,0.001,x"], mass, extra='\n[selection]\nadjust = ["h"]\n')
    result = design(problem)
    corners = result.parts.corners
    assert [c.adjustment[0][2] for c in corners] == pytest.approx([0.1 / 0.9, 0.1 / 1.1], rel=1e-9)
    assert all(c.adjusted_ratio < 1e-9 for c in corners)


def test_tolerance_corners_keep_the_calls_parameters(tmp_path):
    """A study point solves with its own values (``parameters=``), not the file's: the rate
    corners must keep them. With m' = 1.5 m the design is h = m' g r/(k b) = 0.15 m, the
    rate corners leave exactly 10 % of m' g r, and re-setting h gives 0.15/(1 ± 0.1) m. (They
    were taken with the file's m, which reported 35-65 % instead.)"""
    mass = 2.0 / (9.81 * 0.2)
    problem = pendulum(tmp_path, ["P-1,200,0.05,1,50,0.3,0.01,0.001,x"], mass, extra='\n[selection]\nadjust = ["h"]\n')
    result = design(problem, parameters={"m": 1.5 * mass})
    assert result.status is Status.OPTIMAL, result.message
    corners = result.parts.corners
    assert [c.ratio for c in corners] == pytest.approx([0.1, 0.1], rel=1e-6)
    assert [c.adjustment[0][2] for c in corners] == pytest.approx([0.15 / 0.9, 0.15 / 1.1], rel=1e-9)
    assert all(c.adjusted_ratio < 1e-9 for c in corners)


def test_part_limits_decide_and_nearest_is_reported(tmp_path):
    """Three parts of the same rate: one whose initial tension exceeds k·d_min (the string
    would go slack), one too short, one that fits. Then without the fitting one: the
    nearest candidates, each with the limit it violates, and status infeasible."""
    mass = 2.0 / (9.81 * 0.2)
    slack = "SLACK,200,0.05,12,50,0.3,0.01,0.001,x"  # F0/k = 60 mm > d_min = 51.8 mm
    short = "SHORT,200,0.05,1,50,0.2,0.01,0.001,x"  # needs 193 + 50 - 5 = 238 mm > 200 mm
    good = "GOOD,200,0.05,1,50,0.3,0.01,0.001,x"
    result = design(pendulum(tmp_path, [slack, short, good], mass))
    assert result.status is Status.OPTIMAL
    assert result.parts.springs[0].part_number == "GOOD"
    counts = result.parts.search.counts[0]
    assert (counts.parts, counts.rates_solved, counts.failed_limits, counts.fitting) == (3, 1, 2, 1)
    result = design(pendulum(tmp_path, [slack, short], mass))
    assert result.status is Status.INFEASIBLE
    limits = {m.part_number: m.limit for m in result.parts.search.nearest}
    assert limits == {"SLACK": "initial_tension", "SHORT": "max_length"}
    assert "SLACK" in result.message and "slack" in result.message


def test_rate_outside_the_balanceable_window_is_pruned_before_solving(tmp_path):
    """h in [0.02, 0.3] m balances k = m g r/(b h) in [66.7, 1000] N/m: 20 and 5000 N/m are
    pruned without a per-part solve."""
    mass = 2.0 / (9.81 * 0.2)
    rows = ["SOFT,20,0.05,0.1,50,2,0.01,0.001,x", "HARD,5000,0.05,1,500,0.3,0.01,0.001,x", "P-1,200,0.05,1,50,0.3,0.01,0.001,x"]
    result = design(pendulum(tmp_path, rows, mass))
    c = result.parts.search.counts[0]
    assert c.window == pytest.approx((2.0 / 0.03, 2.0 / 0.002), rel=1e-6)
    assert (c.pruned, c.rates_solved) == (2, 1)


# --------------------------------------------------------------------------------------
# Search: brute force agrees; slots that interact go through branch and bound
# --------------------------------------------------------------------------------------

TWO_SPRINGS = one_link_toml(
    "two_slots",
    'm = "3 kg"\nr = "0.3 m"\nh = "0.1 m"\nc = "0.1 m"',
    """
[catalogues.parts]
file = "parts.csv"
[slots.first]
catalogue = "parts"
[slots.second]
catalogue = "parts"
[variables.b1]
lower = "0.01 m"
upper = "0.1 m"
initial = "0.05 m"
[variables.b2]
lower = "0.01 m"
upper = "0.1 m"
initial = "0.05 m"
[variables.M]
lower = "0 kg"
upper = "50 kg"
""" + counter_mass_toml('["-c", 0, 0]', name="M") + """[springs.one]
slot = "first"
from = { frame = "ground", point = [0, "h", 0] }
to = { frame = "link", point = ["b1", 0, 0] }
[springs.two]
slot = "second"
from = { frame = "ground", point = [0, "-h", 0] }
to = { frame = "link", point = ["-b2", 0, 0] }
[objective]
mass_weight = 1
""",
    coordinate="theta",
    joint_range=("-50 deg", "50 deg"),
    body="link",
)


def two_slot_problem(tmp_path: Path, overrides: dict | None = None):
    """Two springs on one link, two slots: k1 b1 h + k2 b2 h + M g c = m g r. They
    interact (one condition), so minimising M couples the choice of both parts."""
    rng = np.random.default_rng(5)
    rows = []
    for i in range(9):
        k = float(rng.uniform(100, 600))
        f0 = float(rng.uniform(0.1, 8))
        l0 = 0.03
        fmax = float(rng.uniform(40, 90))
        rows.append(f"P-{i},{k:.6g},{l0},{f0:.6g},{fmax:.6g},{l0 + (fmax - f0) / k + 0.05:.6g},0.01,0.001,x")
    write(tmp_path / "parts.csv", HEADER + "\n" + "\n".join(rows) + "\n")
    return load_problem(write(tmp_path / "two.toml", TWO_SPRINGS), overrides)


def brute_force(problem):
    """Every pair of parts: solve with their rates as parameters, verify densely, check the
    three limits on dense configurations. Returns the lightest objective and every pair
    of part numbers that reaches it (ties are broken by the search's preference)."""
    designer = Designer(problem)
    slots = problem.slots
    cat = slots[0].catalogue
    q = sample_configurations(problem, 2000, 99)
    found = []
    for i in range(len(cat)):
        for j in range(len(cat)):
            sol = designer.solve(parameters={"first": cat.rate[i], "second": cat.rate[j]})
            if sol.status is not Status.OPTIMAL or not verify(sol, samples=500).balanced:
                continue
            ok = True
            for scenario in problem.scenarios:
                gravity, base = sol.scenario_parameters[scenario.name]
                variables = {k: np.array([[v]]) for k, v in sol.variable_values(scenario.name).items()}
                d = spring_lengths(problem, ["one", "two"], q, variables, base, gravity)
                for spring, row in (("one", i), ("two", j)):
                    m = margins(d[spring].min(), d[spring].max(), cat.rate[row], cat.free_length[row], cat.initial_tension[row], cat.max_load[row], cat.max_length[row])
                    ok &= bool(m.ok(1e-9))
            if ok:
                found.append((sol.objective, cat.part_number[i], cat.part_number[j]))
    if not found:
        return None
    best = min(f[0] for f in found)
    return best, {f[1:] for f in found if f[0] <= best + 1e-7}


def test_search_agrees_with_brute_force_and_branch_and_bound(tmp_path):
    problem = two_slot_problem(tmp_path)
    truth = brute_force(problem)
    assert truth is not None
    result = PartSearch(problem).run()
    assert result.groups == [("first", "second")]  # one condition couples the two slots
    assert result.methods == ["enumeration"]
    chosen = (result.choice.parts["first"], result.choice.parts["second"])
    cat = problem.slots[0].catalogue
    assert result.candidates[0].objective == pytest.approx(truth[0], abs=1e-7)
    assert (cat.part_number[chosen[0]], cat.part_number[chosen[1]]) in truth[1]
    bnb = PartSearch(two_slot_problem(tmp_path, {"selection.max_enumeration": 1})).run()
    assert bnb.methods == ["branch-and-bound"]
    assert bnb.candidates[0].objective == pytest.approx(truth[0], abs=1e-7)
    assert (cat.part_number[bnb.choice.parts["first"]], cat.part_number[bnb.choice.parts["second"]]) in truth[1]


def test_independent_slots_are_searched_separately():
    """Orientation mechanism: four slots whose conditions share no variable."""
    problem = load_problem(Path(__file__).parent.parent / "problems" / "essomba2021_orientation_catalogue.toml")
    result = PartSearch(problem).run()
    assert sorted(result.groups) == [("spring_A",), ("spring_B",), ("spring_C",), ("spring_D",)]


def test_cli_checks_catalogues(tmp_path):
    """`counterpoise catalogue`: ok line per good file; one error line and exit 2 for a bad row."""
    from conftest import run_cli

    bad = write(tmp_path / "bad.csv", f"{HEADER}\nP-1,500,0.05,1,40,0.12,0.01,0.001,x\nP-2,-5,0.05,1,40,0.12,0.01,0.001,x\n")
    proc = run_cli("catalogue", "shipped")
    assert proc.returncode == 0 and "572 parts" in proc.stdout, proc.stderr
    proc = run_cli("catalogue", str(bad))
    assert proc.returncode == 2
    assert proc.stderr.strip() == f"{bad}: row 2 (line 3), column rate_N_per_m: the rate must be positive, got -5 N/m"


@pytest.mark.parametrize(("excess", "fits"), [(1e-11, True), (1e-6, False)])
def test_a_part_at_rounding_distance_outside_the_window_fits(tmp_path, excess, fits):
    """Issue 32 item 17. Balance is k b h = m g r with h ≤ 0.3 m (b = 0.1 m, r = 0.2 m): with
    m = 200 · 0.1 · 0.3/(g · 0.2) × (1 + excess) the 200 N/m part needs h = 0.3 m × (1 + excess),
    just past its bound (the 5000 N/m part needs h = 0.012 m < 0.02 m: it never fits). At
    1e-11 that is rounding: the part fits with h on its bound, the residual ratio about 1e-11.
    At 1e-6 it does not, and the part is named as outside the balanceable range."""
    rows = ["P-1,200,0.05,1,80,0.6,0.01,0.001,x", "P-2,5000,0.05,1,800,0.6,0.01,0.001,x"]
    result = design(pendulum(tmp_path, rows, 200 * 0.1 * 0.3 / (9.81 * 0.2) * (1 + excess)))
    if fits:
        assert result.status is Status.OPTIMAL, result.message
        assert result.parts.chosen == {"s": 0}
        assert next(v for slot, v in result.solution.values.items() if slot.variable == "h") == 0.3
        assert result.verification.residual_ratio == pytest.approx(excess, rel=1e-3)
    else:
        assert result.status is not Status.OPTIMAL
        assert "P-1 (slot s): no balanced design within the bounds uses its rate" in result.message
