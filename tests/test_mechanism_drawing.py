"""The kinematic sketch (plots/mechanism.py) and ``frames``/``draw`` (cli/mechanism.py).

- A closed loop is assembled in every pose drawn.
- The drawing tells the truth: spring forces from the solved design's parts, in
  ``mechanism.png`` (the labels' values) and in ``frames --design`` (issue 21, part 3); before
  a solve both say that they show the file's initial values.
- Labels do not overlap and stay inside their axes; parallelograms are drawn; a side view
  only where the mechanism leaves its plane.
- A bare ``--at`` angle is an error that says how to write it (issue 24, item 6).
"""

from __future__ import annotations

import csv
import io
import math
import re

import numpy as np
import pytest

from conftest import PROBLEMS, solved

from counterpoise import load_problem
from counterpoise.mechanics.closure import closure, scenario_base
from counterpoise.plots.mechanism import _loop_segments, _poses

LAMP = PROBLEMS / "lamp_catalogue.toml"


def test_every_pose_of_a_four_bar_is_assembled():
    problem = load_problem(PROBLEMS / "fourbar_springs.toml")
    main, ghosts = _poses(problem, None)
    c = closure(problem, "fourbar", scenario_base(problem, problem.scenarios[0].name))
    # the crank turns through its full circle: drawn at three quarter points, not at 0 and 360 deg twice
    assert sorted(round(math.degrees(g["theta2"])) for g in ghosts) == [90, 180, 270]
    for pose in [main, *ghosts]:
        q = np.array([[pose[name] for name in c.names]])
        assert np.abs(c.gaps(q)).max() <= 1e-9
        for _, a, _, b in _loop_segments(problem, pose, {v.name: v.initial for v in problem.variables}):
            assert np.linalg.norm(a - b) <= 1e-9  # the two half-links meet at the opened joint


def test_frames_at_a_crank_angle_solve_the_loop_and_refuse_a_dependent_coordinate():
    from counterpoise.cli.mechanism import AtError, parse_at

    problem = load_problem(PROBLEMS / "fourbar_counter_mass.toml")
    coordinates, variables = parse_at(problem, ["theta2=90 deg"])
    assert coordinates["theta2"] == pytest.approx(math.pi / 2)
    for _, a, _, b in _loop_segments(problem, coordinates, variables):
        assert np.linalg.norm(a - b) <= 1e-9
    with pytest.raises(AtError, match="'theta3' is a dependent coordinate of a closed loop"):
        parse_at(problem, ["theta3=10 deg"])


# -- the lamp: forces of the chosen parts --------------------------------------------------


@pytest.fixture(scope="module")
def lamp(tmp_path_factory):
    """The lamp solved once, its reports written as ``solve --plot`` writes them (the
    drawing through the same function), and the drawing's values kept."""
    from counterpoise.plots.mechanism import design_drawing
    from counterpoise.report.files import write_reports

    result = solved("lamp_catalogue")
    assert result.optimal, result.message
    out = tmp_path_factory.mktemp("lamp")
    drawings = []
    folder = write_reports(result, out, lambda f: drawings.append(design_drawing(result, f)))
    return result, folder, drawings[0]


def _csv(path):
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def _home_forces(folder):
    """Each spring's force at home from springs.csv and design.csv alone.

    A pulley-mounted spring pulls k·d (a pin of the pulley's radius on a bracket that keeps
    its orientation: exactly), so springs.csv's max_force_N / max_distance_mm is the part's
    rate k (and min_force_N / min_distance_mm the same). The distance at home follows from
    the lamp's geometry (problems/lamp_catalogue.toml, home q_lower = 65 deg, q_upper = 0):
    the lower spring's pulley is h_1 = 60 mm above the shoulder pivot and its pin c_1 above
    the elbow, on the elbow bracket (the base's axes), 350 mm along the arm, so
    d = |(350 cos 65°, 350 sin 65° + c_1 − 60)|; the upper spring's pulley is h_2 = 50 mm above
    the elbow and its pin c_2 above the head bracket's pivot, the upper arm horizontal (320 mm),
    so d = |(320, c_2 − 50)|.
    """
    design = {r["name"]: float(r["value"]) for r in _csv(folder / "design.csv") if r["kind"] == "variable"}
    c1, c2 = design["c_1"], design["c_2"]
    home = math.radians(65)
    distance = {"lower": math.hypot(350 * math.cos(home), 350 * math.sin(home) + c1 - 60.0), "upper": math.hypot(320.0, c2 - 50.0)}
    out = {}
    for row in _csv(folder / "springs.csv"):
        if row["kind"] != "spring":
            continue
        rate = float(row["max_force_N"]) / float(row["max_distance_mm"])
        assert float(row["min_force_N"]) / float(row["min_distance_mm"]) == pytest.approx(rate, rel=1e-9)
        out[row["spring"]] = rate * distance[row["spring"]]
    return out


