"""The screened part searches agree with brute force on small catalogues, over random
mechanisms: zero-free-length slots (rate windows, designs interpolated between node rates)
and directly attached springs (geometry grid, compass search, most promising first)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from builders import one_link_toml, slot_pendulum_toml
from counterpoise import load_problem
from counterpoise.designer.minimax import MinimaxDesigner
from counterpoise.selection import PartSearch
from counterpoise.selection.direct import _enumerate, search_direct
from counterpoise.selection.groups import reduced_echelon
from counterpoise.selection.screening import best_offset

HEADER = "part_number,rate_N_per_m,free_length_m,initial_tension_N,max_load_N,max_length_m,outer_diameter_m,wire_diameter_m,material"

def _geometry(n: str = "") -> str:
    """The free geometry of a directly attached spring: its arm end r along the arm, its
    ground end (x, y) and its cable c (variables r<n>, x<n>, y<n>, c<n>)."""
    return f"""
[variables.r{n}]
lower = "15 mm"
upper = "90 mm"
initial = "50 mm"
[variables.x{n}]
lower = "-130 mm"
upper = "130 mm"
initial = "0 mm"
[variables.y{n}]
lower = "110 mm"
upper = "270 mm"
initial = "200 mm"
[variables.c{n}]
lower = "0 mm"
upper = "300 mm"
initial = "0 mm"
"""


def _spring(name: str, n: str = "") -> str:
    """Spring ``name`` of slot s, attached directly on the geometry ``n`` of :func:`_geometry`."""
    return f"""
