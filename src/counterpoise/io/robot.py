"""Robot models (URDF, MJCF) read into a small neutral tree of links and joints.

URDF is read with ``yourdfpy`` (a pure reader: every link is kept, fixed joints included,
with its name), MJCF with MuJoCo's own compiler (the one reference for what an MJCF file
means: defaults, ``childclass``, ``<include>``, masses filled from geoms). Both give, for
each link, where it sits in its parent (a translation and a rotation matrix), the joints
that move it, and its mass and centre of mass. :mod:`counterpoise.io.resolve.robot` turns
that tree into frames, coordinates and bodies (docs/robots.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError

Triple = tuple[float, float, float]
Matrix = tuple[Triple, Triple, Triple]

IDENTITY_MATRIX: Matrix = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
#: joint kinds the importer understands (URDF names; MJCF hinge -> revolute, slide -> prismatic)
KINDS = ("revolute", "continuous", "prismatic", "fixed")
#: below this, cos(pitch) is taken as 0 (gimbal lock) when a rotation is split into roll, pitch, yaw
GIMBAL = 1e-12


@dataclass(frozen=True)
class RobotJoint:
    """A joint that moves its link: rotation about (or slide along) ``axis`` through ``anchor``,
    both in the link's frame, by ``value − reference``."""

    name: str
    kind: str
    axis: Triple
    anchor: Triple = (0.0, 0.0, 0.0)
    limits: tuple[float, float] | None = None
    mimic: tuple[str, float, float] | None = None  # (joint, multiplier, offset): value = m q + offset
    reference: float = 0.0


@dataclass(frozen=True)
class RobotLink:
    """A link: its frame is ``parent`` · Trans(xyz) · rotation · joints; mass at ``com``."""

    name: str
    parent: str | None
    xyz: Triple
    rotation: Matrix
    joints: tuple[RobotJoint, ...]
    mass: float
    com: Triple
    joint_name: str | None = None  # the URDF joint that carries it (fixed ones too)


@dataclass(frozen=True)
class RobotModel:
    path: str
    format: str  # "urdf" or "mjcf"
    links: tuple[RobotLink, ...]  # parents before children

    def joints(self) -> dict[str, RobotJoint]:
        return {j.name: j for link in self.links for j in link.joints}


def read_robot(path: Path, fmt: str) -> RobotModel:
    """Read a URDF or MJCF file; problems with the file are :class:`InputError`."""
    if not path.is_file():
        raise InputError(f"no such file: {path}")
    model = _read_urdf(path) if fmt == "urdf" else _read_mjcf(path)
    for link in model.links:
        for joint in link.joints:
            if not all(math.isfinite(c) for c in joint.axis) or not any(joint.axis):
                raise InputError(f"{path.name}: joint '{joint.name}' has no usable axis {joint.axis}")
            if not all(math.isfinite(c) for c in (*link.xyz, *link.com, link.mass, *joint.anchor)):
                raise InputError(f"{path.name}: link '{link.name}' has a value that is not a finite number")
    return model


def rpy_from_matrix(r: Matrix) -> Triple:
    """(roll, pitch, yaw) with r = Rz(yaw) Ry(pitch) Rx(roll), URDF's fixed-axis order."""
    cos_pitch = math.hypot(r[0][0], r[1][0])
    pitch = math.atan2(-r[2][0], cos_pitch)
    if cos_pitch < GIMBAL:  # pitch = ±90°: only roll ∓ yaw is defined; put it all in roll
        return (math.atan2(-r[1][2], r[1][1]), pitch, 0.0)
    return (math.atan2(r[2][1], r[2][2]), pitch, math.atan2(r[1][0], r[0][0]))


def _triple(values: object) -> Triple:
    x, y, z = (float(v) for v in values)  # type: ignore[attr-defined]
    return (x, y, z)


def _matrix(m: object) -> Matrix:
    return (_triple(m[0][:3]), _triple(m[1][:3]), _triple(m[2][:3]))  # type: ignore[index]


