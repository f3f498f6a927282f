"""Payload ranges and adjustable balancing (seed 003, Woo 2019; seed 004 extension).

Hand derivations (docs/derivations.md, section Woo 2019, and docs/payload.md), g = 9.81:

- Stackable mechanism, V = g (C1 l1 sin θ1 + C5 l5 sin θ5) + const with
  C1 = A1 − m_c1 (lever_c1 + dL_c1)/l1 and C5 = A5 + m_c1 + m_c2 (1 + (lever_c2 + dL_c2)/l5);
  A1 = 1762 g, A5 = −2790.5 g for the 1280 g tool (1802, −2870.5 g for 1320 g).
- Counterweight design, levers at their nominal (dL = 0) at 0 g:
  m_c1 = A1 l1 / 151.2 = 352 400/151.2 = 2330.69 g, m_c2 = (−A5 − m_c1) l5 / (l5 + 230.6) = 139.08 g.
- A payload α at the tool adds α to A1 and −α l3/l5 to A5, so α = m_c1 dL_c1/l1 = m_c2 dL_c2/l3:
  dL_c2(31 g) = 31 · 200/139.08 = 44.58 mm; 50 mm of travel give α_max = 139.08 · 50/200 = 34.77 g.
- Hybrid (spring on link 1): the adjustment range needs m_c1 ≥ 122 · 200/50 = 488 g, and the
  added mass m_c1 + (2870.5 − m_c1)·100/261.8 grows with m_c1, so m_c1 = 488 g and
  m_c2 = (2870.5 − 488)·100/261.8 = 910.05 g; at 62 g dL_c1 = 25.41, dL_c2 = 13.63 mm.
- Essomba position mechanism: k1 l11 l12 = g l (½m_L1 + m_L2 + m_S + m_p), so
  l12(m_p) = g l (1659.43 g + m_p)/(k1 l11), l22(m_p) = g l (1103.115 g + m_p)/(k2 l21).
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

from conftest import run_cli

from builders import payload_pendulum_toml
from conftest import PROBLEMS, solved, value

CLI = Path(sys.executable).with_name("counterpoise")
G = 9.81
A1, A5 = 1762.0, -2790.5  # g, 1280 g tool
A1_H, A5_H = 1802.0, -2870.5  # g, 1320 g tool


def _row(result, payload_g: float):
    """The schedule row (display units) at ``payload_g`` grams."""
    for s in result.payload.schedule.rows:
        if abs(s.payload * 1e3 - payload_g) < 1e-9:
            return {k: v * 1e3 for k, v in s.values.items()}
    raise KeyError(payload_g)


class TestWooCounterweight:
    @pytest.fixture
    def result(self):
        return solved("woo2019_counterweight")

    def test_masses(self, result):
        assert result.status.value == "optimal", result.message
        m_c1 = A1 * 200 / 151.2
        m_c2 = (-A5 - m_c1) * 100 / (100 + 230.6)
        assert value(result, "m_c1", "g") == pytest.approx(m_c1, rel=1e-7)
        assert value(result, "m_c2", "g") == pytest.approx(m_c2, rel=1e-7)
        assert value(result, "m_c1", "g") == pytest.approx(2331, abs=1)  # the paper's figures, 1 g
        assert value(result, "m_c2", "g") == pytest.approx(139, abs=1)

    def test_schedule_at_31_g(self, result):
        m_c1, m_c2 = value(result, "m_c1"), value(result, "m_c2")
        row = _row(result, 31)
        assert row["dL_c2"] == pytest.approx(31 * 200 / m_c2, rel=1e-7)
        assert row["dL_c1"] == pytest.approx(31 * 200 / m_c1, rel=1e-7)
        assert row["dL_c2"] == pytest.approx(44.6, abs=0.1)

    def test_schedule_is_linear_and_states_its_formula(self, result):
        lines = {line.variable: line for line in result.payload.schedule.lines}
        m_c2 = value(result, "m_c2") * 1e-3  # kg
        assert set(lines) == {"dL_c1", "dL_c2"}
        assert lines["dL_c2"].slope == pytest.approx(0.2 / m_c2, rel=1e-7)  # m per kg: l3 / m_c2
        assert lines["dL_c2"].intercept == pytest.approx(0.0, abs=1e-12)

    def test_widest_range(self):
        result = solved("woo2019_counterweight", (("objective", "max_payload_range"),))
        assert result.status.value == "optimal", result.message
        m_c2 = value(result, "m_c2", "g")
        assert value(result, "max_payload_range", "g") == pytest.approx(m_c2 * 50 / 200, rel=1e-6)
        assert value(result, "max_payload_range", "g") == pytest.approx(34.75, abs=0.1)
        assert "limited by dL_c2 at its upper limit 50 mm" in result.payload.widest.limit
        # the schedule covers the range found, its last row at the limit
        assert result.payload.schedule.rows[-1].payload * 1e3 == pytest.approx(m_c2 * 50 / 200, rel=1e-6)
        assert result.payload.schedule.feasible


#: a paper reproduction's numbers are those of its idealised springs (zero free length, the
#: design rate exactly): the shipped files build real ones (docs/build.md), checked below
IDEAL = (("settings.ideal_springs", "true"),)


@pytest.mark.parametrize(("name", "variable"), [("woo2019_hybrid", "m_c1"), ("essomba2021_variable_payload", "l12")])
def test_the_shipped_payload_designs_are_built_as_specified(name, variable):
    """As built, each spring is wound a little off the paper's rate and the design follows it:
    balanced as built, its values within the wound rate's 0.5 % of the ideal ones."""
    built, ideal = solved(name), solved(name, IDEAL)
    assert built.optimal, built.message
    assert built.as_built.residual_ratio <= 1e-6
    first = built.problem.scenarios[0].name
    value, paper = built.solution.variable_values(first)[variable], ideal.solution.variable_values(first)[variable]
    assert abs(value / paper - 1) <= 0.005


