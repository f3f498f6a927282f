"""Kinematics and potential energy, written once for every numeric backend.

:class:`Mechanics` evaluates frame poses, positions, masses and the potential energy

    V(q) = Σ_bodies −m g·p  +  Σ_counter-masses −M g·p  +  Σ_springs ½ k |a − b|²

from the problem's expression trees. The values it is given decide the backend: floats,
numpy arrays (real, or complex for complex-step derivatives in :mod:`counterpoise.verify`)
or CasADi SX symbols (to build the NLP in :mod:`counterpoise.nlp`). The physics therefore
exists in one place, and the verification exercises the very code the optimiser used.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from . import expr as ex
from .model import GROUND, Point, Rotation
from .problem import Problem

Scalar = Any  # float | numpy array | casadi.SX
Vec = list  # three Scalars
Mat = list  # 3x3 nested list of Scalars


def _complex_safe_abs(z: Any) -> Any:
    """|x| that keeps the imaginary part of a complex-step perturbation."""
    return np.where(np.real(z) < 0, -z, z)


NUMPY_FUNCTIONS: Mapping[str, Callable[..., Any]] = {
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    "asin": np.arcsin,
    "acos": np.arccos,
    "atan": np.arctan,
    "sqrt": np.sqrt,
    "exp": np.exp,
    "log": np.log,
    "abs": _complex_safe_abs,
}


def casadi_functions() -> Mapping[str, Callable[..., Any]]:
    import casadi as ca

    return {
        "sin": ca.sin,
        "cos": ca.cos,
        "tan": ca.tan,
        "asin": ca.asin,
        "acos": ca.acos,
        "atan": ca.atan,
        "sqrt": ca.sqrt,
        "exp": ca.exp,
        "log": ca.log,
        "abs": ca.fabs,
    }


def _is_const(a: Any, c: float) -> bool:
    return isinstance(a, (int, float)) and a == c


def _mul(a: Scalar, b: Scalar) -> Scalar:
    if _is_const(a, 0.0) or _is_const(b, 0.0):
        return 0.0
    if _is_const(a, 1.0):
        return b
    if _is_const(b, 1.0):
        return a
    return a * b


def _add(a: Scalar, b: Scalar) -> Scalar:
    if _is_const(a, 0.0):
        return b
    if _is_const(b, 0.0):
        return a
    return a + b


def _sum(items: Sequence[Scalar]) -> Scalar:
    out: Scalar = 0.0
    for item in items:
        out = _add(out, item)
    return out


def dot(a: Vec, b: Vec) -> Scalar:
    return _sum([_mul(x, y) for x, y in zip(a, b)])


def matvec(m: Mat, v: Vec) -> Vec:
    return [dot(row, v) for row in m]


def matmul(a: Mat, b: Mat) -> Mat:
    return [[_sum([_mul(a[i][k], b[k][j]) for k in range(3)]) for j in range(3)] for i in range(3)]


def sub(a: Vec, b: Vec) -> Vec:
    return [_add(x, _mul(-1.0, y)) for x, y in zip(a, b)]


IDENTITY: Mat = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]


def unit_vector(v: Vec, functions: Mapping[str, Callable[..., Any]]) -> Vec:
    norm = functions["sqrt"](dot(v, v))
    return [c / norm for c in v]


def rotation_matrix(axis: Vec, angle: Scalar, functions: Mapping[str, Callable[..., Any]]) -> Mat:
    """Rodrigues: R = c I + s [u]x + (1 − c) u uᵀ about a unit ``axis``."""
    c = functions["cos"](angle)
    s = functions["sin"](angle)
    one_c = 1.0 - c
    ux, uy, uz = axis
    cross = [[0.0, _mul(-1.0, uz), uy], [uz, 0.0, _mul(-1.0, ux)], [_mul(-1.0, uy), ux, 0.0]]
    out: Mat = []
    for i in range(3):
        row = []
        for j in range(3):
            term = _add(_mul(c, IDENTITY[i][j]), _mul(s, cross[i][j]) if not _is_const(cross[i][j], 0.0) else 0.0)
            outer = _mul(axis[i], axis[j])
            row.append(_add(term, _mul(one_c, outer)))
        out.append(row)
    return out


class Mechanics:
    """Positions and energies of one problem for one set of values.

    ``base_parameters``: SI values of the literal parameters (a scenario's values);
    ``variables``: values of the design variables; ``coordinates``: values of the
    coordinates (arrays evaluate many configurations at once); ``gravity``: the gravity
    vector (m/s²). Derived parameters are evaluated here, so a study that changes a base
    parameter sees every parameter built on it change too.
    """

    def __init__(
        self,
        problem: Problem,
        base_parameters: Mapping[str, Scalar],
        variables: Mapping[str, Scalar],
        coordinates: Mapping[str, Scalar],
        gravity: Sequence[Scalar],
        functions: Mapping[str, Callable[..., Any]] = NUMPY_FUNCTIONS,
    ) -> None:
        self.problem = problem
        self.functions = functions
        self.gravity = list(gravity)
        env: dict[str, Scalar] = {}
        for p in problem.parameters:
            env[p.name] = base_parameters[p.name] if p.is_base else ex.evaluate(p.expr, env, functions)  # type: ignore[arg-type]
        env.update(variables)
        env.update(coordinates)
        self.env = env
        self._poses: dict[str, tuple[Mat, Vec]] = {}

    def value(self, tree: ex.Expr) -> Scalar:
        return ex.evaluate(tree, self.env, self.functions)

    def vector(self, trees: Sequence[ex.Expr]) -> Vec:
        return [self.value(t) for t in trees]

    # -- kinematics ----------------------------------------------------------------
    def pose(self, frame: str, upto: int | None = None) -> tuple[Mat, Vec]:
        """World rotation and origin of ``frame`` (after its first ``upto`` transforms)."""
        if frame == GROUND:
            return IDENTITY, [0.0, 0.0, 0.0]
        if upto is None and frame in self._poses:
            return self._poses[frame]
        f = self.problem.frame[frame]
        rot, origin = self.pose(f.parent) if f.parent is not None else (IDENTITY, [0.0, 0.0, 0.0])
        for t in f.transforms[:upto]:
            if isinstance(t, Rotation):
                rot = matmul(rot, rotation_matrix(self.axis(t), self.value(t.angle), self.functions))
            else:
                step = matvec(rot, self.vector(t.vector))
                origin = [_add(o, d) for o, d in zip(origin, step)]
        if upto is None:
            self._poses[frame] = (rot, origin)
        return rot, origin

    def axis(self, rotation: Rotation) -> Vec:
        """Unit axis of a rotation (literal axes arrive normalised from the loader)."""
        if all(isinstance(c, ex.Num) for c in rotation.axis):
            return self.vector(rotation.axis)
        return unit_vector(self.vector(rotation.axis), self.functions)

    def position(self, point: Point) -> Vec:
        rot, origin = self.pose(point.frame)
        return [_add(o, d) for o, d in zip(origin, matvec(rot, self.vector(point.position)))]

    # -- energy --------------------------------------------------------------------
    def gravity_energy(self, mass: Scalar, point: Point) -> Scalar:
        return _mul(-1.0, _mul(mass, dot(self.gravity, self.position(point))))

    def energy_terms(self, subsystem: str | None = None) -> tuple[Scalar, Scalar]:
        """(energy of the given bodies, energy of the balancers) of ``subsystem`` (all if None).

        The bodies alone are the unbalanced mechanism; balancers are counter-masses and springs.
        """
        p = self.problem

        def mine(element_subsystem: str | None) -> bool:
            return subsystem is None or element_subsystem == subsystem

        bodies = _sum([self.gravity_energy(self.value(b.mass), b.com) for b in p.bodies if mine(b.subsystem)])
        balancers = [self.gravity_energy(self.value(c.mass), c.position) for c in p.counter_masses if mine(c.subsystem)]
        for s in p.springs:
            if mine(s.subsystem):
                d = sub(self.position(s.ends[0]), self.position(s.ends[1]))
                balancers.append(_mul(0.5, _mul(self.value(s.stiffness), dot(d, d))))
        return bodies, _sum(balancers)

    def energy(self, subsystem: str | None = None) -> Scalar:
        """Potential energy of ``subsystem`` (all elements if None)."""
        return _add(*self.energy_terms(subsystem))

    # -- mass properties -----------------------------------------------------------
    def masses(self, subsystem: str) -> list[tuple[Scalar, Point]]:
        p = self.problem
        out = [(self.value(b.mass), b.com) for b in p.bodies if b.subsystem == subsystem]
        out += [(self.value(c.mass), c.position) for c in p.counter_masses if c.subsystem == subsystem]
        return out

    def total_mass(self, subsystem: str) -> Scalar:
        return _sum([m for m, _ in self.masses(subsystem)])

    def com_distance(self, subsystem: str, frame: str = GROUND) -> Scalar:
        """Distance from ``frame``'s origin to the subsystem's centre of mass."""
        items = self.masses(subsystem)
        total = _sum([m for m, _ in items])
        moment = [0.0, 0.0, 0.0]
        for m, point in items:
            moment = [_add(a, _mul(m, b)) for a, b in zip(moment, self.position(point))]
        com = [c / total for c in moment]
        d = sub(com, self.pose(frame)[1])
        return self.functions["sqrt"](dot(d, d))

    def arm_squared(self, index: int) -> Scalar:
        """d_j² of counter-mass ``index``: squared distance from its joint's axis."""
        cm = self.problem.counter_masses[index]
        if cm.joint is None:
            return 0.0
        frame, i = cm.joint
        rot, origin = self.pose(frame, upto=i)
        t = self.problem.frame[frame].transforms[i]
        axis = matvec(rot, self.axis(t))  # type: ignore[arg-type]
        rel = sub(self.position(cm.position), origin)
        along = dot(axis, rel)
        return _add(dot(rel, rel), _mul(-1.0, _mul(along, along)))

    def added_mass(self) -> Scalar:
        return _sum([self.value(c.mass) for c in self.problem.counter_masses])

    def added_inertia(self) -> Scalar:
        """Σ M_j d_j² (with d_j² rather than d_j, smooth where d_j = 0)."""
        return _sum([_mul(self.value(c.mass), self.arm_squared(j)) for j, c in enumerate(self.problem.counter_masses)])
