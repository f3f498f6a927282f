"""build.csv round trip: the build sheet alone rebuilds the design's balance.

For every problem in problems/ with springs or counter-masses (each solved once per session,
``conftest.solved``), the balancers are rebuilt from build.csv ALONE: each spring from its
two anchor points in their own frames and its rate (a direct mount also from its cable,
free length and initial tension), each counter-mass from its mass and point, each
``adjustment`` row's setting. The problem file supplies only what is not built: its frames
(the kinematics), its bodies and its sampled configurations. The dense verification of that
rebuilt mechanism must find the design's residual ratio to 1e-9 (build.csv keeps 12
significant digits, so its rounding moves a ratio by ~1e-11), and the sheet's spring forces
must be those of springs.csv.

The sheet is the design at home in the home scenario (a payload range's nominal payload, else
the first scenario): it gives the adjustments' settings at home and their range, not each
payload's, and a working mode may move a point; the check is in that scenario.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import replace

import numpy as np
import pytest

from conftest import PROBLEMS, solved

from counterpoise.model.elements import CounterMass, DirectMount, ZeroFreeLengthSpring
from counterpoise.model.expr import Num
from counterpoise.model.mechanism import Point
from counterpoise.model.units import display_unit
from counterpoise.report.build import BUILD_COLUMNS, home_mechanics, home_scenario
from counterpoise.report.files import report_texts, write_reports
from counterpoise.verify.check import verify

NAMES = sorted(p.stem for p in PROBLEMS.glob("*.toml"))
MM = 1e-3


def _rows(text: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(text)))


def _num(cell: str) -> float:
    return float(cell) if cell != "" else math.nan


def _point(row: dict[str, str]) -> Point:
    return Point(row["frame"], tuple(Num(float(row[c]) * MM) for c in ("x_mm", "y_mm", "z_mm")))  # type: ignore[arg-type]


def _world(row: dict[str, str]) -> np.ndarray:
    return np.array([float(row[c]) * MM for c in ("world_x_mm", "world_y_mm", "world_z_mm")])


@pytest.fixture(scope="module")
def sheets():
    """Per problem: (result, build.csv rows, the report texts); built once."""
    cache = {}

    def get(name):
        if name not in cache:
            result = solved(name)
            texts = report_texts(result)
            cache[name] = (result, _rows(texts["build.csv"]) if "build.csv" in texts else None, texts)
        return cache[name]

    return get


def rebuilt_problem(result, rows):
    """The problem with its springs, counter-masses and adjustments taken from build.csv."""
    problem = result.problem
    by = {(r["kind"], r["name"]): r for r in rows}
    springs = []
    for r in (r for r in rows if r["kind"] == "spring"):
        name = r["name"]
        a, b = by[("spring_from", f"{name}.from")], by[("spring_to", f"{name}.to")]
        direct = None
        if ("pulley", f"{name}.pulley") not in by:  # attached directly: F0 + k (d − cable − L0)
            direct = DirectMount(Num(float(r["free_length_mm"]) * MM), Num(float(r["initial_tension_N"])), Num(float(r["cable_mm"]) * MM))
        rate = float(r["rate_N_per_mm"]) * 1e3
        springs.append(ZeroFreeLengthSpring(name, Num(rate), (_point(a), _point(b)), r["subsystem"] or None, direct=direct))
    masses = [
        CounterMass(r["name"], Num(float(r["value"]) * display_unit(r["unit"]).to_si), _point(r), None, r["subsystem"] or None)
        for r in rows
        if r["kind"] == "counter_mass"
    ]
    home = home_scenario(result)
    # the sheet is the design at home in the home scenario: a working mode may move a point
    # (essomba2021_variable_payload turns its adjustment links with the mode)
    scenarios = tuple(s for s in problem.scenarios if s.name == home)
    rebuilt = replace(problem, springs=tuple(springs), counter_masses=tuple(masses), scenarios=scenarios)
    adjust = {r["name"]: float(r["value"]) * display_unit(r["unit"]).to_si for r in rows if r["kind"] == "adjustment"}
    # every other design value is unknown to the sheet: NaN, which would poison the check if used
    values = {slot: adjust.get(slot.variable, math.nan) for slot in result.solution.values}
    return rebuilt, replace(result.solution, problem=rebuilt, values=values, verification=None), scenarios


@pytest.mark.parametrize("name", NAMES)
def test_build_sheet_rebuilds_the_balance(name, sheets):
    result, rows, texts = sheets(name)
    problem = result.problem
    if not (problem.springs or problem.counter_masses):
        assert rows is None
        pytest.skip(f"{name}: nothing built (no springs, no counter-masses)")
    assert list(rows[0]) == BUILD_COLUMNS
    kinds = {r["kind"] for r in rows}
    assert kinds <= {"spring_from", "spring_to", "pulley", "spring", "counter_mass", "adjustment"}
    assert [int(r["item"]) for r in rows] == list(range(1, len(rows) + 1))
    rebuilt, solution, scenarios = rebuilt_problem(result, rows)

    # the design's own dense check on the same scenarios, and the rebuilt one
    design = verify(replace(result.solution, problem=replace(problem, scenarios=scenarios), verification=None)).residual_ratio
    again = verify(solution).residual_ratio
    assert math.isfinite(again)
    assert abs(again - design) <= 1e-9, (again, design)
    if len(problem.scenarios) == 1 and result.payload is None:
        assert abs(design - result.verification.residual_ratio) <= 1e-9

    # at home, the balancers' energy from the sheet's world points alone (no kinematics):
    # Σ ½ k |a − b|² (pulley), F0·x + ½ k x² with x = d − c − L0 (direct), − Σ M g·p
    mech = home_mechanics(result)
    by = {(r["kind"], r["name"]): r for r in rows}
    energy = 0.0
    for r in (r for r in rows if r["kind"] == "spring"):
        k = float(r["rate_N_per_mm"]) * 1e3
        d = float(np.linalg.norm(_world(by[("spring_from", r["name"] + ".from")]) - _world(by[("spring_to", r["name"] + ".to")])))
        assert d == pytest.approx(float(r["distance_home_mm"]) * MM, rel=1e-9, abs=1e-12)
        if ("pulley", r["name"] + ".pulley") in by:
            energy += 0.5 * k * d * d
            assert float(r["force_home_N"]) == pytest.approx(k * d, rel=1e-9, abs=1e-9)
            # the cable from the spring's end over the pulley to the link point serves the
            # whole workspace: it is the largest distance, and never shorter than home's
            assert float(r["cable_mm"]) == pytest.approx(float(r["distance_max_mm"]), rel=1e-12)
            assert float(r["distance_min_mm"]) <= float(r["distance_home_mm"]) * (1 + 1e-9) + 1e-9
            assert float(r["distance_home_mm"]) <= float(r["cable_mm"]) * (1 + 1e-9) + 1e-9
        else:
            x = d - float(r["cable_mm"]) * MM - float(r["free_length_mm"]) * MM
            energy += float(r["initial_tension_N"]) * x + 0.5 * k * x * x
    g = np.array([float(v) for v in mech.gravity])
    for r in (r for r in rows if r["kind"] == "counter_mass"):
        energy -= float(r["value"]) * display_unit(r["unit"]).to_si * float(g @ _world(r))
    balancers = float(mech.energy_terms()[1])
    assert energy == pytest.approx(balancers, rel=1e-9, abs=1e-9 * float(mech.energy_magnitude()))

    # the forces of springs.csv (catalogue parts): the same extremes over the workspace
    if "springs.csv" in texts:
        spec = [r for r in _rows(texts["springs.csv"]) if r["kind"] == "spring"]
        for r in (r for r in rows if r["kind"] == "spring"):
            mine = [s for s in spec if s["spring"] == r["name"]]
            if not mine:
                continue
            assert r["part_number"] == mine[0]["part_number"]
            lo, hi = min(float(s["min_force_N"]) for s in mine), max(float(s["max_force_N"]) for s in mine)
            # home belongs to the workspace, the sample of springs.csv may just miss it
            home = float(r["force_home_N"])
            lo, hi = min(lo, home), max(hi, home)
            assert float(r["force_min_N"]) == pytest.approx(lo, rel=1e-8)
            assert float(r["force_max_N"]) == pytest.approx(hi, rel=1e-8)
            longest = max(float(s["max_length_mm"]) for s in mine)
            assert float(r["length_max_mm"]) == pytest.approx(max(longest, float(r["length_home_mm"])), rel=1e-8)


def test_build_sheet_is_written_with_the_reports(tmp_path, sheets):
    """``write_reports`` puts build.csv beside the other reports; a pulley mount's cable and
    installed length: a catalogue part (L0, F0 known) gives L = d + L0 − F0/k at home."""
    result, rows, _ = sheets("yasir2019_hybrid_catalogue")
    folder = write_reports(result, tmp_path)
    assert (folder / "build.csv").read_text(encoding="utf-8").startswith("item,kind,name,frame,")
    for r in (r for r in rows if r["kind"] == "spring"):
        k = float(r["rate_N_per_mm"])
        expected = float(r["distance_home_mm"]) + float(r["free_length_mm"]) - float(r["initial_tension_N"]) / k
        assert float(r["length_home_mm"]) == pytest.approx(expected, rel=1e-9)
        assert r["part_number"]


def test_realise_pulley_and_direct_mounts_by_hand():
    """mechanics/realisation.py on numbers worked by hand.

    Pulley: k = 0.5 N/mm, L0 = 80 mm, F0 = 5 N, anchors 100 mm apart at home, 50-200 mm over
    the workspace. L − d = L0 − F0/k = 80 − 10 = 70 mm: installed length 170 mm at home; the
    cable is d_max = 200 mm, 100 mm of it behind the pulley at home; the fixed end sits
    200 + 70 = 270 mm behind the pulley; forces k·d = 50 N at home, 25-100 N.
    Direct: k = 0.1 N/mm, L0 = 50 mm, F0 = 2 N, cable 30 mm, d = 100 mm: L = 70 mm,
    F = 2 + 0.1·(70 − 50) = 4 N. A home outside the sampled range (d = 40 mm < 50 mm) widens it.
    """
    from counterpoise.mechanics.realisation import DIRECT, PULLEY, realise

    p = realise(500.0, 0.1, 0.05, 0.2, 0.08, 5.0)
    assert p.mount == PULLEY
    assert (p.cable, p.length_home, p.cable_behind_home, p.anchor_distance) == pytest.approx((0.2, 0.17, 0.1, 0.27), rel=1e-12)
    assert (p.length_min, p.length_max) == pytest.approx((0.12, 0.27), rel=1e-12)
    assert (p.force_home, p.force_min, p.force_max) == pytest.approx((50.0, 25.0, 100.0), rel=1e-12)
    d = realise(100.0, 0.1, 0.1, 0.1, 0.05, 2.0, cable=0.03)
    assert d.mount == DIRECT and d.pulley is None
    assert (d.length_home, d.force_home) == pytest.approx((0.07, 4.0), rel=1e-12)
    wide = realise(500.0, 0.04, 0.05, 0.2)
    assert (wide.distance_min, wide.force_min) == pytest.approx((0.04, 20.0), rel=1e-12)
    assert math.isnan(wide.length_home)  # a designed spring: L0 and F0 not chosen yet
