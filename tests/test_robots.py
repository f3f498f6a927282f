"""[robot] import, orientation frames, the frames and draw commands, bad robot input.

The independent checks against MuJoCo are in ``test_robots_mujoco.py``; here: the
ProblemBuilder gives the same problem as the file, a mimic joint follows its joint (checked
against yourdfpy's own forward kinematics), an orientation frame keeps the named frame's
axes, rpy splitting round-trips, and every file in ``tests/bad_problems/robots/`` is
rejected with one line naming its key.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from conftest import PROBLEMS, ROOT, run_cli, value

from counterpoise.errors import ProblemFileError
from counterpoise.io.builder import ProblemBuilder, rotate, translate
from counterpoise.io.loader import load_problem, load_problem_text
from counterpoise.io.robot import rpy_from_matrix
from counterpoise.mechanics.poses import mechanics, place
from counterpoise.pipeline import design

BAD = Path(__file__).resolve().parent / "bad_problems" / "robots"
GOOD_ROBOTS = Path(__file__).resolve().parent / "robots"
SEED = 7
TOL = 1e-12

MANIFEST = {
    "robot_missing_file.toml": ("robot.urdf", "no such file"),
    "robot_unknown_joint.toml": ("robot.joints.elbow_jiont", "unknown joint 'elbow_jiont' in ur5.urdf (did you mean 'elbow_joint'?)"),
    "robot_joint_moving_and_locked.toml": ("robot.locked.elbow_joint", "listed both as moving (robot.joints) and as locked"),
    "robot_range_beyond_limits.toml": ("robot.joints.elbow_joint.range", "goes beyond the joint's limits [-180 deg, 180 deg]"),
    "robot_locked_beyond_limits.toml": ("robot.locked.wrist_1_joint", "locked value '-400 deg' goes beyond the joint's limits"),
    "robot_locked_bare_number.toml": ("robot.locked.wrist_1_joint", "an angle needs its unit: write '-90 deg' or '-90 rad'"),
    "robot_fixed_joint_moving.toml": ("robot.joints.tool0_fixed_joint", "a fixed joint: it does not move"),
    "robot_urdf_and_mjcf.toml": ("robot.urdf", "not both"),
    "robot_range_in_mm.toml": ("robot.joints.elbow_joint.range", "expected an angle (revolute joint), got a length"),
    "robot_held_outside_limits.toml": ("robot.locked.wrist", "joint 'wrist' is neither moving nor locked, so it is held at 0, outside its limits in the model"),
    "robot_home_in_mm.toml": ("robot.joints.elbow_joint.home", "expected an angle (revolute joint), got a length ('400 mm')"),
    "robot_frame_named_like_a_link.toml": ("frames.forearm_link", "is a link of the robot model ur5.urdf"),
    "robot_broken_urdf.toml": ("robot.urdf", "cannot read the URDF broken.urdf: Opening and ending tag mismatch"),
    "robot_mjcf_not_mjcf.toml": ("robot.mjcf", "cannot read the MJCF broken.urdf"),
    "frame_unknown_orientation.toml": ("frames.elbow_ref.orientation", "unknown frame 'shoulder_lnk' (did you mean 'shoulder_link'?)"),
    # issue 24: nothing silently wrong in a robot model, and a way round what is not supported
    "robot_negative_link_mass.toml": ("robot.urdf", "negative_mass.urdf: link 'arm' has a mass of -1 kg: a mass must be a finite number, not negative"),
    "robot_negative_inertia.toml": ("robot.urdf", "negative_inertia.urdf: link 'hand' has a negative inertia (principal moments (-0.001, 0.001, 0.001) kg m²)"),
    "robot_nonfinite_origin.toml": ("robot.urdf", "nan_origin.urdf: link 'hand' has a position (joint origin) that is not a finite number"),
    "robot_origin_out_of_range.toml": ("robot.urdf", "huge_origin.urdf: link 'hand' has a position (joint origin) out of range: (1e+300, 0, 0) m; lengths up to 1e+06 m are accepted"),
    "robot_joint_missing_link.toml": ("robot.urdf", "missing_link.urdf: joint 'wrist' names link 'palm', which the model does not declare"),
    "robot_xacro.toml": ("robot.urdf", "arm.urdf.xacro is a xacro file (ROS macros, not plain URDF): expand it into a new file first, `xacro arm.urdf.xacro > arm_expanded.urdf`"),
    # issue 32: named .urdf, the suggestion writes a new file (`> arm_macros.urdf` would empty it)
    "robot_xacro_named_urdf.toml": ("robot.urdf", "arm_macros.urdf is a xacro file (ROS macros, not plain URDF): expand it into a new file first, `xacro arm_macros.urdf > arm_macros_expanded.urdf`, and give arm_macros_expanded.urdf"),
    "robot_mjcf_nan.toml": ("robot.mjcf", "nan_pos.xml: the model contains a 'NaN'"),
    "robot_mjcf_free_joint.toml": ("robot.mjcf", "joint 'float' of body 'base' is a free joint (a floating body); only hinge and slide joints are supported: in a copy of the model, delete <freejoint/>"),
    "robot_urdf_floating_joint.toml": ("robot.urdf", "joint 'float' is of type 'floating'; only revolute, continuous, prismatic, fixed joints are supported: in a copy of the model, give it type=\"fixed\""),
    "robot_hyphenated_joint.toml": ("robot.joints.shoulder-joint", "rename the joint in a copy of the model, e.g. sed 's/\"shoulder-joint\"/\"shoulder_joint\"/g' hyphenated.urdf"),
}


def test_manifest_lists_every_robot_file():
    assert {p.name for p in BAD.glob("*.toml")} == set(MANIFEST)


@pytest.mark.parametrize("name", sorted(MANIFEST))
def test_bad_robot_input_names_the_key(name):
    key, fragment = MANIFEST[name]
    path = BAD / name
    assert path.read_text(encoding="utf-8").startswith("# INVALID")
    with pytest.raises(ProblemFileError) as info:
        load_problem(path)
    assert info.value.key == key
    assert fragment in info.value.message


@pytest.mark.parametrize("name", ["robot_broken_urdf.toml", "robot_unknown_joint.toml", "robot_range_beyond_limits.toml", "robot_mjcf_nan.toml"])
def test_bad_robot_input_is_one_line_through_the_cli(name, tmp_path):
    proc = run_cli("solve", str(BAD / name), "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert proc.returncode == 2
    assert len(proc.stderr.splitlines()) == 1, proc.stderr
    assert proc.stderr.startswith(f"{BAD / name}: {MANIFEST[name][0]}: ")
    assert not (tmp_path / "out").exists()


def test_expanded_urdf_declaring_the_xacro_namespace_solves():
    """xacro keeps ``xmlns:xacro`` in every file it expands (issue 32: such a file was refused
    as xacro). The fixture is plain URDF apart from that declaration: a two-link arm in the
    x-z plane (joints about y, gravity along -z), upper link 1.2 kg at 150 mm, forearm 0.6 kg
    at 100 mm past the elbow at 300 mm. Counter-masses at -150 mm (upper) and -100 mm
    (forearm) balance it exactly: about the elbow M_f 0.1 = 0.6 x 0.1, so M_f = 0.6 kg; about
    the shoulder M_u 0.15 = 1.2 x 0.15 + (0.6 + M_f) x 0.3 = 0.54, so M_u = 3.6 kg."""
    urdf = GOOD_ROBOTS / "xacro_expanded_arm.urdf"
    assert 'xmlns:xacro="http://www.ros.org/wiki/xacro"' in urdf.read_text(encoding="utf-8")
    text = f"""