class TestWooHybrid:
    @pytest.fixture
    def result(self):
        return solved("woo2019_hybrid", IDEAL)  # the paper's numbers: its ideal spring

    def test_minimal_counterweights(self, result):
        assert result.status.value == "optimal", result.message
        assert value(result, "m_c1", "g") == pytest.approx(122 * 200 / 50, rel=1e-7)  # 488 g
        assert value(result, "m_c2", "g") == pytest.approx((-A5_H - 488) * 100 / (100 + 161.8), rel=1e-7)  # 910.05 g

    def test_schedule_feasible_with_62_g_row(self, result):
        plan = result.payload.schedule
        assert plan.feasible and len(plan.rows) >= 50
        assert result.payload.checked == pytest.approx((0.0, 0.122))
        row = _row(result, 62)
        assert row["dL_c1"] == pytest.approx(62 * 200 / 488, rel=1e-6)  # 25.41 mm
        assert row["dL_c2"] == pytest.approx(62 * 200 / value(result, "m_c2", "g"), rel=1e-6)  # 13.63 mm

    def test_range_wider_than_the_travel_is_infeasible_naming_the_adjustment(self):
        """m_c1 ≤ 400 g allows 400 · 50/200 = 100 g of the required 122 g."""
        result = solved("woo2019_hybrid", (("variables.m_c1.upper", "400 g"), *IDEAL))
        assert result.status.value == "infeasible"
        assert "limiting adjustment dL_c1 at its upper bound 50 mm at 122 g" in result.message
        # an adjustment pinned to its nominal at 0 g is not reported as a limit
        assert "at 0 g" not in result.message.split("(closest design")[0]


class TestEssombaVariablePayload:
    @pytest.fixture
    def result(self):
        return solved("essomba2021_variable_payload", IDEAL)  # the paper's numbers: its ideal springs

    def test_feasible_in_every_mode(self, result):
        assert result.status.value == "optimal", result.message
        modes = {s.name.split("_instrument")[0] for s in result.problem.scenarios}
        assert modes == {"horizontal", "upward", "downward"}
        assert result.payload.schedule.feasible
        assert all(s.residual_ratio <= 1e-8 for s in result.payload.schedule.rows)

    def test_attachment_points_rise_linearly(self, result):
        l, k1, k2, l1 = 540.0, 1.8507, 1.2302, 50.0
        for mass in (0.0, 100.0, 250.0, 500.0):
            row = _row(result, mass)
            assert row["l12"] == pytest.approx(G * 1e-3 * l * (268.67 + 575.29 + 815.47 + mass) / (k1 * l1), rel=1e-7)
            assert row["l22"] == pytest.approx(G * 1e-3 * l * (287.645 + 815.47 + mass) / (k2 * l1), rel=1e-7)
        assert _row(result, 0)["l12"] == pytest.approx(95, abs=0.1)
        assert _row(result, 500)["l12"] == pytest.approx(123.62, abs=0.1)
        assert _row(result, 0)["l22"] == pytest.approx(95, abs=0.1)
        assert _row(result, 500)["l22"] == pytest.approx(138.06, abs=0.1)
        assert {line.variable for line in result.payload.schedule.lines} == {"l12", "l22"}


# --------------------------------------------------------------------------------------
# The schedule between its grid points, and a payload the adjustment follows non-linearly
# --------------------------------------------------------------------------------------

