"""The cone program of the convex path (``solvers/convex.py``): its rows are kept per set of
bounds, and the program of a call is the one the blocks give written out.

The LP of ``min y0 + y1 + y2`` subject to three affine rows g(y, p) with an equality, a
two-sided row (lbg ≤ g ≤ ubg: one row each side), a one-sided row, a fixed variable, a
variable outside the linear set (fixed in the call) and infinite variable bounds:

- A stacks ∂g/∂y of the equalities, the fixed variables' unit rows, −∂g/∂y of the lbg ≤ g
  rows, ∂g/∂y of the g ≤ ubg rows, −I of the finite lower bounds, I of the finite upper ones;
- b the matching ``lbg − const``, ``lo``, ``const − lbg``, ``ubg − const``, ``−lo``, ``hi``,
  with const = g(y0) − J y0.

Both are compared bit for bit with that block formula (a sign flip and a subtraction of
0 are exact), for two sets of bounds in turn and again after the first (kept rows).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from counterpoise.solvers.base import Bounds, Status
from counterpoise.solvers.convex import ConvexBackend


@pytest.fixture(scope="module")
def backend():
    z, p = ca.SX.sym("z", 4), ca.SX.sym("p", 2)
    # z[3] is a "geometry" variable outside the linear set: it multiplies nothing linear here
    # but enters the rows' constants, as a fixed geometry does
    g = ca.vertcat(z[0] + 2 * z[1] - p[0] + z[3], 3 * z[1] - z[2] + 0.1 * z[3] ** 2, z[0] + z[2] - p[1])
    nlp = {"x": z, "p": p, "f": z[0] + z[1] + z[2], "g": g}
    return ConvexBackend(nlp, [0, 1, 2])


def _blocks(backend, z0, p, b):
    """The cone program's (A, b, zero rows) written out block by block."""
    lbz, ubz, lbg, ubg = (np.asarray(v, dtype=float) for v in (b.lbz, b.ubz, b.lbg, b.ubg))
    zref = np.clip(z0, lbz, ubz)
    fixed = np.ones(4, dtype=bool)
    fixed[backend.linear] = False
    zref[fixed] = lbz[fixed]
    _, grad, g0, jac = (np.array(v, dtype=float) for v in backend._data(zref, p))
    g0, jac = g0.reshape(-1), jac.reshape(g0.size, 3)
    const = g0 - jac @ zref[backend.linear]
    lo, hi = lbz[backend.linear], ubz[backend.linear]
    eye = np.eye(3)
    eq, fix = np.isfinite(lbg) & (lbg == ubg), np.isfinite(lo) & (lo == hi)
    ge, le = np.isfinite(lbg) & ~eq, np.isfinite(ubg) & ~eq
    below, above = np.isfinite(lo) & ~fix, np.isfinite(hi) & ~fix
    A = np.vstack([jac[eq], eye[fix], -jac[ge], jac[le], -eye[below], eye[above]])
    rhs = np.concatenate([lbg[eq] - const[eq], lo[fix], const[ge] - lbg[ge], ubg[le] - const[le], -lo[below], hi[above]])
    return A, rhs, int(eq.sum() + fix.sum())


BOUNDS = [
    # z1 fixed at 0.5, z2 without an upper bound; row 0 an equality, row 1 two-sided, row 2 g ≥ -1
    Bounds(np.array([0.0, 0.5, -1.0, 0.3]), np.array([4.0, 0.5, np.inf, 0.3]), np.array([0.0, -2.0, -1.0]), np.array([0.0, 5.0, np.inf])),
    # nothing fixed, z0 without a lower bound; row 2 one-sided from above
    Bounds(np.array([-np.inf, 0.0, 0.0, -0.7]), np.array([3.0, 2.0, 6.0, -0.7]), np.array([0.0, -1.0, -np.inf]), np.array([0.0, 1.0, 2.5])),
]


def test_program_rows_are_the_blocks_bit_for_bit(backend):
    z0, p = np.array([1.0, 0.2, 0.7, 0.0]), np.array([2.0, 1.3])
    for b in [*BOUNDS, BOUNDS[0]]:  # the last: the rows kept for the first bounds
        program, _ = backend.program(z0, p, b)
        A, rhs, n_zero = _blocks(backend, z0, p, b)
        assert program.A.shape == A.shape and program.n_zero == n_zero and program.n_nonneg == rhs.size - n_zero
        assert np.array_equal(program.A, A) and np.array_equal(program.b, rhs)
        assert program.b.tobytes() == rhs.tobytes()  # the same bits, signs of zeros included
    out = backend.solve(z0, p, BOUNDS[0])
    assert out.status is Status.OPTIMAL and out.multipliers is not None and out.multipliers.shape == (3,)


def test_a_free_geometry_variable_is_refused(backend):
    b = BOUNDS[0]
    loose = Bounds(b.lbz, np.array([4.0, 0.5, np.inf, 0.4]), b.lbg, b.ubg)  # z3 not fixed
    with pytest.raises(ValueError, match="must be fixed"):
        backend.program(np.zeros(4), np.zeros(2), loose)
