"""The relaxed problem (each slot's rate continuous) and each slot's balanceable rate window."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from ..designer.designer import Designer
from ..formulation.layout import Slot
from ..model.problem import Problem, Variable
from ..model.units import display_unit
from ..solvers.base import Status
from ..solvers.ipopt import IpoptBackend

#: a part whose rate is within this relative amount of the window's ends is kept
WINDOW_SLACK = 1e-9


def relaxed_problem(problem: Problem) -> Problem:
    """The problem with each slot's rate a continuous variable over its catalogue's range."""
    names = {s.name for s in problem.slots}
    unit = display_unit("N/mm")
    extra = []
    for s in problem.slots:
        rates = s.catalogue.array("rate")
        lo, hi = float(rates.min()), float(rates.max())
        extra.append(Variable(s.name, lo, hi if hi > lo else lo, float(np.median(rates)), unit, description=f"rate of slot {s.name}"))
    return replace(
        problem,
        parameters=tuple(p for p in problem.parameters if p.name not in names),
        variables=problem.variables + tuple(extra),
        slots=problem.slots,
    )


class RateWindows:
    """The rate-window NLP of a relaxed problem's designer (minimise or maximise one slot's
    rate subject to the balance conditions), built on first use and kept: each search
    passes its parameters and bounds per solve."""

    def __init__(self, designer: Designer) -> None:
        self.designer = designer
        self._backends: dict[tuple[str, ...], IpoptBackend] = {}

    def _backend(self, names: tuple[str, ...]) -> IpoptBackend:
        import casadi as ca

        if names not in self._backends:
            d = self.designer
            f = d.formulation
            w = ca.SX.sym("w", len(names))
            index = [f.design.index[Slot(n, None)] for n in names]
            objective = sum(w[i] * f.z[index[i]] for i in range(len(names)))
            nlp = {"x": f.z, "p": ca.vertcat(f.p, w), "f": objective, "g": ca.vertcat(d.conditions.equalities, f.nonnegative)}
            self._backends[names] = IpoptBackend(nlp, d.options, "rate_window")
        return self._backends[names]

    def solve(
        self,
        relaxed: Problem,
        names: list[str],
        base: Any,
        parameters: Mapping[str, float] | None = None,
        bounds: Mapping[Slot | str, tuple[float, float]] | None = None,
    ) -> tuple[dict[str, tuple[float, float]], int]:
        """Smallest and largest balanceable rate of each slot (two NLPs per slot), and the
        solves made; ``parameters`` and ``bounds`` (SI) as in :meth:`Designer.solve`."""
        d = self.designer
        f = d.formulation
        if d.n_equalities > len(f.design):
            return {n: (float(relaxed.variable[n].lower), float(relaxed.variable[n].upper)) for n in names}, 0
        backend = self._backend(tuple(names))
        index = [f.design.index[Slot(n, None)] for n in names]
        p = f.parameters.values(parameters) if parameters else d.parameters
        # a window without the design constraints: wider, so it prunes safely
        b = d.bounds(d.n_equalities, bounds or None, constraints=False)
        z0 = f.design.to_z(f.design.vector(base.values))
        out, solves = {}, 0
        for i, n in enumerate(names):
            ends = []
            for sign in (1.0, -1.0):
                weights = np.zeros(len(names))
                weights[i] = sign
                res = backend.solve(z0, np.concatenate([p, weights]), b)
                solves += 1
                if res.status is Status.OPTIMAL:
                    ends.append(float(f.design.to_x(res.z)[index[i]]))
                else:  # not settled: do not prune on this side
                    ends.append(relaxed.variable[n].lower if sign > 0 else relaxed.variable[n].upper)
            out[n] = (min(ends), max(ends))
        return out, solves


def inside_window(rates: np.ndarray, window: tuple[float, float]) -> np.ndarray:
    """Which rates lie in the window (with :data:`WINDOW_SLACK`)."""
    lo, hi = window
    return (rates >= lo * (1 - WINDOW_SLACK)) & (rates <= hi * (1 + WINDOW_SLACK))