[problem]
name = "xacro_expanded_arm"
[gravity]
acceleration = "9.81 m/s^2"
direction = [0, 0, -1]
[robot]
urdf = "{urdf.as_posix()}"
joints.shoulder = {{ range = ["-90 deg", "90 deg"] }}
joints.elbow = {{ range = ["-120 deg", "120 deg"] }}
[variables.M_u]
lower = "0 kg"
upper = "20 kg"
[variables.M_f]
lower = "0 kg"
upper = "20 kg"
[counter_masses.M_u]
frame = "upper"
mass = "M_u"
position = ["-150 mm", 0, 0]
[counter_masses.M_f]
frame = "fore"
mass = "M_f"
position = ["-100 mm", 0, 0]
"""
    result = design(load_problem_text(text, str(urdf.with_name("xacro_expanded_arm.toml"))))
    assert result.status.value == "optimal", result.message
    assert value(result, "M_f", "kg") == pytest.approx(0.6, rel=1e-6)
    assert value(result, "M_u", "kg") == pytest.approx(3.6, rel=1e-6)


def _example_robot_data(sub: str) -> Path:
    """A file of example-robot-data, where that package is installed (else the test skips):
    through its loader where it has one, else among the files the distribution installed
    (6.x installs its robots under a cmeel prefix and ships no Python module)."""
    from importlib import metadata

    try:
        from example_robot_data.robots_loader import getModelPath

        path = Path(getModelPath(sub)) / sub
        if path.is_file():
            return path
    except (ImportError, OSError, ValueError):
        pass
    try:
        files = metadata.distribution("example-robot-data").files or []
    except metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed")
    found = [Path(str(f.locate())) for f in files if f.as_posix().endswith(sub)]
    if not found or not found[0].is_file():
        pytest.skip(f"this example-robot-data has no {sub}")
    return found[0]


def test_example_robot_data_panda_solves(tmp_path):
    """example-robot-data's panda.urdf declares xmlns:xacro (xacro expanded it) and is plain
    URDF: it solved before issue 32's regression and must again. A counter-mass on link 2,
    free in its x-y plane, balances the shoulder (joint 2) with the elbow held."""
    urdf = _example_robot_data("panda_description/urdf/panda.urdf")
    text = f"""
