"""A proof that a solve ends infeasible, without the closest-design restarts that settle it.

:meth:`Designer.solve <counterpoise.designer.designer.Designer.solve>` on the IPOPT path
(``Designer._solve``) declares a design infeasible when IPOPT does and none of the
least-squares closest designs it then searches from several starts
(:meth:`~counterpoise.designer.closest.Closest.least_squares_multistart`) meets the balance
equalities to :data:`~counterpoise.designer.balance.BALANCE_TOLERANCE` (IPOPT's verdict is
local; the restarts settle it). Those restarts are most of the cost of an infeasible solve,
and a bisection (the widest payload range, :mod:`counterpoise.payload.widest`) needs only the
verdict.

When the equalities are **affine** in the design (g(z) = J z + c, J independent of z: the
adjustments of a fixed design that move a counter-mass, say), a certificate proves that no
design within the bounds meets them: for any weights y, Hölder's inequality gives for every
z in the box

    max_j |g_j(z)| ≥ y·g(z) / |y|₁ ≥ ( y·c + Σ_i min(w_i l_i, w_i u_i) ) / |y|₁,  w = Jᵀy.

With y the residual r of the box-constrained least-squares design (found by trying each
variable at its lower bound, its upper bound or free), the bound is |r|₂² / |r|₁, at most the
least worst residual (:mod:`counterpoise.solvers.least_residual`). When it exceeds the tolerance by more than rounding, no start of the restarts can end
balanced, so the solve's verdict is "infeasible" as soon as IPOPT says so: :func:`unbalanceable`
runs that one IPOPT solve (the same as the solve's first) and returns True only then. It
changes no result: it is asked only for the verdict, and a False answer means "solve it".
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING
from weakref import WeakKeyDictionary

import numpy as np

from ..formulation.manifold import changed_geometry
from ..solvers.base import Status
from ..solvers.least_residual import least_residual_bound

if TYPE_CHECKING:
    from ..formulation.layout import Slot
    from .designer import Designer
    from .options import BoundsOverride

#: variables beyond which the 3^n bound patterns are not tried (the answer is then "solve it")
MAX_VARIABLES = 6
#: the certificate must exceed the balance tolerance by this share of the largest term of
#: the equalities in the box (a margin for rounding in their evaluation, ~4500 ulps)
ROUNDING_SHARE = 1e-12

#: per designer: whether its balance equalities are affine in the design (computed once)
_AFFINE: "WeakKeyDictionary[Designer, bool]" = WeakKeyDictionary()


def affine_equalities(designer: "Designer") -> bool:
    """Whether the designer's balance equalities are affine in its design vector."""
    known = _AFFINE.get(designer)
    if known is None:
        import casadi as ca

        eq, z = designer.conditions.equalities, designer.formulation.z
        known = bool(eq.numel()) and not ca.depends_on(ca.jacobian(eq, z), z)
        _AFFINE[designer] = known
    return known


def unbalanceable(
    designer: "Designer",
    initial: "Mapping[Slot, float] | None" = None,
    parameters: Mapping[str, float] | None = None,
    bounds: "BoundsOverride | None" = None,
) -> bool:
    """True when ``designer.solve(initial, parameters, bounds)`` certainly declares the design
    infeasible (see the module docstring); False when that is not known: solve it.

    Only the plain IPOPT path of a problem without design constraints (no verification
    rounds), closed loops moved to another geometry, overdetermined conditions or a convex
    (LP) path qualifies; its balance equalities must be affine in the design."""
    d = designer.formulation.design
    n = len(d)
    if (
        designer.convex is not None
        or designer.rows is not None
        or designer.n_equalities > n
        or not 0 < n <= MAX_VARIABLES
        or changed_geometry(designer.problem, parameters)
        or not affine_equalities(designer)
    ):
        return False
    p = designer.formulation.parameters.values(parameters) if parameters else designer.parameters
    b = designer.bounds(designer.n_equalities, bounds)
    lower, upper = np.asarray(b.lbz, dtype=float), np.asarray(b.ubz, dtype=float)
    middle = 0.5 * (lower + upper)
    g, jac, _ = (np.array(v, dtype=float) for v in designer.balance.residual_jacobian()(middle, p))
    g = g.reshape(-1)
    jac = jac.reshape(g.size, n)
    offset = g - jac @ middle
    if not (np.all(np.isfinite(jac)) and np.all(np.isfinite(offset))):
        return False
    # the box widened by a rounding's width, so that a solver's point on a bound is inside it
    slack = 1e-12 * (np.abs(lower) + np.abs(upper) + (upper - lower))
    largest = float((np.abs(offset) + np.abs(jac) @ np.maximum(np.abs(lower), np.abs(upper))).max())
    from .balance import BALANCE_TOLERANCE

    if least_residual_bound(jac, offset, lower - slack, upper + slack) <= BALANCE_TOLERANCE + ROUNDING_SHARE * max(largest, 1.0):
        return False
    # balanced nowhere in the box: the solve is infeasible when its first IPOPT solve says so
    z0 = np.clip(d.to_z(d.vector(initial or {})), b.lbz, b.ubz)
    return designer.backend.solve(z0, p, b).status is Status.INFEASIBLE