PENDULUM = payload_pendulum_toml(
    "pendulum_payload", "u", "0.0025 m^2", "0.09 m^2", '["-sqrt(u)", 0, 0]',
    description="the square of the counter-mass lever: u(p) = ((m + p) r / M)^2, not linear in p",
)


def test_nonlinear_adjustment_is_solved_densely_and_gets_no_formula():
    """Least M: the lever reaches its upper bound 0.3 m at 1 kg, so M = (1 + 1)·0.3/0.3 = 2 kg;
    u(p) = ((1 + p)·0.3/2)² is quadratic: no linear formula, every grid value matches it."""
    from counterpoise.io.loader import load_problem_text
    from counterpoise.pipeline import design

    result = design(load_problem_text(PENDULUM, "pendulum.toml"))
    assert result.status.value == "optimal", result.message
    assert value(result, "M", "kg") == pytest.approx(2.0, rel=1e-7)
    plan = result.payload.schedule
    assert plan.feasible and plan.lines == ()
    for s in plan.rows + plan.between:
        assert s.values["u"] == pytest.approx(((1 + s.payload) * 0.3 / 2) ** 2, rel=1e-7)
    from counterpoise.payload.schedule import BETWEEN

    assert len(plan.between) == BETWEEN * (len(plan.rows) - 1)


class _StubSolver:
    """An adjustment solver whose adjustments fail only in (0.0231, 0.0232) kg: between grid points."""

    class _Settings:
        schedule_points = 51

    def __init__(self):
        from counterpoise.model.units import display_unit

        self.payload = type("P", (), {"unit": display_unit("g")})()
        self.source = type("S", (), {"settings": self._Settings()})()
        self.problem = type("Q", (), {"variables": ()})()

    def at(self, mass):
        from counterpoise.payload.schedule import Setting

        bad = 0.0231 < mass < 0.0232
        return Setting(mass, {}, 0.0, not bad, "hole" if bad else "")


def test_schedule_checks_between_grid_points():
    from counterpoise.payload.schedule import schedule

    plan = schedule(_StubSolver(), 0.0, 0.031)  # grid step 0.5 g: 23.0 and 23.5 g are grid points
    assert all(s.feasible for s in plan.rows)
    assert not plan.feasible
    assert plan.first_failure.payload == pytest.approx(0.023125)  # the first check inside (23.0, 23.5) g


@pytest.mark.parametrize(
    ("lower", "upper", "first_step"),
    [(0.0, 0.122, 0.002), (0.0, 0.031, 0.0005), (0.0, 0.5, 0.01), (0.0, 0.034771, 0.0005)],
)
def test_grid_has_round_steps_and_at_least_50_points(lower, upper, first_step):
    from counterpoise.payload.schedule import grid

    points = grid(lower, upper, 1e-3, 51)
    assert len(points) >= 51 and points[0] == lower and points[-1] == pytest.approx(upper)
    assert points[1] - points[0] == pytest.approx(first_step)


# --------------------------------------------------------------------------------------
# Reports and the command line
# --------------------------------------------------------------------------------------


def test_schedule_csv_and_status(tmp_path):
    from counterpoise.report import write_reports

    folder = write_reports(solved("woo2019_hybrid", IDEAL), tmp_path)
    table = pd.read_csv(folder / "schedule.csv")
    assert list(table.columns) == ["payload [g]", "dL_c1 [mm]", "dL_c2 [mm]", "residual_ratio", "feasible"]
    row = table[table["payload [g]"] == 62].iloc[0]
    assert row["dL_c1 [mm]"] == pytest.approx(25.41, abs=0.01) and row["feasible"] == "yes"
    status = (folder / "status.txt").read_text()
    assert "linear in the payload: dL_c1 = 0 mm + 0.40983607 mm/g × added" in status
    design = pd.read_csv(folder / "design.csv", keep_default_na=False)
    pinned = design[(design["name"] == "dL_c1") & (design["scenario"] == "added_0g")]
    assert list(pinned["active_bound"]) == [""]  # fixed to its nominal, not an active bound


def _cli(*args):  # noqa: ANN202 - conftest.CliRun
    """The command line, in process (conftest.run_cli)."""
    return run_cli(*args)


def test_cli_schedule_prints_the_settings():
    proc = _cli("schedule", str(PROBLEMS / "woo2019_counterweight.toml"), "--payload", "31 g")
    assert proc.returncode == 0, proc.stderr
    line = next(x for x in proc.stdout.splitlines() if "dL_c2" in x)
    assert "44.577" in line and "mm" in line


def test_cli_schedule_outside_the_range_exits_1_with_the_range():
    proc = _cli("schedule", str(PROBLEMS / "woo2019_counterweight.toml"), "--payload", "40 g")
    assert proc.returncode == 1
    assert "payload 40 g is outside the balanceable range 0 g to 34.771 g" in proc.stdout


