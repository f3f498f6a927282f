"""Load a TOML problem file, validate it and resolve it into a typed :class:`Problem`.

Three passes, each failing with a one-line :class:`ProblemFileError` naming the file and
the key: TOML syntax (``tomllib``), shape (:mod:`counterpoise.schema`), then meaning:
units and dimensions, names in expressions, the frame graph, bounds and signs.
"""

from __future__ import annotations

import math
import re
import sys
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from . import expr as ex
from .elements import CounterMass, ZeroFreeLengthSpring
from .errors import InputError, ProblemFileError, UnitError
from .mechanics import NUMPY_FUNCTIONS
from .model import GROUND, Body, Coordinate, Frame, Point, Rotation, Subsystem, Transform, Translation
from .problem import Gravity, Objective, Parameter, Problem, ReportQuantity, Scenario, Settings, Variable
from .schema import ProblemFile, RotateSpec
from .units import (
    DIMENSIONLESS,
    INVERSE_AREA,
    LENGTH,
    MASS,
    STIFFNESS,
    ACCELERATION,
    DisplayUnit,
    Quantity,
    base_unit_symbol,
    canonical_dimension,
    check_dimension,
    dimension_name,
    dimensionality_of,
    display_unit,
    looks_like_quantity,
    parse_quantity,
    pint_quantity,
    ureg,
)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: Functions report expressions may call besides the math functions. Their arguments name
#: a subsystem (and a frame), e.g. ``total_mass(side_left)``, ``com_distance(leg, base)``.
REPORT_FUNCTIONS = frozenset({"total_mass", "com_distance"})
RESERVED = frozenset(ex.MATH_FUNCTIONS | REPORT_FUNCTIONS | set(ex.CONSTANTS) | {GROUND})
DEFAULT_SCENARIO = "nominal"

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def load_problem(path: str | Path, overrides: Mapping[str, str] | None = None) -> Problem:
    """Read, validate and resolve one problem file.

    ``overrides`` maps dotted keys to values applied to the TOML before validation, e.g.
    ``{"objective.inertia_weight": "50 1/m^2", "parameters.r_a": "140 mm"}``.
    """
    path = Path(path)
    label = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ProblemFileError(label, "file", f"cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise ProblemFileError(label, "file", "not UTF-8 text") from None
    return load_problem_text(text, label, overrides)


def load_problem_text(text: str, label: str = "<string>", overrides: Mapping[str, str] | None = None) -> Problem:
    """As :func:`load_problem`, from TOML text (``label`` names it in error messages)."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        line = re.search(r"line (\d+)", msg)
        key = f"line {line.group(1)}" if line else "toml"
        raise ProblemFileError(label, key, f"TOML syntax error: {re.sub(r' ?[(]at line.*', '', msg)}") from None
    for key, value in (overrides or {}).items():
        _apply_override(raw, key, value, label)
    from pydantic import ValidationError

    try:
        spec = ProblemFile.model_validate(raw)
    except ValidationError as exc:
        errors = exc.errors()
        # an unknown key explains a missing one next to it ('uper' hides 'upper'): report it first
        err = next((e for e in errors if e.get("type") == "extra_forbidden"), errors[0])
        loc = _clean_loc(raw, err["loc"], keep_last=err.get("type") == "missing")
        key = ".".join(str(k) for k in loc) or "file"
        raise ProblemFileError(label, key, _pydantic_message(err, errors)) from None
    return _Resolver(spec, label).problem()


def _apply_override(raw: dict[str, Any], key: str, value: Any, label: str) -> None:
    parts = key.split(".")
    node: Any = raw
    for part in parts[:-1]:
        if not isinstance(node, dict):
            raise ProblemFileError(label, key, "override path does not lead to a table")
        node = node.setdefault(part, {})
    if not isinstance(node, dict) or not parts[-1]:
        raise ProblemFileError(label, key, "override path does not lead to a table")
    node[parts[-1]] = value


def _clean_loc(raw: Any, loc: Iterable[Any], keep_last: bool) -> list[Any]:
    """Keep the parts of a pydantic error location that are real keys of the file.

    pydantic adds union tags and markers such as ``[key]``; they are dropped. A missing
    key (``keep_last``) is named although the file does not contain it.
    """
    out: list[Any] = []
    node = raw
    items = list(loc)
    for i, part in enumerate(items):
        if isinstance(node, dict) and part in node:
            node = node[part]
            out.append(part)
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            node = node[part]
            out.append(part)
        elif keep_last and i == len(items) - 1:
            out.append(part)
    return out


def _pydantic_message(err: Mapping[str, Any], errors: list[Any]) -> str:
    kind = err.get("type", "")
    if kind == "extra_forbidden":
        loc = tuple(err["loc"])
        missing = [e["loc"][-1] for e in errors if e.get("type") == "missing" and tuple(e["loc"][:-1]) == loc[:-1]]
        hint = _suggest(str(loc[-1]), [str(m) for m in missing])
        return f"unknown key{hint}"
    if kind == "missing":
        return "missing required key"
    if kind == "too_short":
        return "must not be empty"
    if kind == "string_pattern_mismatch":
        if "." in (err.get("ctx") or {}).get("pattern", ""):  # problem.name
            rule = "letters, digits, '_', '.' and '-', starting with a letter or digit"
        else:
            rule = "letters, digits and '_', starting with a letter"
        return f"invalid name {err.get('input')!r}: use {rule}"
    if kind == "literal_error":
        return f"expected one of {(err.get('ctx') or {}).get('expected', '')}, got {err.get('input')!r}"
    msg = str(err.get("msg", "invalid value"))
    return msg.removeprefix("Value error, ")


# --------------------------------------------------------------------------------------
# Resolution: names, units, graph
# --------------------------------------------------------------------------------------


class _Resolver:
    """Turns a shape-checked :class:`ProblemFile` into a :class:`Problem`."""

    def __init__(self, spec: ProblemFile, label: str) -> None:
        self.spec = spec
        self.label = label
        self.symbol_unit: dict[str, DisplayUnit] = {}  # name -> unit (for dimension checks)
        self.symbol_value: dict[str, float] = {}  # name -> representative SI value
        self.symbol_kind: dict[str, str] = {}  # name -> 'parameters' | 'variables' | 'coordinates' | 'report'
        self.literal_unit: dict[str, DisplayUnit] = {}  # key -> unit of a quantity literal written there
        self.variable_lower: dict[str, float] = {}
        self.signed: list[tuple[str, ex.Expr, Any, str]] = []  # (key, tree, raw, what) of masses and stiffnesses
        self.derived_parameters: list[Parameter] = []

    @contextmanager
    def at(self, key: str) -> Iterator[None]:
        """Attach the file and ``key`` to any input error raised inside the block."""
        try:
            yield
        except InputError as exc:
            raise ProblemFileError(self.label, key, str(exc)) from None

    def fail(self, key: str, message: str) -> ProblemFileError:
        return ProblemFileError(self.label, key, message)

    # -- names ---------------------------------------------------------------------
    def declare(self, kind: str, name: str) -> None:
        key = f"{kind}.{name}"
        if name in RESERVED:
            raise self.fail(key, f"'{name}' is reserved (a function, constant or the ground frame)")
        if name in self.symbol_kind:
            raise self.fail(key, f"name '{name}' is already used by {self.symbol_kind[name]}.{name}")
        self.symbol_kind[name] = kind

    def problem(self) -> Problem:
        s = self.spec
        for kind in ("parameters", "variables", "report"):
            for name in getattr(s, kind):
                self.declare(kind, name)
        for sub in s.subsystems.values():
            for cname in sub.coordinates:
                self.declare("coordinates", cname)
        parameters = self.parameters()
        variables = self.variables()
        subsystems, coordinates = self.subsystems()
        frames = self.frames()
        frame_by_name = {f.name: f for f in frames}
        bodies = self.bodies(frame_by_name)
        counter_masses = self.counter_masses(frame_by_name)
        springs = self.springs(frame_by_name)
        gravity = self.gravity(s.gravity, "gravity")
        scenarios = self.scenarios(gravity, parameters)
        objective = self.objective()
        report = self.report(subsystems, frame_by_name)
        meta = s.problem
        return Problem(
            name=meta.name,
            title=meta.title,
            source=meta.source,
            description=meta.description,
            path=self.label,
            parameters=parameters,
            variables=variables,
            subsystems=subsystems,
            coordinates=coordinates,
            frames=frames,
            bodies=bodies,
            counter_masses=counter_masses,
            springs=springs,
            scenarios=scenarios,
            objective=objective,
            report=report,
            settings=Settings(**s.settings.model_dump()),
        )

    # -- values --------------------------------------------------------------------
    def literal(self, value: Any, key: str) -> Quantity:
        """A value that must be a literal: a quantity string or a number."""
        with self.at(key):
            if isinstance(value, str) and not looks_like_quantity(value):
                raise UnitError(f"expected a quantity such as '135 mm', got '{value}'")
            return parse_quantity(value)

    def expression(self, value: Any, key: str, allowed: Iterable[str], functions: frozenset[str] = ex.MATH_FUNCTIONS) -> ex.Expr:
        """A value that may be a literal or an expression over ``allowed`` names.

        Quantity literals become numbers in SI; a bare number means itself (in SI), and
        is only accepted where the dimension allows it (see :meth:`dimension`).
        """
        with self.at(key):
            if isinstance(value, (int, float)):
                if not math.isfinite(value):
                    raise UnitError(f"value must be finite, got {value}")
                return ex.Num(float(value))
            if looks_like_quantity(value):
                try:
                    q = parse_quantity(value)
                except UnitError as exc:
                    used = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", value)) & set(self.symbol_kind)
                    if used:
                        raise UnitError(
                            f"{exc}: a quantity cannot be part of an expression in '{value}'; "
                            "declare it in [parameters] and use its name"
                        ) from None
                    raise
                self.literal_unit[key] = q.unit
                return ex.Num(q.si)
            tree = ex.parse(value, functions)
            ex.check_names(tree, allowed, value, REPORT_FUNCTIONS & functions)
            return tree

    def dimension(self, tree: ex.Expr, raw: Any, key: str, extra: Mapping[str, Callable[..., Any]] | None = None) -> str:
        """The dimensionality of an expression (pint evaluation on representative values)."""
        if isinstance(tree, ex.Num):
            unit = self.literal_unit.get(key)
            if unit is not None:
                return unit.dimension
            return "" if tree.value != 0 else "zero"
        reg = ureg()
        env = {n: pint_quantity(self.symbol_value[n], self.symbol_unit[n]) for n in ex.names(tree, REPORT_FUNCTIONS) if n in self.symbol_unit}
        funcs = _numpy_functions()
        if extra:
            funcs.update(extra)
        with self.at(key):
            result = _evaluate_checked(tree, env, funcs, raw)
        if not isinstance(result, reg.Quantity):
            return ""
        return dimensionality_of(result)

    def expect(self, tree: ex.Expr, raw: Any, key: str, dimension: str, what: str) -> None:
        found = self.dimension(tree, raw, key)
        if found == "zero":
            return  # a literal 0 fits any dimension
        if found == "" and isinstance(tree, ex.Num) and dimension != DIMENSIONLESS and key not in self.literal_unit:
            raise self.fail(key, f"{what} needs a unit: write e.g. '{raw} {_example_unit(dimension)}'")
        with self.at(key):
            check_dimension(found, dimension, f"'{raw}'")
        self.finite(tree, raw, key)

    def finite(self, tree: ex.Expr, raw: Any, key: str) -> float:
        """Evaluate at the given parameters and the initial design; the value must be finite."""
        env = {n: v for n, v in self.symbol_value.items() if self.symbol_kind.get(n) in ("parameters", "variables", "coordinates")}
        with np.errstate(all="ignore"):
            try:
                value = complex(ex.evaluate(tree, env, _numpy_functions()))
            except (ArithmeticError, ValueError, TypeError):
                value = complex("nan")
        if value.imag != 0 or not math.isfinite(value.real):
            where = "" if ex.names(tree) <= self._parameter_names() else " at the initial design"
            raise self.fail(key, f"'{raw}' does not evaluate to a finite number{where}")
        return value.real

    def _parameter_names(self) -> set[str]:
        return {n for n, k in self.symbol_kind.items() if k == "parameters"}

    # -- sections ------------------------------------------------------------------
    def parameters(self) -> tuple[Parameter, ...]:
        entries = self.spec.parameters
        raw_values = {n: (e.value if hasattr(e, "value") else e) for n, e in entries.items()}
        descriptions = {n: getattr(e, "description", "") for n, e in entries.items()}
        literal: dict[str, Quantity] = {}
        derived: dict[str, ex.Expr] = {}
        for name, raw in raw_values.items():
            key = f"parameters.{name}"
            if isinstance(raw, str) and not looks_like_quantity(raw):
                derived[name] = self.expression(raw, key, entries.keys())
            else:
                literal[name] = self.literal(raw, key)
                self.symbol_unit[name] = literal[name].unit
                self.symbol_value[name] = literal[name].si
        order = _topological(derived, lambda n: ex.names(derived[n]) & derived.keys(), "parameters", self.label)
        out: list[Parameter] = [Parameter(n, q.unit, value=q.si, description=descriptions[n]) for n, q in literal.items()]
        for name in order:
            key = f"parameters.{name}"
            tree = derived[name]
            env = {n: pint_quantity(self.symbol_value[n], self.symbol_unit[n]) for n in ex.names(tree)}
            with self.at(key):
                value = _evaluate_checked(tree, env, _numpy_functions(), raw_values[name])
            value = value if isinstance(value, ureg().Quantity) else ureg().Quantity(value, "")
            si = float(value.to_base_units().magnitude)
            if not math.isfinite(si):
                raise self.fail(key, f"'{raw_values[name]}' does not evaluate to a finite number")
            unit = DisplayUnit(base_unit_symbol(value), 1.0, dimensionality_of(value.to_base_units()))
            self.symbol_unit[name] = unit
            self.symbol_value[name] = si
            out.append(Parameter(name, unit, expr=tree, description=descriptions[name]))
        self.derived_parameters = [p for p in out if not p.is_base]
        return tuple(out)

    def variables(self) -> tuple[Variable, ...]:
        out = []
        for name, v in self.spec.variables.items():
            key = f"variables.{name}"
            lower = self.literal(v.lower, f"{key}.lower")
            upper = self.literal(v.upper, f"{key}.upper")
            initial = self.literal(v.initial, f"{key}.initial") if v.initial is not None else None
            with self.at(f"{key}.unit"):
                unit = display_unit(v.unit) if v.unit is not None else (lower.unit if lower.unit.symbol else upper.unit)
            for part, q in (("lower", lower), ("upper", upper), ("initial", initial)):
                if q is not None and q.dimension != unit.dimension and not (q.si == 0 and q.unit.symbol == ""):
                    raise self.fail(f"{key}.{part}", f"expected {dimension_name(unit.dimension)} like unit '{unit.label}', got {dimension_name(q.dimension)}")
            if lower.si > upper.si:
                raise self.fail(key, f"lower bound {v.lower} is greater than upper bound {v.upper}")
            init = initial.si if initial is not None else 0.5 * (lower.si + upper.si)
            if not lower.si <= init <= upper.si:
                raise self.fail(f"{key}.initial", f"initial value {v.initial} lies outside [{v.lower}, {v.upper}]")
            self.symbol_unit[name] = unit
            self.symbol_value[name] = init
            self.variable_lower[name] = lower.si
            out.append(Variable(name, lower.si, upper.si, init, unit, v.adjustable, v.description))
        return tuple(out)

    def subsystems(self) -> tuple[tuple[Subsystem, ...], tuple[Coordinate, ...]]:
        subs, coords = [], []
        for sname, sub in self.spec.subsystems.items():
            for cname, c in sub.coordinates.items():
                key = f"subsystems.{sname}.coordinates.{cname}"
                lo = self.literal(c.range[0], f"{key}.range")
                hi = self.literal(c.range[1], f"{key}.range")
                if lo.dimension != hi.dimension:
                    raise self.fail(f"{key}.range", "both ends of a range need the same dimension")
                if lo.dimension not in ("", canonical_dimension(LENGTH)):
                    raise self.fail(f"{key}.range", f"a coordinate is an angle or a length, got {dimension_name(lo.dimension)}")
                if not lo.si < hi.si:
                    raise self.fail(f"{key}.range", f"empty range [{c.range[0]}, {c.range[1]}]: the lower end must be below the upper end")
                home = self.literal(c.home, f"{key}.home").si if c.home is not None else 0.5 * (lo.si + hi.si)
                if not lo.si <= home <= hi.si:
                    raise self.fail(f"{key}.home", "home lies outside the range")
                self.symbol_unit[cname] = lo.unit
                self.symbol_value[cname] = home
                coords.append(Coordinate(cname, sname, lo.si, hi.si, home, lo.unit, c.description))
            subs.append(Subsystem(sname, tuple(sub.coordinates), sub.description))
        return tuple(subs), tuple(coords)

    def _geometry_names(self) -> set[str]:
        return {n for n, k in self.symbol_kind.items() if k in ("parameters", "variables", "coordinates")}

    def _design_names(self) -> set[str]:
        return {n for n, k in self.symbol_kind.items() if k in ("parameters", "variables")}

    def vector(
        self, values: Iterable[Any], key: str, dimension: str, what: str, allowed: set[str]
    ) -> tuple[ex.Expr, ex.Expr, ex.Expr]:
        out = []
        for i, raw in enumerate(values):
            k = f"{key}.{i}"
            tree = self.expression(raw, k, allowed)
            self.expect(tree, raw, k, dimension, what)
            out.append(tree)
        return (out[0], out[1], out[2])

    def frames(self) -> tuple[Frame, ...]:
        specs = self.spec.frames
        coordinate_subsystem = {c: s for s, sub in self.spec.subsystems.items() for c in sub.coordinates}
        for name, f in specs.items():
            if name == GROUND:
                raise self.fail(f"frames.{name}", "'ground' is the fixed world frame and cannot be declared")
            if f.parent != GROUND and f.parent not in specs:
                close = _suggest(f.parent, list(specs) + [GROUND])
                raise self.fail(f"frames.{name}.parent", f"unknown frame '{f.parent}'{close}")
        order = _topological(
            {n: None for n in specs}, lambda n: {specs[n].parent} - {GROUND}, "frames", self.label, key_suffix="parent"
        )
        frames: dict[str, Frame] = {}
        for name in order:
            f = specs[name]
            key = f"frames.{name}"
            transforms: list[Transform] = []
            used: set[str] = set()
            for i, t in enumerate(f.transforms):
                tkey = f"{key}.transforms.{i}"
                if isinstance(t, RotateSpec):
                    axis = self.axis(t.rotate, f"{tkey}.rotate")
                    angle = self.expression(t.angle, f"{tkey}.angle", self._geometry_names())
                    self.expect(angle, t.angle, f"{tkey}.angle", DIMENSIONLESS, "an angle")
                    used |= ex.names(angle)
                    transforms.append(Rotation(axis, angle))
                else:
                    vec = self.vector(t.translate, f"{tkey}.translate", LENGTH, "a translation", self._geometry_names())
                    for comp in vec:
                        used |= ex.names(comp)
                    transforms.append(Translation(vec))
            subsystems = {coordinate_subsystem[n] for n in used if n in coordinate_subsystem}
            parent_sub = frames[f.parent].subsystem if f.parent != GROUND else None
            if parent_sub is not None:
                subsystems.add(parent_sub)
            if len(subsystems) > 1:
                raise self.fail(
                    key, f"moves with coordinates of several subsystems ({', '.join(sorted(subsystems))}); subsystems must move independently"
                )
            frames[name] = Frame(name, f.parent, tuple(transforms), next(iter(subsystems), None), f.description)
        return tuple(frames[n] for n in order)

    def axis(self, value: Any, key: str) -> tuple[ex.Expr, ex.Expr, ex.Expr]:
        if isinstance(value, str):
            return tuple(ex.Num(c) for c in _AXES[value])  # type: ignore[return-value]
        # an axis may depend on parameters and variables (a tilt), not on coordinates
        vec = self.vector(value, key, DIMENSIONLESS, "an axis component", self._design_names())
        norm = math.sqrt(sum(self.finite(c, value, key) ** 2 for c in vec))
        if norm == 0:
            raise self.fail(key, "the rotation axis must not be the zero vector")
        if all(isinstance(c, ex.Num) for c in vec):
            return tuple(ex.Num(c.value / norm) for c in vec)  # type: ignore[union-attr,return-value]
        return vec

    def point(self, frame: str, position: Iterable[Any], key: str, frames: Mapping[str, Frame], frame_key: str) -> Point:
        if frame != GROUND and frame not in frames:
            raise self.fail(frame_key, f"unknown frame '{frame}'{_suggest(frame, list(frames) + [GROUND])}")
        # a point is fixed in its frame: it may not move with coordinates (use a frame for that)
        return Point(frame, self.vector(position, key, LENGTH, "a position", self._design_names()))

    def nonnegative(self, tree: ex.Expr, raw: Any, key: str, dimension: str, what: str) -> None:
        """Type-check a mass or stiffness; it must not be negative.

        Fixed values are checked here; values that depend on variables are checked at the
        initial design here and kept ≥ 0 by constraints of the NLP.
        """
        self.expect(tree, raw, key, dimension, what)
        if isinstance(tree, ex.Name) and self.variable_lower.get(tree.id, 0.0) < 0:
            raise self.fail(f"variables.{tree.id}.lower", f"'{tree.id}' is {what}: its lower bound must not be negative")
        value = self.finite(tree, raw, key)
        if value < 0:
            where = "" if ex.names(tree) <= self._parameter_names() else " at the initial design"
            raise self.fail(key, f"{what} must not be negative, got '{raw}'{where}")
        self.signed.append((key, tree, raw, what))

    def _subsystem_of(self, frame: str, frames: Mapping[str, Frame]) -> str | None:
        return None if frame == GROUND else frames[frame].subsystem

    def bodies(self, frames: Mapping[str, Frame]) -> tuple[Body, ...]:
        out = []
        for name, b in self.spec.bodies.items():
            key = f"bodies.{name}"
            mass = self.expression(b.mass, f"{key}.mass", self._design_names())
            self.nonnegative(mass, b.mass, f"{key}.mass", MASS, "a mass")
            com = self.point(b.frame, b.com, f"{key}.com", frames, f"{key}.frame")
            out.append(Body(name, mass, com, self._subsystem_of(b.frame, frames), b.description))
        return tuple(out)

    def counter_masses(self, frames: Mapping[str, Frame]) -> tuple[CounterMass, ...]:
        out = []
        for name, c in self.spec.counter_masses.items():
            key = f"counter_masses.{name}"
            mass = self.expression(c.mass, f"{key}.mass", self._design_names())
            self.nonnegative(mass, c.mass, f"{key}.mass", MASS, "a mass")
            pos = self.point(c.frame, c.position, f"{key}.position", frames, f"{key}.frame")
            joint = self.joint(c.frame, c.joint, frames, f"{key}.joint")
            out.append(CounterMass(name, mass, pos, joint, self._subsystem_of(c.frame, frames), c.description))
        return tuple(out)

    def joint(self, frame: str, coordinate: str | None, frames: Mapping[str, Frame], key: str) -> tuple[str, int] | None:
        """Innermost rotation of the chain driven by ``coordinate`` (any coordinate if None)."""
        coordinates = {n for n, k in self.symbol_kind.items() if k == "coordinates"}
        if coordinate is not None and coordinate not in coordinates:
            raise self.fail(key, f"unknown coordinate '{coordinate}'{_suggest(coordinate, coordinates)}")
        wanted = {coordinate} if coordinate else coordinates
        name: str | None = frame
        while name is not None and name != GROUND:
            f = frames[name]
            for i in range(len(f.transforms) - 1, -1, -1):
                t = f.transforms[i]
                if isinstance(t, Rotation) and ex.names(t.angle) & wanted:
                    return (name, i)
            name = f.parent
        if coordinate is not None:
            raise self.fail(key, f"no rotation driven by '{coordinate}' carries frame '{frame}'")
        return None

    def springs(self, frames: Mapping[str, Frame]) -> tuple[ZeroFreeLengthSpring, ...]:
        out = []
        for name, s in self.spec.springs.items():
            key = f"springs.{name}"
            k = self.expression(s.stiffness, f"{key}.stiffness", self._design_names())
            self.nonnegative(k, s.stiffness, f"{key}.stiffness", STIFFNESS, "a stiffness")
            a = self.point(s.from_.frame, s.from_.point, f"{key}.from.point", frames, f"{key}.from.frame")
            b = self.point(s.to.frame, s.to.point, f"{key}.to.point", frames, f"{key}.to.frame")
            subs = {self._subsystem_of(a.frame, frames), self._subsystem_of(b.frame, frames)} - {None}
            if len(subs) > 1:
                raise self.fail(key, f"connects subsystems {' and '.join(sorted(subs))}; subsystems must move independently")  # type: ignore[arg-type]
            out.append(ZeroFreeLengthSpring(name, k, (a, b), next(iter(subs), None), s.description))
        return tuple(out)

    def gravity(self, g: Any, key: str) -> Gravity:
        acc = self.literal(g.acceleration, f"{key}.acceleration")
        with self.at(f"{key}.acceleration"):
            check_dimension(acc.dimension, ACCELERATION, f"'{g.acceleration}'")
        if acc.si < 0:
            raise self.fail(f"{key}.acceleration", "must not be negative (give the direction instead)")
        d = [float(c) for c in g.direction]
        norm = math.sqrt(sum(c * c for c in d))
        if not math.isfinite(norm) or norm == 0:
            raise self.fail(f"{key}.direction", "must be a non-zero vector of finite numbers")
        return Gravity(acc.si, (d[0] / norm, d[1] / norm, d[2] / norm))

    def scenarios(self, gravity: Gravity, parameters: tuple[Parameter, ...]) -> tuple[Scenario, ...]:
        if not self.spec.scenarios:
            return (Scenario(DEFAULT_SCENARIO, gravity, {}),)
        base = {p.name: p for p in parameters if p.is_base}
        out = []
        for name, sc in self.spec.scenarios.items():
            key = f"scenarios.{name}"
            g = self.gravity(sc.gravity, f"{key}.gravity") if sc.gravity is not None else gravity
            values: dict[str, float] = {}
            for pname, raw in sc.parameters.items():
                pkey = f"{key}.parameters.{pname}"
                if pname not in base:
                    hint = " (only literal parameters can change per scenario)" if pname in self.spec.parameters else _suggest(pname, base)
                    raise self.fail(pkey, f"unknown parameter '{pname}'{hint}")
                q = self.literal(raw, pkey)
                if q.dimension != base[pname].unit.dimension and not (q.si == 0 and not q.unit.symbol):
                    raise self.fail(pkey, f"expected {dimension_name(base[pname].unit.dimension)}, got {dimension_name(q.dimension)}")
                values[pname] = q.si
            self.check_scenario_values(values, key)
            out.append(Scenario(name, g, values, sc.description))
        return tuple(out)

    def check_scenario_values(self, values: Mapping[str, float], key: str) -> None:
        """Masses and stiffnesses stay finite and ≥ 0 with a scenario's parameter values."""
        if not values:
            return
        saved = dict(self.symbol_value)
        try:
            for name, value in values.items():
                self.symbol_value[name] = value
            for p in self.derived_parameters:
                with np.errstate(all="ignore"):
                    value = complex(ex.evaluate(p.expr, self.symbol_value, _numpy_functions()))  # type: ignore[arg-type]
                if value.imag != 0 or not math.isfinite(value.real):
                    raise self.fail(key, f"parameter '{p.name}' is not a finite number in this scenario")
                self.symbol_value[p.name] = value.real
            for what_key, tree, raw, what in self.signed:
                try:
                    value = self.finite(tree, raw, key)
                except ProblemFileError as exc:
                    raise self.fail(key, f"{exc.message} (for {what_key} in this scenario)") from None
                if value < 0:
                    raise self.fail(key, f"{what} {what_key} = '{raw}' is negative in this scenario")
        finally:
            self.symbol_value = saved

    def objective(self) -> Objective:
        o = self.spec.objective
        key = "objective.inertia_weight"
        w = self.literal(o.inertia_weight, key)
        if w.si != 0:
            with self.at(key):
                check_dimension(w.dimension, INVERSE_AREA, f"'{o.inertia_weight}'")
        if w.si < 0:
            raise self.fail(key, "must not be negative")
        return Objective(o.mass_weight, w.si)

    def report(self, subsystems: tuple[Subsystem, ...], frames: Mapping[str, Frame]) -> tuple[ReportQuantity, ...]:
        specs = self.spec.report
        known = self._design_names() | set(specs)
        functions = ex.MATH_FUNCTIONS | REPORT_FUNCTIONS
        trees: dict[str, ex.Expr] = {}
        sub_names = {s.name for s in subsystems}
        for name, r in specs.items():
            key = f"report.{name}.expression"
            tree = self.expression(r.expression, key, known, functions)
            for call in ex.calls(tree):
                if call.func in REPORT_FUNCTIONS:
                    self.report_call(call, r.expression, key, sub_names, frames)
            trees[name] = tree
        order = _topological(trees, lambda n: ex.names(trees[n], REPORT_FUNCTIONS) & trees.keys(), "report", self.label)
        extra = {
            "total_mass": ex.NameArgs(lambda *a: ureg().Quantity(1.0, "kg")),
            "com_distance": ex.NameArgs(lambda *a: ureg().Quantity(0.1, "m")),
        }
        out = []
        for name in order:
            r = specs[name]
            key = f"report.{name}"
            with self.at(f"{key}.unit"):
                unit = display_unit(r.unit)
            found = self.dimension(trees[name], r.expression, f"{key}.expression", extra)
            if found == "zero":
                found = unit.dimension
            if found != unit.dimension:
                raise self.fail(f"{key}.unit", f"'{r.expression}' is {dimension_name(found)} but the unit '{unit.label}' is {dimension_name(unit.dimension)}")
            self.symbol_unit[name] = unit
            self.symbol_value[name] = 1.0
            out.append(ReportQuantity(name, trees[name], unit, r.description))
        return tuple(out)

    def report_call(self, call: ex.Call, raw: str, key: str, subsystems: set[str], frames: Mapping[str, Frame]) -> None:
        arity = {"total_mass": (1, 1), "com_distance": (1, 2)}[call.func]
        if not arity[0] <= len(call.args) <= arity[1] or not all(isinstance(a, ex.Name) for a in call.args):
            usage = "total_mass(subsystem)" if call.func == "total_mass" else "com_distance(subsystem[, frame])"
            raise self.fail(key, f"'{raw}': use {usage} with names")
        sub = call.args[0].id  # type: ignore[union-attr]
        if sub not in subsystems:
            raise self.fail(key, f"unknown subsystem '{sub}' in '{raw}'{_suggest(sub, subsystems)}")
        if len(call.args) == 2:
            fr = call.args[1].id  # type: ignore[union-attr]
            if fr != GROUND and fr not in frames:
                raise self.fail(key, f"unknown frame '{fr}' in '{raw}'{_suggest(fr, list(frames) + [GROUND])}")


def _numpy_functions() -> dict[str, Callable[..., Any]]:
    """The numpy backend's functions, with a plain abs (pint quantities and complex floats)."""
    return {**NUMPY_FUNCTIONS, "abs": np.abs}


def _evaluate_checked(tree: ex.Expr, env: Mapping[str, Any], functions: Mapping[str, Callable[..., Any]], raw: Any) -> Any:
    """Evaluate on pint quantities; unit clashes and arithmetic failures become UnitErrors."""
    import pint

    with np.errstate(all="ignore"):
        try:
            return ex.evaluate(tree, env, functions)
        except InputError:
            raise
        except pint.DimensionalityError as exc:
            raise UnitError(f"inconsistent units in '{raw}': {_short(exc)}") from None
        except Exception as exc:  # ZeroDivisionError, OverflowError, pint's offset errors, ...
            raise UnitError(f"cannot evaluate '{raw}': {_short(exc)}") from None


_suggest = ex.suggest


def _short(exc: Exception) -> str:
    text = " ".join(str(exc).split())
    return text[:160]


def _example_unit(dimension: str) -> str:
    return {LENGTH: "mm", MASS: "g", STIFFNESS: "N/mm"}.get(dimension, "mm")


def _topological(nodes: Mapping[str, Any], deps: Callable[[str], set[str]], section: str, label: str, key_suffix: str = "") -> list[str]:
    """Order ``nodes`` so that dependencies come first; a cycle is a ProblemFileError."""
    order: list[str] = []
    state: dict[str, int] = {}

    def visit(n: str, path: list[str]) -> None:
        if state.get(n) == 2:
            return
        if state.get(n) == 1:
            cycle = path[path.index(n):] + [n]
            key = f"{section}.{n}" + (f".{key_suffix}" if key_suffix else "")
            raise ProblemFileError(label, key, f"cyclic definition: {' -> '.join(cycle)}")
        state[n] = 1
        for d in sorted(deps(n)):
            visit(d, path + [n])
        state[n] = 2
        order.append(n)

    for n in nodes:
        visit(n, [])
    return order
