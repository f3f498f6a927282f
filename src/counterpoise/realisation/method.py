"""The realisation layer: a design whose springs can be built as specified and balance as built.

:class:`RealisationMethod` wraps a problem's design method (every other layer inside it)
and, after each solve:

1. designs the helical spring of every free-stiffness spring (:mod:`counterpoise.springs`)
   and measures every realisation limit over the workspace (:mod:`.limits`: clearance,
   slack, wrap, plane, the spring itself);
2. where a limit the design can move is violated, adds it as a design constraint (kind
   ``realisation``, tightened to what the spring needs) and solves again: at most
   :data:`ROUNDS` rounds, each started from the last design;
3. re-solves the design for the rate each designed spring is wound to (its rounded coils
   and diameter), the stiffness held there, so that the points on the build sheet balance
   the spring that will be made (:func:`wound`);
4. judges: a limit still violated, or a spring that cannot be made, is ``infeasible``
   (source ``realisation``), naming the spring, the limit and where; the last design is the
   closest buildable one the rounds reached, and is reported as for any infeasible problem.

A problem whose springs are declared ideal (``[settings] ideal_springs = true``: a paper's
idealised design) is not wrapped: its limits are only reported (:func:`report_of`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any

from ..designer.methods import DesignMethod
from ..designer.options import SolveOptions
from ..designer.solution import Solution
from ..model import expr as ex
from ..model.problem import Problem
from ..solvers.base import Status
from ..designer.minimax import minimax_of
from ..selection.result import PartsReport
from .limits import Limit, checked_solution, constraints, evaluate, tuned_envelope
from .result import RealisationReport

#: rounds of added realisation constraints, at most
ROUNDS = 4
#: a wound rate counts as the design rate within this share (no re-solve)
SAME_RATE = 1e-12
#: re-solves for the wound rates, at most (a spring designed for the new working range may
#: be wound to another rate: solved again for that one)
WOUND_ROUNDS = 3


def designed_of(solution: Solution) -> tuple[Any, ...]:
    """The designed springs of ``solution`` (free-stiffness springs; empty when none)."""
    if not any(s.slot is None for s in solution.problem.springs):
        return ()
    from ..springs.workspace import designed_springs

    return designed_springs(solution, checked_solution(solution), tuned_envelope(solution))


def report_of(solution: Solution, ideal: bool = False) -> RealisationReport:
    """The realisation limits of ``solution`` as they stand (no rounds, no verdict)."""
    springs = designed_of(solution)
    return RealisationReport(evaluate(solution, springs, solution.extra(PartsReport)), springs, ideal=ideal)


class RealisationMethod(DesignMethod):
    """Design ``problem`` with the method ``build(problem)`` makes, within the realisation
    limits of its springs (see the module docstring). ``build`` is called again for the
    problem with realisation constraints added, once per round that needs one."""

    phase = "designing"

    def __init__(self, problem: Problem, build: Callable[[Problem], DesignMethod], inner: DesignMethod | None = None) -> None:
        self._problem = problem
        self._build = build
        self.inner = inner if inner is not None else build(problem)
        self.phase = getattr(self.inner, "phase", "designing")
        #: methods of the problems with realisation constraints, by their constraints' content
        self._methods: dict[tuple[Any, ...], DesignMethod] = {}

    @property
    def problem(self) -> Problem:
        return self._problem

    def _method(self, problem: Problem) -> DesignMethod:
        if problem is self._problem:
            return self.inner
        key = (tuple((c.name, c.lower, c.upper) for c in problem.constraints), tuple((s.name, s.stiffness) for s in problem.springs))
        if key not in self._methods:
            self._methods[key] = self._build(problem)
        return self._methods[key]

    def solve_with(self, options: SolveOptions) -> Solution:
        problem = self._problem
        solution = self.inner.solve_with(options)
        if not problem.springs:
            return solution
        added: list[str] = []
        rounds = 0
        forced: tuple[Limit, ...] = ()  # the violated limits of the last optimal design
        springs: tuple[Any, ...] = ()
        limits: tuple[Limit, ...] = ()
        while True:
            if not _ok(solution):
                if forced:  # the realisation constraints made it infeasible: say which limits
                    return _unbuildable(solution, forced, springs, rounds)
                return solution  # not balanced in the ideal model already: its own verdict stands
            springs = designed_of(solution)
            limits = evaluate(solution, springs, solution.extra(PartsReport))
            if rounds >= ROUNDS:
                break
            new = constraints(problem, limits)
            if not new:
                break
            forced = tuple(lim for lim in limits if not lim.met)
            names = {c.name for c in new}
            problem = replace(problem, constraints=tuple(c for c in problem.constraints if c.name not in names) + new)
            added += [n for n in sorted(names) if n not in added]
            rounds += 1
            solution = self._method(problem).solve_with(replace(options, initial=dict(solution.values)))
        wound: dict[str, tuple[float, float]] = {}
        if _ok(solution) and springs:
            solution, springs, limits, wound = self._wound(problem, solution, springs, limits, options)
        report = RealisationReport(limits, springs, tuple(added), rounds, wound)
        solution = solution.with_extra(report)
        return _judged(solution, report)

    def _wound(
        self, problem: Problem, solution: Solution, springs: Sequence[Any], limits: tuple[Limit, ...], options: SolveOptions
    ) -> tuple[Solution, tuple[Any, ...], tuple[Limit, ...], dict[str, tuple[float, float]]]:
        """The design re-solved for the wound rates (see :func:`wound_rates`), with its
        springs' designs checked again for the new working range; as it was when no rate
        moves, or with a limit naming the springs when no design balances them as wound.

        A geometry held at a bound can follow a rate on one side of the design rate only:
        when the springs as designed cannot be followed, each is tried wound on the other
        side of its design rate alone, then all of them (at most n + 2 tries)."""
        _, _, changed = wound_rates(problem, springs)
        if not changed:
            return solution, tuple(springs), limits, {}
        tries = [tuple(springs)] + [_other_side(springs, {n: changed[n]}) for n in changed]
        if len(changed) > 1:
            tries.append(_other_side(springs, changed))
        for option in tries:
            followed = self._follow(problem, solution, option, options)
            if followed is not None:
                final, made = followed
                rates = {d.spring: float(d.design.rate) for d in made if d.ok}
                wound = {n: (design, rates.get(n, first)) for n, (design, first) in changed.items()}
                return final, made, evaluate(final, made, final.extra(PartsReport)), wound
        note = "; ".join(f"{n}: designed for {a / 1e3:.6g} N/mm, wound to {b / 1e3:.6g} N/mm" for n, (a, b) in changed.items())
        limit = Limit(next(iter(changed)), "spring", math.nan, math.nan, "lower", "", "", None,
                      f"no design balances the springs as wound ({note}), on either side of their design rates: "
                      "free a point of the spring or a tune variable so the geometry can follow its rate")
        return solution, tuple(springs), (*limits, limit), changed

    def _follow(
        self, problem: Problem, solution: Solution, springs: Sequence[Any], options: SolveOptions
    ) -> tuple[Solution, tuple[Any, ...]] | None:
        """The design solved again for these springs' wound rates (each spring kept as wound
        while the geometry follows it, :func:`_same_springs`); None when no design balances them."""
        held: dict[str, float] = {}
        for _ in range(WOUND_ROUNDS):
            fixed, replaced, changed = wound_rates(problem, springs)
            if not changed:
                return solution, tuple(springs)
            held.update(fixed)
            problem = with_rates(problem, replaced)
            over: dict[Any, tuple[float, float]] = {**(options.bounds or {}), **{name: (k, k) for name, k in held.items()}}
            again = self._method(problem).solve_with(replace(options, bounds=over, initial=dict(solution.values)))
            if not _ok(again):
                return None
            if minimax_of(again) is None and again.verification is None:
                # a solver may call a design held at a bound balanced to its own tolerance:
                # the dense check says whether it follows the wound rate (and is kept for run())
                from ..verify.check import check

                verification = check(again, "dense")
                if not verification.balanced:
                    return None
                again = replace(again, verification=verification)
            solution, springs = again, _same_springs(springs, designed_of(again))
        return (solution, tuple(springs)) if not wound_rates(problem, springs)[2] else None


def _other_side(springs: Sequence[Any], changed: Mapping[str, tuple[float, float]]) -> tuple[Any, ...]:
    """The springs of ``changed`` designed again, wound on the other side of their design rate."""
    from ..springs.design import redesign_on_side

    out = []
    for d in springs:
        if d.spring in changed and d.ok:
            design_rate, wound_rate = changed[d.spring]
            other = redesign_on_side(d.design, -1 if wound_rate > design_rate else 1)
            out.append(replace(d, design=other) if other.ok else d)
        else:
            out.append(d)
    return tuple(out)


def with_rates(problem: Problem, rates: Mapping[str, float]) -> Problem:
    """``problem`` with these springs' stiffness set to a number (N/m)."""
    if not rates:
        return problem
    return replace(problem, springs=tuple(replace(s, stiffness=ex.Num(rates[s.name])) if s.name in rates else s for s in problem.springs))