[problem]
name = "erd_panda"
[gravity]
acceleration = "9.81 m/s^2"
direction = [0, 0, -1]
[robot]
urdf = "{urdf.as_posix()}"
joints.panda_joint2 = {{ range = ["-90 deg", "90 deg"] }}
locked.panda_joint4 = "-90 deg"
[variables.M]
lower = "0 kg"
upper = "100 kg"
[variables.x]
lower = "-300 mm"
upper = "300 mm"
[variables.y]
lower = "-300 mm"
upper = "300 mm"
[counter_masses.M]
frame = "panda_link2"
mass = "M"
position = ["x", "y", 0]
"""
    (tmp_path / "panda.toml").write_text(text, encoding="utf-8")
    proc = run_cli("solve", str(tmp_path / "panda.toml"), "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "status: optimal" in (tmp_path / "out" / "erd_panda" / "status.txt").read_text(encoding="utf-8")


def test_links_are_frames_and_bodies():
    problem = load_problem(PROBLEMS / "ur5_shoulder_elbow.toml")
    links = [f.name for f in problem.frames if f.link]
    assert links == ["base_link", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link", "tool0"]
    masses = {b.name: b.mass.value for b in problem.bodies}
    assert masses == {"shoulder_link": 3.7, "upper_arm_link": 8.393, "forearm_link": 2.275, "wrist_1_link": 1.219, "wrist_2_link": 1.219, "wrist_3_link": 0.1879}
    assert [c.name for c in problem.coordinates] == ["shoulder_lift_joint", "elbow_joint"]
    assert {f.name: f.subsystem for f in problem.frames}["shoulder_link"] is None  # pan held at 0
    assert {f.name: f.subsystem for f in problem.frames}["tool0"] == "arm"


def test_builder_gives_the_file_problem():
    urdf = (PROBLEMS / "robots" / "ur5.urdf").as_posix()
    b = ProblemBuilder("ur5_built", direction=(0, 0, -1))
    b.robot(urdf=urdf, subsystem="arm", joints={"shoulder_lift_joint": ("-180 deg", "0 deg"), "elbow_joint": ("-150 deg", "150 deg")}, locked={"wrist_1_joint": "-90 deg"})
    b.parameter("shoulder_height", "89.159 mm").parameter("h_1", "150 mm").parameter("h_2", "150 mm").parameter("k_1", "4000 N/m").parameter("k_2", "2000 N/m")
    b.frame("lift_ref", translate(0, 0, "shoulder_height"), parent="shoulder_link")
    b.frame("elbow_ref", parent="forearm_link", orientation="shoulder_link")
    for v in ("x_1", "y_1", "x_2", "y_2"):
        b.variable(v, "-500 mm", "500 mm")
    b.spring("shoulder", "k_1", ("lift_ref", (0, 0, "h_1")), ("upper_arm_link", ("x_1", "y_1", 0)))
    b.spring("elbow", "k_2", ("elbow_ref", (0, 0, "h_2")), ("forearm_link", ("x_2", "y_2", 0)))
    built = b.build()
    loaded = load_problem(PROBLEMS / "ur5_shoulder_elbow.toml")
    q = {"shoulder_lift_joint": -0.7, "elbow_joint": 1.1}
    design = {"x_1": -0.1, "y_1": 0.02, "x_2": -0.08, "y_2": 0.01}
    a = {(p.kind, p.name): p.position for p in place(built, q, design)}
    c = {(p.kind, p.name): p.position for p in place(loaded, q, design)}
    assert a.keys() == c.keys()
    assert max(np.abs(np.subtract(a[k], c[k])).max() for k in a) <= TOL


def test_orientation_frame_keeps_the_named_frames_axes():
    """A frame hung from a chain of two branches keeps the axes of a frame on another branch."""
    b = ProblemBuilder("orient", direction=(0, 0, -1))
    b.subsystem("s", q1=("-90 deg", "90 deg"), q2=("-90 deg", "90 deg"), q3=("-90 deg", "90 deg"))
    b.frame("a", rotate("z", "q1"), translate("100 mm", 0, "20 mm"), rotate((1, 1, 0), "30 deg"))
    b.frame("b", translate("50 mm"), rotate("y", "q2"), rotate("x", "q3"), parent="a")
    b.frame("c", rotate("x", "q3"), translate(0, "70 mm"), parent="a")
    b.frame("r", translate("10 mm", 0, 0), rotate("z", "q1"), parent="b", orientation="c")
    b.body("m", "b", "1 kg", ("10 mm", 0, 0))
    problem = b.build()
    rng = np.random.default_rng(SEED)
    for _ in range(20):
        q = {n: rng.uniform(-1.5, 1.5) for n in ("q1", "q2", "q3")}
        mech = mechanics(problem, q, {})
        rot_r, origin_r = mech.pose("r")
        rot_c, _ = mech.pose("c")
        rot_b, origin_b = mech.pose("b")
        assert np.abs(np.array(rot_r, dtype=float) - np.array(rot_c, dtype=float)).max() <= TOL
        # the origin follows the parent: b's origin plus b's x axis times 10 mm
        expected = np.array(origin_b, dtype=float) + 0.01 * np.array(rot_b, dtype=float)[:, 0]
        assert np.abs(np.array(origin_r, dtype=float) - expected).max() <= TOL


def _rpy(roll, pitch, yaw):
    cr, sr, cp, sp, cy, sy = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return rz @ ry @ rx


@pytest.mark.parametrize("angles", [(0.3, -0.7, 2.1), (1.0, math.pi / 2, 0.4), (-0.5, -math.pi / 2, 1.2), (0.0, 0.0, 0.0)])
def test_rpy_split_round_trips(angles):
    r = _rpy(*angles)
    back = _rpy(*rpy_from_matrix(tuple(tuple(row) for row in r)))
    assert np.abs(back - r).max() <= 1e-12


MIMIC_URDF = """<robot name="mimic">
  <link name="base"/>
  <joint name="drive" type="revolute"><parent link="base"/><child link="a"/><origin xyz="0 0 0.1" rpy="0.2 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <link name="a"><inertial><mass value="1"/><origin xyz="0.1 0 0"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <joint name="follow" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0.3 0 0" rpy="0 0 0.5"/>
    <axis xyz="0 1 0"/><limit lower="-5" upper="5" effort="1" velocity="1"/><mimic joint="drive" multiplier="-2" offset="0.3"/></joint>
  <link name="b"><inertial><mass value="0.5"/><origin xyz="0.2 0 0"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
