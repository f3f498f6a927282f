"""Balancer synthesis (issue 34; docs/synthesis.md): the hand-derived two-link case, the
examples of problems/synthesis/, the compositions, and the input errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import ROOT

SYNTHESIS = ROOT / "problems" / "synthesis"


def _synthesise(name: str, **overrides: object):
    from counterpoise.io.loader import load_problem
    from counterpoise.synthesis import synthesise

    return synthesise(load_problem(SYNTHESIS / name, overrides or None))


@pytest.fixture(scope="module")
def arm2():
    return _synthesise("arm2_springs.toml")


@pytest.fixture(scope="module")
def fourbar():
    return _synthesise("fourbar_sites.toml")


@pytest.fixture(scope="module")
def leg():
    return _synthesise("yasir2019_leg.toml")


@pytest.fixture(scope="module")
def sphere():
    return _synthesise("spherical_chain_3r.toml")


def test_hand_case_two_link_arm(arm2):
    """docs/synthesis.md#hand: one spring never balances the two-link arm, and the only
    pair of springs that does is ground-link_2 with link_1-link_2."""
    assert arm2.status == "optimal"
    assert arm2.cost == 2 and arm2.grid_bound == pytest.approx(2)
    assert {t.labels for t in arm2.topologies} == {("spring ground-link_2", "spring link_1-link_2")}
    assert arm2.complete and arm2.conditions_exact
    # the relaxation cannot see that the spring's elbow term and its link-2 term share one
    # attachment point (docs/synthesis.md#bound): its bound lies between 1 and the minimum
    assert 1 <= arm2.relaxation_bound <= 2
    (t,) = arm2.topologies
    spring = next(e for e in t.grid.elements if arm2.classes[e.cls].name == "ground-link_2")
    a, b = spring.points[0]
    # hand derivation: a straight above the shoulder (a_x = 0), b on link 2's axis at
    # b_x = l1 m2 c2 / (m1 c1 + m2 l1) = 0.4·0.2/(0.4 + 0.4) = 0.1 m, and
    # k a_y l1 = g (m1 c1 + m2 l1) = 9.81·0.8 = 7.848 J
    assert a[0] == pytest.approx(0.0, abs=1e-12) and b[1] == pytest.approx(0.0, abs=1e-12)
    assert b[0] == pytest.approx(0.1, rel=1e-9)
    assert spring.magnitude * a[1] * 0.4 == pytest.approx(9.81 * 0.8, rel=1e-9)


def test_the_hand_case_terms(arm2):
    """terms.csv's structure (docs/synthesis.md#hand): gravity makes sin(q1) with
    g (m1 c1 + m2 l1) = 7.848 J and sin(q1 + q2) with g m2 c2 = 1.962 J; ground-link_1
    makes only q1 terms, link_1-link_2 only q2 terms, ground-link_2 all three."""
    terms = {row["term"].split(": ")[1]: row for row in arm2.terms}
    assert terms["sin(q1)"]["mechanism_J"] == pytest.approx(9.81 * 0.8, rel=1e-12)
    assert terms["sin(q1 + q2)"]["mechanism_J"] == pytest.approx(9.81 * 0.2, rel=1e-12)
    assert terms["cos(q2)"]["mechanism_J"] == 0
    assert terms["sin(q2)"]["produced_by"] == "spring ground-link_2; spring link_1-link_2"
    assert terms["sin(q1 + q2)"]["produced_by"] == "spring ground-link_2"
    assert terms["sin(q1)"]["produced_by"] == "spring ground-link_1; spring ground-link_2"


@pytest.mark.parametrize("which", ["arm2", "fourbar", "leg", "sphere"])
def test_every_topology_is_exact_and_reproduced_from_its_file(which, request):
    from counterpoise.io.loader import load_problem_text
    from counterpoise.pipeline import design

    result = request.getfixturevalue(which)
    assert result.status == "optimal" and result.topologies
    for t in result.topologies:
        assert t.result.status.value == "optimal", t.result.message
        assert t.result.verification.residual_ratio <= 1e-9
        again = design(load_problem_text(t.text, f"{t.name}.toml"))
        assert again.status.value == "optimal"
        assert again.verification.residual_ratio <= 1e-9
        assert again.solution.objective == pytest.approx(t.result.solution.objective, rel=1e-6, abs=1e-9)


def test_fourbar_two_counter_masses(fourbar):
    """docs/synthesis.md#fourbar: one counter-mass never balances the four-bar; with the
    sites' regions of the file two do, crank and rocker or crank and coupler (coupler and
    rocker would need the coupler's mass beyond B). The lightest: the crank's and the
    rocker's at the far ends of their sites, 150 mm behind O2 and O4, carrying
    C2 = 0.066 kg·m and C4 = 0.15 kg·m (docs/loops.md): 0.44 + 1.0 kg."""
    assert fourbar.cost == 2 and not fourbar.conditions_exact  # a closed loop: sampled on its manifold
    assert {t.labels for t in fourbar.topologies} == {("counter-mass crank_cm", "counter-mass rocker_cm"), ("counter-mass crank_cm", "counter-mass coupler_cm")}
    best, second = fourbar.topologies
    assert best.labels == ("counter-mass crank_cm", "counter-mass rocker_cm")
    assert best.result.solution.added_mass == pytest.approx(0.066 / 0.15 + 0.15 / 0.15, rel=1e-7)
    # crank and coupler: lambda = -m4 p4 / c = -0.2, so the coupler needs M3 s3 = -b 0.2 - m3 p3
    # = -0.18 kg·m (0.9 kg at its site's end, 200 mm behind A) and the crank
    # M2 s2 = -0.2 a - m2 p2 - (m3 + M3) a = -0.246 kg·m (1.64 kg at 150 mm): 2.54 kg
    assert second.result.solution.added_mass == pytest.approx(0.18 / 0.2 + 0.246 / 0.15, rel=1e-7)


def test_seed_001_leg_the_papers_hybrid_is_minimal(leg):
    """Three elements are needed and suffice; the paper's hybrid (counter-masses behind b
    and c, one spring from the ground to link a) is one of the minimal topologies, and at
    the sites' far ends (b_b = 120, b_c = 250 mm) its counter-masses are the free
    extensions' 1239.41 g (docs/derivations.md#yasir-2019)."""
    assert leg.cost == 3 and leg.complete
    hybrid = ("spring ground-link_a", "counter-mass behind_b", "counter-mass behind_c")
    found = {tuple(sorted(t.labels)): t for t in leg.topologies}
    assert tuple(sorted(hybrid)) in found
    assert found[tuple(sorted(hybrid))].result.solution.added_mass == pytest.approx(1.23941, abs=5e-6)
    three = ("counter-mass behind_a", "counter-mass behind_b", "counter-mass behind_c")  # Table 1's choice
    assert tuple(sorted(three)) in found


