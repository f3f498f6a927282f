"""Robot models checked in MuJoCo, an engine independent of counterpoise's kinematics.

The designs of the UR5 problems (URDF import) and of the small MJCF arm are loaded in
MuJoCo; their net gravity torque is MuJoCo's ``qfrc_bias`` at zero velocity, plus the
counter-masses' weights through MuJoCo's point Jacobians (``mj_jac``) and the springs'
k (b − a)ᵀ(J_b − J_a). Over a 30 × 30 grid of the two joints it must stay below 1e-8 of
the largest unbalanced torque. Frame positions printed by ``counterpoise frames`` (the
same :func:`counterpoise.mechanics.poses.place`) must match MuJoCo's to 1e-9 m, and a
random URDF (every joint kind, arbitrary rpy) checks the xyz-then-rpy order.
"""

from __future__ import annotations

import csv
import io
import math
import re
from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from conftest import PROBLEMS, ROOT, run_cli  # noqa: E402
from counterpoise.model import expr as ex  # noqa: E402
from counterpoise.model.functions import NUMPY_FUNCTIONS  # noqa: E402
from counterpoise.io.loader import load_problem, load_problem_text  # noqa: E402
from counterpoise.mechanics.poses import place  # noqa: E402
from counterpoise.pipeline import design  # noqa: E402

GRID = 30
TORQUE_RATIO = 1e-8
POSITION_TOL = 1e-9
SEED = 20261124


def mujoco_from_urdf(path: Path) -> "mujoco.MjModel":
    """MuJoCo's own URDF import, keeping every link as a body (no fusing of fixed joints)."""
    text = path.read_text(encoding="utf-8")
    text = re.sub(r"(<robot [^>]*>)", r'\1<mujoco><compiler fusestatic="false" discardvisual="true"/></mujoco>', text, count=1)
    return mujoco.MjModel.from_xml_string(text)


class Engine:
    """Net generalized gravity force of a design, computed by MuJoCo."""

    def __init__(self, model, problem, values, free_frames):
        self.m, self.d = model, mujoco.MjData(model)
        self.problem, self.values = problem, values
        self.free_frames = free_frames  # frame -> (body it translates with, or None: fixed)
        self.g = np.array(problem.scenarios[0].gravity.direction) * problem.scenarios[0].gravity.acceleration
        self.m.opt.gravity[:] = self.g

    def set(self, q: dict[str, float]) -> None:
        self.d.qpos[:] = 0
        for name, v in q.items():
            self.d.qpos[self.m.joint(name).qposadr[0]] = v
        self.d.qvel[:] = 0
        mujoco.mj_forward(self.m, self.d)

    def point(self, point):
        """World position and translational Jacobian of a point given in a problem frame."""
        local = np.array([self.value(c) for c in point.position])
        if point.frame in self.free_frames:  # a reference frame: translates with a body, world axes
            body, offset = self.free_frames[point.frame]
            jac = np.zeros((3, self.m.nv))
            if body is None:
                return offset + local, jac
            b = self.m.body(body).id
            origin = self.d.xpos[b] + self.d.xmat[b].reshape(3, 3) @ offset
            mujoco.mj_jac(self.m, self.d, jac, None, origin, b)
            return origin + local, jac
        b = self.m.body(point.frame).id
        world = self.d.xpos[b] + self.d.xmat[b].reshape(3, 3) @ local
        jac = np.zeros((3, self.m.nv))
        mujoco.mj_jac(self.m, self.d, jac, None, world, b)
        return world, jac

    def value(self, tree) -> float:
        """A number of the problem file (its expressions name parameters and variables)."""
        return float(ex.evaluate(tree, self.values, NUMPY_FUNCTIONS))

    def torques(self) -> tuple[np.ndarray, np.ndarray]:
        unbalanced = self.d.qfrc_bias.copy()
        net = unbalanced.copy()
        for c in self.problem.counter_masses:
            _, jac = self.point(c.position)
            net += -self.value(c.mass) * jac.T @ self.g
        for s in self.problem.springs:
            (a, ja), (b, jb) = self.point(s.ends[0]), self.point(s.ends[1])
            net += self.value(s.stiffness) * (b - a) @ (jb - ja)
        return net, unbalanced


def _design_values(problem):
    """The design's values, and its problem: as built, each designed spring's stiffness is
    the rate it is wound to (the design followed it), which the file's parameter is not."""
    result = design(problem)
    assert result.optimal, result.message
    assert result.verification.residual_ratio <= 1e-9
    values = dict(result.solution.variable_values(problem.scenarios[0].name))
    values.update({p.name: p.value for p in problem.parameters if p.value is not None})
    return result.problem, values