def _same_springs(before: Sequence[Any], after: Sequence[Any]) -> tuple[Any, ...]:
    """The springs ``after`` a re-solve for their wound rates, each the very spring wound
    ``before`` (same wire, diameter and coils) checked against its new working range: the
    design was solved for that spring's rate, a newly chosen one would have another."""
    from ..springs.design import redesign_at

    made = {(d.spring, d.scenario): d for d in before}
    out = []
    for d in after:
        old = made.get((d.spring, d.scenario)) or made.get((d.spring, "all"))
        if old is None or not old.ok:
            out.append(d)
            continue
        same = redesign_at(old.design, d.design.requirement)
        out.append(replace(d, design=same) if same.ok else d)  # no longer strong enough: the new choice, solved for in turn
    return tuple(out)


def wound_rates(problem: Problem, springs: Sequence[Any]) -> tuple[dict[str, float], dict[str, float], dict[str, tuple[float, float]]]:
    """(variables to hold, springs whose stiffness to set, per spring (design rate, wound
    rate)) for the designed springs whose wound rate differs from the rate they were
    designed for. A stiffness that is a design variable (not adjustable) is held at the
    wound rate, unless springs wound to different rates share it; any other stiffness (a
    number, a parameter, an expression, a shared variable) is set to the wound rate."""
    by_spring = {s.name: s for s in problem.springs}
    fixed: dict[str, float] = {}
    replaced: dict[str, float] = {}
    changed: dict[str, tuple[float, float]] = {}
    shared: set[str] = set()
    for d in springs:
        if not d.ok or (len(problem.scenarios) > 1 and d.scenario != "all"):
            continue
        made = d.design
        design_rate, wound_rate = float(made.requirement.rate), float(made.rate)
        if abs(wound_rate / design_rate - 1.0) <= SAME_RATE or _toleranced(problem, d.spring, design_rate, wound_rate):
            continue
        s = by_spring[d.spring]
        changed[s.name] = (design_rate, wound_rate)
        k = s.stiffness
        if isinstance(k, ex.Name) and k.id in problem.variable and not problem.variable[k.id].adjustable and k.id not in shared:
            if k.id in fixed and abs(fixed[k.id] / wound_rate - 1.0) > SAME_RATE:
                shared.add(k.id)
                fixed.pop(k.id)
                continue
            fixed[k.id] = wound_rate
        else:
            replaced[s.name] = wound_rate
    for name, rate in changed.items():  # springs of a variable that turned out shared: each its own rate
        k = by_spring[name].stiffness
        if isinstance(k, ex.Name) and k.id in shared:
            replaced[name] = rate[1]
    return fixed, replaced, changed


