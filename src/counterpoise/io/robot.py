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
import types
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any, SupportsFloat

from ..errors import InputError
from ..model.expr import suggest
from ..model.units import MAX_LENGTH_M

if TYPE_CHECKING:
    from lxml import etree

Triple = tuple[float, float, float]
Matrix = tuple[Triple, Triple, Triple]

IDENTITY_MATRIX: Matrix = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
#: joint kinds the importer understands (URDF names; MJCF hinge -> revolute, slide -> prismatic)
KINDS = ("revolute", "continuous", "prismatic", "fixed")
#: below this, cos(pitch) is taken as 0 (gimbal lock) when a rotation is split into roll, pitch, yaw
GIMBAL = 1e-12
#: largest robot model file read (bytes): a URDF is parsed with lxml's ``huge_tree`` option
#: (a comment or text node over libxml2's 10 MB limit is fine), so the file size is the bound
MAX_MODEL_BYTES = 256 * 1024 * 1024
#: an inertia tensor's eigenvalue may be this far below 0 (relative to its largest) and count as 0
INERTIA_SLACK = 1e-9
#: the namespaces xacro files declare (ROS wiki addresses, old and new)
XACRO_NAMESPACES = ("http://www.ros.org/wiki/xacro", "http://ros.org/wiki/xacro", "http://wiki.ros.org/xacro")


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
    size = path.stat().st_size
    if size > MAX_MODEL_BYTES:
        raise InputError(f"{path.name} is {size / 2**20:.0f} MB; robot models up to {MAX_MODEL_BYTES // 2**20} MB are read")
    model = _read_urdf(path) if fmt == "urdf" else _read_mjcf(path)
    for link in model.links:
        _check_link(path, link)
    return model


def _check_link(path: Path, link: RobotLink) -> None:
    """Every number of a link usable: finite positions, a mass that is not negative, axes."""
    where = f"{path.name}: link '{link.name}'"
    if not math.isfinite(link.mass) or link.mass < 0:
        raise InputError(f"{where} has a mass of {link.mass:g} kg: a mass must be a finite number, not negative")
    for what, values in (("position (joint origin)", link.xyz), ("centre of mass", link.com), ("orientation", sum(link.rotation, ()))):
        if not all(math.isfinite(c) for c in values):
            raise InputError(f"{where} has a {what} that is not a finite number: {_show(values)}")
    for what, values in (("position (joint origin)", link.xyz), ("centre of mass", link.com), *(("joint position", j.anchor) for j in link.joints)):
        if any(abs(c) > MAX_LENGTH_M for c in values):
            raise InputError(f"{where} has a {what} out of range: {_show(values)} m; lengths up to {MAX_LENGTH_M:g} m are accepted")
    for joint in link.joints:
        if not all(math.isfinite(c) for c in joint.axis) or not any(joint.axis):
            raise InputError(f"{path.name}: joint '{joint.name}' has no usable axis {joint.axis}")
        if not all(math.isfinite(c) for c in joint.anchor):
            raise InputError(f"{path.name}: joint '{joint.name}' of link '{link.name}' has a position that is not a finite number: {_show(joint.anchor)}")
        if joint.limits is not None and not all(math.isfinite(c) for c in joint.limits):
            raise InputError(f"{path.name}: joint '{joint.name}' has limits that are not finite numbers: {_show(joint.limits)}")


def _show(values: Iterable[SupportsFloat]) -> str:
    return "(" + ", ".join(f"{float(v):g}" for v in values) + ")"


def _check_inertia(path: Path, link: str, inertia: object) -> None:
    """An inertia tensor (3×3) of finite numbers with no negative principal moment."""
    import numpy as np

    try:
        matrix = np.asarray(inertia, dtype=float).reshape(3, 3)
    except (TypeError, ValueError):
        raise InputError(f"{path.name}: link '{link}' has an inertia that is not a 3×3 tensor") from None
    if not np.isfinite(matrix).all():
        raise InputError(f"{path.name}: link '{link}' has an inertia that is not a finite number")
    moments = np.linalg.eigvalsh(0.5 * (matrix + matrix.T))
    if moments.min() < -INERTIA_SLACK * max(1.0, float(np.abs(moments).max())):
        raise InputError(f"{path.name}: link '{link}' has a negative inertia (principal moments {_show(moments)} kg m²)")


