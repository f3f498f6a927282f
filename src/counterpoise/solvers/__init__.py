"""Solver backends, one module each, behind the interface of :mod:`.base`.

:mod:`.ipopt` (CasADi ``nlpsol``) solves the general design NLP. A convex backend (cvxpy
with Clarabel) and a discrete one (bonmin or branch and bound over catalogue parts) plug
in beside it with the same :class:`~.base.Backend` call.
"""

from __future__ import annotations

from .base import Backend, Bounds, SolverOutput, Status

__all__ = ["Backend", "Bounds", "SolverOutput", "Status"]