def test_spherical_chain_one_spring_per_link_proven_for_every_point(sphere):
    """Seed 002's chain: three springs, one from the ground to each link, and nothing less
    for any point in the regions (the relaxation's bound is the minimum)."""
    assert sphere.cost == 3 and sphere.relaxation_bound == pytest.approx(3)
    assert {t.labels for t in sphere.topologies} == {("spring ground-link1", "spring ground-link2", "spring ground-link3")}
    assert "also for every point anywhere in the regions" in sphere.proof


def test_the_synthesis_files(arm2, tmp_path):
    from counterpoise.io.loader import load_problem
    from counterpoise.synthesis import write_synthesis

    folder = write_synthesis(arm2, tmp_path)
    assert folder == tmp_path / "arm2_springs-synthesis"
    names = {p.name for p in folder.iterdir()}
    assert {"synthesis.csv", "elements.csv", "terms.csv", "status.txt", "arm2_springs_t1.toml", "arm2_springs_t1"} <= names
    assert (folder / "arm2_springs_t1" / "report.html").is_file()
    lines = (folder / "synthesis.csv").read_text().splitlines()
    assert lines[0].startswith("kind,rank,topology,elements,cost")
    assert lines[1].startswith("minimal,1,spring ground-link_2; spring link_1-link_2,2,2")
    problem = load_problem(folder / "arm2_springs_t1.toml")
    assert problem.synthesis is None and len(problem.springs) == 2
    from counterpoise.cli import main

    with pytest.raises(SystemExit) as exit_:  # `counterpoise solve` takes the written file
        main(["solve", str(folder / "arm2_springs_t1.toml"), "--out", str(tmp_path / "solved"), "--report", "csv"])
    assert exit_.value.code == 0
    summary = (tmp_path / "solved" / "arm2_springs_t1" / "summary.csv").read_text().splitlines()
    assert summary[1].split(",")[1] == "optimal"


def _cli(args, capsys):
    from counterpoise.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(args)
    out = capsys.readouterr()
    return exit_.value.code, out.out, out.err


