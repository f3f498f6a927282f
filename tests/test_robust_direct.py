"""[robust] with a directly attached spring (docs/robust.md#direct-springs): the minimax NLP
over the tolerance corners holds the spring's lengths and max_force at every corner, and the
worst case is labelled a sampled minimax, not exact.

The mechanism: an arm turning about z (φ from the horizontal, ±50°), its mass m = 1 kg at
r = 0.2 m, a spring attached directly from the ground point A = (x, y, 0) to the arm's point
P = R(φ) (b, 0, 0), of rate k = 200 N/m, free length L0 = 50 mm, initial tension F0 = 2 N,
through a cable c. The spring pulls F = F0 + k (d − c − L0) along P → A (d = |A − P|), so
the torque about the pivot is τ = −m g r cos φ + F/d (P × A)_z, and the residual ratio is
max |τ| / (m g r) (the largest gravity torque, at φ = 0). The tests evaluate that law in
numpy at every corner of the tolerances, independently of the engine.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from counterpoise import design, load_problem, write_reports
from counterpoise.cli import main
from counterpoise.robust.result import SAMPLED_MINIMAX, RobustReport
from counterpoise.solvers.base import Status

M, R, G, K, L0, F0 = 1.0, 0.2, 9.81, 200.0, 0.05, 2.0
SLACK_MARGIN = 0.003  # the default springs.<name>.slack_margin (problems/README.md)
MAX_FORCE = 40.0  # binds: the nominal-rate design pulls about 43 N at the +10 % corner

ARM = """
[problem]
name = "robust_direct_arm"

[gravity]
acceleration = "9.81 m/s^2"
direction = [0, -1, 0]

[parameters]
m = "1 kg"
r = "0.2 m"
k = "200 N/m"

[variables.x]
lower = "-0.1 m"
upper = "0.1 m"
initial = "0 m"
[variables.y]
lower = "0.05 m"
upper = "0.5 m"
initial = "0.2 m"
[variables.b]
lower = "0.01 m"
upper = "0.3 m"
initial = "0.1 m"
[variables.c]
lower = "0 m"
upper = "0.3 m"
initial = "0 m"

[subsystems.arm]
coordinates.phi = {{ range = ["-50 deg", "50 deg"] }}

[frames.link]
transforms = [{{ rotate = "z", angle = "phi" }}]

[bodies.link]
frame = "link"
mass = "m"
com = ["r", 0, 0]

[springs.s]
stiffness = "k"
free_length = "50 mm"
initial_tension = "2 N"
max_length = "{max_length}"
max_force = "{max_force}"
mount = "direct"
cable = "c"
from = {{ frame = "ground", point = ["x", "y", 0] }}
to = {{ frame = "link", point = ["b", 0, 0] }}

[robust]
mode = "{mode}"
{weight}{robust}