def rpy_from_matrix(r: Matrix) -> Triple:
    """(roll, pitch, yaw) with r = Rz(yaw) Ry(pitch) Rx(roll), URDF's fixed-axis order."""
    cos_pitch = math.hypot(r[0][0], r[1][0])
    pitch = math.atan2(-r[2][0], cos_pitch)
    if cos_pitch < GIMBAL:  # pitch = ±90°: only roll ∓ yaw is defined; put it all in roll
        return (math.atan2(-r[1][2], r[1][1]), pitch, 0.0)
    return (math.atan2(r[2][1], r[2][2]), pitch, math.atan2(r[1][0], r[0][0]))


def _triple(values: Iterable[SupportsFloat]) -> Triple:
    x, y, z = (float(v) for v in values)
    return (x, y, z)


def _matrix(m: Sequence[Sequence[SupportsFloat]]) -> Matrix:
    """The rotation part of a 4x4 (or 3x3) transform, rows first."""
    return (_triple(m[0][:3]), _triple(m[1][:3]), _triple(m[2][:3]))


def _is_xacro(root: etree._Element) -> bool:
    """Whether a parsed XML tree still holds xacro macros (ROS), not plain URDF.

    The macros are what count: an element of the xacro namespace (``xacro:macro``,
    ``xacro:property``, ``xacro:include``, ``xacro:if``, a macro's call...), an attribute
    of it, or a ``${...}`` / ``$(...)`` substitution in an attribute or a text. The
    namespace declaration alone (``xmlns:xacro``) is not: xacro leaves it in every file it
    expands, and most ROS robots ship such expanded files.
    """
    prefixes = tuple("{" + namespace + "}" for namespace in XACRO_NAMESPACES)
    for element in root.iter():
        if not isinstance(element.tag, str):  # a comment or a processing instruction
            continue
        if element.tag.startswith(prefixes) or any(str(name).startswith(prefixes) for name in element.attrib):
            return True
        if any(_substitutes(value) for value in element.attrib.values()) or _substitutes(element.text):
            return True
    return False


def _substitutes(text: str | bytes | None) -> bool:
    """Whether a text holds a xacro substitution: ``${expression}`` or ``$(arg name)``."""
    return isinstance(text, str) and ("${" in text or "$(" in text)


def _xacro_hint(path: Path) -> str:
    """The way out, writing the expansion to a NEW file: ``xacro a.urdf > a.urdf`` would
    empty the file (the shell truncates it before xacro reads it)."""
    stem = path.name.removesuffix(".xacro").removesuffix(".urdf")
    expanded = f"{stem}_expanded.urdf"
    return f"{path.name} is a xacro file (ROS macros, not plain URDF): expand it into a new file first, `xacro {path.name} > {expanded}`, and give {expanded}"


class _DeferredTrimesh(types.ModuleType):
    """Stands for the ``trimesh`` package while yourdfpy is imported (:func:`import_yourdfpy`).

    Its submodules are trimesh's own files (``__path__`` is the package's folder), so
    ``trimesh.transformations``, which yourdfpy uses to read origins, is the real one; its
    ``__init__`` (which imports scipy, networkx, rtree, shapely: ~0.6–1 s) is not run. Any
    other attribute imports the real package then and is taken from it; while yourdfpy's
    module is executed, the names its annotations use (``trimesh.Trimesh``,
    ``trimesh.Scene``) get placeholder classes instead, since annotations are evaluated
    when a function is defined.
    """

    def __init__(self, locations: list[str]) -> None:
        super().__init__("trimesh")
        self.__path__ = locations
        self._importing = True

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        if self.__dict__.get("_importing"):
            return type(name, (), {"__module__": "trimesh"})
        import importlib

        return getattr(importlib.import_module("trimesh"), name)