def test_a_superstructure_that_cannot_balance_names_the_terms(tmp_path, capsys):
    """Only a spring between the two links: it makes elbow terms only, so gravity's
    sin(q1) and sin(q1 + q2) stay, for any points (exit 1, nothing proven balanced)."""
    code, out, _ = _cli(["synthesise", str(SYNTHESIS / "arm2_springs.toml"), "--out", str(tmp_path), "--set", "synthesis.springs=[['link_1', 'link_2']]"], capsys)
    assert code == 1
    assert "cannot balance exactly" in out and "sin(q1)" in out and "sin(q1 + q2)" in out
    assert "for any points in the regions" in out
    assert "infeasible" in (tmp_path / "arm2_springs-synthesis" / "status.txt").read_text()


@pytest.mark.parametrize(
    "sets, key",
    [
        (["synthesis.regions.elbow={ box = { lower = [0, 0, 0], upper = [1, 1, 0] } }"], "synthesis.regions.elbow"),
        (["synthesis.max_rate=1 kg"], "synthesis.max_rate"),
        (["variables.x={ lower = '0 mm', upper = '1 mm' }"], "variables.x"),
        (["synthesis.adjust=true"], "synthesis.adjust"),
        (["synthesis.springs=[['ground', 'ground']]"], "synthesis.springs.0"),
        (["synthesis.regions.link_1={ segment = [[0, 0, 0], [0, 0, 0]] }"], "synthesis.regions.link_1.segment"),
        (["synthesis.regions.link_1={ holes = [[0, 0, 0]], points = 3 }"], "synthesis.regions.link_1.points"),
    ],
)
def test_bad_synthesis_input_is_one_line_exit_2(sets, key, tmp_path, capsys):
    args = ["synthesise", str(SYNTHESIS / "arm2_springs.toml"), "--out", str(tmp_path)]
    for s in sets:
        args += ["--set", s]
    code, _, err = _cli(args, capsys)
    assert code == 2
    assert err.strip().count("\n") == 0 and f": {key}:" in err
    assert not any(tmp_path.iterdir())


def test_a_file_without_synthesis_is_exit_2(tmp_path, capsys):
    code, _, err = _cli(["synthesise", str(ROOT / "problems" / "fourbar_springs.toml"), "--out", str(tmp_path)], capsys)
    assert code == 2 and ": synthesis: missing" in err


def test_validate_accepts_and_solve_ignores_the_synthesis_table(capsys):
    code, out, _ = _cli(["validate", *(str(p) for p in sorted(SYNTHESIS.glob("*.toml")))], capsys)
    assert code == 0 and out.count("ok  ") == len(list(SYNTHESIS.glob("*.toml")))


def test_payload_range_with_adjustments_and_a_tilting_base():
    """Compositions (docs/synthesis.md#compositions): a pendulum with a 0–0.2 kg payload
    at its tip, adjusted per payload, is balanced by one element, a spring or a
    counter-mass; on a base tilting ±15° only the counter-mass balances it, and springs
    alone cannot (docs/tilt.md)."""
    from counterpoise import ProblemBuilder, rotate
    from counterpoise.synthesis import synthesise

    def pendulum(name: str) -> ProblemBuilder:
        b = ProblemBuilder(name, gravity="9.81 m/s^2", direction=(0, -1, 0))
        b.parameter("m", "0.8 kg").parameter("r", "0.3 m")
        b.subsystem("arm", q=("-180 deg", "180 deg"))
        b.frame("link", rotate("z", "q"))
        b.body("tip", frame="link", mass="m", com=("r", 0, 0))
        return b

    regions = {"ground": {"box": {"lower": ["-100 mm", "0 mm", 0], "upper": ["100 mm", "200 mm", 0]}}, "link": {"segment": [["-200 mm", 0, 0], ["300 mm", 0, 0]]}}
    sites = {"cm": {"frame": "link", "segment": [["-300 mm", 0, 0], [0, 0, 0]]}}
    b = pendulum("payload").payload("tool", frame="link", position=("r", 0, 0), range=("0 kg", "0.2 kg"))
    b.synthesis(regions=regions, sites=sites, max_rate="10 N/mm", max_mass="5 kg", adjust=True)
    result = synthesise(b.build(), raw=b.data)
    assert result.cost == 1 and {t.labels for t in result.topologies} == {("spring ground-link",), ("counter-mass cm",)}
    assert all(t.verified and t.result.payload is not None for t in result.topologies)
    cm = next(t for t in result.topologies if t.labels == ("counter-mass cm",))
    # the counter-mass at the site's far end, 0.3 m behind the pivot, carries the heaviest
    # payload: M 0.3 m = (0.8 + 0.2) kg 0.3 m
    assert cm.result.solution.added_mass == pytest.approx(1.0, rel=1e-7)
    # two working modes, the second with gravity along -x (the base turned by 90°): a
    # spring's ground end cannot turn with gravity, a counter-mass on the link's far side
    # balances both (its moment about the pivot is the tip's, M 0.3 m = 0.8 kg 0.3 m)
    w = pendulum("modes").scenario("upright").scenario("turned", direction=(-1, 0, 0))
    w.synthesis(regions=regions, sites=sites, max_rate="10 N/mm", max_mass="5 kg")
    modes = synthesise(w.build(), raw=w.data)
    assert {x.labels for x in modes.topologies} == {("counter-mass cm",)}
    assert modes.topologies[0].result.solution.added_mass == pytest.approx(0.8, rel=1e-7)
    t = pendulum("tilt").tilt((1, 0, 0), "-15 deg", "15 deg")
    t.synthesis(regions=regions, sites=sites, max_rate="10 N/mm", max_mass="5 kg")
    tilted = synthesise(t.build(), raw=t.data)
    assert {x.labels for x in tilted.topologies} == {("counter-mass cm",)}
    t.synthesis(regions=regions, max_rate="10 N/mm")
    springs = synthesise(t.build(), raw=t.data)
    assert springs.status == "infeasible" and math.isinf(springs.relaxation_bound)
    assert springs.unbalanced and all("sin(q)" in name or "cos(q)" in name for name, _ in springs.unbalanced)