[springs.{name}]
slot = "s"
mount = "direct"
cable = "c{n}"
from = {{ frame = "ground", point = ["x{n}", "y{n}", 0] }}
to = {{ frame = "arm", point = ["r{n}", 0, 0] }}
"""


def arm_toml(mass: float, length: float, lo: float, hi: float, two: bool = False) -> str:
    """An arm (mass ``mass`` kg at ``length`` m, phi in [lo, hi] deg) with one
    directly attached spring s1 from parts.csv, or (``two``) a second one, s2, on its own geometry."""
    rest = '[catalogues.parts]\nfile = "parts.csv"\n[slots.s]\ncatalogue = "parts"\n' + _geometry()
    rest += (_geometry("2") + _spring("s2", "2") + _spring("s1")) if two else _spring("s1")
    return one_link_toml("arm_direct_screening", f'm = "{mass} kg"\nL = "{length} m"', rest, coordinate="phi",
                         joint_range=(f"{lo} deg", f"{hi} deg"), frame="arm", body="arm", com='["L", 0, 0]')


def catalogue(path: Path, rng: np.random.Generator, n: int, rate: tuple[float, float], free_length: tuple[float, float], stroke: tuple[float, float]) -> None:
    rows = []
    for i in range(n):
        k = float(np.exp(rng.uniform(*np.log(rate))))
        l0 = float(rng.uniform(*free_length))
        f0 = float(rng.uniform(0.05, 0.4)) * k * l0
        lmax = l0 + float(rng.uniform(*stroke))
        fmax = f0 + k * (lmax - l0) * float(rng.uniform(0.8, 1.3))
        rows.append(f"P-{i:03d},{k:.6g},{l0:.6g},{f0:.6g},{fmax:.6g},{lmax:.6g},0.01,0.001,x")
    path.write_text(HEADER + "\n" + "\n".join(rows) + "\n", encoding="utf-8")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rate_screening_agrees_with_enumeration(tmp_path, seed):
    """A pendulum with a random mass, lever and range; 40 random parts. The screening
    (forced by max_enumeration = 1) picks the part the enumeration of every rate picks."""
    rng = np.random.default_rng(seed)
    catalogue(tmp_path / "parts.csv", rng, 40, (100.0, 3000.0), (0.02, 0.08), (0.05, 0.4))
    mass, r, b = rng.uniform(0.5, 3.0), rng.uniform(0.1, 0.3), rng.uniform(0.05, 0.15)
    text = slot_pendulum_toml("pendulum_screening", mass, r, b, h_upper="0.4 m", joint_range=(-rng.uniform(30, 80), rng.uniform(30, 80)))
    (tmp_path / "p.toml").write_text(text, encoding="utf-8")
    exhaustive = PartSearch(load_problem(tmp_path / "p.toml")).run()
    screened = PartSearch(load_problem(tmp_path / "p.toml", {"selection.max_enumeration": 1})).run()
    assert exhaustive.methods == ["enumeration"] and screened.methods == ["screening"]
    assert (exhaustive.choice is None) == (screened.choice is None)
    if exhaustive.choice is not None:
        assert screened.choice.parts == exhaustive.choice.parts
        assert screened.choice.robust == pytest.approx(exhaustive.choice.robust, rel=1e-9)
        assert screened.solves < exhaustive.solves
        assert any(line.startswith("group s: screening") for line in screened.evidence)


@pytest.mark.parametrize("seed", [0, 1])
def test_direct_screening_finds_the_brute_force_best(tmp_path, seed):
    """A 1R arm with a random mass and range; 10 random parts for a directly attached
    spring. Every part designed (brute force) and the screened search agree on the best
    worst-case ratio (the screened one may be better: it starts each part from its best
    grid design)."""
    rng = np.random.default_rng(10 + seed)
    catalogue(tmp_path / "parts.csv", rng, 10, (200.0, 3000.0), (0.02, 0.06), (0.05, 0.2))
    text = arm_toml(rng.uniform(0.3, 1.0), rng.uniform(0.2, 0.4), -rng.uniform(20, 50), rng.uniform(20, 50))
    (tmp_path / "a.toml").write_text(text, encoding="utf-8")
    problem = load_problem(tmp_path / "a.toml")
    designer = MinimaxDesigner(problem)
    brute = _enumerate(problem, designer, lambda done, total: None, 0.0, "test")
    screened = search_direct(problem, designer, lambda done, total: None)
    assert screened.methods == ["screening"]
    assert (brute.choice is None) == (screened.choice is None)
    if brute.choice is not None:
        assert screened.choice.robust <= brute.choice.robust * (1 + 1e-3) + 1e-9
        assert screened.solves <= brute.solves


def test_best_offset_is_the_minimax_over_the_interval():
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(5, 30)), rng.normal(size=(5, 30))
    lo, hi = np.full(5, -1.0), np.full(5, 2.0)
    t, value = best_offset(a, b, lo, hi)
    grid = np.linspace(-1, 2, 30001)
    brute = np.abs(a[:, None, :] - grid[None, :, None] * b[:, None, :]).max(axis=2).min(axis=1)
    assert np.allclose(value, brute, atol=1e-3) and (value <= brute + 1e-12).all()
    assert ((t >= lo) & (t <= hi)).all()


def test_reduced_echelon_rows_are_circuits_in_original_columns():
    """Null space of [[1, 1, 0, 0], [0, 0, 1, -1]] : circuits {0, 1} and {2, 3}; the rows of
    the reduced echelon form keep the original column order (no pivot to undo)."""
    null = np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 1.0]])
    mixed = np.array([[1.0, 2.0], [3.0, -1.0]]) @ null
    rows = reduced_echelon(mixed)
    supports = sorted(tuple(np.flatnonzero(np.abs(r) > 1e-12)) for r in rows)
    assert supports == [(0, 1), (2, 3)]
    assert math.isclose(abs(rows[0][0]), 1.0)


def test_direct_pair_screening_finds_the_brute_force_best(tmp_path):
    """Two springs of one part, each with its own geometry: the pair screening (unordered
    pairs of grid geometries, then a compass search) and designing every part agree."""
    rng = np.random.default_rng(21)
    catalogue(tmp_path / "parts.csv", rng, 8, (100.0, 1500.0), (0.02, 0.06), (0.05, 0.2))
    (tmp_path / "two.toml").write_text(arm_toml(0.8, 0.3, -40, 45, two=True), encoding="utf-8")
    problem = load_problem(tmp_path / "two.toml")
    designer = MinimaxDesigner(problem)
    brute = _enumerate(problem, designer, lambda done, total: None, 0.0, "test")
    screened = search_direct(problem, designer, lambda done, total: None)
    assert screened.methods == ["screening"] and "unordered pairs" in screened.evidence[0]
    assert brute.choice is not None and screened.choice is not None
    assert screened.choice.robust <= brute.choice.robust * (1 + 1e-3) + 1e-9


def test_search_evidence_reaches_status_and_summary(tmp_path):
    """The search's evidence (pruned per limit, method and guarantee) is in status.txt's
    part-search lines and the lower bound of the ratio in summary.csv (0: exact balance)."""
    from counterpoise import design
    from counterpoise.selection.report import parts_status
    from counterpoise.report.rows import summary_row

    rng = np.random.default_rng(4)
    catalogue(tmp_path / "parts.csv", rng, 20, (100.0, 3000.0), (0.02, 0.08), (0.05, 0.4))
    (tmp_path / "p.toml").write_text(slot_pendulum_toml("pendulum_screening", 1.0, 0.2, 0.1, h_upper="0.4 m"), encoding="utf-8")
    result = design(load_problem(tmp_path / "p.toml"))
    text = parts_status(result)
    assert "group s: enumeration; every rate in the window solved" in text
    assert "pruned by the rate window" in text
    assert summary_row(result)["lower_bound_ratio"] == 0.0


@pytest.mark.parametrize("seed", [0, 1])
def test_direct_part_bounds_are_below_every_design(tmp_path, seed):
    """The certified per-part lower bound (interval bound over geometry cells) is at most
    the worst ratio of every design of that part (brute force: every part designed), some
    part's bound is positive at three refinement levels (cells refined while below a ratio
    of 1; the bound is first order in the cell size, so not on every random arm), and the
    search's catalogue bound, when it reports one, is at most the brute-force best."""
    from counterpoise.selection.bounds import certifiable, part_bounds
    from counterpoise.selection.direct import part_parameters
    from counterpoise.selection.screening import screen

    rng = np.random.default_rng(30 + seed)
    catalogue(tmp_path / "parts.csv", rng, 10, (200.0, 3000.0), (0.02, 0.06), (0.05, 0.2))
    with open(tmp_path / "parts.csv", "a", encoding="utf-8") as fh:  # far too stiff
        fh.write("STIFF,60000,0.04,5,2000,0.07,0.01,0.001,x\n")
    text = arm_toml(rng.uniform(0.3, 1.0), rng.uniform(0.2, 0.4), -rng.uniform(20, 50), rng.uniform(20, 50))
    (tmp_path / "a.toml").write_text(text, encoding="utf-8")
    problem = load_problem(tmp_path / "a.toml")
    designer = MinimaxDesigner(problem)
    brute = _enumerate(problem, designer, lambda done, total: None, 0.0, "test")
    screened = screen(problem, designer, part_parameters(problem, {"s": 0}))
    assert certifiable(screened.context) == ""
    ratio = {c.parts["s"]: c.robust for c in brute.candidates}
    assert ratio, "no part fits: the test checks nothing"
    bounds = part_bounds(screened.context, designer, 1.0, math.inf, max_depth=3)
    for row, value in ratio.items():
        assert bounds.value[row] <= value
    assert (bounds.value > 0).any()  # positive, or infinite (certified unable to stay within its lengths)
    alone = part_bounds(screened.context, designer, 1.0, math.inf, rows=np.array([0]), max_depth=1)
    assert np.isnan(alone.value[1:]).all() and alone.value[0] <= ratio.get(0, math.inf)
    result = search_direct(problem, designer, lambda done, total: None)
    assert math.isnan(result.lower_bound_ratio) or result.lower_bound_ratio <= min(ratio.values())


def test_direct_slot_through_design(tmp_path):
    """A directly attached slot through design() (the CLI's path): the search reads the
    designer's formulation through the call's wrapper (it raised AttributeError)."""
    from counterpoise import design

    rng = np.random.default_rng(12)
    catalogue(tmp_path / "parts.csv", rng, 8, (200.0, 3000.0), (0.02, 0.06), (0.05, 0.2))
    (tmp_path / "a.toml").write_text(arm_toml(0.6, 0.3, -40, 40), encoding="utf-8")
    result = design(load_problem(tmp_path / "a.toml"))
    assert result.parts is not None and result.parts.search.methods == ["screening"]
    assert any(line.startswith("bound: ") for line in result.parts.search.evidence)