def _read_urdf(path: Path) -> RobotModel:
    import logging

    import yourdfpy
    from lxml import etree

    logger = logging.getLogger("yourdfpy")
    level = logger.level
    logger.setLevel(logging.CRITICAL)  # its warnings would be extra lines: errors are ours to report
    try:
        etree.parse(str(path), etree.XMLParser())  # strict: yourdfpy would recover from broken XML
        urdf = yourdfpy.URDF.load(
            str(path), build_scene_graph=False, load_meshes=False, build_collision_scene_graph=False, load_collision_meshes=False
        )
    except (etree.Error, OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise InputError(f"cannot read the URDF {path.name}: {' '.join(str(exc).split())[:200]}") from None
    finally:
        logger.setLevel(level)
    robot = urdf.robot
    links = {link.name: link for link in robot.links}
    by_child = {}
    for joint in robot.joints:
        if joint.type not in KINDS:
            raise InputError(f"{path.name}: joint '{joint.name}' is of type '{joint.type}'; only {', '.join(KINDS)} joints are supported")
        if joint.parent not in links or joint.child not in links:
            raise InputError(f"{path.name}: joint '{joint.name}' joins unknown links '{joint.parent}' and '{joint.child}'")
        if joint.child in by_child:
            raise InputError(f"{path.name}: link '{joint.child}' is the child of two joints")
        by_child[joint.child] = joint
    roots = [name for name in links if name not in by_child]
    if len(roots) != 1:
        raise InputError(f"{path.name}: a robot needs exactly one root link, found {', '.join(roots) or 'none (a cycle)'}")
    children: dict[str, list[str]] = {}
    for child, joint in by_child.items():
        children.setdefault(joint.parent, []).append(child)
    out: list[RobotLink] = []
    stack = [roots[0]]
    while stack:
        name = stack.pop(0)
        link = links[name]
        mass, com = 0.0, (0.0, 0.0, 0.0)
        if link.inertial is not None and link.inertial.mass is not None:
            mass = float(link.inertial.mass)
            if link.inertial.origin is not None:
                com = _triple(link.inertial.origin[:3, 3])
        joint = by_child.get(name)
        if joint is None:
            out.append(RobotLink(name, None, (0.0, 0.0, 0.0), IDENTITY_MATRIX, (), mass, com))
        else:
            origin = joint.origin
            xyz = _triple(origin[:3, 3]) if origin is not None else (0.0, 0.0, 0.0)
            rot = _matrix(origin) if origin is not None else IDENTITY_MATRIX
            moving: tuple[RobotJoint, ...] = ()
            if joint.type != "fixed":
                axis = _triple(joint.axis) if joint.axis is not None else (1.0, 0.0, 0.0)
                limits = None
                if joint.type != "continuous" and joint.limit is not None and joint.limit.lower is not None and joint.limit.upper is not None:
                    limits = (float(joint.limit.lower), float(joint.limit.upper))
                mimic = None
                if joint.mimic is not None:
                    mimic = (joint.mimic.joint, float(joint.mimic.multiplier if joint.mimic.multiplier is not None else 1.0), float(joint.mimic.offset or 0.0))
                moving = (RobotJoint(joint.name, joint.type, axis, limits=limits, mimic=mimic),)
            out.append(RobotLink(name, joint.parent, xyz, rot, moving, mass, com, joint.name))
        stack.extend(children.get(name, []))
    return RobotModel(str(path), "urdf", tuple(out))


def _quaternion_matrix(q: object) -> Matrix:
    w, x, y, z = (float(v) for v in q)  # type: ignore[attr-defined]
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return (
        (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
    )


def _read_mjcf(path: Path) -> RobotModel:
    import mujoco

    try:
        model = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise InputError(f"cannot read the MJCF {path.name}: {' '.join(str(exc).split())[:200]}") from None
    hinge, slide = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)
    names = {}
    for b in range(1, model.nbody):
        names[b] = model.body(b).name or f"body{b}"
    mimics: dict[int, tuple[int, float, float]] = {}
    for e in range(model.neq):
        if int(model.eq_type[e]) == int(mujoco.mjtEq.mjEQ_JOINT) and model.eq_obj2id[e] >= 0:
            c = [float(v) for v in model.eq_data[e][:5]]
            if any(c[2:]):
                raise InputError(f"{path.name}: joint equality '{model.equality(e).name}' is not linear (polycoef beyond the first two)")
            mimics[int(model.eq_obj1id[e])] = (int(model.eq_obj2id[e]), c[1], c[0])
    out: list[RobotLink] = []
    for b in range(1, model.nbody):
        joints = []
        for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]):
            name = model.joint(j).name or f"joint{j}"
            kind = int(model.jnt_type[j])
            if kind not in (hinge, slide):
                raise InputError(f"{path.name}: joint '{name}' is a free or ball joint; only hinge and slide joints are supported")
            limits = (float(model.jnt_range[j][0]), float(model.jnt_range[j][1])) if model.jnt_limited[j] else None
            ref = float(model.qpos0[model.jnt_qposadr[j]])
            mimic = None
            if j in mimics:
                other, scale, offset = mimics[j]
                other_ref = float(model.qpos0[model.jnt_qposadr[other]])
                mimic = (model.joint(other).name or f"joint{other}", scale, ref + offset - scale * other_ref)
            joints.append(
                RobotJoint(name, "revolute" if kind == hinge else "prismatic", _triple(model.jnt_axis[j]), _triple(model.jnt_pos[j]), limits, mimic, ref)
            )
        parent = int(model.body_parentid[b])
        out.append(
            RobotLink(
                names[b],
                names.get(parent),
                _triple(model.body_pos[b]),
                _quaternion_matrix(model.body_quat[b]),
                tuple(joints),
                float(model.body_mass[b]),
                _triple(model.body_ipos[b]),
            )
        )
    return RobotModel(str(path), "mjcf", tuple(out))