def _check_grid(engine: Engine, problem, held: dict[str, float]) -> None:
    names = [c.name for c in problem.coordinates]
    grids = [np.linspace(c.lower, c.upper, GRID) for c in problem.coordinates]
    dofs = [engine.m.joint(n).dofadr[0] for n in names]
    worst, largest = 0.0, 0.0
    for q1 in grids[0]:
        for q2 in grids[1]:
            engine.set({**held, names[0]: q1, names[1]: q2})
            net, unbalanced = engine.torques()
            worst = max(worst, float(np.abs(net[dofs]).max()))
            largest = max(largest, float(np.abs(unbalanced[dofs]).max()))
    assert largest > 1.0  # the arm really is unbalanced (N m)
    assert worst <= TORQUE_RATIO * largest, (worst, largest)


UR5_HELD = {"wrist_1_joint": -math.pi / 2}


def test_ur5_springs_balance_the_arm_in_mujoco():
    problem, values = _design_values(load_problem(PROBLEMS / "ur5_shoulder_elbow.toml"))
    model = mujoco_from_urdf(PROBLEMS / "robots" / "ur5.urdf")
    # lift_ref: fixed, shoulder_height above the base; elbow_ref: at the forearm's origin, base axes
    free = {"lift_ref": (None, np.array([0.0, 0.0, values["shoulder_height"]])), "elbow_ref": ("forearm_link", np.zeros(3))}
    engine = Engine(model, problem, values, free)
    _check_grid(engine, problem, UR5_HELD)


def test_ur5_counter_masses_balance_the_arm_in_mujoco():
    problem, values = _design_values(load_problem(PROBLEMS / "ur5_shoulder_elbow_counter_mass.toml"))
    model = mujoco_from_urdf(PROBLEMS / "robots" / "ur5.urdf")
    _check_grid(Engine(model, problem, values, {}), problem, UR5_HELD)


def test_mjcf_arm_balanced_in_mujoco():
    problem, values = _design_values(load_problem(PROBLEMS / "mjcf_arm.toml"))
    model = mujoco.MjModel.from_xml_path(str(PROBLEMS / "robots" / "arm.xml"))
    free = {"shoulder_ref": (None, np.array([0.0, 0.0, 0.55])), "elbow_ref": ("upper_arm", np.array([0.4, 0.0, 0.0]))}
    _check_grid(Engine(model, problem, values, free), problem, {})


def _positions_match(problem, model, held, configurations):
    rng = np.random.default_rng(SEED)
    data = mujoco.MjData(model)
    links = [f.name for f in problem.frames if f.link]
    bodies = {b.name for b in problem.bodies}
    worst = 0.0
    for _ in range(configurations):
        q = {c.name: rng.uniform(c.lower, c.upper) for c in problem.coordinates}
        data.qpos[:] = model.qpos0
        for name, v in {**held, **q}.items():
            data.qpos[model.joint(name).qposadr[0]] = v
        mujoco.mj_kinematics(model, data)
        placed = {(p.kind, p.name): p.position for p in place(problem, q, {v.name: v.initial for v in problem.variables})}
        for link in links:
            worst = max(worst, float(np.abs(np.array(placed[("frame", link)]) - data.xpos[model.body(link).id]).max()))
            if link in bodies:
                worst = max(worst, float(np.abs(np.array(placed[("body", link)]) - data.xipos[model.body(link).id]).max()))
    assert worst <= POSITION_TOL, worst
    return worst


def test_ur5_frames_match_mujoco_at_random_configurations():
    problem = load_problem(PROBLEMS / "ur5_shoulder_elbow.toml")
    _positions_match(problem, mujoco_from_urdf(PROBLEMS / "robots" / "ur5.urdf"), UR5_HELD, 100)


def test_frames_command_prints_mujoco_positions():
    """The CLI table (CSV, in the file's mm) against MuJoCo at one configuration."""
    path = PROBLEMS / "ur5_shoulder_elbow.toml"
    proc = run_cli("frames", str(path), "--at", "shoulder_lift_joint=-40 deg", "--at", "elbow_joint=75 deg", "--csv")
    assert proc.returncode == 0, proc.stderr
    rows = {(r["kind"], r["name"]): r for r in csv.DictReader(io.StringIO(proc.stdout))}
    model = mujoco_from_urdf(PROBLEMS / "robots" / "ur5.urdf")
    data = mujoco.MjData(model)
    for name, v in {**UR5_HELD, "shoulder_lift_joint": math.radians(-40), "elbow_joint": math.radians(75)}.items():
        data.qpos[model.joint(name).qposadr[0]] = v
    mujoco.mj_kinematics(model, data)
    for link in ("upper_arm_link", "forearm_link", "wrist_3_link", "tool0"):
        row = rows[("frame", link)]
        assert row["unit"] == "mm"
        printed = np.array([float(row[c]) for c in "xyz"]) * 1e-3
        assert np.abs(printed - data.xpos[model.body(link).id]).max() <= POSITION_TOL