def import_yourdfpy() -> Any:  # Any: the yourdfpy module (it ships no type information)
    """yourdfpy, imported without running trimesh's ``__init__`` (see :class:`_DeferredTrimesh`).

    counterpoise reads a URDF's links, joints and inertials only (no meshes, no scene
    graph), and ``import trimesh`` was ~90 % of the time to read a robot model. trimesh stays
    importable: ``import trimesh`` afterwards imports the whole package as usual, and what
    yourdfpy does with meshes, if it is ever asked to, goes to the real package. Should
    yourdfpy not import this way (another version), it is imported plainly.
    """
    import importlib
    import importlib.util
    import sys

    if "yourdfpy" in sys.modules or "trimesh" in sys.modules:
        return importlib.import_module("yourdfpy")
    spec = importlib.util.find_spec("trimesh")
    if spec is None or not spec.submodule_search_locations:
        return importlib.import_module("yourdfpy")
    stand_in = _DeferredTrimesh(list(spec.submodule_search_locations))
    sys.modules["trimesh"] = stand_in
    try:
        module = importlib.import_module("yourdfpy")
    except Exception:  # noqa: BLE001 - any failure this way: forget it and import plainly below
        for name in [n for n in sys.modules if n == "yourdfpy" or n.startswith("yourdfpy.")]:
            del sys.modules[name]
        module = None
    finally:
        stand_in._importing = False
        if sys.modules.get("trimesh") is stand_in:
            del sys.modules["trimesh"]
    return module if module is not None else importlib.import_module("yourdfpy")


