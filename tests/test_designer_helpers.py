"""The one bounded Gauss-Newton helper (issue 19, part 4): steps, bounds, acceptance, stops.

Every figure below is worked by hand in the test's docstring; the residuals are small
closed-form functions, so the helper is tested apart from any problem.
"""

from __future__ import annotations

import ast

import numpy as np
import pytest

from counterpoise.solvers.gauss_newton import CONVERGED, ITERATIONS, NO_FREE_VARIABLE, REJECTED, gauss_newton
from conftest import ROOT


def linear(a, b, admissible=lambda z: True):
    """r(z) = A z − b, J = A."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return lambda z: (a @ z - b, a, admissible(z))


def test_linear_system_is_solved_in_one_step():
    """r = (z0 + z1 − 3, z0 − z1 − 1): z = (2, 1); one step of a linear system lands on it."""
    out = gauss_newton(linear([[1, 1], [1, -1]], [3, 1]), np.zeros(2), np.full(2, -10.0), np.full(2, 10.0), tolerance=1e-12)
    assert out.z == pytest.approx([2.0, 1.0], abs=1e-14)
    assert out.steps == 1 and out.stop == CONVERGED and out.worst <= 1e-12


def test_the_start_is_not_modified():
    z = np.zeros(2)
    gauss_newton(linear([[1, 1], [1, -1]], [3, 1]), z, np.full(2, -10.0), np.full(2, 10.0))
    assert (z == 0).all()


def test_a_step_beyond_a_bound_is_projected_then_stops():
    """r = z − 2 with z ≤ 1, from 0: the step to 2 is clipped to 1 (|r| 2 → 1, kept); the next
    step is clipped back to 1, |r| stays 1 (not smaller): rejected, z = 1."""
    out = gauss_newton(linear([[1.0]], [2.0]), np.zeros(1), np.array([-5.0]), np.array([1.0]))
    assert out.z == pytest.approx([1.0])
    assert out.worst == pytest.approx(1.0)
    assert (out.steps, out.stop) == (1, REJECTED)


def test_a_rank_deficient_system_takes_the_minimum_norm_step():
    """r = (z0 + z1 − 2, 2 z0 + 2 z1 − 4) has rank 1: every z0 + z1 = 2 solves it; the
    rank-revealing least-squares step from 0 is the shortest, (1, 1)."""
    out = gauss_newton(linear([[1, 1], [2, 2]], [2, 4]), np.zeros(2), np.full(2, -10.0), np.full(2, 10.0), tolerance=1e-12)
    assert out.z == pytest.approx([1.0, 1.0], abs=1e-14)
    assert out.stop == CONVERGED


def test_nonlinear_residual_converges_quadratically():
    """r = z² − 2 from z = 1: Newton's iterates 1.5, 1.41667, 1.4142157, ... reach √2 to
    rounding in at most 6 steps."""
    out = gauss_newton(lambda z: (z**2 - 2.0, np.diag(2.0 * z), True), np.ones(1), np.zeros(1), np.full(1, 3.0), iterations=20, tolerance=1e-15)
    assert out.z[0] == pytest.approx(np.sqrt(2.0), rel=1e-15)
    assert out.steps <= 6 and out.stop == CONVERGED


def test_an_inadmissible_step_is_not_taken():
    """r = z − 2 from 0, but points above 1.5 are inadmissible (a sign constraint): the
    first step (to 2) is rejected and the start stands."""
    out = gauss_newton(linear([[1.0]], [2.0], lambda z: bool(z[0] <= 1.5)), np.zeros(1), np.array([-5.0]), np.array([5.0]))
    assert out.z == pytest.approx([0.0])
    assert (out.steps, out.stop) == (0, REJECTED)


def test_decrease_asks_for_enough_progress():
    """r = z − 2 with z ≤ 0.5, from 0: the clipped step gives |r| 1.5 = 0.75 × 2, kept under
    the default rule (any decrease) and rejected when each step must halve |r|."""
    args = (linear([[1.0]], [2.0]), np.zeros(1), np.array([-5.0]), np.array([0.5]))
    assert gauss_newton(*args).z == pytest.approx([0.5])
    halving = gauss_newton(*args, decrease=0.5)
    assert halving.z == pytest.approx([0.0]) and halving.stop == REJECTED


def test_plain_newton_keeps_every_step():
    """r = atan z from z = 2: Newton's step z − (1 + z²) atan z moves away from 0 (|z| grows
    for |z| > 1.39), so the monotone rule rejects the first step; ``decrease=None`` takes
    all of them (the caller judges the end point)."""
    evaluate = lambda z: (np.arctan(z), np.diag(1.0 / (1.0 + z**2)), True)  # noqa: E731
    args = (evaluate, np.full(1, 2.0), np.full(1, -1e6), np.full(1, 1e6))
    assert gauss_newton(*args).z == pytest.approx([2.0])
    plain = gauss_newton(*args, iterations=3, decrease=None)
    assert abs(plain.z[0]) > 2.0 and (plain.steps, plain.stop) == (3, ITERATIONS)


@pytest.mark.parametrize("free", [np.array([False, True]), np.array([1])])
def test_only_free_variables_move(free):
    """r = (z0 + z1 − 3), only z1 free, from (1, 0): z1 = 2, z0 stays 1 (mask or indices)."""
    out = gauss_newton(linear([[1, 1]], [3]), np.array([1.0, 0.0]), np.full(2, -10.0), np.full(2, 10.0), free=free, tolerance=1e-12)
    assert out.z == pytest.approx([1.0, 2.0])


def test_no_free_variable_returns_the_start():
    out = gauss_newton(linear([[1, 1]], [3]), np.array([1.0, 0.0]), np.full(2, -10.0), np.full(2, 10.0), free=np.zeros(2, dtype=bool))
    assert out.z == pytest.approx([1.0, 0.0]) and out.stop == NO_FREE_VARIABLE and out.worst == pytest.approx(2.0)


def test_an_empty_residual_is_converged():
    out = gauss_newton(lambda z: (np.zeros(0), np.zeros((0, 1)), True), np.ones(1), np.zeros(1), np.full(1, 2.0))
    assert out.stop == CONVERGED and out.steps == 0


def test_bad_arguments_are_errors():
    args = (linear([[1.0]], [2.0]), np.zeros(1), np.zeros(1), np.ones(1))
    with pytest.raises(ValueError):
        gauss_newton(*args, iterations=-1)
    with pytest.raises(ValueError):
        gauss_newton(*args, decrease=0.0)


def test_the_designer_has_no_gauss_newton_loop_of_its_own():
    """Every polish of the designer goes through the helper: designer/ calls lstsq nowhere."""
    for path in (ROOT / "src" / "counterpoise" / "designer").glob("*.py"):
        calls = [n for n in ast.walk(ast.parse(path.read_text())) if isinstance(n, ast.Attribute) and n.attr in ("lstsq", "pinv")]
        assert not calls, f"{path.name} solves its own least-squares steps"
