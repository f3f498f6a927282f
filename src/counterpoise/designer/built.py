"""What the designer's parts read of the NLP a designer built: :class:`Built`.

The parts of :class:`~counterpoise.designer.designer.Designer` that need more than their own
state (the convex path and the certificate, :mod:`.convex`; the design constraints'
conflicts, :mod:`.constrained`) take the designer as a :class:`Built`, so they name no
designer type and the designer imports them without a circle.
"""

from __future__ import annotations

from typing import Any, Protocol

from ..formulation.conditions import BalanceConditions
from ..formulation.constraints import ConstraintRows
from ..formulation.formulation import Formulation
from ..model.problem import Problem
from .balance import Balance


class Built(Protocol):
    """A designer's problem, formulation, balance conditions, constraint rows (None: none),
    NLP (CasADi expressions: casadi ships no type information), IPOPT options and
    :class:`~.balance.Balance`."""

    problem: Problem
    formulation: Formulation
    conditions: BalanceConditions
    rows: ConstraintRows | None
    nlp: dict[str, Any]
    options: dict[str, Any]
    balance: Balance
