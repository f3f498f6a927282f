"""The assumption behind exact, rank-compressed balance conditions, stated and checked.

Rank compression (:mod:`.compression`) needs the residual ∂V/∂q of every design to lie in
one fixed, finite-dimensional space of functions of q. That holds when the potential
energy is a trigonometric polynomial in the joint angles (a polynomial in slider
positions) whose frequencies do not depend on the design:

- gravity acting on rigid bodies and counter-masses, and zero-free-length springs
  (energy ½ k |a − b|², a quadratic form of the attachment points);
- every rotation angle *affine* in the coordinates, with coefficients free of design
  variables (``q``, ``q1 - q2``, ``2*q + phi0``; not ``sqrt(q)`` or ``b*q``);
- every translation *polynomial* in the coordinates (a slider ``[s, 0, 0]``).

A problem outside this class (a spring with a free length or an initial tension attached
directly, an angle that is a non-linear function of a coordinate) has no finite set of
exact conditions; it needs another formulation, such as the smallest worst-case residual
over sampled configurations. :func:`check_exact_conditions` says which entry of the file
breaks the assumption instead of letting the compression return a wrong rank.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from ..errors import ProblemFileError
from ..model import expr as ex
from ..model.mechanism import Rotation
from ..model.problem import Problem

#: Configurations (seeded) on which :func:`degeneracies` samples the unbalanced energy.
DEGENERACY_SAMPLES = 64
DEGENERACY_SEED = 14
#: The weight's energy "does not change" when it varies by less than this fraction of
#: Σ m g |p| (a scale of the energy itself).
DEGENERACY_TOLERANCE = 1e-9


@dataclass(frozen=True)
class _Affine:
    """An expression affine in the coordinates: names in its constant part and in the
    coefficients of the coordinates, and whether a coordinate appears at all."""

    constant: frozenset[str]
    coefficient: frozenset[str]
    moves: bool


def affine_form(tree: ex.Expr, coordinates: frozenset[str]) -> _Affine | None:
    """The affine structure of ``tree`` in ``coordinates``, or None if it is not affine."""
    if isinstance(tree, ex.Num):
        return _Affine(frozenset(), frozenset(), False)
    if isinstance(tree, ex.Name):
        if tree.id in coordinates:
            return _Affine(frozenset(), frozenset(), True)
        return _Affine(frozenset({tree.id}), frozenset(), False)
    if isinstance(tree, ex.Neg):
        return affine_form(tree.operand, coordinates)
    if isinstance(tree, ex.Call):
        parts = [affine_form(a, coordinates) for a in tree.args]
        if any(p is None or p.moves for p in parts):
            return None
        return _Affine(frozenset().union(*(p.constant for p in parts if p)), frozenset(), False)
    if isinstance(tree, ex.BinOp):
        a, b = affine_form(tree.left, coordinates), affine_form(tree.right, coordinates)
        if a is None or b is None:
            return None
        if tree.op in "+-":
            return _Affine(a.constant | b.constant, a.coefficient | b.coefficient, a.moves or b.moves)
        if tree.op == "*":
            if a.moves and b.moves:
                return None
            fixed, moving = (b, a) if a.moves else (a, b)
            return _Affine(a.constant | b.constant, moving.coefficient | fixed.constant if moving.moves else frozenset(), moving.moves)
        if tree.op == "/":
            if b.moves:
                return None
            return _Affine(a.constant | b.constant, a.coefficient | b.constant if a.moves else frozenset(), a.moves)
        if a.moves or b.moves:  # **
            return None
        return _Affine(a.constant | b.constant, frozenset(), False)
    return None


def polynomial_degree(tree: ex.Expr, coordinates: frozenset[str]) -> int | None:
    """Degree of ``tree`` as a polynomial in ``coordinates``, or None if it is not one."""
    if isinstance(tree, ex.Num):
        return 0
    if isinstance(tree, ex.Name):
        return 1 if tree.id in coordinates else 0
    if isinstance(tree, ex.Neg):
        return polynomial_degree(tree.operand, coordinates)
    if isinstance(tree, ex.Call):
        return 0 if all(polynomial_degree(a, coordinates) == 0 for a in tree.args) else None
    if isinstance(tree, ex.BinOp):
        a, b = polynomial_degree(tree.left, coordinates), polynomial_degree(tree.right, coordinates)
        if a is None or b is None:
            return None
        if tree.op in "+-":
            return max(a, b)
        if tree.op == "*":
            return a + b
        if tree.op == "/":
            return a if b == 0 else None
        if b == 0 and a == 0:
            return 0
        if b == 0 and isinstance(tree.right, ex.Num) and float(tree.right.value).is_integer() and tree.right.value >= 0:
            return a * int(tree.right.value)
        return None
    return None


def check_exact_conditions(problem: Problem) -> None:
    """Raise :class:`ProblemFileError` naming the first entry that breaks the assumption."""
    coordinates = frozenset(c.name for c in problem.coordinates)
    variables = frozenset(problem.variable)
    for spring in problem.springs:
        if spring.direct is not None:
            raise ProblemFileError(
                problem.path,
                f"springs.{spring.name}.mount",
                "a directly attached spring (free length, initial tension) has no exact balance conditions: "
                "design it with the minimax designer (counterpoise.designer.minimax), as design() does",
            )
        if not spring.exact:
            raise ProblemFileError(
                problem.path,
                f"springs.{spring.name}.pulley.radius",
                "a cable to a point over a pulley of radius > 0 has no exact balance conditions: design it with the "
                "minimax designer (counterpoise.designer.minimax), as design() does, or wrap the cable onto a pin (pin = true)",
            )
    for frame in problem.frames:
        for i, t in enumerate(frame.transforms):
            key = frame.key(i)
            if isinstance(t, Rotation):
                form = affine_form(t.angle, coordinates)
                if form is None:
                    raise ProblemFileError(
                        problem.path,
                        key if key.endswith((".theta", ".alpha")) else f"{key}.angle",
                        "the angle is not affine in the coordinates, so the potential energy is not a trigonometric "
                        "polynomial and exact balance conditions cannot be derived from samples",
                    )
                used = form.coefficient & variables
                if used:
                    raise ProblemFileError(
                        problem.path,
                        key if key.endswith((".theta", ".alpha")) else f"{key}.angle",
                        f"the coefficient of a coordinate depends on the design variable(s) {', '.join(sorted(used))}: "
                        "exact balance conditions need coordinate coefficients fixed by parameters",
                    )
            else:
                for j, component in enumerate(t.vector):
                    if polynomial_degree(component, coordinates) is None:
                        raise ProblemFileError(
                            problem.path,
                            key if key.endswith((".a", ".d")) else f"{key}.translate.{j}",
                            "the translation is not a polynomial in the coordinates, so exact balance conditions "
                            "cannot be derived from samples",
                        )


#: the degeneracy warnings of the problems asked last (:func:`problem_warnings`), by id, with a weak reference
_FOUND: dict[int, tuple["weakref.ref[Problem]", tuple[str, ...]]] = {}
_FOUND_SIZE = 8


def problem_warnings(problem: Problem) -> tuple[str, ...]:
    """:func:`degeneracies` of ``problem``, found once per problem and then read (the
    console script finds them at load; a report written later in the same process reads
    them instead of finding them again)."""
    entry = _FOUND.get(id(problem))
    if entry is not None and entry[0]() is problem:
        return entry[1]
    found = tuple(degeneracies(problem))
    if len(_FOUND) >= _FOUND_SIZE:
        _FOUND.pop(next(iter(_FOUND)))
    _FOUND[id(problem)] = (weakref.ref(problem), found)
    return found


def degeneracies(problem: Problem) -> list[str]:
    """Why there may be nothing to balance: warnings, one line each (empty if none).

    A problem whose weight does no work as the mechanism moves comes out "optimal" with
    any design, which hides a transcription mistake. Found here, on the given bodies (the
    unbalanced mechanism) at the initial design, :data:`DEGENERACY_SAMPLES` seeded
    configurations per scenario:

    - no bodies at all (a file cut short before its frames and bodies);
    - a coordinate that no frame uses (it moves nothing);
    - zero gravity in a scenario;
    - a weight whose energy does not change over the ranges (gravity normal to the plane
      of motion, centres of mass on the joint axes), in a scenario or along a coordinate.
    """
    from ..mechanics.energy import Mechanics

    out: list[str] = []
    if not problem.bodies:
        return ["nothing to balance: the problem has no bodies (is the file cut short before its frames and bodies?)"]
    used: set[str] = set().union(*(frame.names() for frame in problem.frames))
    idle = [c.name for c in problem.coordinates if c.name not in used]
    for name in idle:
        out.append(f"coordinate '{name}' drives no frame: it moves nothing, so there is nothing to balance about it")
    rng = np.random.default_rng(DEGENERACY_SEED)
    coordinates = {c.name: c.lower + (c.upper - c.lower) * rng.random(DEGENERACY_SAMPLES) for c in problem.coordinates}
    variables = {v.name: v.initial for v in problem.variables}
    for scenario in problem.scenarios:
        where = f" in scenario '{scenario.name}'" if len(problem.scenarios) > 1 else ""
        if scenario.gravity.acceleration == 0:
            out.append(f"gravity is zero{where}: there is no weight to balance")
            continue
        base = {p.name: scenario.parameters.get(p.name, p.value) for p in problem.base_parameters}

        def weight(values: dict[str, np.ndarray]) -> tuple[np.ndarray, float]:
            m = Mechanics(problem, base, variables, values, scenario.gravity.vector)
            energy = np.zeros(DEGENERACY_SAMPLES)
            scale = 0.0
            for body in problem.bodies:
                mass = np.broadcast_to(np.asarray(m.value(body.mass), dtype=float), (DEGENERACY_SAMPLES,))
                p = np.array([np.broadcast_to(np.asarray(c, dtype=float), (DEGENERACY_SAMPLES,)) for c in m.position(body.com)])
                energy = energy + np.broadcast_to(np.asarray(m.gravity_energy(mass, body.com), dtype=float), (DEGENERACY_SAMPLES,))
                scale += float(np.max(np.abs(mass) * np.linalg.norm(p, axis=0))) * scenario.gravity.acceleration
            return energy, scale

        energy, scale = weight(coordinates)
        threshold = DEGENERACY_TOLERANCE * scale
        if np.ptp(energy) <= threshold:
            out.append(
                f"nothing to balance{where}: the weight of the bodies does no work over the coordinates' ranges "
                "(is gravity normal to the plane of motion, or every centre of mass on a joint axis?)"
            )
            continue
        for c in problem.coordinates:
            if c.name in idle or c.dependent:  # a loop's dependent coordinate follows the others
                continue
            moved = dict(coordinates)
            moved[c.name] = c.lower + (c.upper - c.lower) * rng.random(DEGENERACY_SAMPLES)
            if np.max(np.abs(weight(moved)[0] - energy)) <= threshold:
                out.append(f"coordinate '{c.name}' does not change the weight's energy{where}: there is no torque to balance about it")
    return list(dict.fromkeys(out))
