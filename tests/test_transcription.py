"""No silent transcription mistakes (issue 14): angles, units inside expressions, catalogue
units, problems with nothing to balance, every error of a file reported.

The bad-problem files in ``tests/bad_problems/`` pin the messages through the command
line; this file checks the rules themselves, the values they produce, and what stays
accepted.
"""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path

import pytest

from conftest import PROBLEMS, ROOT, run_cli

from counterpoise.catalogue import mapping_from, read_catalogue
from counterpoise.catalogue.reader import CatalogueUnitsError
from counterpoise.errors import ExpressionError, ProblemFileError, ProblemFileErrors
from counterpoise.formulation.assumptions import degeneracies
from counterpoise.io.loader import load_problem, load_problem_text
from counterpoise.model import expr as ex
from counterpoise.studies.spec import plan_study

YASIR = (PROBLEMS / "yasir2019_counter_mass.toml").read_text(encoding="utf-8")
CLI = Path(sys.executable).with_name("counterpoise")


def _load(*edits: tuple[str, str]):
    text = YASIR
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new, 1)
    return load_problem_text(text, "y.toml")


def _error(*edits: tuple[str, str]) -> ProblemFileError:
    with pytest.raises(ProblemFileError) as info:
        _load(*edits)
    return info.value


def _angle_of(problem, frame: str, index: int) -> ex.Expr:
    return problem.frame[frame].transforms[index].angle


def _rotate_b(text: str) -> tuple[str, str]:
    """Link b's rotation angle replaced by ``text``."""
    return ('angle = "theta_b" }', 'angle = "' + text + '" }')


# -- angles --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("angle", "fragment"),
    [
        ("theta_b + 90", "adds the bare number 90 to an angle"),
        ("theta_b - 1.5708", "write '1.5708 rad' or '90 deg'"),
        ("90 - theta_b", "adds the bare number 90 to an angle"),
        ("theta_b + 2*45", "adds the bare number 90 to an angle"),
        ("theta_b + sin(90)", "sin() of the bare number 90 takes it as radians"),
    ],
)
def test_a_bare_number_added_to_an_angle_is_an_error(angle, fragment):
    err = _error(_rotate_b(angle))
    assert err.key == "frames.link_b.transforms.1.angle" and fragment in err.message


@pytest.mark.parametrize(
    "angle",
    ["theta_b + 90 deg", "-theta_b - 90 deg", "90 deg - theta_b", "theta_b + pi/2", "2*theta_b", "theta_b/2 + 0", "theta_b + 0", "0", "0.5 rad"],
)
def test_angles_written_with_units_or_pi_are_accepted(angle):
    _load(_rotate_b(angle))


def test_a_quantity_inside_an_expression_has_its_si_value():
    p = _load(_rotate_b("-theta_b - 90 deg"))
    tree = _angle_of(p, "link_b", 1)
    assert ex.evaluate(tree, {"theta_b": 0.25}, {}) == pytest.approx(-0.25 - math.pi / 2)
    q = _load(('r_a = { value = "135 mm"', 'r_a = { value = "130 mm + 5 mm"'), ('b_c = { value = "200 mm"', 'b_c = { value = "0.2 m - 0 mm"'))
    values = {par.name: par for par in q.parameters}
    assert ex.evaluate(values["r_a"].expr, {}, {}) == pytest.approx(0.135)
    assert ex.evaluate(values["b_c"].expr, {}, {}) == pytest.approx(0.2)


def test_units_in_an_expression_must_agree():
    err = _error(("com = [\"r_c\", 0, 0]", "com = [\"r_c + 5 g\", 0, 0]"))
    assert err.key == "bodies.tip.com.0" and "inconsistent units in 'r_c + 5 g'" in err.message


def test_parse_without_a_quantity_reader_says_units_are_not_allowed():
    with pytest.raises(ExpressionError, match=r"units are not allowed in this expression \('90 deg'\)"):
        ex.parse("q - 90 deg")
    tree = ex.parse("q - 90 deg", quantity=lambda n, u: n * math.pi / 180 if u == "deg" else None)
    assert ex.evaluate(tree, {"q": 1.0}, {}) == pytest.approx(1.0 - math.pi / 2)
    with pytest.raises(ExpressionError, match="unknown unit 'r' "):
        ex.parse("2 r", quantity=lambda n, u: None)


def test_a_parameter_or_variable_given_as_a_bare_number_is_not_an_angle():
    err = _error(("m_c = {", 'phi = 1.2\nm_c = {'), _rotate_b("theta_b + phi"))
    assert "adds parameters.phi, a bare number, to an angle" in err.message
    err = _error(("m_c = {", 'phi = 1.2\nm_c = {'), _rotate_b("phi"))
    assert err.message == "'phi' uses parameters.phi, a bare number, as an angle: give it a unit there (deg or rad)"
    _load(("m_c = {", 'phi = "1.2 rad"\nratio = 0.5\nm_c = {'), _rotate_b("ratio * theta_b + phi"))


