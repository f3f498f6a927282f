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

import weakref
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..formulation.constraints import ConstraintRows, ConstraintValue, describe, evaluate
from ..model.constraints import FORCE_LIMIT
from ..solvers.base import Bounds, SolverOutput, Status
from .solution import Solution

if TYPE_CHECKING:
    from ..solvers.ipopt import IpoptBackend
    from .built import Built

#: solver_status of a design whose IPOPT run said infeasible although the balance alone holds
BALANCEABLE_BUT_INFEASIBLE = "infeasible_with_constraints"
#: IPOPT's return code when an evaluation gave an inf or a NaN
INVALID_NUMBER = "Invalid_Number_Detected"
#: a slack of the elastic problem above this (scaled rows) names its constraint
SLACK_TOLERANCE = 1e-6


#: the message of an optimal design whose constraint the dense check finds violated
BETWEEN_SAMPLES = "constraint violated between the sampled configurations after the verification rounds"


def between_samples(solution: Solution) -> bool:
    """Whether ``solution`` failed only because a sampled constraint is violated between its
    rows' configurations (the solver held the rows): what a verification round may fix."""
    return solution.status is Status.FAILED and solution.message.startswith(BETWEEN_SAMPLES)


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
        return replace(solution, status=Status.FAILED, message=f"{BETWEEN_SAMPLES}: {text}")
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


#: the elastic problem of each designer, built once (its weights are parameters): a payload
#: schedule asks it at every infeasible grid row
_ELASTIC: weakref.WeakKeyDictionary[Any, tuple[IpoptBackend, Any]] = weakref.WeakKeyDictionary()


def _elastic(designer: Built) -> tuple[IpoptBackend, Any]:
    """The elastic NLP of ``designer``'s constraint rows: variables (z, σ), parameters
    (p, w) with w_j ≥ 1 the scale of group j, minimise Σ w_j σ_j subject to the balance, the
    design's inequalities and (g_i / w_j) ± σ_j within the rows' bounds / w_j; and the
    function of the rows g(z, p)."""
    import casadi as ca

    from ..solvers.ipopt import IpoptBackend

    found = _ELASTIC.get(designer)
    if found is not None:
        return found
    rows = designer.rows
    if rows is None:
        raise ValueError("an elastic problem needs constraint rows")
    f = designer.formulation
    n_groups = len(rows.groups)
    sigma = ca.SX.sym("sigma", n_groups)
    w = ca.SX.sym("w", n_groups)
    member = np.zeros((rows.count, n_groups))
    for j, g in enumerate(rows.groups):
        member[g.start : g.stop, j] = 1.0
    per_row = ca.mtimes(ca.DM(member), w)
    spread = ca.mtimes(ca.DM(member), sigma)
    scaled = rows.g / per_row
    g_el = ca.vertcat(designer.conditions.equalities, f.nonnegative, scaled + spread, scaled - spread)
    nlp = {"x": ca.vertcat(f.z, sigma), "p": ca.vertcat(f.p, w), "f": ca.dot(w, sigma), "g": g_el}
    built = _ELASTIC[designer] = (IpoptBackend(nlp, designer.options, "elastic"), ca.Function("rows", [f.z, f.p], [rows.g]))
    return built


def name_conflict(designer: Built, z: np.ndarray, p: np.ndarray, b: Bounds) -> Conflict | None:
    """An infeasible constrained design that the balance alone allows: the constraints the
    elastic problem had to relax, by name, and the elastic design itself (None: not the
    constraints' fault, or the elastic problem did not balance)."""
    rows = designer.rows
    if rows is None or rows.count == 0:
        return None
    f = designer.formulation
    n_groups = len(rows.groups)
    lo_rows, hi_rows = np.where(np.isfinite(rows.lbg), rows.lbg, -np.inf), np.where(np.isfinite(rows.ubg), rows.ubg, np.inf)
    # each slack s_j = w_j σ_j in units of the rows' own violation at z (at least 1): from a
    # slack of 1, a bound of 1e-12 N (rows scaled by it, missed by ~1e13) left IPOPT's
    # restoration stuck, "infeasible", and the limit unnamed. σ starts at 1 + 1/w: the start
    # is feasible when z balances. The objective is still Σ s (the scaled rows' slack).
    backend, rows_of = _elastic(designer)
    rows_at = np.asarray(rows_of(z, p), dtype=float).reshape(-1)
    with np.errstate(invalid="ignore"):
        beyond = np.nan_to_num(np.fmax(np.fmax(lo_rows - rows_at, rows_at - hi_rows), 0.0), nan=1.0, posinf=1.0)
    weight = np.array([max(1.0, float(beyond[g.start : g.stop].max(initial=0.0))) for g in rows.groups])
    per_row = np.ones(rows.count)
    for j, g in enumerate(rows.groups):
        per_row[g.start : g.stop] = weight[j]
    n_eq, n_in = int(designer.conditions.equalities.numel()), int(f.nonnegative.numel())
    bounds = Bounds(
        np.concatenate([b.lbz, np.zeros(n_groups)]),
        np.concatenate([b.ubz, np.full(n_groups, np.inf)]),
        np.concatenate([np.zeros(n_eq + n_in), lo_rows / per_row, np.full(rows.count, -np.inf)]),
        np.concatenate([np.zeros(n_eq), np.full(n_in, np.inf), np.full(rows.count, np.inf), hi_rows / per_row]),
    )
    out = backend.solve(np.concatenate([z, 1.0 + 1.0 / weight]), np.concatenate([np.asarray(p, dtype=float).reshape(-1), weight]), bounds)
    zz, s = out.z[: z.size], weight * out.z[z.size :]
    if out.status is not Status.OPTIMAL or not designer.balance.balances(zz, p):
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


