"""The resolution context: symbol tables and the checks every section of a file shares.

A :class:`Context` knows the file's label, every declared name and its unit, and turns raw
values into SI numbers or expression trees, checking dimensions, names and finiteness.
Errors raised below it (units, expressions) get the file and key attached here.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable, Iterator, Mapping, Set as AbstractSet
from contextlib import contextmanager
from typing import Any

import numpy as np

from ...errors import InputError, ProblemFileError, UnitError, raise_errors
from ...model.functions import NUMPY_FUNCTIONS
from ...model import expr as ex
from ...model.mechanism import GROUND, Frame, Point
from ...model.constraints import CONSTRAINT_FUNCTIONS
from ...model.problem import Parameter
from ...model.units import (
    DIMENSIONLESS,
    LENGTH,
    MASS,
    STIFFNESS,
    DisplayUnit,
    Quantity,
    angle_hint,
    check_dimension,
    canonical_dimension,
    check_length_range,
    dimensionality_of,
    display_unit,
    is_angle_unit,
    looks_like_quantity,
    parse_quantity,
    pint_quantity,
    ureg,
)
from ..schema import ProblemFile
from ... import registry

#: Functions report expressions may call besides the math functions. Their arguments name
#: a subsystem (and a frame), e.g. ``total_mass(side_left)``, ``com_distance(leg, base)``.
REPORT_FUNCTIONS = frozenset({"total_mass", "com_distance"})
#: Functions whose arguments are names (of a subsystem, frame, spring, counter-mass): the
#: report functions and the named quantities of constraints (counterpoise.model.constraints).
NAME_FUNCTIONS = REPORT_FUNCTIONS | CONSTRAINT_FUNCTIONS
RESERVED = frozenset(ex.MATH_FUNCTIONS | REPORT_FUNCTIONS | set(ex.CONSTANTS) | {GROUND})
#: Random points of the box on which expressions that depend on variables or coordinates
#: are checked for finite values (besides its corners).
BOX_SAMPLES = 256
AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


class Context:
    """Shared state of one file's resolution (see the module docstring)."""

    def __init__(self, spec: ProblemFile, label: str) -> None:
        self.spec = spec
        self.label = label
        self.symbol_unit: dict[str, DisplayUnit] = {}  # name -> unit (for dimension checks)
        self.symbol_value: dict[str, float] = {}  # name -> representative SI value
        self.symbol_kind: dict[str, str] = {}  # name -> 'parameters' | 'variables' | 'coordinates' | 'report'
        self.literal_unit: dict[str, DisplayUnit] = {}  # key -> unit of a quantity literal written there
        self.variable_lower: dict[str, float] = {}
        self.box: dict[str, tuple[float, float]] = {}  # variable or coordinate -> its range (SI)
        self.signed: list[tuple[str, ex.Expr, Any, str]] = []  # (key, tree, raw, what) of masses and stiffnesses
        self.derived_parameters: list[Parameter] = []
        self.coupled: dict[str, ex.Expr] = {}  # coupled coordinate -> its tree in the coordinates
        self.payload_masses: dict[str, Any] = {}  # payload -> (lower, upper, nominal, unit), SI
        #: errors found so far that did not stop the resolution (see :meth:`item`)
        self.errors: list[ProblemFileError] = []
        #: derived parameter -> its angle kind (see :meth:`angle_kind`)
        self.name_kinds: dict[str, tuple[str, str]] = {}

    @contextmanager
    def at(self, key: str) -> Iterator[None]:
        """Attach the file and ``key`` to any input error raised inside the block."""
        try:
            yield
        except InputError as exc:
            raise ProblemFileError(self.label, key, str(exc)) from None

    def fail(self, key: str, message: str) -> ProblemFileError:
        return ProblemFileError(self.label, key, message)

    @contextmanager
    def item(self) -> Iterator[None]:
        """One independent entry (a variable, a scenario): an error inside is recorded and
        the resolution goes on with the next entry, so that every error of a file is
        reported. Call :meth:`check` before anything that needs the entries."""
        try:
            yield
        except ProblemFileError as exc:
            self.errors.append(exc)

    def defer(self, error: ProblemFileError) -> None:
        """Record ``error`` and go on (the caller substitutes a harmless value)."""
        self.errors.append(error)

    def check(self) -> None:
        """Raise the errors recorded so far (one line each), if any."""
        raise_errors(self.errors)

    # -- names ---------------------------------------------------------------------

    def declare(self, kind: str, name: str) -> None:
        key = f"{kind}.{name}"
        if name in RESERVED:
            raise self.fail(key, f"'{name}' is reserved (a function, constant or the ground frame)")
        if name in self.symbol_kind:
            raise self.fail(key, f"name '{name}' is already used by {self.symbol_kind[name]}.{name}")
        self.symbol_kind[name] = kind

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
                except UnitError:  # '90 deg - q_lift': an expression that starts with a quantity
                    tree = ex.parse(value, functions, read_quantity)
                else:
                    self.literal_unit[key] = q.unit
                    return ex.Num(q.si, q.unit.symbol)
            else:
                tree = ex.parse(value, functions, read_quantity)
            ex.check_names(tree, allowed, value, NAME_FUNCTIONS & functions)
            if self.coupled and ex.names(tree) & self.coupled.keys():
                tree = ex.substitute(tree, self.coupled)
            return tree

    def dimension(self, tree: ex.Expr, raw: Any, key: str, extra: Mapping[str, Callable[..., Any]] | None = None) -> str:
        """The dimensionality of an expression (pint evaluation on representative values)."""
        if isinstance(tree, ex.Num):
            if tree.unit:
                return display_unit(tree.unit).dimension
            unit = self.literal_unit.get(key)
            if unit is not None:
                return unit.dimension
            return "" if tree.value != 0 else "zero"
        self.angle_kind(tree, raw, key)  # no bare number added to an angle
        reg = ureg()
        env = {n: pint_quantity(self.symbol_value[n], self.symbol_unit[n]) for n in ex.names(tree, NAME_FUNCTIONS) if n in self.symbol_unit}
        funcs = numpy_functions()
        if extra:
            funcs.update(extra)
        with self.at(key):
            result = evaluate_checked(tree, env, funcs, raw)
        if not isinstance(result, reg.Quantity):
            return ""
        return dimensionality_of(result)

    # -- angles --------------------------------------------------------------------

    def angle_kind(self, tree: ex.Expr, raw: Any, key: str) -> tuple[str, str]:
        """What an expression is as far as angles go, and where that comes from.

        pint treats angles as dimensionless, so '90' and '90 deg' have the same dimension
        and a bare number would silently be radians. This tracks, besides dimensions:
        ``angle`` (written with an angle unit: a quantity such as '90 deg', a coordinate,
        parameter or variable given in deg or rad, asin/acos/atan of something),
        ``bare`` (a non-zero number without a unit, or a parameter or variable given as
        one), ``zero`` (a bare 0) and ``other``. Adding a bare number to an angle, or
        handing one to sin/cos/tan, is an error: the number would be taken as radians.
        Products and quotients of an angle by a number stay angles (``2*theta``).
        """
        if isinstance(tree, ex.Num):
            if tree.unit:
                return ("angle" if is_angle_unit(tree.unit) else "other", "")
            return ("bare", f"{tree.value:g}") if tree.value != 0 else ("zero", "")
        if isinstance(tree, ex.Name):
            return self._name_kind(tree.id)
        if isinstance(tree, ex.Neg):
            return self.angle_kind(tree.operand, raw, key)
        if isinstance(tree, ex.Call):
            args = [self.angle_kind(a, raw, key) for a in tree.args] if tree.func in ex.MATH_FUNCTIONS else []
            if tree.func in ("sin", "cos", "tan") and args and args[0][0] == "bare":
                raise self.fail(key, f"'{raw}': {tree.func}() of {_bare_what(args[0][1])} takes it as radians: {_bare_fix(args[0][1])}")
            if tree.func in ("asin", "acos", "atan"):
                return ("angle", "")
            if tree.func == "abs" and args:
                return args[0]
            return ("bare", args[0][1]) if args and args[0][0] == "bare" else ("other", "")
        if isinstance(tree, ex.BinOp):
            a = self.angle_kind(tree.left, raw, key)
            b = self.angle_kind(tree.right, raw, key)
            if a[0] == b[0] == "bare" and not ex.names(tree):  # '2*45': the number it makes
                with np.errstate(all="ignore"):
                    try:
                        a = b = ("bare", f"{float(np.real(ex.evaluate(tree, {}, numpy_functions()))):g}")
                    except (ArithmeticError, ValueError, TypeError):
                        pass  # '1/0': reported elsewhere; the first number is named meanwhile
            kinds = {a[0], b[0]}
            if tree.op in "+-":
                if kinds == {"angle", "bare"}:
                    bare = a if a[0] == "bare" else b
                    raise self.fail(key, f"'{raw}' adds {_bare_what(bare[1])} to an angle, which takes it as radians: {_bare_fix(bare[1])}")
                if "zero" in kinds:
                    return b if a[0] == "zero" else a
                if "angle" in kinds:
                    return ("angle", "")
                return ("bare", a[1]) if kinds == {"bare"} else ("other", "")
            if tree.op == "*":
                if kinds == {"angle"}:
                    return ("other", "")
                if "angle" in kinds:
                    return ("angle", "")
                return ("bare", a[1]) if kinds == {"bare"} else ("other", "")
            if tree.op == "/":
                if a[0] == "angle":
                    return ("other", "") if b[0] == "angle" else ("angle", "")
                return ("bare", a[1]) if kinds == {"bare"} else ("other", "")
            return ("bare", a[1]) if kinds == {"bare"} else ("other", "")  # **
        return ("other", "")

    def _name_kind(self, name: str) -> tuple[str, str]:
        if name in self.name_kinds:
            return self.name_kinds[name]
        unit = self.symbol_unit.get(name)
        kind = self.symbol_kind.get(name)
        if unit is None:
            return ("other", "")
        if is_angle_unit(unit.symbol):
            return ("angle", "")
        if unit.symbol or unit.dimension or kind not in ("parameters", "variables"):
            return ("other", "")
        if kind == "parameters" and self.symbol_value.get(name) == 0:
            return ("zero", "")
        section = "parameters" if kind == "parameters" else "variables"
        return ("bare", f"{section}.{name}")

    def expect_angle(self, tree: ex.Expr, raw: Any, key: str) -> None:
        """An angle is expected here: a bare number (or a parameter given as one) is an
        error saying how to write it, e.g. "write '90 deg' or '1.5708 rad'"."""
        kind, where = self.angle_kind(tree, raw, key)
        if kind == "bare":
            if where.startswith(("parameters.", "variables.")):
                raise self.fail(key, f"'{raw}' uses {where}, a bare number, as an angle: give it a unit there (deg or rad)")
            raise self.fail(key, f"a bare number used as an angle ('{raw}' would be radians): {angle_hint(float(where))}")

    def expect(self, tree: ex.Expr, raw: Any, key: str, dimension: str, what: str) -> None:
        found = self.dimension(tree, raw, key)
        if found == "zero":
            return  # a literal 0 fits any dimension
        if found == "" and isinstance(tree, ex.Num) and dimension != DIMENSIONLESS and key not in self.literal_unit:
            raise self.fail(key, f"{what} needs a unit: write e.g. '{raw} {example_unit(dimension)}'")
        with self.at(key):
            check_dimension(found, dimension, f"'{raw}'")
        value = self.finite(tree, raw, key)
        if not isinstance(tree, ex.Num):  # a literal was checked when it was read
            with self.at(key):  # a length or position computed from parameters: the same bound
                check_length_range(value, canonical_dimension(dimension), raw)

    def finite(self, tree: ex.Expr, raw: Any, key: str) -> float:
        """Evaluate at the given parameters and the initial design; the value must be finite."""
        env = {n: v for n, v in self.symbol_value.items() if self.symbol_kind.get(n) in ("parameters", "slots", "variables", "coordinates")}
        with np.errstate(all="ignore"):
            try:
                value = complex(ex.evaluate(tree, env, numpy_functions()))
            except (ArithmeticError, ValueError, TypeError):
                value = complex("nan")
        if value.imag != 0 or not math.isfinite(value.real):
            where = "" if ex.names(tree) <= self.parameter_names() else " at the initial design"
            raise self.fail(key, f"'{raw}' does not evaluate to a finite number{where}")
        self.finite_everywhere(tree, raw, key)
        return value.real

    def finite_everywhere(self, tree: ex.Expr, raw: Any, key: str) -> None:
        """The value must also be finite over the whole box of the variables' bounds and the
        coordinates' ranges it depends on: the NLP samples random designs and configurations
        in that box. Checked on every corner (up to 2^10) and :data:`BOX_SAMPLES` seeded
        random points; the first point where it is not finite is named."""
        moving = sorted(n for n in ex.names(tree) if n in self.box)
        if not moving or isinstance(tree, ex.Name):
            return
        lo = np.array([self.box[n][0] for n in moving])
        hi = np.array([self.box[n][1] for n in moving])
        points = [lo + (hi - lo) * np.random.default_rng(0).random((BOX_SAMPLES, len(moving)))]
        if len(moving) <= 10:
            points.insert(0, np.array(list(itertools.product(*zip(lo, hi))), dtype=float))
        q = np.vstack(points)
        env: dict[str, Any] = {n: v for n, v in self.symbol_value.items() if self.symbol_kind.get(n) in ("parameters", "variables", "coordinates")}
        env.update({n: q[:, i] for i, n in enumerate(moving)})
        with np.errstate(all="ignore"):
            try:
                values = np.broadcast_to(np.asarray(ex.evaluate(tree, env, numpy_functions()), dtype=float), (len(q),))
            except (ArithmeticError, ValueError, TypeError):
                values = np.full(len(q), np.nan)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            i = int(bad[0])
            at = ", ".join(f"{n} = {_shown(q[i, j], self.symbol_unit[n])}" for j, n in enumerate(moving))
            raise self.fail(key, f"'{raw}' is not a finite number everywhere within the bounds: {values[i]} at {at}")

    def parameter_names(self) -> set[str]:
        return {n for n, k in self.symbol_kind.items() if k in ("parameters", "slots")}

    # -- sections ------------------------------------------------------------------

    def geometry_names(self) -> set[str]:
        return {n for n, k in self.symbol_kind.items() if k in ("parameters", "slots", "variables", "coordinates", "coupled")}

    def design_names(self) -> set[str]:
        return {n for n, k in self.symbol_kind.items() if k in ("parameters", "slots", "variables")}

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

    def axis(self, value: Any, key: str) -> tuple[ex.Expr, ex.Expr, ex.Expr]:
        if isinstance(value, str):
            x, y, z = AXES[value]
            return (ex.Num(x), ex.Num(y), ex.Num(z))
        # an axis may depend on parameters and variables (a tilt), not on coordinates
        vec = self.vector(value, key, DIMENSIONLESS, "an axis component", self.design_names())
        norm = math.sqrt(sum(self.finite(c, value, key) ** 2 for c in vec))
        if norm == 0:
            raise self.fail(key, "the rotation axis must not be the zero vector")
        a, b, c = vec
        if isinstance(a, ex.Num) and isinstance(b, ex.Num) and isinstance(c, ex.Num):
            return (ex.Num(a.value / norm), ex.Num(b.value / norm), ex.Num(c.value / norm))
        return vec

    def point(self, frame: str, position: Iterable[Any], key: str, frames: Mapping[str, Frame], frame_key: str) -> Point:
        if frame != GROUND and frame not in frames:
            # reported with the file's other errors; the point is placed on the ground meanwhile
            self.defer(self.fail(frame_key, f"unknown frame '{frame}'{suggest(frame, list(frames) + [GROUND])}"))
            frame = GROUND
        # a point is fixed in its frame: it may not move with coordinates (use a frame for that)
        return Point(frame, self.vector(position, key, LENGTH, "a position", self.design_names()))

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
            where = "" if ex.names(tree) <= self.parameter_names() else " at the initial design"
            raise self.fail(key, f"{what} must not be negative, got '{raw}'{where}")
        self.signed.append((key, tree, raw, what))

    def subsystem_of(self, frame: str, frames: Mapping[str, Frame]) -> str | None:
        if frame == GROUND or frame not in frames:  # an unknown frame is reported by point()
            return None
        return frames[frame].subsystem