def test_bounds_and_homes_of_angles_need_units():
    err = _error(('coordinates.theta_b = { range = ["-180 deg", "180 deg"]', 'coordinates.theta_b = { range = ["-180 deg", "180 deg"], home = 3'))
    assert err.key == "subsystems.leg.coordinates.theta_b.home" and "write '3 deg' or '0.05236 rad'" in err.message
    err = _error(("[counter_masses.M_a]", '[variables.tilt]\nlower = "0 deg"\nupper = 45\n\n[counter_masses.M_a]'))
    assert err.key == "variables.tilt.upper" and "write '45 deg'" in err.message


def test_a_bare_zero_is_an_angle_in_any_unit():
    p = _load(('range = ["-180 deg", "180 deg"], description = "link b', 'range = [0, "180 deg"], description = "link b'))
    assert p.coordinate["theta_b"].lower == 0.0


def test_study_vary_of_an_angle_needs_a_unit():
    problem = load_problem(PROBLEMS / "spherical_chain_3r.toml")
    with pytest.raises(ProblemFileError) as info:
        plan_study(problem, ["alpha1=0:90:3"], "s.toml")
    assert str(info.value).startswith("s.toml: --vary alpha1: '90' is a bare number used as an angle (alpha1 is in deg): write '90 deg'")
    plan = plan_study(problem, ["alpha1=0:90 deg:3"], "s.toml")
    assert [p["alpha1"] for p in plan.points] == pytest.approx([0.0, math.pi / 4, math.pi / 2])


def test_the_angle_validator_for_other_sections():
    """resolve.quantities.angle(ctx, value, key): what imported robot joints call."""
    import tomllib

    from counterpoise.io.resolve.context import Context
    from counterpoise.io.resolve.quantities import angle
    from counterpoise.io.schema import ProblemFile

    ctx = Context(ProblemFile.model_validate(tomllib.loads(YASIR)), "y.toml")
    assert angle(ctx, "-90 deg", "robot.locked.j") == pytest.approx(-math.pi / 2)
    assert angle(ctx, 0, "robot.locked.j") == 0.0
    with pytest.raises(ProblemFileError, match="robot.locked.j: a bare number used as an angle: write '90 deg' or '1.5708 rad'"):
        angle(ctx, 90, "robot.locked.j")
    with pytest.raises(ProblemFileError, match="expected an angle"):
        angle(ctx, "90 mm", "robot.locked.j")


def test_every_shipped_problem_writes_its_angles_with_units():
    for path in sorted(PROBLEMS.glob("*.toml")):
        load_problem(path)


# -- every error of a file ----------------------------------------------------------------


def test_every_unknown_frame_is_reported():
    err = _error(('frame = "link_c"\nmass = "m_c"', 'frame = "link_cc"\nmass = "m_c"'), ('frame = "link_a"\nmass = "M_a"', 'frame = "link_x"\nmass = "M_a"'))
    assert isinstance(err, ProblemFileErrors)
    assert [e.key for e in err.errors] == ["bodies.tip.frame", "counter_masses.M_a.frame"]
    assert str(err).count("\n") == 1 and str(err).startswith("y.toml: bodies.tip.frame: unknown frame 'link_cc'")


def test_every_schema_error_is_reported_once_per_key():
    err = _error(('{ rotate = "z", angle = "theta_b" }', '{ rotate = "w", angel = "theta_b" }'), ('uper', 'uper') if False else ("upper = \"20 kg\"", "upper = \"20 kg\"\nlowr = 1"))
    assert [e.key for e in err.errors] == ["frames.link_b.transforms.1.rotate", "frames.link_b.transforms.1.angel", "variables.M_a.lowr"]
    assert err.errors[1].message == "unknown key (did you mean 'angle'?)"  # the missing 'angle' is not a line of its own
    assert err.errors[2].message == "unknown key"  # 'lower' is there already


def test_bad_variables_are_all_reported():
    err = _error(('upper = "20 kg"', 'upper = "20 mm"'), ('lower = "0 g"\nupper = "20 kg"', 'lower = "30 kg"\nupper = "20 kg"'))
    assert [e.key for e in err.errors] == ["variables.M_a.upper", "variables.M_b"]


# -- catalogue units ----------------------------------------------------------------------