def _ok(solution: Solution) -> bool:
    """The design is optimal by its solver and by every layer's own verdict."""
    return solution.status is Status.OPTIMAL and (solution.verdict is None or solution.verdict.status is Status.OPTIMAL)


def _toleranced(problem: Problem, spring: str, design_rate: float, wound_rate: float) -> bool:
    """A [robust] design whose rate tolerance of ``spring`` covers the wound rate: the robust
    layer's worst case (and its tuning) already answers for it; the design is not solved again."""
    spec = problem.robust
    if spec is None:
        return False
    for tol in spec.tolerances:
        if tol.kind == "rate" and tol.item in (spring, "", "*"):
            allowed = tol.amount * design_rate if tol.relative else tol.amount
            if abs(wound_rate - design_rate) <= allowed:
                return True
    return False


def _unbuildable(solution: Solution, forced: Sequence[Limit], springs: Sequence[Any], rounds: int) -> Solution:
    """The design of a round whose realisation constraints no balanced design keeps: judged
    infeasible, naming the limits the round added and what the solver's word was."""
    problem = solution.problem
    text = "; ".join(lim.text(problem) for lim in forced[:3])
    more = f" (and {len(forced) - 3} more)" if len(forced) > 3 else ""
    message = (
        f"infeasible as built: {text}{more}; no balanced design within the bounds keeps "
        f"{'this limit' if len(forced) == 1 else 'these limits'} (free the spring's points or its rate, or declare "
        f"the springs ideal); {solution.message}"
    )
    report = RealisationReport(tuple(forced), tuple(springs), tuple(c.name for c in problem.constraints if c.kind == "realisation"), rounds)
    return replace(solution, status=Status.INFEASIBLE, message=message).with_extra(report).judged(Status.INFEASIBLE, message, "realisation")


def _judged(solution: Solution, report: RealisationReport) -> Solution:
    """``solution`` judged infeasible when a realisation limit is violated (the layer's own
    verdict), else as it is."""
    violated = report.violated
    if not violated or not _ok(solution):
        return solution  # balanced and buildable, or an inner layer's own verdict stands
    problem = solution.problem
    text = "; ".join(lim.text(problem) for lim in violated[:3])
    more = f" (and {len(violated) - 3} more)" if len(violated) > 3 else ""
    rounds = f" after {report.rounds} round{'s' if report.rounds != 1 else ''} of realisation constraints" if report.rounds else ""
    message = f"infeasible as built{rounds}: {text}{more}"
    return replace(solution, status=Status.INFEASIBLE, message=message).judged(Status.INFEASIBLE, message, "realisation")