def test_lamp_drawing_shows_the_forces_of_the_chosen_parts(lamp):
    """Acceptance (issue 21): the forces in mechanism.png equal springs.csv at home to 0.1 %."""
    _, folder, drawing = lamp
    expected = _home_forces(folder)
    assert set(drawing.forces) == set(expected) == {"lower", "upper"}
    for name, force in expected.items():
        assert drawing.forces[name] == pytest.approx(force, rel=1e-3)
        (label,) = [lb for lb in drawing.labels if lb.kind == "spring" and name in lb.names]
        assert label.values[label.names.index(name)] == pytest.approx(force, rel=1e-3)
        shown = float(re.search(rf"{name} ([0-9.]+) N", label.text).group(1))
        assert shown == pytest.approx(force, rel=1e-3)
    assert drawing.path.name == "mechanism.png" and (folder / "mechanism.png").read_bytes()[:4] == b"\x89PNG"  # written aside, then moved in


def test_frames_after_a_solve_shows_the_forces_of_the_chosen_parts(lamp, capsys):
    """Acceptance (issue 21): ``frames --design`` equals springs.csv at home to 0.1 %."""
    from counterpoise.cli import main

    _, folder, _ = lamp
    expected = _home_forces(folder)
    with pytest.raises(SystemExit) as exited:
        main(["frames", str(LAMP), "--design", str(folder), "--csv"])
    assert exited.value.code == 0
    captured = capsys.readouterr()
    rows = list(csv.DictReader(io.StringIO(captured.out)))
    for name, force in expected.items():
        for end in ("from", "to"):
            (row,) = [r for r in rows if r["name"] == f"{name}.{end}"]
            assert float(row["force_N"]) == pytest.approx(force, rel=1e-3)
    assert "CP-EXT-" in captured.err  # the line saying which design it shows names the parts


def test_draw_with_a_design_folder_draws_the_same_forces(lamp, tmp_path):
    from counterpoise.cli.mechanism import draw

    _, folder, drawing = lamp
    again = draw(load_problem(LAMP), None, tmp_path, folder)
    assert again.forces == pytest.approx(drawing.forces, rel=1e-9)
    assert again.path == tmp_path / "lamp_catalogue" / "mechanism.png"


def test_before_a_solve_frames_and_draw_say_they_show_the_initial_values(tmp_path, capsys):
    """No part is chosen before a solve: the slot springs have no force (not a placeholder)."""
    from counterpoise.cli import main
    from counterpoise.cli.mechanism import draw

    with pytest.raises(SystemExit) as exited:
        main(["frames", str(LAMP), "--csv"])
    assert exited.value.code == 0
    captured = capsys.readouterr()
    assert "the file's initial values" in captured.err
    springs = [r for r in csv.DictReader(io.StringIO(captured.out)) if r["kind"] == "spring"]
    assert len(springs) == 4 and all(r["force_N"] == "" for r in springs)
    with pytest.raises(SystemExit) as exited:
        main(["frames", str(LAMP)])
    assert exited.value.code == 0
    assert "the file's initial values" in " ".join(capsys.readouterr().out.split())
    drawing = draw(load_problem(LAMP), None, tmp_path)
    assert all(math.isnan(f) for f in drawing.forces.values())
    assert {lb.text for lb in drawing.labels if lb.kind == "spring"} == {"lower: part not chosen", "upper: part not chosen"}


