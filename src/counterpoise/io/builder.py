"""Build a problem in Python code: the same sections as a problem file, the same checks.

Tests, studies, notebooks and importers (URDF) build problems here instead of writing
TOML strings. Each method adds one entry of the file format (see ``problems/README.md``)
and returns the builder, so calls chain; :meth:`ProblemBuilder.build` validates the
whole thing through :func:`counterpoise.io.loader.load_problem_data` and returns the typed
:class:`~counterpoise.model.problem.Problem`, with errors naming the key as for a file::

    from counterpoise import ProblemBuilder, design

    b = ProblemBuilder("pendulum", gravity="9.81 m/s^2", direction=(0, -1, 0))
    b.parameter("m", "0.8 kg").parameter("r", "0.3 m")
    b.subsystem("arm", q=("-180 deg", "180 deg"))
    b.frame("link", rotate("z", "q"))
    b.body("tip", frame="link", mass="m", com=("r", 0, 0))
    b.variable("M", "0 kg", "100 kg").variable("b", "0.02 m", "1 m")
    b.counter_mass("cm", frame="link", mass="M", position=("-b", 0, 0))
    b.objective(inertia_weight="16 1/m^2")
    result = design(b.build())
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from typing import Any

from ..model.problem import Problem

Value = str | int | float
Vec3 = Sequence[Value]


def rotate(axis: str | Vec3, angle: Value) -> dict[str, Any]:
    """A rotation transform: ``axis`` is ``"x"``, ``"y"``, ``"z"`` or a 3-vector."""
    return {"rotate": axis if isinstance(axis, str) else list(axis), "angle": angle}


def translate(x: Value, y: Value = 0, z: Value = 0) -> dict[str, Any]:
    """A translation transform."""
    return {"translate": [x, y, z]}


def dh(a: Value, alpha: Value, d: Value, theta: Value) -> dict[str, Any]:
    """A modified (Craig) Denavit-Hartenberg row: Rot_x(alpha) Trans_x(a) Rot_z(theta) Trans_z(d)."""
    return {"dh": {"a": a, "alpha": alpha, "d": d, "theta": theta}}


class ProblemBuilder:
    """Collects the sections of a problem; :meth:`build` validates and resolves them."""

    def __init__(
        self,
        name: str,
        gravity: Value = "9.81 m/s^2",
        direction: Vec3 = (0, -1, 0),
        title: str = "",
        source: str = "",
        description: str = "",
    ) -> None:
        self._data: dict[str, Any] = {
            "problem": {"name": name, "title": title, "source": source, "description": description},
            "gravity": {"acceleration": gravity, "direction": list(direction)},
        }

    @property
    def data(self) -> dict[str, Any]:
        """A copy of the problem as nested dicts, exactly as a TOML file would parse."""
        return copy.deepcopy(self._data)

    def _put(self, section: str, name: str, entry: Any) -> "ProblemBuilder":
        self._data.setdefault(section, {})[name] = entry
        return self

    @staticmethod
    def _described(entry: dict[str, Any], description: str) -> dict[str, Any]:
        if description:
            entry["description"] = description
        return entry

    def parameter(self, name: str, value: Value, description: str = "") -> "ProblemBuilder":
        return self._put("parameters", name, {"value": value, "description": description} if description else value)

    def subsystem(
        self,
        name: str,
        description: str = "",
        homes: Mapping[str, Value] | None = None,
        coupled: Mapping[str, Value] | None = None,
        dependent: Mapping[str, Value] | None = None,
        **coordinates: tuple[Value, Value],
    ) -> "ProblemBuilder":
        """A subsystem and its coordinates as ``name=(lower, upper)`` ranges (``homes`` optional;
        ``coupled`` names expressions of the coordinates, e.g. ``{"psi": "-theta"}``;
        ``dependent`` maps coordinates solved from the loop closures to their homes, which
        pick the assembly branch, e.g. ``{"theta3": "56 deg"}``, see :meth:`loop`)."""
        coords: dict[str, Any] = {}
        for cname, (lo, hi) in coordinates.items():
            coords[cname] = {"range": [lo, hi]}
            if homes and cname in homes:
                coords[cname]["home"] = homes[cname]
        for cname, home in (dependent or {}).items():
            coords[cname] = {"dependent": True, "home": home}
        entry: dict[str, Any] = {"coordinates": coords}
        if coupled:
            entry["coupled"] = dict(coupled)
        return self._put("subsystems", name, self._described(entry, description))

    def frame(
        self, name: str, *transforms: Mapping[str, Any], parent: str = "ground", description: str = "", orientation: str | None = None
    ) -> "ProblemBuilder":
        """A frame: ``parent`` and transforms made with :func:`rotate` and :func:`translate`;
        ``orientation`` names a frame whose axes it keeps (a parallelogram's reference link)."""
        entry: dict[str, Any] = {"parent": parent, "transforms": [dict(t) for t in transforms]}
        if orientation is not None:
            entry["orientation"] = orientation
        return self._put("frames", name, self._described(entry, description))

    def robot(
        self,
        urdf: str | None = None,
        mjcf: str | None = None,
        subsystem: str = "robot",
        joints: Mapping[str, tuple[Value, Value]] | None = None,
        locked: Mapping[str, Value] | None = None,
        homes: Mapping[str, Value] | None = None,
        description: str = "",
    ) -> "ProblemBuilder":
        """A robot model (docs/robots.md): ``urdf`` or ``mjcf`` (absolute, or relative to the
        ``label`` given to :meth:`build`), the moving ``joints`` as ``name: (lower, upper)``,
        the ``locked`` ones as ``name: value``; every link becomes a frame and a body."""
        entry: dict[str, Any] = {"subsystem": subsystem}
        for key, value in (("urdf", urdf), ("mjcf", mjcf)):
            if value is not None:
                entry[key] = str(value)
        entry["joints"] = {}
        for jname, (lo, hi) in (joints or {}).items():
            entry["joints"][jname] = {"range": [lo, hi]}
            if homes and jname in homes:
                entry["joints"][jname]["home"] = homes[jname]
        if locked:
            entry["locked"] = dict(locked)
        self._data["robot"] = self._described(entry, description)
        return self

    def loop(
        self,
        name: str,
        joint: str,
        a: tuple[str, Vec3],
        b: tuple[str, Vec3],
        axis: Vec3 | None = None,
        description: str = "",
        axis_b: Vec3 | None = None,
    ) -> "ProblemBuilder":
        """The joint ``name`` where a closed loop was opened: ``joint`` is ``"revolute"`` (give
        its ``axis`` in frame a's coordinates, and optionally ``axis_b``, the same axis in
        frame b's), ``"prismatic"`` (its ``axis``: the slide) or ``"spherical"``; ``a`` and
        ``b`` are ``(frame, point)`` of the two points it keeps together (see docs/loops.md)."""
        entry: dict[str, Any] = {"joint": joint, "a": {"frame": a[0], "point": list(a[1])}, "b": {"frame": b[0], "point": list(b[1])}}
        if axis is not None:
            entry["axis"] = list(axis)
        if axis_b is not None:
            entry["axis_b"] = list(axis_b)
        return self._put("loops", name, self._described(entry, description))

    def body(self, name: str, frame: str, mass: Value, com: Vec3, description: str = "") -> "ProblemBuilder":
        return self._put("bodies", name, self._described({"frame": frame, "mass": mass, "com": list(com)}, description))

    def variable(
        self,
        name: str,
        lower: Value,
        upper: Value,
        initial: Value | None = None,
        unit: str | None = None,
        adjustable: bool = False,
        description: str = "",
        nominal: Value | None = None,
        travel: Value | None = None,
    ) -> "ProblemBuilder":
        entry: dict[str, Any] = {"lower": lower, "upper": upper}
        if initial is not None:
            entry["initial"] = initial
        if unit is not None:
            entry["unit"] = unit
        if adjustable:
            entry["adjustable"] = True
        for key, value in (("nominal", nominal), ("travel", travel)):
            if value is not None:
                entry[key] = value
        return self._put("variables", name, self._described(entry, description))

    def payload(
        self, name: str, frame: str, range: tuple[Value, Value], position: Vec3 = (0, 0, 0), nominal: Value | None = None, description: str = ""
    ) -> "ProblemBuilder":
        """A payload range (see docs/payload.md): a mass in ``range`` at ``position`` in ``frame``."""
        entry: dict[str, Any] = {"frame": frame, "position": list(position), "range": list(range)}
        if nominal is not None:
            entry["nominal"] = nominal
        return self._put("payloads", name, self._described(entry, description))

    def counter_mass(
        self, name: str, frame: str, mass: Value, position: Vec3, joint: str | None = None, description: str = ""
    ) -> "ProblemBuilder":
        entry: dict[str, Any] = {"frame": frame, "mass": mass, "position": list(position)}
        if joint is not None:
            entry["joint"] = joint
        return self._put("counter_masses", name, self._described(entry, description))

    def spring(
        self, name: str, stiffness: Value, from_: tuple[str, Vec3], to: tuple[str, Vec3], description: str = "", max_force: Value | None = None
    ) -> "ProblemBuilder":
        """A zero-free-length spring between a point of frame ``from_[0]`` and one of ``to[0]``;
        ``max_force``: its largest force, a limit of the design ("60 N")."""
        entry: dict[str, Any] = {
            "stiffness": stiffness,
            "from": {"frame": from_[0], "point": list(from_[1])},
            "to": {"frame": to[0], "point": list(to[1])},
        }
        if max_force is not None:
            entry["max_force"] = max_force
        return self._put("springs", name, self._described(entry, description))

    def constraint(
        self, name: str, expression: str, lower: Value | None = None, upper: Value | None = None, unit: str | None = None, description: str = ""
    ) -> "ProblemBuilder":
        """``lower ≤ expression ≤ upper`` on the design (docs/constraints.md): variables,
        parameters, report quantities and named quantities such as ``force_max(<spring>)``."""
        entry: dict[str, Any] = {"expression": expression}
        for key, value in (("lower", lower), ("upper", upper), ("unit", unit)):
            if value is not None:
                entry[key] = value
        return self._put("constraints", name, self._described(entry, description))

    def substitution(
        self, body: str, points: Mapping[str, tuple[Vec3, str, Vec3]], description: str = ""
    ) -> "ProblemBuilder":
        """Replace ``body`` by point masses: ``points[name] = (at, frame, point)``, ``at`` in the
        body's frame, ``point`` the same point in the receiving ``frame``."""
        entry = {name: {"at": list(at), "frame": frame, "point": list(point)} for name, (at, frame, point) in points.items()}
        return self._put("substitutions", body, self._described({"points": entry}, description))

    def tilt(self, axis: Vec3, lower: Value, upper: Value, description: str = "") -> "ProblemBuilder":
        """A continuous range of base tilts about ``axis`` (of the base) that the balance must
        hold for (``[gravity] tilt``; docs/tilt.md). Several tilts compose in the order given."""
        entry: dict[str, Any] = {"axis": list(axis), "range": [lower, upper]}
        if description:
            entry["description"] = description
        self._data["gravity"].setdefault("tilt", []).append(entry)
        return self

    def scenario(
        self,
        name: str,
        parameters: Mapping[str, Value] | None = None,
        gravity: Value | None = None,
        direction: Vec3 | None = None,
        description: str = "",
    ) -> "ProblemBuilder":
        """A working condition: its own parameter values and, optionally, its own gravity."""
        entry: dict[str, Any] = {"parameters": dict(parameters or {})}
        if gravity is not None or direction is not None:
            base = self._data["gravity"]
            entry["gravity"] = {
                "acceleration": gravity if gravity is not None else base["acceleration"],
                "direction": list(direction) if direction is not None else list(base["direction"]),
            }
        return self._put("scenarios", name, self._described(entry, description))

    def objective(
        self, mass_weight: float = 1.0, inertia_weight: Value = 0, stiffness_weight: Value = 0, goal: str | None = None
    ) -> "ProblemBuilder":
        """Minimise added mass, inertia and stiffness; ``goal="max_payload_range"`` finds the widest payload range instead."""
        weights = {"mass_weight": mass_weight, "inertia_weight": inertia_weight, "stiffness_weight": stiffness_weight}
        self._data["objective"] = goal if goal is not None else weights
        return self

    def report(self, name: str, expression: str, unit: str = "", description: str = "") -> "ProblemBuilder":
        return self._put("report", name, self._described({"expression": expression, "unit": unit}, description))

    def synthesis(self, regions: Mapping[str, Mapping[str, Any]] | None = None, sites: Mapping[str, Mapping[str, Any]] | None = None, **table: Any) -> "ProblemBuilder":
        """The ``[synthesis]`` table (docs/synthesis.md): ``regions`` per frame, ``sites`` per
        name (each a region table: ``box``, ``segment`` or ``holes``, ``points``...), and its
        keys, e.g. ``max_rate="10 N/mm"``."""
        entry: dict[str, Any] = dict(table)
        if regions:
            entry["regions"] = {k: dict(v) for k, v in regions.items()}
        if sites:
            entry["sites"] = {k: dict(v) for k, v in sites.items()}
        self._data["synthesis"] = entry
        return self

    def settings(self, **values: Any) -> "ProblemBuilder":
        self._data.setdefault("settings", {}).update(values)
        return self

    def build(self, label: str | None = None, overrides: Mapping[str, Any] | None = None) -> Problem:
        """Validate and resolve; errors are ProblemFileErrors naming ``label`` and the key."""
        from .loader import load_problem_data

        name = self._data["problem"]["name"]
        return load_problem_data(self._data, label or f"<built:{name}>", overrides)


