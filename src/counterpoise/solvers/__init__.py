"""Solver backends, one module each, behind the interface of :mod:`.base`.

:mod:`.ipopt` (CasADi ``nlpsol``) solves the general design NLP; :mod:`.convex` (Clarabel,
given its matrices) solves it as an LP/QP when the free variables enter linearly. A discrete
backend (bonmin or branch and bound over catalogue parts) plugs in beside them with the
same :class:`~.base.Backend` call. :mod:`.gauss_newton` is the one bounded Gauss-Newton
loop with which the designer polishes a solver's point.
"""

from __future__ import annotations

from .base import Backend, Bounds, SolverOutput, Status

__all__ = ["Backend", "Bounds", "SolverOutput", "Status"]