[settings]
ideal_springs = true
"""


def arm(tmp_path: Path, robust: str, mode: str = "minimise", max_length: str = "0.6 m", max_force: str = "40 N") -> Path:
    path = tmp_path / "arm.toml"
    weight = 'weight = "1 kg"\n' if mode == "minimise" else ""  # kg per unit of ratio: the objective is the band alone (no added mass)
    path.write_text(ARM.format(robust=robust, mode=mode, weight=weight, max_length=max_length, max_force=max_force), encoding="utf-8")
    return path


def by_hand(values: dict[str, float], rate: float, point: float, n: int = 20001, tension: float = 0.0):
    """Per corner (signs of the rate, then from.x/y/z, to.x/y/z when ``point`` > 0, then the
    initial tension's when ``tension`` > 0): the residual ratio max |τ|/(m g r), the spring's
    length d − c and force F on φ ∈ [−50°, 50°]."""
    phi = np.radians(np.linspace(-50.0, 50.0, n))
    out = {}
    points = 6 if point > 0 else 0
    for signs in itertools.product((-1, 1), repeat=1 + points + (tension > 0)):
        k = K * (1 + signs[0] * rate)
        f0 = F0 + (signs[-1] * tension if tension > 0 else 0.0)
        e = np.array(signs[1 : 1 + points], dtype=float) * point if points else np.zeros(6)
        a = np.array([values["x"] + e[0], values["y"] + e[1], e[2]])
        local = np.array([values["b"] + e[3], e[4], e[5]])
        p = np.stack([local[0] * np.cos(phi) - local[1] * np.sin(phi), local[0] * np.sin(phi) + local[1] * np.cos(phi), np.full_like(phi, local[2])])
        v = a[:, None] - p
        d = np.sqrt((v**2).sum(axis=0))
        length = d - values["c"]
        force = f0 + k * (length - L0)
        tau = -M * G * R * np.cos(phi) + force / d * (p[0] * a[1] - p[1] * a[0])
        out[signs] = (np.abs(tau).max() / (M * G * R), length, force)
    return out


def _values(result) -> dict[str, float]:
    return {slot.variable: value for slot, value in result.solution.values.items()}


def test_rate_tolerance_worst_corner_agrees_with_the_force_law(tmp_path):
    """Rate ±10 %: the engine's worst-case band of both designs (over the corners on its dense
    sample) is the largest of the hand-evaluated corners on a denser grid (its 10 001 points
    are among the test's 20 001: equal to rounding), the named worst corner is the hand's,
    and every corner keeps the spring taut, within its longest length and below max_force."""
    result = design(load_problem(arm(tmp_path, 'tolerances.rate = "10 %"')))
    assert result.status is Status.OPTIMAL, result.message
    assert "directly attached spring s" in result.message and "not exact" in result.message
    report = result.solution.extra(RobustReport)
    assert report.exactness.startswith(SAMPLED_MINIMAX)
    corners = by_hand(_values(result), 0.1, 0.0)
    ratios = {signs: value[0] for signs, value in corners.items()}
    assert report.bands["robust"]["all"] == pytest.approx(max(ratios.values()), rel=1e-6)
    worst = max(ratios, key=lambda s: ratios[s])
    assert report.worst_corner["robust"].startswith(f"rate s {'+' if worst[0] > 0 else '-'}10 % at phi = ")
    # the robust design is no worse than the nominal one over the box (it minimises the band)
    assert report.bands["robust"]["all"] <= report.bands["nominal"]["all"] + 1e-9
    for _, length, force in corners.values():
        assert length.min() >= L0 + SLACK_MARGIN - 1e-5  # LENGTH_TOLERANCE: between the NLP's samples
        assert length.max() <= 0.6
        assert force.max() <= MAX_FORCE * (1 + 1e-6)
    # max_force binds at the stiffer corner, as design.csv says
    assert corners[(1,)][2].max() == pytest.approx(MAX_FORCE, rel=1e-6)
    (limit,) = [c for c in result.solution.constraints if c.constraint.name == "s.max_force"]
    assert limit.active == "upper" and limit.corner == "rate s +10 %"


def test_point_tolerance_corners_and_lengths_by_hand(tmp_path):
    """Rate ±10 % and every end ±2 mm per axis (7 deviations, 128 corners): the band is the
    largest of the 128 hand-evaluated corners, every corner keeps the length limits and
    max_force, and status.txt says the worst case is a sampled minimax, not exact, naming
    the worst corner."""
    result = design(load_problem(arm(tmp_path, 'tolerances.rate = "10 %"\ntolerances.point = "2 mm"')))
    assert result.status is Status.OPTIMAL, result.message
    folder = write_reports(result, tmp_path / "out")
    status = (folder / "status.txt").read_text(encoding="utf-8")
    assert f"robust: the worst case is {SAMPLED_MINIMAX}" in status
    assert "the residual is not affine in point s from.x" in status
    report = result.solution.extra(RobustReport)
    corners = by_hand(_values(result), 0.1, 0.002)
    ratios = {signs: value[0] for signs, value in corners.items()}
    assert report.bands["robust"]["all"] == pytest.approx(max(ratios.values()), rel=1e-6)
    assert f"robust: robust design: worst-case residual ratio {report.bands['robust']['all']:.4g} at {report.worst_corner['robust']}" in status
    tolerance = (folder / "tolerance.csv").read_text(encoding="utf-8")
    assert f'robust,worst_corner,"{report.worst_corner["robust"]}",' in tolerance
    # the named corner ("rate s -10 %, point s from.x +2 mm, ... at phi = ..."), in the hand's
    # order (rate, from.x/y/z, to.x/y/z), is a worst one by hand (the z signs tie in pairs)
    named = report.worst_corner["robust"].split(" at ")[0].split(", ")
    assert [part.split()[1 if part.startswith("rate") else 2] for part in named] == ["s"] + ["from.x", "from.y", "from.z", "to.x", "to.y", "to.z"]
    signs = tuple(1 if part.split()[-2][0] == "+" else -1 for part in named)
    assert ratios[signs] == pytest.approx(max(ratios.values()), rel=1e-6)
    for _, length, force in corners.values():
        assert length.min() >= L0 + SLACK_MARGIN - 1e-5
        assert length.max() <= 0.6
        assert force.max() <= MAX_FORCE * (1 + 1e-6)


def test_initial_tension_tolerance_of_a_direct_spring(tmp_path):
    """A direct spring's initial tension ±0.5 N is a deviation of its force F0 + ΔF0 + k x
    (not a force along a pulley's cable): the ordinary design's band over rate × tension
    corners and the tension-only band agree with the force law by hand. The ordinary design
    (mode "none") uses max_force (40 N) fully at the nominal rate, so the stiffest corner
    breaks it: infeasible, the corner named, never optimal."""
    result = design(load_problem(arm(tmp_path, 'tolerances.rate = "10 %"\ntolerances.initial_tension = "0.5 N"', mode="none")))
    assert result.status is Status.INFEASIBLE, result.message
    assert "s.max_force" in result.message and "at the tolerance corner rate s +10 %, initial_tension s +0.5 N" in result.message
    band = result.solution.extra(RobustReport).bands["nominal"]
    corners = by_hand(_values(result), 0.1, 0.0, tension=0.5)
    assert band["all"] == pytest.approx(max(v[0] for v in corners.values()), rel=1e-6)
    assert max(v[2].max() for v in corners.values()) > MAX_FORCE  # the breach, by hand
    only = by_hand(_values(result), 0.0, 0.0, tension=0.5)
    assert band["initial_tension"] == pytest.approx(max(v[0] for v in only.values()), rel=1e-6)


def test_mode_none_names_the_corner_that_breaks_the_length(tmp_path):
    """The ordinary design (mode "none") with ends ±1 cm per axis and a longest length of
    60 mm (7 mm above L0 + slack margin): some corner shortens the spring by more than 7 mm
    (a corner moves the ends by up to 2 cm along each axis), so the design is infeasible and
    the message names the corner; the hand evaluation agrees that the corner breaks a limit."""
    result = design(load_problem(arm(tmp_path, 'tolerances.point = "1 cm"', mode="none", max_length="60 mm")))
    assert result.status is Status.INFEASIBLE, result.message
    assert "breaks the hardware at a tolerance corner: corner point s" in result.message
    corners = by_hand(_values(result), 0.0, 0.01)
    assert any(length.min() < L0 + SLACK_MARGIN or length.max() > 0.06 for _, length, _ in corners.values())


def test_minimax_infeasible_names_the_corner(tmp_path):
    """mode "minimise" with the same too-wide tolerance: no geometry keeps the length within
    7 mm at all 64 corners; infeasible (never optimal), naming the spring and a corner."""
    result = design(load_problem(arm(tmp_path, 'tolerances.point = "1 cm"', max_length="60 mm")))
    assert result.status is Status.INFEASIBLE, result.message
    assert "keeps the directly attached spring s within its lengths at every tolerance corner" in result.message
    assert "corner point s from.x" in result.message


@pytest.mark.parametrize(
    ("extra", "key", "message"),
    [
        ('tune = ["x"]', "robust.tune", "not combinable yet: tune with directly attached springs"),
        ('shape = "ellipsoid"\ntolerances.point = "1 mm"', "robust.shape", "not combinable yet: shape = \"ellipsoid\" with a point tolerance"),
    ],
)
def test_still_refused_with_direct_springs(tmp_path, capsys, extra, key, message):
    """What is not built yet stays an input error: exit 2, the key named, nothing written."""
    path = arm(tmp_path, 'tolerances.rate = "10 %"\n' + extra)
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stop:
        main(["solve", str(path), "--out", str(out)])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert key in err and message in err
    assert not out.exists()


def test_slots_with_limit_stay_refused(tmp_path, capsys):
    """[robust] with [slots] (the catalogue lamp) combines in mode "none" (tests/test_robust_slots.py);
    "limit" is still an input error: exit 2 naming robust.mode, nothing written. ([loops]
    combines: tests/test_robust_loops.py.)"""
    problems = Path(__file__).resolve().parents[1] / "problems"
    path = tmp_path / "lamp_catalogue.toml"
    path.write_text((problems / "lamp_catalogue.toml").read_text(encoding="utf-8") + '\n[robust]\nmode = "limit"\nlimit = 0.2\ntolerances.rate = "10 %"\n', encoding="utf-8")
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stop:
        main(["solve", str(path), "--out", str(out)])
    assert stop.value.code == 2
    assert 'robust.mode: not combinable yet: mode = "limit" with [slots]' in capsys.readouterr().err
    assert not out.exists()


def test_repeated_corner_rows_are_held_once():
    """Corners that differ only across the plane of a planar mechanism (a point deviation
    along z moves a spring's length by the same amount at + and −) give rows equal bit for
    bit; the minimax NLP keeps the first of each (half the rows of the point test above),
    and keeps rows that differ anywhere."""
    from counterpoise.robust.minimax import first_of_repeats

    values = np.array([[1.0, 2.0], [3.0, 4.0], [1.0, 2.0], [1.0, 2.0 + 1e-15], [3.0, 4.0], [0.0, 0.0]])
    assert first_of_repeats(values) == [0, 1, 3, 5]
    assert first_of_repeats(np.zeros((0, 2))) == []
    nan = np.array([[np.nan, 1.0], [np.nan, 1.0], [2.0, 2.0]])
    assert first_of_repeats(nan) == [0, 1, 2]  # not finite at a probe: never merged