def test_a_spring_with_a_given_rate_shows_its_force_before_a_solve(tmp_path):
    """fourbar_springs: the rates are design variables, so before a solve the drawing shows the
    file's initial rate, k_crank = 100 N/m. The crank spring runs from (0, h = 100 mm) to the
    crank at r = 60 mm from O2; at home (theta2 = 0) d = sqrt(60² + 100²) mm = 116.62 mm, so it
    pulls 100 N/m × 0.11662 m = 11.662 N."""
    from counterpoise.cli.mechanism import draw

    drawing = draw(load_problem(PROBLEMS / "fourbar_springs.toml"), None, tmp_path)
    assert drawing.forces["crank_spring"] == pytest.approx(100.0 * math.hypot(0.060, 0.100), rel=1e-9)
    (label,) = [lb for lb in drawing.labels if "crank_spring" in lb.names]
    assert label.text == "crank_spring 11.66 N"


# -- labels, parallelograms, views ------------------------------------------------------------


def _assert_labels_apart_and_inside(drawing):
    views = list(drawing.views)
    for i, a in enumerate(drawing.labels):
        frame = drawing.axes[views.index(a.view)]
        x0, y0, x1, y1 = a.box
        assert frame[0] <= x0 < x1 <= frame[2] and frame[1] <= y0 < y1 <= frame[3], (a.text, a.box, frame)
        for b in drawing.labels[i + 1 :]:
            if b.view != a.view:
                continue
            apart = a.box[2] <= b.box[0] or b.box[2] <= a.box[0] or a.box[3] <= b.box[1] or b.box[3] <= a.box[1]
            assert apart, (a.text, a.box, b.text, b.box)


@pytest.mark.parametrize("name", ["ur5_shoulder_elbow", "fourbar_springs"])
def test_labels_do_not_overlap_and_stay_inside(name, tmp_path):
    from counterpoise.cli.mechanism import draw

    drawing = draw(load_problem(PROBLEMS / f"{name}.toml"), None, tmp_path)
    _assert_labels_apart_and_inside(drawing)
    values = [lb for lb in drawing.labels if lb.kind != "frame"]
    assert values, "springs and counter-masses are labelled"


def test_holder_drawing_shows_forces_within_the_parts_range(tmp_path):
    """yasir2019_hybrid_catalogue (issue 21): the drawing labelled its springs 183 N, a
    placeholder rate, where springs.csv says 26.9-48.3 N over the workspace. Home lies in the
    workspace, so each drawn force lies within its spring's [min_force_N, max_force_N]."""
    from counterpoise.plots.mechanism import design_drawing
    from counterpoise.realisation.report import springs_rows

    result = solved("yasir2019_hybrid_catalogue")
    drawing = design_drawing(result, tmp_path)
    rows = [r for r in springs_rows(result) if r["kind"] == "spring"]
    assert {r["spring"] for r in rows} == set(drawing.forces) == {"left", "right", "middle"}
    for r in rows:
        assert r["min_force_N"] * (1 - 1e-9) <= drawing.forces[r["spring"]] <= r["max_force_N"] * (1 + 1e-9)
    _assert_labels_apart_and_inside(drawing)


def test_lamp_labels_do_not_overlap_and_none_is_left_out(lamp):
    _, _, drawing = lamp
    _assert_labels_apart_and_inside(drawing)
    assert drawing.omitted == ()
    assert drawing.views == ("plane of motion",)  # planar: no side view


