"""Constraints at a solved design: their values, which bind, and which conflict.

- :func:`attach_constraints` evaluates every constraint at a solution (home quantities
  exactly, workspace extremes on the dense sample and the rows' configurations), with its
  sensitivity from the solver's multipliers, and names the binding ones in the message
  (status.txt). A sampled extreme still beyond its bound after the verification rounds
  makes the design ``failed``, named.
- :func:`name_conflict`: when the design is infeasible but the balance alone is not, the
  *elastic* problem (each constraint may be missed by a slack s ≥ 0; minimise Σ s subject to
  the balance) says which constraints cannot hold together, by name.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..formulation.constraints import ConstraintRows, ConstraintValue, describe, evaluate
from ..solvers.base import Bounds, SolverOutput, Status
from .solution import Solution

if TYPE_CHECKING:
    from .designer import Designer

#: solver_status of a design whose IPOPT run said infeasible although the balance alone holds
BALANCEABLE_BUT_INFEASIBLE = "infeasible_with_constraints"
#: a slack of the elastic problem above this (scaled rows) names its constraint
SLACK_TOLERANCE = 1e-6


def attach_constraints(solution: Solution, rows: ConstraintRows | None, multipliers: np.ndarray | None) -> Solution:
    """``solution`` with its constraint values and the binding ones named in its message."""
    problem = solution.problem
    if not problem.constraints:
        return solution
    values = evaluate(problem, solution, rows, multipliers)
    solution = replace(solution, constraints=values)
    if solution.status is not Status.OPTIMAL:
        return solution
    violated = [v for v in values if v.active == "violated"]
    if violated:
        text = "; ".join(describe(problem, v) for v in violated[:3])
        return replace(solution, status=Status.FAILED, message=f"constraint violated between the sampled configurations after the verification rounds: {text}")
    binding = [v for v in values if v.active in ("upper", "lower")]
    if binding:
        return replace(solution, message=solution.message + "; binding: " + "; ".join(describe(problem, v) for v in binding))
    return solution


@dataclass(frozen=True)
class Conflict:
    """What the elastic problem found (see :func:`name_conflict`): the message, the elastic
    design (balanced, scaled z: the design the message describes) and, per (constraint,
    scenario), the amount (SI) it had to be relaxed by."""

    message: str
    z: np.ndarray
    relaxed: dict[tuple[str, str], float]


def name_conflict(designer: "Designer", z: np.ndarray, p: np.ndarray, b: Bounds) -> Conflict | None:
    """An infeasible constrained design that the balance alone allows: the constraints the
    elastic problem had to relax, by name, and the elastic design itself (None: not the
    constraints' fault, or the elastic problem did not balance)."""
    import casadi as ca

    from ..solvers.ipopt import IpoptBackend

    rows = designer.rows
    if rows is None or rows.count == 0:
        return None
    f = designer.formulation
    n_groups = len(rows.groups)
    slack = ca.SX.sym("s", n_groups)
    member = np.zeros((rows.count, n_groups))
    for j, g in enumerate(rows.groups):
        member[g.start : g.stop, j] = 1.0
    spread = ca.mtimes(ca.DM(member), slack)
    eq = designer.conditions.equalities
    g_el = ca.vertcat(eq, f.nonnegative, rows.g + spread, rows.g - spread)
    nlp = {"x": ca.vertcat(f.z, slack), "p": f.p, "f": ca.sum1(slack), "g": g_el}
    backend = IpoptBackend(nlp, designer.options, "elastic")
    n_eq, n_in = int(eq.numel()), int(f.nonnegative.numel())
    lo_rows, hi_rows = np.where(np.isfinite(rows.lbg), rows.lbg, -np.inf), np.where(np.isfinite(rows.ubg), rows.ubg, np.inf)
    bounds = Bounds(
        np.concatenate([b.lbz, np.zeros(n_groups)]),
        np.concatenate([b.ubz, np.full(n_groups, np.inf)]),
        np.concatenate([np.zeros(n_eq + n_in), lo_rows, np.full(rows.count, -np.inf)]),
        np.concatenate([np.zeros(n_eq), np.full(n_in, np.inf), np.full(rows.count, np.inf), hi_rows]),
    )
    out = backend.solve(np.concatenate([z, np.ones(n_groups)]), p, bounds)
    zz, s = out.z[: z.size], out.z[z.size :]
    if out.status is not Status.OPTIMAL or not designer.balances(zz, p):
        return None
    missed = [(float(s[j]), g) for j, g in enumerate(rows.groups) if s[j] > SLACK_TOLERANCE]
    if not missed:
        return None
    by_name: dict[str, tuple[float, list[str], Any]] = {}
    relaxed: dict[tuple[str, str], float] = {}
    for amount, g in missed:
        c = g.constraint
        worst, scenarios, _ = by_name.get(c.name, (0.0, [], c))
        by_name[c.name] = (max(worst, amount * g.scale), [*scenarios, g.scenario], c)
        relaxed[(c.name, g.scenario)] = amount * g.scale
    parts = []
    n_scenarios = len(designer.problem.scenarios)
    for name, (amount, scenarios, c) in sorted(by_name.items(), key=lambda t: -t[1][0] / max(abs(t[1][2].upper or 0), abs(t[1][2].lower or 0), 1e-300)):
        where = "" if n_scenarios == 1 or len(set(scenarios)) == n_scenarios else f" in scenario{'s' if len(scenarios) > 1 else ''} {', '.join(repr(x) for x in scenarios)}"
        parts.append(f"{name}{where} (missed by {c.unit.from_si(amount):.4g} {c.unit.label})".replace(" )", ")"))
    message = "infeasible: the constraints cannot all hold together with the balance: " + ", ".join(parts) + (
        " (the smallest total relaxation that balances; relax or remove these)"
    )
    return Conflict(message, zz, relaxed)


def conflict_message(problem: Any, conflict: Conflict, values: Sequence[ConstraintValue]) -> str:
    """The conflict's message with the constraints that bind in the elastic design (those
    not relaxed, at a bound), as design.csv shows them."""
    binding = [v for v in values if v.active in ("upper", "lower") and (v.name, v.scenario) not in conflict.relaxed]
    if not binding:
        return conflict.message
    return conflict.message + "; in that design, binding: " + "; ".join(describe(problem, v) for v in binding)


def rows_multipliers(out: SolverOutput, rows: ConstraintRows | None) -> np.ndarray | None:
    """The constraint rows' multipliers of a solver output (the rows are last in g)."""
    if rows is None or out.status is not Status.OPTIMAL or out.multipliers is None or out.multipliers.size < rows.count:
        return None
    return np.asarray(out.multipliers[out.multipliers.size - rows.count :], dtype=float)