def test_same_rate_for_every_spring(tmp_path):
    result = _synthesise("arm2_springs.toml", **{"synthesis.same_rate": True})
    (t,) = result.topologies
    rates = [e.magnitude for e in t.grid.elements]
    assert rates[0] == pytest.approx(rates[1], rel=1e-12)
    assert {s.stiffness.id for s in t.result.problem.springs} == {"k"}  # type: ignore[attr-defined]
    assert t.result.verification.residual_ratio <= 1e-9


def test_the_conditions_are_the_energy_coefficients():
    """Each class's coefficient rows times its weights give the energy's coefficients: a
    random spring's and counter-mass's energy through the engine's mechanics, transformed
    the same way, equals the rows' prediction."""
    from counterpoise.io.loader import load_problem
    from counterpoise.synthesis.conditions import conditions
    from counterpoise.synthesis.structure import element_classes, spring_weights

    problem = load_problem(SYNTHESIS / "arm2_springs.toml")
    classes = element_classes(problem.synthesis)
    cond = conditions(problem, classes)
    rng = np.random.default_rng(3)
    a, b, k = rng.normal(size=3) * 0.1, rng.normal(size=3) * 0.1, 123.0
    a[2] = b[2] = 0.0
    rows = cond.matrix[1] @ spring_weights(k, a, b)  # ground-link_2
    # the spring's energy ½ k |a − o_2 − R_2 b|² at q, on a fine grid of (q1, q2): its
    # sin(q1 + q2) coefficient by quadrature
    q1, q2 = np.meshgrid(np.linspace(0, 2 * np.pi, 64, endpoint=False), np.linspace(0, 2 * np.pi, 64, endpoint=False))
    o2 = 0.4 * np.stack([np.cos(q1), np.sin(q1)])
    phi = q1 + q2
    p = o2 + np.stack([np.cos(phi) * b[0] - np.sin(phi) * b[1], np.sin(phi) * b[0] + np.cos(phi) * b[1]])
    energy = 0.5 * k * ((a[0] - p[0]) ** 2 + (a[1] - p[1]) ** 2)
    for term, basis in (("sin(q1 + q2)", np.sin(phi)), ("cos(q2)", np.cos(q2)), ("sin(q1)", np.sin(q1))):
        i = [n.split(": ")[1] for n in cond.names].index(term)
        assert rows[i] == pytest.approx(2 * np.mean(energy * basis), abs=1e-12)


def test_progress_lines_give_the_bound_and_the_incumbent(monkeypatch):
    """On a long run (here: every line, the delay set to 0) the search says the master's
    bound and the incumbent through the progress module."""
    from counterpoise import progress
    from counterpoise.synthesis import search

    monkeypatch.setattr(search, "NOTE_AFTER_S", 0.0)
    lines: list[str] = []
    with progress.sink(lines.append):
        result = _synthesise("arm2_springs.toml")
    assert result.cost == 2
    said = [line for line in lines if line.startswith("synthesis: ")]
    assert said and all("bound " in line and "incumbent " in line for line in said)
    assert any("incumbent 2" in line for line in said)