def test_parallelograms_of_reference_links_are_drawn():
    """The lamp: the lower parallelogram's joints are the shoulder pivot (base_height = 60 mm
    above the ground) and the elbow (L_1 = 350 mm along the arm at 65 deg); the upper's the
    elbow and the head bracket (L_2 = 320 mm further, horizontal). The second bar is offset
    by a tenth of the first bar (35 and 32 mm) along an axis of the base (x or y)."""
    from counterpoise.mechanics.poses import default_values
    from counterpoise.plots.mechanism import _joint_frames, _joint_positions, _parallelograms, scenario_with

    problem = load_problem(LAMP)
    coordinates, variables = default_values(problem)
    scenario = scenario_with(problem, None)
    joints = _joint_positions(problem, _joint_frames(problem), coordinates, variables, scenario)
    bars = _parallelograms(problem, coordinates, variables, scenario, joints, np.array([0.0, 0.0, 1.0]))
    assert len(bars) == 2
    q = math.radians(65)
    shoulder = np.array([0.0, 0.060, 0.0])
    elbow = shoulder + 0.350 * np.array([math.cos(q), math.sin(q), 0.0])
    head = elbow + np.array([0.320, 0.0, 0.0])
    (lower, lower_offset), (upper, upper_offset) = bars
    assert np.allclose(lower, [shoulder, elbow], atol=1e-12) and np.allclose(upper, [elbow, head], atol=1e-12)
    assert sorted(np.abs(lower_offset)) == pytest.approx([0.0, 0.0, 0.035])
    assert sorted(np.abs(upper_offset)) == pytest.approx([0.0, 0.0, 0.032])
    assert np.linalg.norm(np.cross(lower_offset, [0.0, 0.0, 1.0])) > 0  # in the plane of motion
    ur5 = load_problem(PROBLEMS / "ur5_shoulder_elbow.toml")
    coordinates, variables = default_values(ur5)
    joints = _joint_positions(ur5, _joint_frames(ur5), coordinates, variables)
    assert len(_parallelograms(ur5, coordinates, variables, scenario_with(ur5, None), joints, None)) == 1


def test_a_side_view_only_where_the_mechanism_leaves_its_plane():
    from counterpoise.mechanics.poses import place
    from counterpoise.plots.mechanism import _basis, _views

    for name, count in (("lamp_catalogue", 1), ("ur5_shoulder_elbow", 1), ("spherical_chain_3r", 3)):
        problem = load_problem(PROBLEMS / f"{name}.toml")
        main, ghosts = _poses(problem, None)
        initial = {v.name: v.initial for v in problem.variables}
        clouds = [np.array([p.position for p in place(problem, pose, initial)]) for pose in [main, *ghosts]]
        assert len(_views(*_basis(problem, clouds))) == count, name


# -- bad input ---------------------------------------------------------------------------------


@pytest.mark.parametrize("command", ["frames", "draw"])
def test_a_bare_at_angle_is_an_error_that_says_how_to_write_it(command, tmp_path, capsys):
    """Issue 24, item 6: '--at q_upper=90' was taken as 90 rad (5156.62 deg)."""
    from counterpoise.cli import main

    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exited:
        main([command, str(LAMP), "--at", "q_upper=90", *(["--out", str(out)] if command == "draw" else [])])
    assert exited.value.code == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith(f"{LAMP}: --at q_upper=90: ") and "write '90 deg' or '1.5708 rad'" in lines[0]
    assert captured.out == "" and not out.exists()


def test_a_bare_zero_and_a_bare_number_for_a_length_keep_their_meaning():
    """A bare 0 is 0 rad for an angle (as in --vary); a bare number for a length stays an error."""
    from counterpoise.cli.mechanism import AtError, parse_at

    problem = load_problem(LAMP)
    coordinates, _ = parse_at(problem, ["q_upper=0"])
    assert coordinates["q_upper"] == 0.0
    with pytest.raises(AtError, match="expected a length, got dimensionless"):
        parse_at(problem, ["c_1=120"])


def test_a_design_folder_of_another_problem_or_none_is_one_line_exit_2(lamp, tmp_path, capsys):
    from counterpoise.cli import main

    _, folder, _ = lamp
    for args, fragment in (
        (["frames", str(PROBLEMS / "fourbar_springs.toml"), "--design", str(folder)], "holds a design of problem 'lamp_catalogue'"),
        (["draw", str(LAMP), "--design", str(tmp_path), "--out", str(tmp_path / "out")], "no design.csv there"),
    ):
        with pytest.raises(SystemExit) as exited:
            main(args)
        assert exited.value.code == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and fragment in lines[0], lines
    assert not (tmp_path / "out").exists()
