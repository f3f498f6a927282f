"""Screening every part of a zero-free-length slot at once, before the exact solves.

Within the slot's balanceable rate window the design of the relaxed problem with the rate
fixed, z*(k), varies smoothly with k. The screening solves it exactly at a few node rates
(:data:`NODES`), interpolates every design variable linearly in k between them, and from
these designs evaluates in one numpy pass per scenario, for every part of the window:

- its three limit margins (:mod:`counterpoise.catalogue.limits`) over sampled configurations;
- its tolerance sensitivity: max over configurations and coordinates of
  Σ_springs t_k·(k·d − F0)·|∂d/∂q_j| + t_F·F0·|∂d/∂q_j| (the tolerance band's terms: the rate
  error acts on the extension d − F0/k beyond the initial tension; without the
  nominal residual, which exact balance makes zero), which ranks parts that tie on the
  objective the way ``selection.prefer`` does.

Parts predicted to break a limit by more than :data:`PREDICTION_MARGIN` (relative) are
pruned; the others are ranked by (interpolated objective, sensitivity, price), in the
order ``selection.prefer`` gives these three, and their
rates solved exactly in that order, at most :data:`EXACT_RATES` distinct rates. The exact
solves, limits and tolerance bands then decide as in the enumeration. The prediction is
not a certificate: the evidence says how many parts each step set aside.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..catalogue.limits import LIMITS, margins, violation
from ..mechanics.sampling import MAX_CORNERS
from .geometry import spring_lengths
from .screening import energy_arrays

#: node rates at which the design is solved exactly (spread over the window's distinct rates)
NODES = 9
#: parts whose predicted relative limit violation exceeds this are pruned without a solve
PREDICTION_MARGIN = 0.05
#: at most this many distinct rates are solved exactly after the screening
EXACT_RATES = 24
#: configurations per subsystem of the screening (the limit check's sample is cut to this)
SCREEN_SAMPLES = 128


@dataclass
class RateScreen:
    """The screening of one slot: which rates to solve, and what it set aside."""

    order: np.ndarray  # distinct rates to solve exactly, most promising first
    nodes: list[tuple[dict[str, float], Any]]  # (fixed rate, exact solution) of the node solves
    predicted_fail: dict[str, int] = field(default_factory=dict)  # limit -> parts pruned by prediction
    candidates: int = 0  # parts predicted to fit
    beyond_budget: int = 0  # predicted-fitting parts whose rate was not solved (budget)


def _cut(q: Mapping[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
    """The first ``n`` random configurations of each subsystem, and the box's corners (the
    sample ends with them: :func:`counterpoise.verify.residuals.configurations`)."""
    out = {}
    for k, v in q.items():
        corners = 2 ** v.shape[1] if 2 ** v.shape[1] <= MAX_CORNERS else 0
        out[k] = np.vstack([v[:n], v[len(v) - corners :]]) if len(v) > n + corners else v
    return out


def screen_rates(search: Any, name: str, rates: np.ndarray, kept: np.ndarray, others: Mapping[str, tuple[float, float]]) -> RateScreen:
    """Screen the kept parts (rows) of slot ``name`` whose distinct rates are ``rates`` (sorted)."""
    slot = search.slots[name]
    relaxed = search.relaxed
    picks = np.unique(np.round(np.linspace(0, len(rates) - 1, min(NODES, len(rates)))).astype(int))
    nodes = []
    for i in picks:
        k = float(rates[i])
        sol = search.solve_relaxed(search.base.values, {name: (k, k), **others})
        search.solves += 1
        if sol.status.value == "optimal":
            nodes.append(({name: k}, sol))
    if len(nodes) < 2:
        return RateScreen(np.arange(len(rates)), nodes)
    node_k = np.array([fixed[name] for fixed, _ in nodes])
    node_objective = np.array([sol.objective for _, sol in nodes])
    objective = np.interp(rates, node_k, node_objective)
    a = slot.catalogue.arrays
    part_rate = a["rate"][kept]
    at = np.searchsorted(rates, part_rate)  # index of each part's rate among the distinct rates
    q = _cut(search.q, SCREEN_SAMPLES)
    d_min = np.full(len(rates), np.inf)
    d_max = np.zeros(len(rates))
    springs = [s for s in relaxed.springs if s.name in slot.springs]
    names = [v.name for v in relaxed.variables]
    designs = {}
    for scenario in relaxed.scenarios:
        values = {v: np.interp(rates, node_k, [sol.variable_values(scenario.name)[v] for _, sol in nodes]) for v in names}
        designs[scenario.name] = values
        gravity, base = nodes[0][1].scenario_parameters[scenario.name]
        lengths = spring_lengths(relaxed, [s.name for s in springs], q, {v: x[:, None] for v, x in values.items()}, base, gravity)
        for s in springs:  # the slack margin: the part must stay that much beyond F0/k
            d_min = np.minimum(d_min, lengths[s.name].min(axis=1) - s.slack_margin)
            d_max = np.maximum(d_max, lengths[s.name].max(axis=1))
    part = {f: a[f][kept] for f in ("rate", "free_length", "initial_tension", "max_load", "max_length")}
    m = margins(d_min[at], d_max[at], **part)
    amount, which = violation(m, **part)
    fail = amount > PREDICTION_MARGIN
    predicted_fail: dict[str, int] = {}
    for w in which[fail]:
        predicted_fail[LIMITS[int(w)]] = predicted_fail.get(LIMITS[int(w)], 0) + 1
    ok = np.flatnonzero(~fail)
    # tolerance sensitivity, only at the rates of parts predicted to fit
    used, local = np.unique(at[ok], return_inverse=True)
    sens_k = np.zeros((len(used), 0))
    sens_f = np.zeros((len(used), 0))
    for scenario in relaxed.scenarios:
        gravity, base = nodes[0][1].scenario_parameters[scenario.name]
        values = {v: x[used] for v, x in designs[scenario.name].items()}
        for sub in relaxed.subsystems:
            mine = [s for s in springs if s.subsystem == sub.name]
            if not mine or not len(used):
                continue
            _, arr = energy_arrays(relaxed, sub.name, q[sub.name], values, base, gravity, mine, rest=False)
            rate_term = sum(np.abs(d[:, :, None] * grad) for d, grad in arr.values())  # (n, N, n_q)
            tension_term = sum(np.abs(grad) for _, grad in arr.values())
            sens_k = np.hstack([sens_k, rate_term.reshape(len(used), -1)])
            sens_f = np.hstack([sens_f, tension_term.reshape(len(used), -1)])
    tk = np.nan_to_num(slot.rate_tolerance)
    tf = np.nan_to_num(slot.initial_tension_tolerance)
    # t_k (k d − F0)|∂d/∂q| + t_F F0 |∂d/∂q| summed over the slot's springs (selection/tolerance.py)
    sensitivity = (tk * part["rate"][ok, None] * sens_k[local] + (tf - tk) * part["initial_tension"][ok, None] * sens_f[local]).max(axis=1, initial=0.0)
    price = np.nan_to_num(a["price"][kept][ok], nan=np.inf)
    keys = {"objective": np.round(objective[at[ok]], 9), "robust": sensitivity, "price": price}
    order_of = {"objective": ("objective", "robust", "price"), "robust": ("robust", "objective", "price"), "price": ("price", "objective", "robust")}
    first, second, third = order_of.get(search.problem.selection.prefer, order_of["objective"])
    ranked = ok[np.lexsort((keys[third], keys[second], keys[first]))]  # the last key sorts first
    order: list[int] = []
    for i in ranked:
        if at[i] not in order:
            order.append(int(at[i]))
    beyond = int(np.isin(at[ok], order[EXACT_RATES:]).sum())
    return RateScreen(np.array(order[:EXACT_RATES], dtype=int), nodes, predicted_fail, len(ok), beyond)