def _shown(si: float, unit: DisplayUnit) -> str:
    """An SI value in its display unit, for a message: '250 g', '0.25'."""
    text = f"{unit.from_si(si):.4g}"
    return f"{text} {unit.symbol}" if unit.symbol else text


def _bare_what(where: str) -> str:
    if where.startswith(("parameters.", "variables.")):
        return f"{where}, a bare number,"
    return f"the bare number {where}"


def _bare_fix(where: str) -> str:
    if where.startswith(("parameters.", "variables.")):
        return "give it a unit there (deg or rad)"
    try:
        return angle_hint(float(where))
    except ValueError:
        return "give the number a unit (deg or rad)"


def read_quantity(number: float, unit: str) -> float | None:
    """A quantity inside an expression ('90 deg'): its SI value, or None if ``unit`` is not
    a unit (the text is then parsed as it stands)."""
    try:
        u = display_unit(unit)
    except UnitError:
        return None
    si = number * u.to_si
    if not math.isfinite(si):
        raise UnitError(f"value must be finite, got '{number:g} {unit}' (too large once converted to SI units)")
    check_length_range(si, u.dimension, f"{number:g} {unit}")
    return si


def _pint_constant(num: ex.Num) -> Any:
    """A number in pint evaluation: with its unit when it was written with one."""
    return pint_quantity(num.value, display_unit(num.unit)) if num.unit else num.value


