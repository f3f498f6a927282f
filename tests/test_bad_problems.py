"""Invalid problem files are rejected with one line naming the file and the key.

Every file in ``tests/bad_problems/`` is a copy of ``problems/yasir2019_counter_mass.toml``
with ONE defect, described in its first (comment) line. :data:`MANIFEST` says, for each
file, which dotted key the error must name and a fragment of the message; a file without
an entry fails :func:`test_manifest_lists_every_file`.

Through the command line (``counterpoise solve FILE --out DIR``) each file must give exit
status 2, exactly one line on stderr per error -- ``<file>: <key>: <message>`` -- no
traceback and nothing written. Most files have one error; an entry's ``also`` lists the
further lines of a file with several (every error of a file is reported). The same expectations are checked in-process on
:func:`counterpoise.loader.load_problem`, and the expression whitelist is tested directly.

Entries with a ``bug`` are known defects of ``src/`` (an invalid file accepted, a stray
warning on stderr, a malformed key). Their tests are ``xfail(strict=True)``: when the bug
is fixed they XPASS and fail, so the ``bug`` note must be removed (and the expectation
checked) together with the fix.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any, NamedTuple

import pytest

from conftest import run_cli
from counterpoise.model import expr as ex
from counterpoise.errors import ExpressionError, ProblemFileError
from counterpoise.io.loader import load_problem

HERE = Path(__file__).resolve().parent
BAD = HERE / "bad_problems"
GOOD = HERE.parent / "problems" / "yasir2019_counter_mass.toml"
CLI = Path(sys.executable).with_name("counterpoise")


class Expect(NamedTuple):
    key: str  # dotted key the error line must name
    fragment: str  # must occur in the message
    bug: str = ""  # non-empty: known src bug, tests are xfail(strict=True)
    also: tuple[tuple[str, str], ...] = ()  # (key, fragment) of the further error lines, in order

    @property
    def lines(self) -> list[tuple[str, str]]:
        return [(self.key, self.fragment), *self.also]


MANIFEST: dict[str, Expect] = {
    # TOML and file level
    "toml_syntax_error.toml": Expect("line 17", "TOML syntax error: Unclosed inline table"),
    "toml_duplicate_table.toml": Expect("line 53", "TOML syntax error: Cannot declare ('variables', 'M_a') twice"),
    "not_utf8.toml": Expect("file", "not UTF-8 text"),
    "toml_nested_too_deeply.toml": Expect("toml", "TOML syntax error: arrays or tables nested too deeply"),
    # shape (schema)
    "missing_gravity_section.toml": Expect("gravity", "missing required key"),
    "unknown_key_typo_descripton.toml": Expect("parameters.r_a.descripton", "unknown key (did you mean 'description'?)"),
    # the unknown key is reported, with the required key it probably meant
    "unknown_key_typo_uper.toml": Expect("variables.M_a.uper", "unknown key (did you mean 'upper'?)"),
    "nan_value.toml": Expect("parameters.r_a.value", "value must be finite, got nan"),
    "inf_value.toml": Expect("bodies.tip.com.1", "value must be finite, got inf"),
    # units and dimensions
    "unknown_unit_mmm.toml": Expect("parameters.r_a", "unknown unit 'mmm'"),
    "mass_in_mm.toml": Expect("bodies.tip.mass", "expected a mass, got a length ('400 mm')"),
    "spring_stiffness_as_mass.toml": Expect(
        "springs.s_a.stiffness", "expected a stiffness (force per length), got a mass ('2 kg')"
    ),
    "gravity_wrong_dimension.toml": Expect("gravity.acceleration", "expected an acceleration, got a quantity of dimension [length] / [time]"),
    "report_unit_mismatch.toml": Expect(
        "report.added_mass_leg.unit", "'M_a + M_b + M_c' is a mass but the unit 'mm' is a length"
    ),
    # signs and bounds
    "negative_body_mass.toml": Expect("bodies.tip.mass", "a mass must not be negative, got '-400 g'"),
    "variable_lower_above_upper.toml": Expect("variables.M_a", "lower bound 30 kg is greater than upper bound 20 kg"),
    "coordinate_empty_range.toml": Expect(
        "subsystems.leg.coordinates.theta_a.range", "empty range [57.2 deg, 57.2 deg]"
    ),
    # names
    "unknown_name_in_expression.toml": Expect(
        "counter_masses.M_a.position.0", "unknown name 'b_aa' in '-b_aa' (did you mean 'b_a'?)"
    ),
    "duplicate_name_parameter_and_variable.toml": Expect("variables.M_a", "name 'M_a' is already used by parameters.M_a"),
    "reserved_name_pi.toml": Expect("parameters.pi", "'pi' is reserved"),
    # forbidden expressions
    "expr_dunder_import.toml": Expect("bodies.tip.com.0", "function '__import__' is not allowed"),
    "expr_attribute_access.toml": Expect(
        "frames.link_b.transforms.0.translate.0", "attribute access not allowed in 'r_a.real'"
    ),
    "expr_lambda.toml": Expect("report.added_mass_leg.expression", "lambda not allowed"),
    "expr_list_comprehension.toml": Expect("counter_masses.M_b.mass", "comprehensions not allowed"),
    # frame graph
    "frame_unknown_parent.toml": Expect("frames.link_c.parent", "unknown frame 'link_bb' (did you mean 'link_b'?)"),
    "frame_cyclic_parents.toml": Expect("frames.link_a.parent", "cyclic definition: link_a -> link_c -> link_b -> link_a"),
    "frame_named_ground.toml": Expect("frames.ground", "'ground' is the fixed world frame and cannot be declared"),
    # values that are not finite or negative only once evaluated
    "nonfinite_mass_expression.toml": Expect("bodies.tip.mass", "'m_c * 1e300 * 1e300' does not evaluate to a finite number"),
    "nan_mass_expression.toml": Expect("bodies.tip.mass", "'m_c * sqrt(-1)' does not evaluate to a finite number"),
    "negative_counter_mass_expression.toml": Expect(
        "counter_masses.M_a.mass", "a mass must not be negative, got '-M_a' at the initial design"
    ),
    # names and literals the schema rejects
    "invalid_parameter_name.toml": Expect("parameters.r-a", "invalid name 'r-a'"),
    "unknown_rotation_axis.toml": Expect("frames.link_a.transforms.0.rotate", "expected one of 'x', 'y' or 'z', got 'w'"),
    # numbers too large for a float (Python integers have no limit)
    "big_integer_in_expression.toml": Expect("bodies.tip.mass", "number too large in 'm_c * 1111"),
    "big_integer_value.toml": Expect("parameters.b_a.value", "number too large (400 digits)"),
    "variable_span_overflows.toml": Expect("variables.M_b", "the bounds -1e308 kg and 1e308 kg are too far apart (their difference overflows)"),
    "bound_overflows_in_si.toml": Expect("variables.M_a.upper", "value must be finite, got '1e308 t' (too large once converted to SI units)"),
    # objective weights: finite, and a zero still has to have the right dimension
    "mass_weight_inf.toml": Expect("objective.mass_weight", "must be a finite number, got 'inf'"),
    "mass_weight_nan.toml": Expect("objective.mass_weight", "must be a finite number, got 'nan'"),
    "mass_weight_too_large.toml": Expect("objective.mass_weight", "'1e+308' is too large: weights above 1e+12 (SI) overflow"),
    "inertia_weight_zero_acceleration.toml": Expect(
        "objective.inertia_weight", "expected an inverse area (1/length^2), got an acceleration ('0 m/s^2')"
    ),
    # text Python would read differently from what is written
    "expr_non_ascii_name.toml": Expect(
        "bodies.tip.mass", "non-ASCII character '\uff4d' (U+FF4D) in '\uff4d_c': names use ASCII letters, digits and '_'"
    ),
    "expr_comment_hash.toml": Expect("bodies.tip.mass", "'#' is not allowed in 'm_c # * 2'"),
    # what an error line echoes is capped (see test_error_lines_are_short)
    "long_unit_echo.toml": Expect("parameters.r_a", "unknown unit 'mmmmmmmmmm"),
    # finite at the initial design is not enough: the NLP samples the whole box of bounds
    "nan_on_variable_box.toml": Expect(
        "counter_masses.M_a.mass", "'M_a * sqrt(x - 0.5)' is not a finite number everywhere within the bounds: nan at M_a = 0 g, x = 0"
    ),
    # spatial mechanisms, working modes, substitution (issue 6)
    "rotation_zero_axis.toml": Expect("frames.link_a.transforms.0.rotate", "the rotation axis must not be the zero vector"),
    "gravity_zero_direction.toml": Expect("gravity.direction", "must be a non-zero vector"),
    # a tilting base (issue 23)
    "tilt_bare_angles.toml": Expect("gravity.tilt[0].range", "bare numbers used as an angle: write ['-15 deg', '15 deg']"),
    # issue 32 item 9: 3^n scenarios had no cap (10 axes ran minutes, 20 a MemoryError)
    "tilt_too_many_scenarios.toml": Expect(
        "gravity.tilt", "5 tilt ranges give 3^5 = 243 tilt nodes: 243 balance scenarios, more than the 81 designed at once (MAX_SCENARIOS"
    ),
    "tilt_zero_axis.toml": Expect("gravity.tilt[1].axis", "must be a non-zero vector"),
    "scenario_unknown_parameter.toml": Expect("scenarios.long.parameters.r_aa", "unknown parameter 'r_aa' (did you mean 'r_a'?)"),
    "substitution_impossible.toml": Expect(
        "substitutions.tip", "no substitution exists for body 'tip': its centre of mass must lie on the line through the two points"
    ),
    "substitution_not_coincident.toml": Expect(
        "substitutions.tip.points.at_end",
        "substitution point 'at_end' does not coincide with the point of frame 'link_c' that receives it: at home they are 10 mm apart",
    ),
    "dh_row_missing_theta.toml": Expect("frames.link_c.transforms.0.dh.theta", "missing required key"),
    "coupled_unknown_coordinate.toml": Expect("subsystems.leg.coupled.phi_c", "unknown name 'theta_d' in 'theta_c - theta_d'"),
    # payload ranges and adjustments (docs/payload.md)
    "payload_range_reversed.toml": Expect("payloads.tool.range", "lower end 122 g is greater than upper end 0 g"),
    "payload_without_frame.toml": Expect("payloads.tool.frame", "missing required key"),
    "payload_range_in_mm.toml": Expect("payloads.tool.range", "expected a mass, got a length ('0 mm')"),
    "two_payloads.toml": Expect("payloads.camera", "only one payload range per problem is supported"),
    "max_payload_range_without_payload.toml": Expect("objective", "max_payload_range needs a payload range"),
    "travel_exceeds_bounds.toml": Expect("variables.M_c.travel", "travel 30 kg exceeds the span of the bounds [0 g, 20 kg]"),
    "travel_not_adjustable.toml": Expect("variables.M_c.travel", "only an adjustable variable has a travel (add adjustable = true)"),
    # spring catalogues and slots (the CSV files are in bad_problems/catalogues/)
    "catalogue_negative_rate.toml": Expect(
        "catalogues.parts.file", "negative_rate.csv: row 2 (line 3), column rate_N_per_m: the rate must be positive, got -500 N/m"
    ),
    "catalogue_max_length_below_free_length.toml": Expect(
        "catalogues.parts.file",
        "max_length_below_free_length.csv: row 3 (line 4), column max_length_m: the maximum length 0.06 m must be above the free length 0.08 m",
    ),
    # issue 32 item 15: a column named twice was read from one of them without a word
    "catalogue_duplicate_header.toml": Expect(
        "catalogues.parts.file", "duplicate_header.csv: header: column 'rate_N_per_m' appears twice (columns 2, 10)"
    ),
    "slot_unknown_catalogue.toml": Expect("slots.s.catalogue", "unknown catalogue 'shop'"),
    "spring_slot_and_stiffness.toml": Expect("springs.s.slot", "give either a stiffness or a slot"),
    # the design options of a free-stiffness spring (docs/springs.md)
    "spring_design_unknown_material.toml": Expect("springs.s_a.material", "unknown spring material 'unobtainium'"),
    "spring_design_outer_diameter_not_a_length.toml": Expect("springs.s_a.max_outer_diameter", "expected a length"),
    "spring_design_safety_factor_below_one.toml": Expect("springs.s_a.min_safety_factor", "greater than or equal to 1"),
    "spring_design_slack_margin_negative.toml": Expect("springs.s_a.slack_margin", "must be a length ≥ 0, got '-2 mm'"),
    "spring_design_slack_margin_not_a_length.toml": Expect("springs.s_a.slack_margin", "expected a length"),
    "spring_design_max_length_not_a_length.toml": Expect("springs.s_a.max_length", "expected a length"),
    "spring_design_max_length_zero.toml": Expect("springs.s_a.max_length", "must be a positive length, got '0 mm'"),
    "slot_count_min_above_max.toml": Expect("slots.s.count", "min 3 is greater than max 2"),
    "slot_tolerance_above_100_percent.toml": Expect("slots.s.rate_tolerance", "a tolerance must be between 0 and 100 %, got '150 %'"),
    "catalogue_units_si_on_n_mm.toml": Expect(
        "catalogues.parts.units",
        "in_n_mm.csv: not plausible for extension springs read in SI units: column rate_N_per_m: median 0.52 N/m "
        "(expected 1 N/m to 1000 N/mm); column free_length_m: median 30 m (expected 1 mm to 1 m); "
        'the values are most plausible in N-mm units: set units = "N-mm"',
    ),
    # no diameter columns: the rates, lengths and loads alone are checked (issue 24). The file
    # holds 15 parts of the shipped catalogue (25-100 mm free length) written in lbf/in, in and
    # lbf. Read as N-mm, a force per area is 25.4² / 4.448 = 145 times its true value; 4.16 and
    # 3.64 are the medians of the file's numbers rate / free length and max load / free length²
    "catalogue_inch_read_as_n_mm.toml": Expect(
        "catalogues.parts.units",
        "inch_without_diameters.csv: not plausible for extension springs read in N-mm units: rate / free length "
        "(columns rate_lbf_per_in, free_length_in): median 4.16 N/mm² (expected 5e-05 to 3 N/mm²); max load / free length² "
        '(columns max_load_lbf, free_length_in): median 3.64 N/mm² (expected 1e-04 to 3 N/mm²); the values are most plausible in inch units: set units = "inch"',
    ),
    # issue 32 item 8: two weak springs (0.114 and 0.742 lbf/in, 1.18-8.7 in) in lbf and inch read
    # as N-mm lie in every band (0.097 and 0.30 N/mm² of rate / free length); no steel spring of
    # those rates and lengths carries those loads (catalogue/physics.py; tests/test_catalogue.py
    # checks the relation on the shipped catalogue in every unit system)
    "catalogue_inch_two_parts_read_as_n_mm.toml": Expect(
        "catalogues.parts.units",
        "inch_two_parts.csv: not plausible for extension springs read in N-mm units: no steel spring of these rates and free lengths "
        "(columns rate_lbf_per_in, free_length_in) carries these max loads and initial tensions (columns max_load_lbf, initial_tension_lbf)",
    ),
    # angles: a bare number is not taken as radians without a word (issue 14)
    "angle_bare_number.toml": Expect(
        "frames.link_a.transforms.1.angle", "a bare number used as an angle ('90' would be radians): write '90 deg' or '1.5708 rad'"
    ),
    "angle_bare_range.toml": Expect(
        "subsystems.leg.coordinates.theta_a.range", "bare numbers used as an angle: write ['57.2 deg', '209.7 deg'] or give the unit rad"
    ),
    "angle_bare_added_in_expression.toml": Expect(
        "frames.link_b.transforms.1.angle", "'theta_b + 90' adds the bare number 90 to an angle, which takes it as radians: write '90 deg' or '1.5708 rad'"
    ),
    "angle_bare_in_scenario.toml": Expect(
        "scenarios.tilted.parameters.phi", "a bare number used as an angle (deg elsewhere): write '90 deg' or '1.5708 rad'"
    ),
    "angle_bare_dh_alpha.toml": Expect("frames.link_c.transforms.0.dh.alpha", "a bare number used as an angle ('90' would be radians): write '90 deg'"),
    # issue 24: a length too large to compute with, a name too long for a folder
    "length_out_of_range.toml": Expect(
        "parameters.r_a", "value out of range: '1e308 mm' is 1e+305 m; lengths up to 1e+06 m (1000 km) are accepted"
    ),
    "problem_name_too_long.toml": Expect("problem.name", "too long (300 characters; at most 128, since it names the report folder)"),
    "angle_bare_home.toml": Expect(
        "subsystems.leg.coordinates.theta_a.home", "a bare number used as an angle (deg elsewhere): write '90 deg' or '1.5708 rad'"
    ),
    "expr_unknown_unit.toml": Expect("frames.link_b.transforms.1.angle", "cannot parse 'theta_b + 90 xdeg': unknown unit 'xdeg' (or a missing '*')"),
    # unknown keys: the unknown key itself, with the nearest key its table knows
    "unknown_key_beside_union_tag.toml": Expect("frames.link_b.transforms.0.offset", "unknown key"),
    "unknown_key_typo_angel.toml": Expect("frames.link_b.transforms.1.angel", "unknown key (did you mean 'angle'?)"),
    "unknown_key_typo_transform.toml": Expect("frames.link_a.transform", "unknown key (did you mean 'transforms'?)"),
    "unknown_key_typo_stifness.toml": Expect("springs.s.stifness", "unknown key (did you mean 'stiffness'?)"),
    # design constraints ([constraints.<name>])
    "constraint_unknown_name.toml": Expect("constraints.cap.expression", "unknown name 'M_q' in 'M_a + M_q'"),
    "constraint_function_not_allowed.toml": Expect("constraints.cap.expression", "function 'open' is not allowed"),
    "constraint_bound_dimension.toml": Expect("constraints.cap.upper", "'300 mm' is a length but 'M_a + M_b' is a mass"),
    # issue 32 item 15: a bound without a unit said "expected a quantity such as '135 mm'",
    # also where the expression is dimensionless and a plain number is right ("100" is now read)
    "constraint_bound_plain_number_on_a_mass.toml": Expect(
        "constraints.cap.upper", "'100' is a plain number but 'M_a + M_b' is a mass: give the bound with its unit, such as '100 kg'"
    ),
    "constraint_dimensionless_bound_not_a_number.toml": Expect(
        "constraints.cap.upper", "expected a plain number such as 100 ('M_a / M_b' is dimensionless), got 'a hundred'"
    ),
    "constraint_no_bounds.toml": Expect("constraints.cap", "give lower and/or upper"),
    "constraint_unknown_counter_mass.toml": Expect("constraints.inside.expression", "unknown counter-mass 'M_z' in 'x_home(M_z)'"),
    "constraint_spring_without_springs.toml": Expect("constraints.pull.expression", "unknown spring 'M_a' in 'force_max(M_a)' (the problem has no spring)"),
    "constraint_lower_above_upper.toml": Expect("constraints.cap", "lower 3 kg is greater than upper 2 kg"),
    "constraint_inconsistent_units.toml": Expect("constraints.cap.expression", "inconsistent units in 'M_a + b_a'"),
    "constraint_total_with_argument.toml": Expect("constraints.cap.expression", "added_mass() takes no argument"),
    # [robust]
    "robust_unknown_body.toml": Expect("robust.tolerances.mass.tipp", "unknown body or counter-mass 'tipp' (did you mean 'tip'?)"),
    "robust_limit_missing.toml": Expect("robust.limit", 'mode = "limit" needs a limit'),
    # tolerances and weights out of range (issue 31 part 6, issue 32 item 12)
    "robust_relative_tolerance_100_percent.toml": Expect("robust.tolerances.mass", "a relative tolerance must be below 100 %"),
    "robust_absolute_tolerance_beyond_nominal.toml": Expect(
        "robust.tolerances.mass.tip", "an absolute mass tolerance of '1 kg' is not below the nominal mass (at most 0.4 kg within the bounds)"
    ),
    "robust_absolute_tolerance_counter_mass_beyond_bounds.toml": Expect(
        "robust.tolerances.mass.M_a", "an absolute mass tolerance of '1e308 kg' is not below the nominal mass (at most 20 kg within the bounds)"
    ),
    "robust_weight_too_large.toml": Expect("robust.weight", "'1e308 kg' is too large: weights above 1e+09 kg"),
    "robust_tune_duplicated.toml": Expect("robust.tune.1", "'M_a' is listed twice (first as robust.tune.0)"),
    "robust_com_tolerance_too_large.toml": Expect("robust.tolerances.com.tip", "a com tolerance of '5 m' is beyond 1 m"),
    "robust_pitch_not_a_tune_variable.toml": Expect("robust.pitch.M_b", "'M_b' is not a tune variable"),
    # every error of a file, one line each
    "frame_two_unknown_parents.toml": Expect(
        "frames.link_b.parent",
        "unknown frame 'link_aa' (did you mean 'link_a'?)",
        also=(("frames.link_c.parent", "unknown frame 'link_bb' (did you mean 'link_b'?)"),),
    ),
}

#: Longest error line (after ``<file>: ``) a bad file may produce: echoed input is clipped.
MAX_LINE = 600

VALID = sorted(name for name, e in MANIFEST.items() if not e.bug)


def _params() -> list:
    return [
        pytest.param(name, id=name.removesuffix(".toml"), marks=[pytest.mark.xfail(strict=True, reason=e.bug)] if e.bug else [])
        for name, e in sorted(MANIFEST.items())
    ]


def _run(*args: str, cwd: Path) -> Any:
    """The command line, in process (conftest.run_cli); test_one_bad_file_stops_the_whole_run
    keeps a real process for the exit status of the console script."""
    return run_cli(*args, cwd=cwd)


def _run_process(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}
    return subprocess.run(
        [str(CLI), *args], cwd=cwd, env=env, capture_output=True, text=True, encoding="utf-8", errors="replace", timeout=300
    )


def _assert_no_traceback(text: str) -> None:
    assert "Traceback" not in text and "❱" not in text, text


def _assert_error_line(line: str, path: Path, expect: Expect) -> None:
    prefix = f"{path}: {expect.key}: "
    assert line.startswith(prefix), f"expected {prefix!r}..., got {line!r}"
    assert expect.fragment in line[len(prefix):], f"{expect.fragment!r} not in {line!r}"


# --------------------------------------------------------------------------------------
# The manifest
# --------------------------------------------------------------------------------------


def test_manifest_lists_every_file():
    files = {p.name for p in BAD.iterdir() if p.is_file()}
    assert files == set(MANIFEST), f"unlisted: {sorted(files - set(MANIFEST))}, missing: {sorted(set(MANIFEST) - files)}"
    assert len(files) >= 12
    assert len(VALID) >= 12


@pytest.mark.parametrize("name", sorted(MANIFEST))
def test_file_starts_with_a_comment_saying_what_is_wrong(name):
    first = (BAD / name).read_bytes().split(b"\n", 1)[0].decode("ascii")
    assert first.startswith("# INVALID"), first


def test_good_problem_is_valid():
    """The files are copies of this one; it must load, or every test here proves nothing."""
    assert load_problem(GOOD).name == "yasir2019_counter_mass"


# --------------------------------------------------------------------------------------
# In-process: counterpoise.loader.load_problem
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", _params())
def test_load_problem_names_the_key(name):
    expect = MANIFEST[name]
    path = BAD / name
    with pytest.raises(ProblemFileError) as info:
        load_problem(path)
    err = info.value
    assert err.file == str(path)
    assert err.key == expect.key
    assert expect.fragment in err.message
    errors = getattr(err, "errors", (err,))
    assert len(errors) == len(expect.lines), str(err)
    assert str(err) == "\n".join(f"{path}: {e.key}: {e.message}" for e in errors)
    for e, (key, fragment) in zip(errors, expect.lines):
        assert e.key == key and fragment in e.message, str(e)
        assert "\n" not in str(e)
        assert len(f"{e.key}: {e.message}") <= MAX_LINE, f"{len(str(e))} characters"


# --------------------------------------------------------------------------------------
# Through the command line
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", _params())
def test_solve_rejects_with_one_line(name, tmp_path):
    expect = MANIFEST[name]
    path = BAD / name
    proc = _run("solve", str(path), "--out", str(tmp_path / "out"), cwd=tmp_path)
    _assert_no_traceback(proc.stdout)
    _assert_no_traceback(proc.stderr)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == len(expect.lines) and all(line.strip() for line in lines), proc.stderr
    for line, (key, fragment) in zip(lines, expect.lines):
        _assert_error_line(line, path, Expect(key, fragment))
        assert len(line) <= len(f"{path}: ") + MAX_LINE, f"{len(line)} characters"
    assert list(tmp_path.iterdir()) == [], "nothing may be written for bad input"


def test_validate_rejects_every_file(tmp_path):
    """One run over all files: exit 2 and exactly one line per error, in order."""
    paths = [BAD / name for name in VALID]
    proc = _run("validate", *map(str, paths), cwd=tmp_path)
    _assert_no_traceback(proc.stdout)
    _assert_no_traceback(proc.stderr)
    assert proc.returncode == 2
    assert "ok " not in proc.stdout
    lines = proc.stderr.splitlines()
    expected = [(path, Expect(key, fragment)) for path in paths for key, fragment in MANIFEST[path.name].lines]
    assert len(lines) == len(expected), proc.stderr
    for line, (path, expect) in zip(lines, expected):
        _assert_error_line(line, path, expect)
    assert list(tmp_path.iterdir()) == []


def test_one_bad_file_stops_the_whole_run(tmp_path):
    """A good file followed by a bad one: nothing is solved or written, exit 2."""
    bad = BAD / "negative_body_mass.toml"
    proc = _run_process("solve", str(GOOD), str(bad), "--out", str(tmp_path / "out"), cwd=tmp_path)
    _assert_no_traceback(proc.stdout)
    _assert_no_traceback(proc.stderr)
    assert proc.returncode == 2
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    _assert_error_line(lines[0], bad, MANIFEST[bad.name])
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------------------
# The expression whitelist (counterpoise.expr.parse)
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("__import__('os')", "function '__import__' is not allowed"),
        ("__import__('os').system('true')", "only plain function calls are allowed"),
        ("a.b", "attribute access not allowed"),
        ("lambda: 1", "lambda not allowed"),
        ("[x for x in y]", "comprehensions not allowed"),
        ("(x for x in y)", "comprehensions not allowed"),
        ("a if b else c", "conditional expressions not allowed"),
        ("a < b", "comparisons not allowed"),
        ("a and b", "boolean operators not allowed"),
        ('"s"', "only numbers may appear as constants"),
        ("True", "only numbers may appear as constants"),
        ("f(1)", "function 'f' is not allowed"),
        ("sin(x=1)", "keyword or starred arguments are not allowed"),
        ("sin(*a)", "keyword or starred arguments are not allowed"),
        ("a[0]", "subscripts not allowed"),
        ("(a, b)", "tuples not allowed"),
        ("(a := 1)", "assignment not allowed"),
        ("__builtins__", "names starting with '_' are not allowed"),
        ("a // b", "is not allowed"),
        ("~a", "is not allowed"),
        ("1e999", "value must be finite"),
        ("a +", "cannot parse"),
        ("", "empty expression"),
        ("a + " * 200 + "a", "longer than 500 characters"),
    ],
)
def test_parse_rejects(text, fragment):
    with pytest.raises(ExpressionError) as info:
        ex.parse(text)
    assert fragment in str(info.value)


def test_parse_accepts_whitelisted_expression():
    tree = ex.parse("sin(theta) * r_a + 2**3")
    assert ex.names(tree) == {"theta", "r_a"}
    assert [c.func for c in ex.calls(tree)] == ["sin"]
    value = ex.evaluate(tree, {"theta": 0.5, "r_a": 2.0}, {"sin": math.sin})
    assert value == pytest.approx(math.sin(0.5) * 2.0 + 8.0)
