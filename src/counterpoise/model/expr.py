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
import difflib
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Union

from ..errors import ExpressionError

MAX_LENGTH = 500

#: Mathematical functions an expression may call (each backend supplies its own version).
MATH_FUNCTIONS = frozenset({"sin", "cos", "tan", "asin", "acos", "atan", "sqrt", "exp", "log", "abs"})
#: Constants every expression may use.
CONSTANTS: Mapping[str, float] = {"pi": math.pi}


@dataclass(frozen=True)
class Num:
    value: float


@dataclass(frozen=True)
class Name:
    id: str


@dataclass(frozen=True)
class BinOp:
    op: str  # one of + - * / **
    left: "Expr"
    right: "Expr"


@dataclass(frozen=True)
class Neg:
    operand: "Expr"


@dataclass(frozen=True)
class Call:
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


def parse(text: str, functions: Iterable[str] = MATH_FUNCTIONS) -> Expr:
    """Parse ``text`` into an :data:`Expr`, allowing calls only to ``functions``."""
    if not isinstance(text, str):
        raise ExpressionError(f"expected an expression string, got {text!r}")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"expression longer than {MAX_LENGTH} characters")
    if not text.strip():
        raise ExpressionError("empty expression")
    _check_characters(text)
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        raise ExpressionError(f"cannot parse '{text}': {exc.msg}") from None
    except (ValueError, MemoryError, RecursionError) as exc:  # null bytes, absurd nesting
        raise ExpressionError(f"cannot parse '{text}': {type(exc).__name__}") from None
    allowed = frozenset(functions)
    return _convert(tree.body, text, allowed)


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


def _convert(node: ast.AST, text: str, functions: frozenset[str]) -> Expr:
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
        if node.id.startswith("_"):
            raise ExpressionError(f"names starting with '_' are not allowed: '{node.id}' in '{text}'")
        return Name(node.id)
    if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
        return BinOp(_BINOPS[type(node.op)], _convert(node.left, text, functions), _convert(node.right, text, functions))
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        operand = _convert(node.operand, text, functions)
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
        return Call(name, tuple(_convert(a, text, functions) for a in node.args))
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


def suggest(name: str, candidates: Iterable[str]) -> str:
    """' (did you mean 'x'?)' for the closest candidate, or ''."""
    close = difflib.get_close_matches(name, sorted(candidates), n=1)
    return f" (did you mean '{close[0]}'?)" if close else ""


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


def evaluate(expr: Expr, env: Mapping[str, Any], functions: Mapping[str, Callable[..., Any]]) -> Any:
    """Evaluate ``expr`` with names from ``env`` and calls from ``functions``.

    Works for any value type supporting ``+ - * / **`` (float, numpy, CasADi SX, pint).
    """
    if isinstance(expr, Num):
        return expr.value
    if isinstance(expr, Name):
        if expr.id in env:
            return env[expr.id]
        if expr.id in CONSTANTS:
            return CONSTANTS[expr.id]
        raise ExpressionError(f"unknown name '{expr.id}'")
    if isinstance(expr, Neg):
        return -evaluate(expr.operand, env, functions)
    if isinstance(expr, BinOp):
        a = evaluate(expr.left, env, functions)
        b = evaluate(expr.right, env, functions)
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
        return fn(*(evaluate(a, env, functions) for a in expr.args))
    raise ExpressionError(f"cannot evaluate {expr!r}")  # unreachable for trees built by parse()
