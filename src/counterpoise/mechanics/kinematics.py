"""3-D kinematics on any backend: small vector algebra that skips exact zeros and ones.

Vectors are lists of three scalars and matrices nested 3×3 lists, so that every entry may
be a float, a numpy array or a CasADi symbol. Multiplying by a literal 0 or 1 is skipped,
which keeps the CasADi graphs of planar mechanisms small.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from ..model.functions import Functions

Scalar = Any  # float | numpy array | casadi.SX
Vec = list[Scalar]  # three Scalars
Mat = list[list[Scalar]]  # 3x3 nested list of Scalars


#: the Python numbers a literal 0 or 1 may be (numpy's float64 is a float)
_NUMBER = (int, float)


def _is_const(a: Any, c: float) -> bool:
    return isinstance(a, _NUMBER) and a == c


# mul, add and add_all (and dot, through them) are called hundreds of times per evaluation
# of a mechanism on a few configurations (a study point's certificate): the tests of
# _is_const are written out in the three, with the same outcome in every case.
def mul(a: Scalar, b: Scalar) -> Scalar:
    if isinstance(a, _NUMBER):
        if a == 0.0:
            return 0.0
        if isinstance(b, _NUMBER) and b == 0.0:
            return 0.0
        if a == 1.0:
            return b
    elif isinstance(b, _NUMBER):
        if b == 0.0:
            return 0.0
    else:
        return a * b
    if isinstance(b, _NUMBER) and b == 1.0:
        return a
    return a * b


def add(a: Scalar, b: Scalar) -> Scalar:
    if isinstance(a, _NUMBER) and a == 0.0:
        return b
    if isinstance(b, _NUMBER) and b == 0.0:
        return a
    return a + b


def add_all(items: Sequence[Scalar]) -> Scalar:
    out: Scalar = 0.0
    for item in items:
        if isinstance(out, _NUMBER) and out == 0.0:
            out = item
        elif not (isinstance(item, _NUMBER) and item == 0.0):
            out = out + item
    return out


def dot(a: Sequence[Scalar], b: Sequence[Scalar]) -> Scalar:
    """``add_all([mul(x, y) for x, y in zip(a, b)])``, with ``mul`` and ``add_all``
    written out (the same outcome in every case; the hot loop of the kinematics)."""
    out: Scalar = 0.0
    for x, y in zip(a, b):
        if isinstance(x, _NUMBER):
            if x == 0.0:
                term = 0.0
            elif isinstance(y, _NUMBER):
                term = 0.0 if y == 0.0 else (y if x == 1.0 else (x if y == 1.0 else x * y))
            else:
                term = y if x == 1.0 else x * y
        elif isinstance(y, _NUMBER):
            term = 0.0 if y == 0.0 else (x if y == 1.0 else x * y)
        else:
            term = x * y
        if isinstance(out, _NUMBER) and out == 0.0:
            out = term
        elif not (isinstance(term, _NUMBER) and term == 0.0):
            out = out + term
    return out


def matvec(m: Mat, v: Vec) -> Vec:
    return [dot(row, v) for row in m]


def matmul(a: Mat, b: Mat) -> Mat:
    columns = list(zip(*b))
    return [[dot(row, column) for column in columns] for row in a]


def sub(a: Vec, b: Vec) -> Vec:
    return [add(x, mul(-1.0, y)) for x, y in zip(a, b)]


def cross(a: Vec, b: Vec) -> Vec:
    """a × b."""
    return [add(mul(a[1], b[2]), mul(-1.0, mul(a[2], b[1]))), add(mul(a[2], b[0]), mul(-1.0, mul(a[0], b[2]))), add(mul(a[0], b[1]), mul(-1.0, mul(a[1], b[0])))]


IDENTITY: Mat = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]


def unit_vector(v: Vec, functions: Functions) -> Vec:
    norm = functions["sqrt"](dot(v, v))
    return [c / norm for c in v]


def exact_cos_sin(angle: Scalar, functions: Functions) -> tuple[Scalar, Scalar]:
    """cos and sin of ``angle``; exact 0 and ±1 for a constant multiple of 90°.

    A literal "90 deg" is π/2 in SI, whose floating-point cosine is 6e-17, not 0: that
    rounding would couple axes that are exactly perpendicular and add spurious terms.
    """
    if isinstance(angle, (int, float)):
        quarter = float(angle) / (math.pi / 2)
        n = round(quarter)
        if abs(quarter - n) < 1e-12:
            return _QUARTER_TURNS[n % 4]
    return functions["cos"](angle), functions["sin"](angle)


_QUARTER_TURNS = ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))


def _basis_index(axis: Vec) -> int | None:
    """0, 1 or 2 when ``axis`` is the constant unit vector x, y or z, else None."""
    if not all(isinstance(c, (int, float)) for c in axis):
        return None
    values = [float(c) for c in axis]
    for i in range(3):
        if values[i] == 1.0 and all(values[j] == 0.0 for j in range(3) if j != i):
            return i
    return None


def rotation_matrix(axis: Vec, angle: Scalar, functions: Functions) -> Mat:
    """Rotation by ``angle`` about a unit ``axis``.

    About x, y or z the elementary matrix is built entry by entry (exact zeros and ones);
    any other axis uses Rodrigues, R = c I + s [u]x + (1 − c) u uᵀ.
    """
    c, s = exact_cos_sin(angle, functions)
    index = _basis_index(axis)
    if index is not None:
        i, j = (index + 1) % 3, (index + 2) % 3
        out: Mat = [[0.0] * 3 for _ in range(3)]
        out[index][index] = 1.0
        out[i][i] = c
        out[j][j] = c
        out[i][j] = mul(-1.0, s)
        out[j][i] = s
        return out
    one_c = 1.0 - c
    ux, uy, uz = axis
    cross = [[0.0, mul(-1.0, uz), uy], [uz, 0.0, mul(-1.0, ux)], [mul(-1.0, uy), ux, 0.0]]
    out = []
    for i in range(3):
        row = []
        for j in range(3):
            term = add(mul(c, IDENTITY[i][j]), mul(s, cross[i][j]) if not _is_const(cross[i][j], 0.0) else 0.0)
            outer = mul(axis[i], axis[j])
            row.append(add(term, mul(one_c, outer)))
        out.append(row)
    return out