</robot>
"""


def test_mimic_joint_follows_its_joint(tmp_path):
    """Against yourdfpy's own forward kinematics (which applies the mimic)."""
    yourdfpy = pytest.importorskip("yourdfpy")
    (tmp_path / "mimic.urdf").write_text(MIMIC_URDF, encoding="utf-8")
    text = '[problem]\nname = "mimic"\n[gravity]\nacceleration = "9.81 m/s^2"\ndirection = [0, 0, -1]\n[robot]\nurdf = "mimic.urdf"\njoints.drive = { range = ["-1 rad", "1 rad"] }\n'
    problem = load_problem_text(text, str(tmp_path / "mimic.toml"))
    assert {f.name: f.subsystem for f in problem.frames}["b"] == "robot"
    urdf = yourdfpy.URDF.load(str(tmp_path / "mimic.urdf"), load_meshes=False)
    for q in (-0.8, 0.1, 0.9):
        urdf.update_cfg({"drive": q})
        placed = {p.name: p.position for p in place(problem, {"drive": q}, {}) if p.kind == "frame"}
        for link in ("a", "b"):
            assert np.abs(np.array(placed[link]) - urdf.get_transform(link)[:3, 3]).max() <= TOL


def test_frames_command_rejects_an_unknown_name(tmp_path):
    proc = run_cli("frames", str(PROBLEMS / "ur5_shoulder_elbow.toml"), "--at", "elbo=3 deg")
    assert proc.returncode == 2
    assert "'elbo' is neither a coordinate nor a design variable" in proc.stderr
    assert len(proc.stderr.splitlines()) == 1


