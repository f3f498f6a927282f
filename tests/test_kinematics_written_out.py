"""``kinematics.dot`` and ``matmul`` write ``mul`` and ``add_all`` out (the hot loop of a study
point's certificate); they must give what the plain composition gives, bit for bit, for every
mix of literal numbers (0, 1, −0.0, others), numpy arrays (real and complex) and CasADi
symbols (the NLP is built from the same code: its expression graph must not change); and
``Mechanics.gravity_energy``, which skips the position components along which gravity is a
literal 0, must give what −m g·p of the whole position gives."""

from __future__ import annotations

import itertools

import casadi as ca
import numpy as np

from conftest import PROBLEMS
from counterpoise.io.loader import load_problem
from counterpoise.mechanics import kinematics as K
from counterpoise.mechanics.energy import Mechanics
from counterpoise.mechanics.kinematics import add_all, mul


def _dot(a, b):
    return add_all([mul(x, y) for x, y in zip(a, b)])


def _matmul(a, b):
    return [[add_all([mul(a[i][k], b[k][j]) for k in range(3)]) for j in range(3)] for i in range(3)]


def _same(x, y) -> bool:
    if isinstance(x, ca.SX) or isinstance(y, ca.SX):
        return type(x) is type(y) and str(x) == str(y)
    if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        return type(x) is type(y) and x.dtype == y.dtype and np.array_equal(np.atleast_1d(x).view(np.uint8), np.atleast_1d(y).view(np.uint8))
    return type(x) is type(y) and np.copysign(1.0, x) == np.copysign(1.0, y) and (x == y or (x != x and y != y))


def _outcome(f, *args):
    """f's value, or the type of what it raised (an SX times a numpy array raises either way)."""
    try:
        return f(*args)
    except TypeError as exc:
        return type(exc)


def _scalars():
    rng = np.random.default_rng(3)
    real = rng.normal(size=5)
    return [0.0, -0.0, 1.0, 0, 1, -1.0, 2.5, 1e-200, real, real + 1e-20j * rng.normal(size=5), ca.SX.sym("s")]


def test_dot_is_mul_then_add_all():
    values = _scalars()
    for a in itertools.product(values, repeat=3):
        for b in ([1.0, 0.0, values[-3]], [values[-2], values[-1], 2.0], list(reversed(a)), [1e-200, 0.0, -0.0]):
            new, old = _outcome(K.dot, list(a), b), _outcome(_dot, list(a), b)
            assert new is old if isinstance(old, type) else _same(new, old)


def test_matmul_is_the_plain_product():
    rng = np.random.default_rng(5)
    values = _scalars()
    for _ in range(300):
        a = [[values[i] for i in rng.integers(len(values), size=3)] for _ in range(3)]
        b = [[values[i] for i in rng.integers(len(values), size=3)] for _ in range(3)]
        out, ref = _outcome(K.matmul, a, b), _outcome(_matmul, a, b)
        if isinstance(ref, type):
            assert out is ref
            continue
        assert all(_same(x, y) for row, ref_row in zip(out, ref) for x, y in zip(row, ref_row))


def test_gravity_energy_skips_only_what_gravity_drops():
    problem = load_problem(PROBLEMS / "yasir2019_free_extensions.toml")
    rng = np.random.default_rng(9)
    coords = {c.name: rng.uniform(-3, 3, size=7) + 1e-20j for c in problem.coordinates}
    base = {p.name: float(p.value) for p in problem.base_parameters}
    variables = {v.name: float(v.initial) for v in problem.variables}
    for gravity in ([0.0, -9.81, 0.0], [1.5, 0.0, -9.81], [0.0, 0.0, 0.0], [2.0, -3.0, 4.0]):
        mech = Mechanics(problem, base, variables, coords, gravity)
        for body in problem.bodies:
            full = mul(-1.0, mul(2.0, K.dot(mech.gravity, mech.position(body.com))))
            assert _same(mech.gravity_energy(2.0, body.com), full)
