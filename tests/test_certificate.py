"""The exact certificate of balance (``verify/certificate.py``) and its use in studies.

Properties only (no figure of a search is pinned):

- on random mechanisms whose residual is a trigonometric polynomial (revolute joints with
  integer couplings such as ``2*q2 - q1``, a tilted axis, a slider, counter-masses and a
  ZFL spring), with random design values (so unbalanced), the certificate's bound of each
  coordinate is at least the dense check's largest sampled |residual|: Σ |coefficients|
  bounds the polynomial everywhere, and the dense check samples the same function;
- a balanced seed problem certifies, and the same design with a counter-mass moved does not;
- degrees read off the expression trees, and what is not certifiable;
- a study reports ``certificate`` = ``exact`` by default and ``sampled`` with ``--check dense``,
  with the same designs.
"""

from __future__ import annotations

import csv
import dataclasses

import numpy as np
import pytest

from conftest import PROBLEMS, solved
from counterpoise.cli.app import main
from counterpoise.io.loader import load_problem, load_problem_text
from counterpoise.pipeline import build_method, design, run
from counterpoise.verify.certificate import EXACT, SAMPLED, certificate, certificate_of, certify, degrees, why_not
from counterpoise.verify.check import check, verify


def _random_mechanism(seed: int) -> str:
    """A two-subsystem mechanism with random geometry and masses (lengths 0.05-0.4 m,
    masses 0.1-2 kg), gravity in a random direction."""
    rng = np.random.default_rng(seed)
    L = rng.uniform(0.05, 0.4, 8)
    m = rng.uniform(0.1, 2.0, 4)
    g = rng.normal(size=3)
    g /= np.linalg.norm(g)
    axis = rng.normal(size=3)
    return f"""
[problem]
name = "random_trig_{seed}"
[gravity]
acceleration = "9.81 m/s^2"
direction = [{g[0]:.6f}, {g[1]:.6f}, {g[2]:.6f}]
[subsystems.arm]
coordinates.q1 = {{ range = ["-100 deg", "120 deg"] }}
coordinates.q2 = {{ range = ["-180 deg", "180 deg"] }}
[subsystems.slide]
coordinates.s = {{ range = ["-50 mm", "80 mm"] }}
coordinates.q3 = {{ range = ["0 deg", "90 deg"] }}
[frames.a]
transforms = [{{ rotate = "z", angle = "q1" }}]
[frames.b]
parent = "a"
transforms = [{{ translate = ["{L[0]:.5f} m", 0, 0] }}, {{ rotate = [{axis[0]:.4f}, {axis[1]:.4f}, {axis[2]:.4f}], angle = "2*q2 - q1 + 17 deg" }}]
[frames.c]
transforms = [{{ translate = ["s", "{L[1]:.5f} m", 0] }}, {{ rotate = "x", angle = "q3" }}]
[bodies.link_a]
frame = "a"
mass = "{m[0]:.4f} kg"
com = ["{L[2]:.5f} m", "{L[3]:.5f} m", 0]
[bodies.link_b]
frame = "b"
mass = "{m[1]:.4f} kg"
com = ["{L[4]:.5f} m", 0, "{L[5]:.5f} m"]
[bodies.slider]
frame = "c"
mass = "{m[2]:.4f} kg"
com = [0, "{L[6]:.5f} m", 0]
[variables.M_a]
lower = "0 kg"
upper = "10 kg"
[variables.M_b]
lower = "0 kg"
upper = "10 kg"
[variables.M_c]
lower = "0 kg"
upper = "10 kg"
[variables.k]
lower = "0 N/m"
upper = "1000 N/m"
[counter_masses.M_a]
frame = "a"
mass = "M_a"
position = ["-0.1 m", 0, 0]
[counter_masses.M_b]
frame = "b"
mass = "M_b"
position = ["-0.1 m", "0.05 m", 0]
[counter_masses.M_c]
frame = "c"
mass = "M_c"
position = [0, "-0.1 m", 0]
[springs.s1]
stiffness = "k"
from = {{ frame = "ground", point = [0, "{L[7]:.5f} m", 0] }}
to = {{ frame = "b", point = ["0.05 m", 0, 0] }}
"""