def test_draw_writes_the_picture(tmp_path):
    proc = run_cli("draw", str(PROBLEMS / "mjcf_arm.toml"), "--at", "elbow=45 deg", "--out", str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    png = tmp_path / "mjcf_arm" / "mechanism.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_limit_just_inside_180_deg_is_not_shown_as_180(tmp_path):
    """Issue 24: limits of ±3.14159 rad and a ±180 deg range were reported as
    "beyond the joint's limits [-180 deg, 180 deg]": the limit rounded to the range it misses.
    3.14159 rad = 179.999848 deg; the range passes it by 2.65e-6 rad = 0.000152 deg."""
    from counterpoise.errors import CounterpoiseError

    (tmp_path / "m.urdf").write_text(MIMIC_URDF.replace('lower="-2" upper="2"', 'lower="-3.14159" upper="3.14159"'), encoding="utf-8")
    text = '[problem]\nname = "m"\n[gravity]\nacceleration = "9.81 m/s^2"\ndirection = [0, 0, -1]\n[robot]\nurdf = "m.urdf"\njoints.drive = { range = ["-180 deg", "180 deg"] }\n'
    with pytest.raises(CounterpoiseError) as caught:
        load_problem_text(text, str(tmp_path / "m.toml"))
    message = str(caught.value)
    assert "[-179.999848 deg, 179.999848 deg]" in message and "by 0.000152 deg" in message, message