def _read_urdf(path: Path) -> RobotModel:
    import io
    import logging

    from lxml import etree

    yourdfpy = import_yourdfpy()

    logger = logging.getLogger("yourdfpy")
    level = logger.level
    logger.setLevel(logging.CRITICAL)  # its warnings would be extra lines: errors are ours to report
    try:
        source: object = str(path)
        try:  # strict: yourdfpy would recover from broken XML
            root = etree.parse(str(path), etree.XMLParser()).getroot()
        except etree.XMLSyntaxError as exc:
            if not any(word in str(exc).lower() for word in ("too big", "huge", "too long")):
                raise
            # a comment or text over libxml2's 10 MB limit: read with lxml's huge_tree option
            # (the file size is bounded by MAX_MODEL_BYTES), expanding no entity (huge_tree
            # lifts libxml2's guard against entity amplification) and fetching nothing; the
            # comments stripped, the rest is small enough for yourdfpy's own parser
            parser = etree.XMLParser(huge_tree=True, resolve_entities=False, no_network=True, load_dtd=False)
            root = etree.parse(str(path), parser).getroot()
            etree.strip_tags(root, etree.Comment)
            source = io.BytesIO(etree.tostring(root))
        if _is_xacro(root):
            raise InputError(_xacro_hint(path))
        urdf = yourdfpy.URDF.load(
            source, build_scene_graph=False, load_meshes=False, build_collision_scene_graph=False, load_collision_meshes=False
        )
    except (etree.Error, OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        if "${" in str(exc) or "prefix xacro" in str(exc) or path.name.endswith(".xacro"):
            raise InputError(_xacro_hint(path)) from None
        raise InputError(f"cannot read the URDF {path.name}: {' '.join(str(exc).split())[:200]}") from None
    finally:
        logger.setLevel(level)
    robot = urdf.robot
    links = {link.name: link for link in robot.links}
    by_child = {}
    for joint in robot.joints:
        if joint.type not in KINDS:
            hint = ""
            if joint.type in ("floating", "planar"):  # a floating base: fix it to its parent
                hint = f": in a copy of the model, give it type=\"fixed\" so that link '{joint.child}' is fixed to '{joint.parent}' (see docs/robots.md)"
            raise InputError(f"{path.name}: joint '{joint.name}' is of type '{joint.type}'; only {', '.join(KINDS)} joints are supported{hint}")
        missing = [name for name in dict.fromkeys((joint.parent, joint.child)) if name not in links]
        if missing:
            what = " and ".join(f"'{name}'" for name in missing)
            raise InputError(f"{path.name}: joint '{joint.name}' names link{'s' if len(missing) > 1 else ''} {what}, which the model does not declare{suggest(missing[0], list(links))}")
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
            if not math.isfinite(mass) or mass < 0:  # before its inertia: the first thing wrong is named
                raise InputError(f"{path.name}: link '{name}' has a mass of {mass:g} kg: a mass must be a finite number, not negative")
            if link.inertial.inertia is not None:
                _check_inertia(path, name, link.inertial.inertia)
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


def _quaternion_matrix(q: Iterable[SupportsFloat]) -> Matrix:
    w, x, y, z = (float(v) for v in q)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return (
        (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
    )


def _compile_mjcf(path: Path) -> tuple[Any, list[str]]:  # Any: mujoco.MjModel (mujoco ships no type information)
    """MuJoCo's model of ``path`` and the warnings its compiler gave (kept, not printed: the
    one-line contract). An MJCF whose mesh files are missing is compiled without those
    meshes when every body with such a mesh has an explicit ``<inertial>`` (the meshes then
    weigh nothing in the model, and counterpoise needs nothing else of them)."""
    import mujoco

    warnings: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(warnings.append)
    try:
        try:
            return mujoco.MjModel.from_xml_path(str(path)), warnings
        except ValueError as exc:
            text = " ".join(str(exc).split())
            spec = _without_missing_meshes(path) if "Error opening file" in text or "mesh" in text.lower() else None
            if spec is None:
                raise InputError(f"cannot read the MJCF {path.name}: {text[:200]}{_mjcf_hint(text)}") from None
        try:
            return spec.compile(), warnings
        except ValueError as exc:
            raise InputError(f"cannot read the MJCF {path.name}: {' '.join(str(exc).split())[:200]}") from None
    finally:
        mujoco.set_mju_user_warning(previous)


def _mjcf_hint(text: str) -> str:
    if "Error opening file" in text:
        return " (a missing mesh file is left out when its body has an explicit <inertial>; give the others theirs, or the files)"
    return ""


def _without_missing_meshes(path: Path) -> Any:  # Any: mujoco.MjSpec or None (mujoco ships no type information)
    """The model's spec with every mesh whose file is missing removed, with the geoms that
    use it; None when there is no such mesh or a body that loses one has no explicit
    ``<inertial>`` (its mass would change)."""
    import mujoco

    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except ValueError:
        return None
    base = Path(spec.modelfiledir or path.parent)
    meshdir = Path(spec.meshdir) if spec.meshdir else Path()
    missing = set()
    for mesh in spec.meshes:
        if mesh.file:
            where = Path(mesh.file) if Path(mesh.file).is_absolute() else base / meshdir / mesh.file
            if not where.is_file() and not (base / mesh.file).is_file():
                missing.add(mesh.name or Path(mesh.file).stem)
    if not missing:
        return None
    doomed = [g for g in spec.geoms if g.meshname in missing]
    for geom in doomed:
        body = spec.body(geom.parent.name) if geom.parent is not None else None
        if body is None or not body.explicitinertial:
            return None
    for geom in doomed:
        spec.delete(geom)
    for mesh in [m for m in spec.meshes if (m.name or Path(m.file).stem) in missing]:
        spec.delete(mesh)
    return spec


def _joint_hint(name: str, body: str, free: bool) -> str:
    if free:
        return (f"joint '{name}' of body '{body}' is a free joint (a floating body); only hinge and slide joints are supported: "
                f"in a copy of the model, delete <freejoint/> (or <joint type=\"free\"/>) from body '{body}' so that it is fixed to its parent")
    return (f"joint '{name}' of body '{body}' is a ball joint; only hinge and slide joints are supported: in a copy of the model, "
            "replace it by three hinge joints with orthogonal axes at the same pos")


def _read_mjcf(path: Path) -> RobotModel:
    import mujoco

    model, warnings = _compile_mjcf(path)
    if any("NaN" in w for w in warnings):
        raise InputError(f"{path.name}: the model contains a 'NaN' (MuJoCo: {' '.join(warnings[0].split())[:120]})")
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
                raise InputError(f"{path.name}: {_joint_hint(name, names[b], kind == int(mujoco.mjtJoint.mjJNT_FREE))}")
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
