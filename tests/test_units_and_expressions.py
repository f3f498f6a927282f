"""Quantities, display units and the expression evaluator on its backends."""

from __future__ import annotations

import math

import numpy as np
import pytest

from counterpoise.model import expr as ex
from counterpoise.errors import UnitError
from counterpoise.model.units import display_unit, looks_like_quantity, parse_quantity


@pytest.mark.parametrize(
    ("text", "si", "unit"),
    [
        ("135 mm", 0.135, "mm"),
        ("400 g", 0.4, "g"),
        ("0.5161 N/mm", 516.1, "N/mm"),
        ("57.2 deg", math.radians(57.2), "deg"),
        ("9.81 m/s^2", 9.81, "m/s^2"),
        ("50 1/m^2", 50.0, "1/m^2"),
        ("2e3 g", 2.0, "g"),
        (0.25, 0.25, ""),
    ],
)
def test_parse_quantity(text, si, unit):
    q = parse_quantity(text)
    assert q.si == pytest.approx(si, rel=1e-12)
    assert q.unit.symbol == unit
    assert q.display_value == pytest.approx(float(str(text).split()[0]) if isinstance(text, str) else text)


@pytest.mark.parametrize("text", ["r_a + b_b", "2*r_a", "1/r_c", "5e-324*pi/180", "3e5", "-b_a"])
def test_expressions_are_not_quantities(text):
    assert not looks_like_quantity(text)


def test_unknown_unit():
    with pytest.raises(UnitError, match="unknown unit 'mmm'"):
        parse_quantity("135 mmm")


def test_display_unit_round_trip():
    u = display_unit("N/mm")
    assert u.from_si(516.1) == pytest.approx(0.5161)
    assert display_unit("").label == "1"


def test_evaluate_on_floats_numpy_and_casadi():
    import casadi as ca

    from counterpoise.mechanics import NUMPY_FUNCTIONS, casadi_functions

    tree = ex.parse("sqrt(a**2 + b**2) * cos(t) - abs(-a) / 2")
    expected = math.hypot(3, 4) * math.cos(0.3) - 1.5
    assert ex.evaluate(tree, {"a": 3.0, "b": 4.0, "t": 0.3}, NUMPY_FUNCTIONS) == pytest.approx(expected)
    arr = ex.evaluate(tree, {"a": np.array([3.0, 3.0]), "b": 4.0, "t": 0.3}, NUMPY_FUNCTIONS)
    np.testing.assert_allclose(arr, [expected, expected])
    a = ca.SX.sym("a")
    sym = ex.evaluate(tree, {"a": a, "b": 4.0, "t": 0.3}, casadi_functions())
    assert float(ca.Function("f", [a], [sym])(3.0)) == pytest.approx(expected)


def test_complex_safe_abs_keeps_the_derivative():
    from counterpoise.mechanics import NUMPY_FUNCTIONS

    h = 1e-30
    z = -2.0 + 1j * h
    assert np.imag(NUMPY_FUNCTIONS["abs"](z)) / h == pytest.approx(-1.0)  # d|x|/dx at x = -2


def test_names_and_calls():
    tree = ex.parse("total_mass(leg) + 2 * m", frozenset(ex.MATH_FUNCTIONS | {"total_mass"}))
    assert ex.names(tree, frozenset({"total_mass"})) == {"m"}
    assert [c.func for c in ex.calls(tree)] == ["total_mass"]


@pytest.mark.parametrize("text", ["sin(1, 2)", "sqrt()"])
def test_math_functions_take_one_argument(text):
    with pytest.raises(ex.ExpressionError, match="takes one argument"):
        ex.parse(text)


def test_the_units_known_without_pint_are_pints():
    """model.units.KNOWN_UNITS (read without importing pint: the as-built check reads its
    sheet's mm, deg and kg through them) give pint's size and dimension for each symbol."""
    from counterpoise.model import units

    reg = units.ureg()
    for symbol, known in units.KNOWN_UNITS.items():
        base = reg.Quantity(1.0, symbol).to_base_units()
        assert known.symbol == symbol
        assert known.to_si == pytest.approx(float(base.magnitude), rel=1e-15)
        assert known.dimension == units.dimensionality_of(base)