def _with_values(solution, rng):
    """The solution with every variable set to a random value inside its bounds (unbalanced)."""
    problem = solution.problem
    values = {slot: float(rng.uniform(problem.variable[slot.variable].lower, problem.variable[slot.variable].upper)) for slot in solution.values}
    return dataclasses.replace(solution, values=values, verification=None)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_bound_is_at_least_the_dense_sampled_maximum(seed):
    problem = load_problem_text(_random_mechanism(seed), f"random_{seed}.toml")
    # degrees from the trees: q1 turns frame a (1) and, with coefficient -1, frame b (1): 2
    # in the spring's end on b and in link_b; q2 (coefficient 2) 2; s enters a translation
    # (1); q3 one rotation (1)
    assert degrees(problem, "arm") == {"q1": 2, "q2": 2}
    assert degrees(problem, "slide") == {"s": 1, "q3": 1}
    found = certificate(problem)
    assert found is not None
    solution = build_method(problem).solve()
    rng = np.random.default_rng(seed)
    for _ in range(3):
        unbalanced = _with_values(solution, rng)
        exact = found.verify(unbalanced)
        dense = verify(unbalanced)
        bound = {(c.subsystem, c.coordinate): c.max_residual for c in exact.checks}
        for c in dense.checks:
            # the dense maximum is a sampled value of the same polynomial: never above the
            # bound (up to rounding of both, 1e-9 relative)
            assert c.max_residual <= bound[(c.subsystem, c.coordinate)] * (1 + 1e-9) + 1e-12
        assert not exact.balanced  # random values do not balance


def _part_alone(part, solution):
    """One part's figures computed on its own, as the certificate did before it grouped the
    parts of one grid shape: (bound, largest |torque|, largest |balancer force|, worst sample)."""
    variables = solution.variable_values(part.scenario)
    gravity, base = solution.scenario_parameters[part.scenario]
    r, t = part.evaluator.evaluate(variables, base, gravity)
    n_q = r.shape[1]
    c = part.coefficients(np.concatenate([r, t], axis=1)).reshape(-1, 2 * n_q)
    bound = np.abs(c[:, :n_q]).sum(axis=0)
    both = part.basis_real @ c.real - part.basis_imag @ c.imag if np.iscomplexobj(c) else part.basis_real @ c
    rs, ts = both[:, :n_q], both[:, n_q:]
    with np.errstate(invalid="ignore"):
        return bound, np.abs(ts).max(axis=0), np.abs(rs - ts).max(axis=0), np.argmax(np.abs(rs), axis=0)


def test_grouped_parts_give_each_part_s_own_figures_bit_for_bit():
    """The parts of one grid shape are transformed and multiplied in one call each
    (numpy transforms line by line and multiplies a stack matrix by matrix): every figure
    equals the part's own computation exactly, with two scenarios (two parts per grid
    shape), a slider (Chebyshev axis) and random, unbalanced design values."""
    text = _random_mechanism(4).replace("[subsystems.slide]", '[scenarios.a]\n[scenarios.b]\ngravity = { acceleration = "9.81 m/s^2", direction = [1, 0, 0] }\n[subsystems.slide]')
    problem = load_problem_text(text, "random_two_scenarios.toml")
    found = certificate(problem)
    assert found is not None and len(found.parts) == 4 and any(len(g.parts) == 2 for g in found.groups)
    solution = build_method(problem).solve()
    rng = np.random.default_rng(4)
    for design in (solution, _with_values(solution, rng), _with_values(solution, rng)):
        checks = iter(found.verify(design).checks)
        for part in found.parts:
            bound, loads, balancers, worst = _part_alone(part, design)
            for j, name in enumerate(part.evaluator.names):
                c = next(checks)
                assert (c.scenario, c.subsystem, c.coordinate) == (part.scenario, part.subsystem, name)
                assert c.max_residual == bound[j] and c.max_gravity_torque == loads[j] and c.max_balancer_force == balancers[j]
                assert c.worst_configuration == tuple(part.samples[worst[j]])


@pytest.fixture(scope="module")
def hybrid():
    problem = load_problem(PROBLEMS / "yasir2019_hybrid.toml")
    return problem, run(build_method(problem), quantities=False)


def test_balanced_seed_problem_certifies(hybrid):
    problem, result = hybrid
    exact = certify(result.solution)
    assert exact is not None and exact.balanced and certificate_of(exact) == EXACT
    # the residual ratio is an upper bound; both are rounding noise for this LP optimum
    assert exact.residual_ratio <= problem.settings.verify_tolerance
    # the reference: a lower bound of the dense check's box maximum, within 5 % of it
    dense = result.verification
    assert certificate_of(dense) == SAMPLED
    assert 0.95 * dense.reference("revolute") <= exact.reference("revolute") <= dense.reference("revolute") * (1 + 1e-9)
    # 3 revolute coordinates of degree 1 per subsystem: a 3 x 3 x 3 grid
    assert {c.configurations for c in exact.checks} == {27}
    assert check(result.solution, "auto") is not None and certificate_of(check(result.solution, "auto")) == EXACT
    assert certificate_of(check(result.solution, "dense")) == SAMPLED