@pytest.mark.parametrize(
    ("payload", "fragment"), [("31 mm", "--payload: expected a mass, got a length ('31 mm')"), ("31 gg", "--payload: unknown unit 'gg'")]
)
def test_cli_schedule_bad_payload_exits_2(payload, fragment, tmp_path):
    path = PROBLEMS / "woo2019_counterweight.toml"
    proc = _cli("schedule", str(path), "--payload", payload)
    assert proc.returncode == 2
    assert proc.stderr.strip() == f"{path}: {fragment}" or proc.stderr.strip().startswith(f"{path}: {fragment}")
    assert "Traceback" not in proc.stderr


def test_cli_schedule_without_payload_exits_2():
    path = PROBLEMS / "yasir2019_counter_mass.toml"
    proc = _cli("schedule", str(path), "--payload", "31 g")
    assert proc.returncode == 2 and proc.stderr.startswith(f"{path}: payloads: no payload range declared")


def test_builder_payload_equals_the_file():
    """The Python API builds the same problem as the TOML text of the non-linear pendulum."""
    from counterpoise import ProblemBuilder, rotate
    from counterpoise.io.loader import load_problem_text

    b = ProblemBuilder("pendulum_payload", gravity="9.81 m/s^2", direction=(0, -1, 0))
    b.parameter("m", "1 kg").parameter("r", "0.3 m")
    b.subsystem("arm", q=("-180 deg", "180 deg"))
    b.frame("link", rotate("z", "q"))
    b.body("tip", frame="link", mass="m", com=("r", 0, 0))
    b.payload("tool", frame="link", position=("r", 0, 0), range=("0 kg", "1 kg"))
    b.variable("M", "0 kg", "20 kg")
    b.variable("u", "0.0025 m^2", "0.09 m^2", adjustable=True, description="the square of the counter-mass lever: u(p) = ((m + p) r / M)^2, not linear in p")
    b.counter_mass("cm", frame="link", mass="M", position=("-sqrt(u)", 0, 0))
    built = b.build("pendulum.toml")
    read = load_problem_text(PENDULUM, "pendulum.toml")
    assert built.payloads == read.payloads and built.variables == read.variables and built.bodies == read.bodies


def test_schedule_failing_inside_the_range_fails_the_design_naming_the_payload(monkeypatch):
    """A schedule that fails at 62 g (forced here) makes 62 g a design sample; when it still
    fails there the design is reported failed, naming that payload."""
    import dataclasses

    from counterpoise.io.loader import load_problem
    from counterpoise.payload import design as payload_design
    from counterpoise.pipeline import design

    real = payload_design.schedule

    def failing_at_62_g(solver, lower, upper):
        plan = real(solver, lower, upper)
        rows = tuple(dataclasses.replace(s, feasible=False) if abs(s.payload - 0.062) < 1e-12 else s for s in plan.rows)
        return dataclasses.replace(plan, rows=rows)

    monkeypatch.setattr(payload_design, "schedule", failing_at_62_g)
    result = design(load_problem(PROBLEMS / "woo2019_hybrid.toml"))
    assert result.status.value == "failed"
    assert "first failing payload 62 g" in result.message
    assert result.payload.samples == pytest.approx((0.0, 0.062, 0.122))  # 62 g was added to the samples


DESIGNED_SPRING = """[variables.k]
lower = "0 N/m"
upper = "1 N/m"
[springs.s]
stiffness = "k"
max_force = "1 N"
from = { frame = "ground", point = [0, "0.1 m", 0] }
to = { frame = "link", point = ["0.1 m", 0, 0] }
"""


def test_a_payload_design_that_balances_no_payload_gets_its_springs_designed():
    """Issue 32 item 10 (``KeyError: 0.0``, exit 3): 1 kg at 0.3 m is 2.94 N·m; a counter-mass
    of at most 0.1 kg at most 0.5 m behind the joint (0.49 N·m) and a spring of at most 1 N/m
    (k a h ≤ 0.01 N·m) balance no payload of the range. The schedule has no feasible payload;
    the designed spring is then sized on the design itself, not looked up in an empty schedule.
    (Its max_force makes it a problem with constraints too: the other form of the report.)"""
    from counterpoise import design
    from counterpoise.io.loader import load_problem_text

    text = payload_pendulum_toml("pay", "b", "0.05 m", "0.5 m", '["-b", 0, 0]', mass_upper="0.1 kg") + DESIGNED_SPRING
    result = design(load_problem_text(text, "pay.toml"))
    assert result.status.value == "infeasible"
    assert not any(s.feasible for s in result.payload.schedule.rows)
    assert result.payload.schedule_solution() is result.payload.solution
    assert {s.spring for s in result.springs} == {"s"}