def file_key(c: Any) -> str:
    """Where a constraint is in the problem file: ``constraints.<name>.expression``, or a
    spring's ``springs.<name>.max_force``."""
    return f"springs.{c.spring}.max_force" if c.kind == FORCE_LIMIT and c.spring else f"constraints.{c.name}.expression"


def _design_text(designer: Built, z: np.ndarray) -> str:
    d = designer.formulation.design
    problem = designer.problem
    parts = []
    for slot, v in d.values(d.to_x(z)).items():
        u = problem.variable[slot.variable].unit
        where = f" ({slot.scenario})" if slot.scenario else ""
        parts.append(f"{slot.variable}{where}={u.from_si(v):.6g} {u.label}".rstrip())
    return ", ".join(parts[:MAX_NAMED_VARIABLES]) + (", ..." if len(parts) > MAX_NAMED_VARIABLES else "")


#: the variables a message lists at most (the point where a constraint is not a finite number)
MAX_NAMED_VARIABLES = 6


def name_invalid_numbers(designer: Built, points: Sequence[np.ndarray], p: np.ndarray) -> str:
    """The constraints whose value or derivative is not a finite number at the first of
    ``points`` where some is (the solver's last point, then its start): what IPOPT's
    ``Invalid_Number_Detected`` met, by name and key; "" when no constraint is the cause
    there (the balance or the objective, say)."""
    import casadi as ca

    rows = designer.rows
    if rows is None or rows.count == 0:
        return ""
    f = designer.formulation
    evaluate_rows = ca.Function("rows_jacobian", [f.z, f.p], [rows.g, ca.jacobian(rows.g, f.z)])
    for z in points:
        with np.errstate(all="ignore"):
            g, jac = (np.array(v, dtype=float) for v in evaluate_rows(z, p))
        g = g.reshape(-1)
        bad: dict[str, str] = {}
        for group in rows.groups:
            c = group.constraint
            if c.name in bad:
                continue
            values, slopes = g[group.start : group.stop], jac[group.start : group.stop]
            if not np.all(np.isfinite(values)):
                bad[c.name] = f"{c.name} ({file_key(c)}) has no finite value"
            elif not np.all(np.isfinite(slopes)):
                shown = values[0] * group.scale
                bad[c.name] = f"{c.name} ({file_key(c)}) = " + f"{c.unit.from_si(shown):.6g} {c.unit.label}".rstrip() + " has no finite derivative"
        if bad:
            return (
                "; ".join(bad.values())
                + f" at the solver's point ({_design_text(designer, z)}): a division by zero, or a square root, logarithm or power "
                "of a number at or below zero, in the constraint's expression; keep its arguments away from zero within the "
                "variables' bounds (or bound the variables)"
            )
    return ""


def unmet_at(problem: Any, values: Sequence[ConstraintValue]) -> str:
    """The constraints a design misses, by name, value, bound and distance (for a design the
    solver could not bring within its limits)."""
    unmet = [v for v in values if v.active == "violated"]
    out = []
    for v in unmet:
        u = v.constraint.unit
        above = v.upper is not None and v.value > v.upper
        limit = v.upper if above else v.lower
        if limit is None:
            continue
        what = f"{v.name} ({file_key(v.constraint)})"
        if v.constraint.kind == FORCE_LIMIT:
            what += f": spring {v.constraint.spring} pulls {u.from_si(v.value):.6g} {u.label}".rstrip() + f" against its max_force {u.from_si(limit):.6g} {u.label}".rstrip()
        else:
            what += f" = {u.from_si(v.value):.6g} {u.label}".rstrip() + f" against its {'upper' if above else 'lower'} bound {u.from_si(limit):.6g} {u.label}".rstrip()
        what += f", {u.from_si(abs(v.value - limit)):.4g} {u.label}".rstrip() + f" {'over' if above else 'under'}"
        if v.configuration:
            at = ", ".join(f"{n}={problem.coordinate[n].unit.from_si(x):.4g} {problem.coordinate[n].unit.label}".rstrip() for n, x in v.configuration.items())
            what += f" (at {at})"
        if len(problem.scenarios) > 1:
            what += f" in scenario '{v.scenario}'"
        out.append(what)
    return "; ".join(out)


def rows_multipliers(out: SolverOutput, rows: ConstraintRows | None) -> np.ndarray | None:
    """The constraint rows' multipliers of a solver output (the rows are last in g)."""
    if rows is None or out.status is not Status.OPTIMAL or out.multipliers is None or out.multipliers.size < rows.count:
        return None
    return np.asarray(out.multipliers[out.multipliers.size - rows.count :], dtype=float)