def numpy_functions() -> dict[str, Callable[..., Any]]:
    """The numpy backend's functions, with a plain abs (pint quantities and complex floats)."""
    return {**NUMPY_FUNCTIONS, "abs": np.abs}


def evaluate_checked(tree: ex.Expr, env: Mapping[str, Any], functions: Mapping[str, Callable[..., Any]], raw: Any) -> Any:
    """Evaluate on pint quantities; unit clashes and arithmetic failures become UnitErrors."""
    import pint

    with np.errstate(all="ignore"):
        try:
            return ex.evaluate(tree, env, functions, _pint_constant)
        except InputError:
            raise
        except pint.DimensionalityError as exc:
            raise UnitError(f"inconsistent units in '{raw}': {_short(exc)}") from None
        except Exception as exc:  # ZeroDivisionError, OverflowError, pint's offset errors, ...
            raise UnitError(f"cannot evaluate '{raw}': {_short(exc)}") from None


suggest = ex.suggest


def _short(exc: Exception) -> str:
    text = " ".join(str(exc).split())
    return text[:160]


def example_unit(dimension: str) -> str:
    return {LENGTH: "mm", MASS: "g", STIFFNESS: "N/mm"}.get(dimension, "mm")


def topological(nodes: Mapping[str, object], deps: Callable[[str], AbstractSet[str]], section: str, label: str, key_suffix: str = "") -> list[str]:
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


def combinations(ctx: Context) -> None:
    """The problem-file tables a registered design layer cannot be combined with yet
    (:data:`counterpoise.registry.REGISTRY`, each entry's ``not_with``): an input error
    naming the layer's table, e.g. "not combinable yet: [robust] with [slots]"."""
    for entry in registry.REGISTRY:
        if not entry.table or not getattr(ctx.spec, entry.table, None):
            continue
        for other in entry.not_with:
            if getattr(ctx.spec, other, None):
                raise ctx.fail(entry.table, f"not combinable yet: [{entry.table}] with [{other}]" + (f" ({entry.docs})" if entry.docs else ""))
