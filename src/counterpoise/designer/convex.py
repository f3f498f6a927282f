"""The convex path of the designer and the certificate gap of a general design.

- **Convex path.** When every design variable enters the balance conditions, the sign
  constraints and the objective linearly (a fixed geometry: only masses, stiffnesses and
  payload shares are free), the design problem is an LP. :func:`convex_backend` detects
  this (on the CasADi expressions, not on names) and the designer then solves it with
  Clarabel (:mod:`counterpoise.solvers.convex`, ``Designer._solve_convex``); the solution
  reports ``solver = clarabel``.
- **Certificate gap.** For a general problem solved by IPOPT, the variables that do not
  enter any position (frames, points) are the *linear* ones. With the geometry fixed at
  IPOPT's answer, the best linear variables are an LP; ``certificate_gap`` = IPOPT's
  objective − that LP's optimum, in kg: how much lighter the design could be at the same
  geometry. It is 0 (to rounding) at a true optimum, and 0 by construction on the convex path.

Multi-start is a design method of its own (:class:`counterpoise.designer.methods.MultiStart`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np

from ..model import expr as ex
from ..model.problem import Problem
from ..solvers.base import Bounds, Status

if TYPE_CHECKING:
    from ..solvers.convex import ConvexBackend
    from .built import Built


def geometric_variables(problem: Problem) -> set[str]:
    """Variables that appear in a position: a frame transform, a body's centre of mass, a
    counter-mass position or a spring end."""
    trees: list[ex.Expr] = [tree for frame in problem.frames for t in frame.transforms for tree in t.expressions]
    points = [b.com for b in problem.bodies] + [c.position for c in problem.counter_masses]
    points += [end for s in problem.springs for end in s.ends]
    for point in points:
        trees += list(point.position)
    names: set[str] = set()
    for tree in trees:
        names |= ex.names(tree)
    return names & set(problem.variable)


def linear_slots(designer: Built) -> list[int]:
    """Indices of the design-vector slots whose variables never move a point."""
    geometric = geometric_variables(designer.problem)
    return [i for i, slot in enumerate(designer.formulation.design.slots) if slot.variable not in geometric]


def convex_backend(designer: Built, choice: str) -> "ConvexBackend | None":
    """The LP/QP backend when the whole problem is convex and ``choice`` allows it."""
    from ..solvers.convex import ConvexBackend, affine_variables

    if choice not in ("auto", "ipopt", "clarabel"):
        raise ValueError(f"unknown backend {choice!r}: expected auto, ipopt or clarabel")
    if choice == "ipopt":
        return None
    n = len(designer.formulation.design)
    every = list(range(n))
    convex = n > 0 and len(linear_slots(designer)) == n and affine_variables(designer.nlp, every)
    if not convex:
        if choice == "clarabel":
            raise ValueError(f"{designer.problem.name}: not a convex problem (a design variable moves a point or enters nonlinearly)")
        return None
    return ConvexBackend(designer.nlp, every)


def nonlinear_constraints(designer: Built) -> tuple[str, ...]:
    """The constraints whose rows are nonlinear in the design, when without them the problem
    would be an LP (so a nonlinear constraint moved it to the NLP); else ()."""
    import casadi as ca

    from ..solvers.convex import affine_variables

    rows = designer.rows
    n = len(designer.formulation.design)
    if rows is None or n == 0 or len(linear_slots(designer)) != n:
        return ()
    f = designer.formulation
    plain = {**designer.nlp, "g": ca.vertcat(designer.conditions.equalities, f.nonnegative)}
    if not affine_variables(plain, list(range(n))):
        return ()
    names = []
    for g in rows.groups:
        part = rows.g[g.start : g.stop]
        if ca.depends_on(ca.jacobian(part, f.z), f.z) and g.constraint.name not in names:
            names.append(g.constraint.name)
    return tuple(names)


class Certificate:
    """The certificate LP of a designer (see the module docstring), built on first use.

    It reads only the designer's public parts (problem, formulation, NLP) and keeps its own
    state, so the designer's internals stay its own.
    """

    def __init__(self, designer: Built) -> None:
        self.problem = designer.problem
        self.formulation = designer.formulation
        self.nlp = designer.nlp
        self._lp: ConvexBackend | Literal[False] | None = None  # None: not built; False: no LP to compare with

    def backend(self) -> "ConvexBackend | Literal[False]":
        """The LP backend over the linear slots, or False when there is none."""
        from ..solvers.convex import ConvexBackend, affine_variables

        if self._lp is None:
            geometric = geometric_variables(self.problem)
            linear = [i for i, slot in enumerate(self.formulation.design.slots) if slot.variable not in geometric]
            ok = bool(linear) and affine_variables(self.nlp, linear)
            self._lp = ConvexBackend(self.nlp, linear) if ok else False
        return self._lp

    def gap(self, z: np.ndarray, p: np.ndarray, b: Bounds, solver: str, objective: float) -> float:
        """Objective minus the LP optimum at the geometry of ``z`` (kg)."""
        if solver == "clarabel":
            return 0.0
        lp = self.backend()
        if lp is False or b.lbg.size != int(self.nlp["g"].numel()):
            return float("nan")
        fixed = np.ones(z.size, dtype=bool)
        fixed[lp.linear] = False
        lbz, ubz = b.lbz.copy(), b.ubz.copy()
        lbz[fixed] = ubz[fixed] = np.clip(z[fixed], b.lbz[fixed], b.ubz[fixed])
        try:
            cert = lp.solve(z, p, Bounds(lbz, ubz, b.lbg, b.ubg))
        except ValueError:
            return float("nan")
        if cert.status is not Status.OPTIMAL:
            return float("nan")
        best = float(self.formulation.report_values(cert.z, p)[0][0, 0])
        return objective - best
