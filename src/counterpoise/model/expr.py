"""Whitelisted expressions of problem files.

An expression such as ``"r_a + 0.5*b_b"`` or ``"rho_side * m_endo"`` is parsed with
:mod:`ast` and then *walked*: only numbers, names, ``+ - * / **``, unary minus and calls of
whitelisted functions survive, translated into the small immutable tree below. Nothing is
ever passed to ``eval``. The same tree is evaluated on floats, numpy arrays (complex, for
complex-step derivatives), CasADi SX symbols and pint quantities (to check dimensions),
by handing :func:`evaluate` the matching function table.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Callable, Iterable, Mapping
import re
from dataclasses import dataclass, field
from typing import Any, Union

from ..errors import ExpressionError

MAX_LENGTH = 500

#: Mathematical functions an expression may call (each backend supplies its own version).
MATH_FUNCTIONS = frozenset({"sin", "cos", "tan", "asin", "acos", "atan", "sqrt", "exp", "log", "abs"})
#: Constants every expression may use.
CONSTANTS: Mapping[str, float] = {"pi": math.pi}


@dataclass(frozen=True)
class Num:
    """A number; ``value`` is in SI. ``unit`` is the unit it was written in ('' for a bare
    number): kept for dimension checks and to tell an angle from a bare number."""

    value: float
    unit: str = field(default="", compare=False)


@dataclass(frozen=True)
class Name:
    """A parameter, constant or coordinate named in an expression."""

    id: str


@dataclass(frozen=True)
class BinOp:
    """``left op right``, one of + - * / **."""

    op: str  # one of + - * / **
    left: "Expr"
    right: "Expr"


@dataclass(frozen=True)
class Neg:
    """``-operand``."""

    operand: "Expr"


@dataclass(frozen=True)
class Call:
    """A call of a whitelisted function."""

    func: str
    args: tuple["Expr", ...]


Expr = Union[Num, Name, BinOp, Neg, Call]

_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}

_FORBIDDEN = {
    ast.Attribute: "attribute access",
    ast.Subscript: "subscripts",
    ast.Lambda: "lambda",
    ast.ListComp: "comprehensions",
    ast.SetComp: "comprehensions",
    ast.DictComp: "comprehensions",
    ast.GeneratorExp: "comprehensions",
    ast.Compare: "comparisons",
    ast.BoolOp: "boolean operators",
    ast.IfExp: "conditional expressions",
    ast.NamedExpr: "assignment",
    ast.Starred: "starred arguments",
    ast.List: "lists",
    ast.Tuple: "tuples",
    ast.Dict: "dicts",
    ast.Set: "sets",
    ast.JoinedStr: "strings",
    ast.Await: "await",
    ast.Yield: "yield",
}


#: A number directly followed by a unit inside an expression: ``90 deg``, ``135 mm``,
#: ``0.5 N/mm`` (a compound unit is written without spaces), ``2 m^2``. Compiled on first
#: use (``re``'s own cache), not at import: a solve whose problem comes from the cache parses none.
_NUMBER_UNIT = (
    r"(?<![\w.])((?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*"
    r"([A-Za-z][A-Za-z0-9_]*(?:/[A-Za-z][A-Za-z0-9_]*)*(?:(?:\^|\*\*)-?\d+)?)(?![\w(])"
)
#: Prefix of the names that stand for quantities while Python parses the text.
_PLACEHOLDER = "_quantity_"

#: ``quantity(number, unit)`` -> the value in SI, or None when ``unit`` is not a unit.
QuantityReader = Callable[[float, str], "float | None"]


def parse(text: str, functions: Iterable[str] = MATH_FUNCTIONS, quantity: QuantityReader | None = None) -> Expr:
    """Parse ``text`` into an :data:`Expr`, allowing calls only to ``functions``.

    With ``quantity``, a number followed by a unit (``"-q_lift - 90 deg"``) is a quantity:
    a :class:`Num` holding its SI value and its unit. Without it, such text is an error
    saying that units are not allowed there.
    """
    if not isinstance(text, str):
        raise ExpressionError(f"expected an expression string, got {text!r}")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"expression longer than {MAX_LENGTH} characters")
    if not text.strip():
        raise ExpressionError("empty expression")
    _check_characters(text)
    source, quantities = _quantities(text, quantity)
    try:
        tree = ast.parse(source.strip(), mode="eval")
    except SyntaxError as exc:
        unit = re.search(_NUMBER_UNIT, source)
        if unit is not None and quantity is None:
            raise ExpressionError(
                f"cannot parse '{text}': units are not allowed in this expression ('{unit.group(0)}'); "
                "declare the quantity in [parameters] and use its name"
            ) from None
        if unit is not None and unit.group(2) not in CONSTANTS:
            raise ExpressionError(f"cannot parse '{text}': unknown unit '{unit.group(2)}' (or a missing '*')") from None
        raise ExpressionError(f"cannot parse '{text}': {exc.msg}") from None
    except (ValueError, MemoryError, RecursionError) as exc:  # null bytes, absurd nesting
        raise ExpressionError(f"cannot parse '{text}': {type(exc).__name__}") from None
    allowed = frozenset(functions)
    return _convert(tree.body, text, allowed, quantities)


def _quantities(text: str, quantity: QuantityReader | None) -> tuple[str, dict[str, Num]]:
    """``text`` with every quantity (number and unit) replaced by a placeholder name."""
    if quantity is None or _PLACEHOLDER in text:
        return text, {}
    found: dict[str, Num] = {}

    def replace(m: re.Match[str]) -> str:
        unit = m.group(2)
        if unit in CONSTANTS or unit in MATH_FUNCTIONS:
            return m.group(0)
        try:
            number = float(m.group(1))
        except (ValueError, OverflowError):
            return m.group(0)
        si = quantity(number, unit)
        if si is None:
            return m.group(0)
        name = f"{_PLACEHOLDER}{len(found)}"
        found[name] = Num(si, unit)
        return f" {name} "

    return re.sub(_NUMBER_UNIT, replace, text), found


def _check_characters(text: str) -> None:
    """Reject text that Python would read differently from what it shows.

    Python folds identifiers to NFKC, so the fullwidth 'ｍ' or the script 'ℓ' would silently
    become the names 'm' and 'l'; and everything after '#' is a comment it ignores.
    """
    for ch in text:
        if not ch.isascii():
            raise ExpressionError(
                f"non-ASCII character '{ch}' (U+{ord(ch):04X}) in '{text}': names use ASCII letters, digits and '_'"
            )
    if "#" in text:
        raise ExpressionError(f"'#' is not allowed in '{text}' (a TOML comment goes after the closing quote)")


def _convert(node: ast.AST, text: str, functions: frozenset[str], quantities: Mapping[str, Num] | None = None) -> Expr:
    quantities = quantities or {}
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            raise ExpressionError(f"only numbers may appear as constants in '{text}', got {node.value!r}")
        try:
            value = float(node.value)
        except OverflowError:  # a Python int has no size limit
            raise ExpressionError(f"number too large in '{text}'") from None
        if not math.isfinite(value):
            raise ExpressionError(f"value must be finite in '{text}'")
        return Num(value)
    if isinstance(node, ast.Name):
        if node.id in quantities:
            return quantities[node.id]
        if node.id.startswith("_"):
            raise ExpressionError(f"names starting with '_' are not allowed: '{node.id}' in '{text}'")
        return Name(node.id)
    if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
        return BinOp(
            _BINOPS[type(node.op)], _convert(node.left, text, functions, quantities), _convert(node.right, text, functions, quantities)
        )
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        operand = _convert(node.operand, text, functions, quantities)
        return Neg(operand) if isinstance(node.op, ast.USub) else operand
    if isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name):
            raise ExpressionError(f"only plain function calls are allowed in '{text}'")
        name = node.func.id
        if name not in functions:
            raise ExpressionError(
                f"function '{name}' is not allowed in '{text}' (allowed: {', '.join(sorted(functions))})"
            )
        if node.keywords or any(isinstance(a, ast.Starred) for a in node.args):
            raise ExpressionError(f"keyword or starred arguments are not allowed in '{text}'")
        if name in MATH_FUNCTIONS and len(node.args) != 1:
            raise ExpressionError(f"{name}() takes one argument in '{text}'")
        return Call(name, tuple(_convert(a, text, functions, quantities) for a in node.args))
    for kind, label in _FORBIDDEN.items():
        if isinstance(node, kind):
            raise ExpressionError(f"{label} not allowed in '{text}'")
    raise ExpressionError(f"'{ast.unparse(node)}' is not allowed in '{text}'")


def names(expr: Expr, name_arg_functions: frozenset[str] = frozenset()) -> frozenset[str]:
    """Every value name an expression refers to.

    Function names are excluded, and so are the arguments of ``name_arg_functions``
    (functions such as ``total_mass(leg)`` whose arguments name things, not values).
    """
    if isinstance(expr, Name):
        return frozenset({expr.id})
    if isinstance(expr, BinOp):
        return names(expr.left, name_arg_functions) | names(expr.right, name_arg_functions)
    if isinstance(expr, Neg):
        return names(expr.operand, name_arg_functions)
    if isinstance(expr, Call) and expr.func not in name_arg_functions:
        out: frozenset[str] = frozenset()
        for a in expr.args:
            out |= names(a, name_arg_functions)
        return out
    return frozenset()


def substitute(expr: Expr, trees: Mapping[str, Expr]) -> Expr:
    """``expr`` with every name in ``trees`` replaced by its tree (coupled coordinates)."""
    if isinstance(expr, Name):
        return trees.get(expr.id, expr)
    if isinstance(expr, BinOp):
        return BinOp(expr.op, substitute(expr.left, trees), substitute(expr.right, trees))
    if isinstance(expr, Neg):
        return Neg(substitute(expr.operand, trees))
    if isinstance(expr, Call):
        return Call(expr.func, tuple(substitute(a, trees) for a in expr.args))
    return expr


def calls(expr: Expr) -> tuple[Call, ...]:
    """Every call in an expression, outermost first."""
    if isinstance(expr, Call):
        return (expr,) + tuple(c for a in expr.args for c in calls(a))
    if isinstance(expr, BinOp):
        return calls(expr.left) + calls(expr.right)
    if isinstance(expr, Neg):
        return calls(expr.operand)
    return ()


def nearest(name: str, candidates: Iterable[str]) -> str | None:
    """The candidate closest to ``name`` (difflib's ratio ≥ 0.6), or None."""
    import difflib  # only for a message (~1.5 ms to import)

    close = difflib.get_close_matches(name, sorted(candidates), n=1)
    return close[0] if close else None


def suggest(name: str, candidates: Iterable[str]) -> str:
    """' (did you mean 'x'?)' for the closest candidate, or ''."""
    close = nearest(name, candidates)
    return f" (did you mean '{close}'?)" if close else ""


def check_names(
    expr: Expr, known: Iterable[str], text: str, name_arg_functions: frozenset[str] = frozenset()
) -> None:
    """Raise :class:`ExpressionError` naming the first unknown name (with a suggestion)."""
    known_set = set(known) | set(CONSTANTS)
    for name in sorted(names(expr, name_arg_functions)):
        if name not in known_set:
            raise ExpressionError(f"unknown name '{name}' in '{text}'{suggest(name, known_set)}")


class NameArgs:
    """Marks a function whose arguments are *names* (of a subsystem, a frame), not values.

    ``total_mass(leg)`` in a report expression receives the string ``"leg"``.
    """

    def __init__(self, fn: Callable[..., Any]) -> None:
        self.fn = fn

    def __call__(self, *names: str) -> Any:
        return self.fn(*names)


def evaluate(
    expr: Expr, env: Mapping[str, Any], functions: Mapping[str, Callable[..., Any]], constant: Callable[[Num], Any] | None = None
) -> Any:
    """Evaluate ``expr`` with names from ``env`` and calls from ``functions``.

    Works for any value type supporting ``+ - * / **`` (float, numpy, CasADi SX, pint).
    ``constant`` gives the value of a number (default: its SI value; pint evaluation
    gives numbers written with a unit their unit).
    """
    if isinstance(expr, Num):
        return expr.value if constant is None else constant(expr)
    if isinstance(expr, Name):
        if expr.id in env:
            return env[expr.id]
        if expr.id in CONSTANTS:
            return CONSTANTS[expr.id]
        raise ExpressionError(f"unknown name '{expr.id}'")
    if isinstance(expr, Neg):
        return -evaluate(expr.operand, env, functions, constant)
    if isinstance(expr, BinOp):
        a = evaluate(expr.left, env, functions, constant)
        b = evaluate(expr.right, env, functions, constant)
        if expr.op == "+":
            return a + b
        if expr.op == "-":
            return a - b
        if expr.op == "*":
            return a * b
        if expr.op == "/":
            return a / b
        return a**b
    if isinstance(expr, Call):
        fn = functions[expr.func]
        if isinstance(fn, NameArgs):
            return fn(*(a.id for a in expr.args if isinstance(a, Name)))
        return fn(*(evaluate(a, env, functions, constant) for a in expr.args))
    raise ExpressionError(f"cannot evaluate {expr!r}")  # unreachable for trees built by parse()