def test_unbalanced_seed_design_does_not_certify(hybrid):
    problem, result = hybrid
    s = result.solution
    slot = next(slot for slot in s.values if slot.variable.startswith("M_b"))
    moved = dataclasses.replace(s, values={**s.values, slot: s.values[slot] * 1.01}, verification=None)
    assert certify(moved) is None
    assert not certificate(problem).verify(moved).balanced
    assert certificate_of(check(moved, "auto")) == SAMPLED  # the dense check decides
    assert not check(moved, "auto").balanced


@pytest.mark.parametrize(
    ("name", "reason"),
    [("fourbar_counter_mass.toml", "closed loops"), ("so_arm100_direct.toml", "attached directly")],
)
def test_not_certifiable(name, reason):
    assert reason in why_not(load_problem(PROBLEMS / name))


def test_non_integer_coupling_is_not_certifiable():
    text = _random_mechanism(1).replace('"2*q2 - q1 + 17 deg"', '"0.5*q2"')
    assert "non-integer" in why_not(load_problem_text(text, "half.toml"))
    text = _random_mechanism(1).replace('translate = ["s",', 'translate = ["0.1 m * cos(q3)",')
    assert why_not(load_problem_text(text, "cos.toml")) is not None


def test_study_reports_the_certificate(tmp_path, capsys):
    file = str(PROBLEMS / "yasir2019_hybrid.toml")
    rows = {}
    for mode in ("auto", "dense"):
        out = tmp_path / mode
        with pytest.raises(SystemExit) as exit_:
            main(["study", file, "--vary", "m_endo=500 g:700 g:3", "--jobs", "1", "--no-plot", "--out", str(out), "--check", mode])
        assert exit_.value.code in (0, None)
        with (out / "yasir2019_hybrid-study" / "study.csv").open(encoding="utf-8") as handle:
            rows[mode] = list(csv.DictReader(handle))
    assert [r["certificate"] for r in rows["auto"]] == [EXACT] * 3
    assert [r["certificate"] for r in rows["dense"]] == [SAMPLED] * 3
    for a, d in zip(rows["auto"], rows["dense"]):
        assert a["status"] == d["status"] == "optimal"
        assert a["k [N/mm]"] == d["k [N/mm]"] and a["objective_kg"] == d["objective_kg"]  # the same designs


def test_solve_check_option(tmp_path, capsys):
    file = str(PROBLEMS / "yasir2019_counter_mass.toml")
    for mode, expected in (("dense", SAMPLED), ("auto", EXACT)):
        with pytest.raises(SystemExit) as exit_:
            main(["solve", file, "--out", str(tmp_path / mode), "--report", "csv", "--check", mode])
        assert exit_.value.code == 0
        with (tmp_path / mode / "yasir2019_counter_mass" / "summary.csv").open(encoding="utf-8") as handle:
            assert next(csv.DictReader(handle))["certificate"] == expected
    with pytest.raises(SystemExit) as exit_:
        main(["solve", file, "--out", str(tmp_path / "bad"), "--check", "exactly"])
    assert exit_.value.code == 2
    assert "--check" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_design_default_is_the_dense_check():
    result = solved("yasir2019_counter_mass")
    assert certificate_of(result.verification) == SAMPLED


def test_study_of_a_closed_loop_falls_back_to_the_dense_check(tmp_path, capsys):
    # a four-bar's residual lives on its loop's manifold: not certifiable, so every point
    # is verified by the dense check even with the default --check auto
    with pytest.raises(SystemExit) as exit_:
        main(["study", str(PROBLEMS / "fourbar_counter_mass.toml"), "--vary", "m3=0.7 kg:0.9 kg:2", "--jobs", "1", "--no-plot", "--out", str(tmp_path)])
    assert exit_.value.code in (0, None)
    with (tmp_path / "fourbar_counter_mass-study" / "study.csv").open(encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert [r["certificate"] for r in rows] == [SAMPLED, SAMPLED]
    assert all(r["status"] == "optimal" for r in rows)