def _catalogue_in(tmp_path: Path, scale_length: float, scale_rate: float, scale_force: float) -> Path:
    shipped = list(csv.reader((ROOT / "src/counterpoise/data/extension_springs.csv").read_text(encoding="utf-8").splitlines()))
    header, rows = shipped[0], shipped[1:]
    scale = {"rate_N_per_m": scale_rate, "free_length_m": scale_length, "max_length_m": scale_length, "outer_diameter_m": scale_length,
             "wire_diameter_m": scale_length, "initial_tension_N": scale_force, "max_load_N": scale_force}
    out = [header] + [[f"{float(v) * scale[h]:.6g}" if h in scale else v for h, v in zip(header, row)] for row in rows]
    path = tmp_path / "parts.csv"
    path.write_text("\n".join(",".join(r) for r in out) + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("written", "read", "fits"),
    [
        ((1e3, 1e-3, 1.0), "SI", "N-mm"),  # lengths in mm, rates in N/mm
        ((1.0, 1.0, 1.0), "N-mm", "SI"),
        ((1 / 0.0254, 0.0254 / 4.4482216152605, 1 / 4.4482216152605), "SI", "inch"),
    ],
)
def test_a_catalogue_read_in_the_wrong_units_says_which_fit(tmp_path, written, read, fits):
    path = _catalogue_in(tmp_path, *written)
    with pytest.raises(CatalogueUnitsError) as info:
        read_catalogue(path, mapping_from("counterpoise", read))
    assert info.value.key == "units"
    assert f"not plausible for extension springs read in {read} units" in info.value.message
    assert f'most plausible in {fits} units: set units = "{fits}"' in info.value.message
    read_catalogue(path, mapping_from("counterpoise", fits))


def test_shipped_catalogue_is_plausible():
    read_catalogue("shipped")  # the problems' own catalogues: test_every_shipped_problem_writes_its_angles_with_units


# -- nothing to balance ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("edit", "warning"),
    [
        (("direction = [0, -1, 0]", "direction = [0, 0, -1]"), "nothing to balance: the weight of the bodies does no work"),
        (('acceleration = "9.81 m/s^2"', 'acceleration = "0 m/s^2"'), "gravity is zero: there is no weight to balance"),
        (('angle = "theta_c" }', 'angle = "0 deg" }'), "coordinate 'theta_c' drives no frame"),
        (('com = ["r_c", 0, 0]', 'com = [0, 0, "r_c"]'), "coordinate 'theta_c' does not change the weight's energy"),
    ],
)
def test_nothing_to_balance_is_a_warning(edit, warning):
    found = degeneracies(_load(edit))
    assert any(w.startswith(warning) for w in found), found


def test_a_file_cut_short_before_its_frames_has_nothing_to_balance():
    problem = load_problem_text(YASIR[: YASIR.index("[frames.link_a]")], "cut.toml")
    assert degeneracies(problem) == ["nothing to balance: the problem has no bodies (is the file cut short before its frames and bodies?)"]


#: shipped problems whose warning is the point of the file: the leg plane's tilt about a
#: vertical axis does no work (docs/seeds.md#yasir-tilt), and the warning says exactly that
EXPECTED_WARNINGS = {
    "yasir2019_leg_tilt.toml": ["coordinate 'psi' does not change the weight's energy: there is no torque to balance about it"],
}


def test_shipped_problems_have_something_to_balance():
    for path in sorted(PROBLEMS.glob("*.toml")):
        assert degeneracies(load_problem(path)) == EXPECTED_WARNINGS.get(path.name, []), path.name


def test_the_tilted_leg_file_warns_only_while_its_tilt_axis_is_vertical():
    path = PROBLEMS / "yasir2019_leg_tilt.toml"
    assert degeneracies(load_problem(path, overrides={"parameters.beta": "60 deg"})) == []


def test_the_warning_reaches_stderr_and_status_txt(tmp_path, monkeypatch):
    # found once, at load; the report layer writes what the CLI found (issue 19 §4)
    import counterpoise.formulation.assumptions as assumptions

    calls = []
    original = assumptions.degeneracies
    monkeypatch.setattr(assumptions, "degeneracies", lambda problem: calls.append(problem.name) or original(problem))
    path = tmp_path / "flat.toml"
    path.write_text(YASIR.replace("direction = [0, -1, 0]", "direction = [0, 0, -1]"), encoding="utf-8")
    proc = run_cli("solve", str(path), "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert f"{path}: warning: nothing to balance" in proc.stderr
    status = (tmp_path / "out" / "yasir2019_counter_mass" / "status.txt").read_text(encoding="utf-8")
    assert "warning: nothing to balance: the weight of the bodies does no work" in status
    assert calls == ["yasir2019_counter_mass"]


def test_a_report_reads_the_problems_warnings_once_found(monkeypatch):
    """Reports written in code without the warnings (``write_reports(result)``) take the
    problem's degeneracy warnings as found once for that problem, not found again on each
    report (issue 33: the report layer reads what was computed)."""
    import counterpoise.formulation.assumptions as assumptions
    from counterpoise.pipeline import design
    from counterpoise.report.files import report_texts

    calls = []
    original = assumptions.degeneracies
    monkeypatch.setattr(assumptions, "degeneracies", lambda problem: calls.append(problem.name) or original(problem))
    result = design(load_problem_text(YASIR.replace("direction = [0, -1, 0]", "direction = [0, 0, -1]"), "flat.toml"))
    first, again = report_texts(result)["status.txt"], report_texts(result)["status.txt"]
    assert first == again and "warning: nothing to balance" in first
    assert calls == ["yasir2019_counter_mass"]