RANDOM_LINKS = 6


def _random_urdf(rng) -> str:
    """A chain with random origins (xyz, rpy), axes and joint kinds, masses at random points."""
    parts = ['<robot name="random">', '<link name="l0"/>']
    kinds = ["revolute", "continuous", "prismatic", "fixed", "revolute", "revolute"]
    for i in range(1, RANDOM_LINKS + 1):
        kind = kinds[i - 1]
        xyz = " ".join(f"{v:.6f}" for v in rng.uniform(-0.3, 0.3, 3))
        rpy = " ".join(f"{v:.6f}" for v in rng.uniform(-math.pi, math.pi, 3))
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        com = " ".join(f"{v:.6f}" for v in rng.uniform(-0.2, 0.2, 3))
        limit = '<limit lower="-2" upper="2" effort="1" velocity="1"/>' if kind in ("revolute", "prismatic") else ""
        axis_text = f'<axis xyz="{axis[0]:.6f} {axis[1]:.6f} {axis[2]:.6f}"/>' if kind != "fixed" else ""
        parts.append(
            f'<joint name="j{i}" type="{kind}"><parent link="l{i - 1}"/><child link="l{i}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/>{axis_text}{limit}</joint>'
        )
        parts.append(
            f'<link name="l{i}"><inertial><origin xyz="{com}" rpy="0 0 0"/><mass value="{rng.uniform(0.5, 2):.4f}"/>'
            '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>'
        )
    parts.append("</robot>")
    return "\n".join(parts)


def test_random_urdf_origins_and_axes_match_mujoco(tmp_path):
    """xyz then rpy = Rz(yaw) Ry(pitch) Rx(roll), arbitrary axes, every joint kind."""
    rng = np.random.default_rng(SEED)
    (tmp_path / "random.urdf").write_text(_random_urdf(rng), encoding="utf-8")
    moving = {"j1": '["-2 rad", "2 rad"]', "j2": '["-3 rad", "3 rad"]', "j3": '["-0.5 m", "0.5 m"]', "j5": '["-1 rad", "1 rad"]'}
    text = "\n".join(
        ['[problem]\nname = "random"\n[gravity]\nacceleration = "9.81 m/s^2"\ndirection = [0, 0, -1]', '[robot]\nurdf = "random.urdf"']
        + [f"joints.{n} = {{ range = {r} }}" for n, r in moving.items()]
        + ['locked.j6 = "0.7 rad"']
    )
    problem = load_problem_text(text, str(tmp_path / "random.toml"))
    model = mujoco_from_urdf(tmp_path / "random.urdf")
    _positions_match(problem, model, {"j6": 0.7}, 50)


def test_example_robot_data_ur5_is_balanced_by_counter_masses():
    """The UR5 URDF of example-robot-data (ROS layout: the arm along each link's z)."""
    erd = pytest.importorskip("example_robot_data")
    sub = "ur_description/urdf/ur5_robot.urdf"
    try:
        from example_robot_data.robots_loader import getModelPath

        urdf = Path(getModelPath(sub)) / sub
    except (ImportError, OSError, ValueError, IOError):
        pytest.skip(f"example-robot-data {getattr(erd, '__version__', '')} has no {sub}")
    if not urdf.is_file():
        pytest.skip(f"no {urdf}")
    text = f"""
[problem]
name = "erd_ur5"
[gravity]
acceleration = "9.81 m/s^2"
direction = [0, 0, -1]
[robot]
urdf = "{urdf.as_posix()}"
joints.shoulder_lift_joint = {{ range = ["-180 deg", "0 deg"] }}
joints.elbow_joint = {{ range = ["-150 deg", "150 deg"] }}
locked.wrist_1_joint = "-90 deg"
[variables.M_u]
lower = "0 kg"
upper = "200 kg"
[variables.M_f]
lower = "0 kg"
upper = "200 kg"
[counter_masses.M_u]
frame = "upper_arm_link"
mass = "M_u"
position = [0, 0, "-200 mm"]
[counter_masses.M_f]
frame = "forearm_link"
mass = "M_f"
position = [0, 0, "-150 mm"]
"""
    problem = load_problem_text(text, "erd_ur5.toml")
    problem, values = _design_values(problem)
    model = mujoco_from_urdf(urdf)
    _check_grid(Engine(model, problem, values, {}), problem, UR5_HELD)
