"""[robust] with a payload range: tolerances × payloads, the tuning travel reserved on top of
the payload adjustment (issue 31, part 2), on problems/camera_jib_robust.toml.

The jib (docs/robust.md#a-camera-jib): camera m ∈ [2, 8] kg at L = 0.8 m, boom m_b = 2.5 kg at
c_b = 0.25 m, counterweight M_c at x behind the pivot (the slide, 0-400 mm, per camera), a
spring k from h above the pivot to a = 0.15 m (h the tuning screw, factory setting 80 mm).
Balance: (m L + m_b c_b − M_c x) g = k h a at every camera. The slide covers the cameras:
M_c (x(8) − x(2)) = 6 kg × L = 4.8 kg·m. A counterweight 5 % light needs the span
4.8/(0.95 M_c), which no screw setting changes (the screw shifts every camera alike), so the
slide must keep travel: designed on the whole slide (M_c = 12 kg) the corner would need
0.4/0.95 = 421.05 mm of 400, 10.526 mm beyond each end (the screw tunes at 5 kg with the slide
where the design puts it: the middle). The range is designed again with the slide narrowed by
that much at both ends: span 378.95 mm, M_c = 4.8/0.37895 = 12.6667 kg, x(2 kg) = 10.526 mm,
x(5 kg) = 200 mm (the schedule is linear in the payload), x(8 kg) = 389.47 mm, and the spring
carries the rest at 2 kg: k = (2 × 0.8 + 2.5 × 0.25 − M_c x(2)) g/(h a) = 1709.94 N/m.
"""

from __future__ import annotations

import pytest

from counterpoise.errors import ProblemFileError
from counterpoise.io.loader import load_problem
from counterpoise.pipeline import design
from counterpoise.solvers.base import Status

from conftest import PROBLEMS, solved
from counterpoise.robust.result import RobustReport

RESERVE = 0.4 * 0.05 / (2 * 0.95)  # m at each end: (0.4/0.95 − 0.4)/2
SPAN = 0.4 - 2 * RESERVE
M_C = 6 * 0.8 / SPAN


@pytest.fixture(scope="module")
def jib():
    return solved("camera_jib_robust")


def _values(result) -> dict[str, float]:
    return {(slot.variable, slot.scenario): v for slot, v in result.solution.values.items()}


def test_jib_is_tunable_at_every_camera_with_travel_reserved(jib):
    assert jib.optimal, jib.message
    report = jib.solution.extra(RobustReport)
    assert report.tuning_status == "balanced"
    assert len(report.corners) == 1 + 2**3  # rate, boom mass, counterweight mass
    assert all(c.after <= 1e-8 for c in report.corners)
    v = _values(jib)
    assert v[("M_c", None)] == pytest.approx(M_C, rel=1e-6)
    assert v[("x", "camera_2kg")] == pytest.approx(RESERVE, rel=1e-6)
    assert v[("x", "camera_5kg")] == pytest.approx(0.2, rel=1e-6)
    assert v[("x", "camera_8kg")] == pytest.approx(0.4 - RESERVE, rel=1e-6)
    assert v[("k", None)] == pytest.approx((2 * 0.8 + 2.5 * 0.25 - M_C * RESERVE) * 9.81 / (0.08 * 0.15), rel=1e-6)
    assert "travel reserved for tuning: x 10.53 mm at its lower end and 10.53 mm at its upper end" in jib.message
    # every corner's settings: the screw once, the slide per camera, within the slide
    for c in report.corners:
        settings = dict(c.settings)
        assert 0.04 <= settings["h"] <= 0.12
        assert all(0 <= settings[f"x@camera_{m}kg"] <= 0.4 + 1e-12 for m in (2, 5, 8))
        assert settings["x@camera_5kg"] == pytest.approx(0.2, rel=1e-9)  # tuned at 5 kg with the slide at the design's
    nominal = next(c for c in report.corners if set(c.signs) == {0})
    assert dict(nominal.settings)["h"] == pytest.approx(0.08, rel=1e-9)  # the factory setting balances the nominal jib


def test_jib_with_a_short_screw_names_the_camera_and_the_limit(tmp_path):
    """A screw of 75-85 mm cannot take the corner (rate −10 %, boom +5 %, counterweight −5 %):
    infeasible, the corner, the camera and the limits named."""
    text = (PROBLEMS / "camera_jib_robust.toml").read_text(encoding="utf-8")
    old = '[variables.h]\nlower = "40 mm"\nupper = "120 mm"'
    assert old in text
    path = tmp_path / "jib.toml"
    path.write_text(text.replace(old, '[variables.h]\nlower = "75 mm"\nupper = "85 mm"'), encoding="utf-8")
    result = design(load_problem(path))
    assert result.status is Status.INFEASIBLE
    assert "tuning infeasible: corner corner_mpm (rate lift -10 %, mass boom +5 %, mass cw -5 %) at camera = " in result.message
    assert "h at its upper bound 85 mm" in result.message


def test_a_robust_mode_with_a_payload_range_is_not_combinable(tmp_path):
    text = (PROBLEMS / "camera_jib_robust.toml").read_text(encoding="utf-8").replace('[robust]\n', '[robust]\nmode = "limit"\nlimit = 0.05\n')
    path = tmp_path / "jib_limit.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ProblemFileError) as error:
        load_problem(path)
    assert error.value.key == "robust.mode"
    assert "not combinable yet" in error.value.message
