"""Balance conditions on the configuration manifold of a subsystem with closed loops.

On the manifold h(q_i, q_d) = 0 (:mod:`counterpoise.mechanics.closure`) the generalized
force along the independent coordinates is V's gradient through the implicit function
theorem:

    r_i = ∂V/∂q_i + (dq_d/dq_i)ᵀ ∂V/∂q_d,     dq_d/dq_i = −(∂h/∂q_d)⁺ ∂h/∂q_i.

Sampled on manifold points (solved at the formulation's parameter values) and random
designs, the stacked r has a numerical rank; :func:`manifold_conditions` keeps that many
rows, exactly as :mod:`.conditions` does for open chains (:mod:`.compression`), and hands
them to the designer as equalities g(z, p) = 0 with the same interface. What this
guarantees, and what it does not, is written in docs/loops.md: the rows are exact at their
points; that they stand for the whole manifold rests on the rank having saturated, which
the dense check of :mod:`counterpoise.verify.manifold` tests independently.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Protocol, TypeVar

import numpy as np

from ..kept import Kept
from ..model.problem import Problem


def manifold_conditions(
    formulation: Any,
    block: Any,
    parameters: np.ndarray,
    rng: np.random.Generator,
    random_designs: Callable[[int, np.random.Generator], np.ndarray],
) -> tuple[int, Any]:
    """(rank, CasADi column of equalities or None) of one (subsystem, scenario) block."""
    import casadi as ca

    from ..mechanics.closure import closure  # imported for closed loops only (~3 ms)
    from .compression import NOISE_TOLERANCE, adaptive_compression, coordinate_weights, largest_value, sample_residuals

    f = formulation
    _, base = f.parameters.scenario_values(parameters)[block.scenario]
    c = closure(f.problem, block.subsystem, base)
    ind, dep = c.independent, c.dependent
    n, n_i = len(c.names), len(ind)

    def sample(n_conf: int, n_design: int) -> tuple[np.ndarray, Any, float]:
        qi = c.lower + (c.upper - c.lower) * rng.random((n_conf, n_i))
        points = c.solve(qi)
        z = random_designs(n_design, rng)
        full = sample_residuals(block.residual, points.q, z, parameters).reshape(n_conf, n, n_design)
        values = (full[:, ind, :] + np.einsum("kdi,kdj->kij", points.tangent, full[:, dep, :])).reshape(n_conf * n_i, n_design)
        noise = NOISE_TOLERANCE * largest_value(block.magnitude, points.q, z, parameters)
        weights = coordinate_weights(values, n_i, noise)
        return values * np.tile(weights, n_conf)[:, None], (points, weights), 0.0

    start_designs = max(32, 2 * (len(f.design) + 1) + 8)
    comp, (points, weights) = adaptive_compression(sample, start_configurations=16 + 8 * n_i, start_designs=start_designs)
    if not comp.rank:
        return 0, None
    rows = []
    at: dict[int, Any] = {}
    for r in comp.rows:
        k, j = int(r) // n_i, int(r) % n_i
        if k not in at:
            at[k] = block.residual(points.q[k], f.z, f.p)
        g = at[k]
        along = g[int(ind[j])] + sum(float(points.tangent[k, d, j]) * g[int(dep[d])] for d in range(len(dep)))
        rows.append(along * float(weights[j]))
    return comp.rank, ca.mtimes(ca.DM(comp.matrix), ca.vertcat(*rows))


#: rebuilt designers kept per designer, one per loop geometry (see :func:`for_geometry`)
GEOMETRIES_KEPT = 4
#: a parameter value counts as changed beyond this relative difference
SAME_VALUE = 1e-12


def changed_geometry(problem: Problem, parameters: Any) -> tuple[tuple[str, float], ...]:
    """The loop-geometry parameters (:func:`~counterpoise.mechanics.closure.geometry_parameters`)
    that ``parameters`` (name -> SI value, or None) sets to another value than the problem's:
    sorted (name, value) pairs, empty when every manifold stays the one the equalities were built on."""
    if not parameters or not problem.loops:
        return ()
    from ..mechanics.closure import geometry_parameters  # imported for closed loops only (~3 ms)

    names = {n for sub in {loop.subsystem for loop in problem.loops} for n in geometry_parameters(problem, sub)}
    values = {q.name: q.value for q in problem.base_parameters}
    out = []
    for name in sorted(names & set(parameters)):
        old, new = values.get(name), float(parameters[name])
        if old is None or abs(new - float(old)) > SAME_VALUE * max(abs(new), abs(float(old)), 1.0):
            out.append((name, new))
    return tuple(out)


def with_values(problem: Problem, values: Any) -> Problem:
    """``problem`` with these base-parameter values (SI) as its own: a designer built on it
    solves its manifold conditions on that geometry."""
    from dataclasses import replace

    return replace(problem, parameters=tuple(replace(q, value=float(values[q.name])) if q.is_base and q.name in values else q for q in problem.parameters))


class _Owner(Protocol):
    """A designer: what :func:`for_geometry` reads of it."""

    @property
    def problem(self) -> Problem: ...


#: the designer type a :class:`Geometries` keeps (a designer keeps designers of its own kind)
D = TypeVar("D", bound=_Owner)


class Geometries(Kept[tuple[tuple[str, float], ...], D]):
    """The designers one designer rebuilt for other loop geometries (:func:`for_geometry`),
    by the changed (name, value) pairs: owned by that designer (a field it creates), at most
    :data:`GEOMETRIES_KEPT`, the least recently used dropped first."""

    def __init__(self) -> None:
        super().__init__(GEOMETRIES_KEPT)


def for_geometry(owner: D, parameters: Mapping[str, float] | None, build: Callable[[Problem], D], geometries: Geometries[D]) -> D:
    """The designer to solve ``parameters`` with: ``owner`` itself, or, when they change a
    loop's geometry, one built by ``build`` on the problem with those values (the manifold
    equalities are solved at the build's geometry, docs/loops.md), kept in ``geometries``
    (the owner's :class:`Geometries`) per geometry."""
    changed = changed_geometry(owner.problem, parameters)
    if not changed:
        return owner
    return geometries.get(changed, lambda: build(with_values(owner.problem, dict(changed))))
