"""The shortcuts of the payload searches give the answers of a full solve.

- :meth:`AdjustmentSolver.at` remembers a payload solved from a start: the same pair again
  returns what a new solve returns (the widest-range search re-solves its starting schedule).
- :meth:`AdjustmentSolver.probe` settles a payload that cannot be balanced by a certificate
  (:mod:`counterpoise.designer.unbalanceable`) instead of the closest-design restarts: when
  it says "cannot", a full solve says infeasible too.

Woo's counterweight design (tests/test_payload.py): dL_c2 = α · l3 / m_c2 with l3 = 200 mm
and 50 mm of travel, so payloads above m_c2 · 50/200 ≈ 34.77 g cannot be balanced; 31 g can.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import solved

from counterpoise.designer.unbalanceable import unbalanceable
from counterpoise.solvers.least_residual import least_residual_bound
from counterpoise.payload.schedule import Adjusters, AdjustmentSolver

#: the adjustment method, built once for the module (as a payload method keeps it)
ADJUSTERS = Adjusters()


@pytest.fixture(scope="module")
def design():
    return solved("woo2019_counterweight")


def _solver(design):
    """A new adjustment solver of the counterweight design, with nothing solved yet (the
    shared result's own solver stays untouched)."""
    return AdjustmentSolver(design.payload.adjuster.source, design.payload.shared(), adjusters=ADJUSTERS)


def test_least_residual_bound_by_hand():
    """g = (z1 − 2, z2) on the box [0, 1]²: the least max |g| is 1 (z1 = 1, z2 = 0); a box
    that holds the balanced point (2, 0) has none above 0; g = (z1 − 2, z1 + 2) on [−1, 1]:
    max(|z1 − 2|, |z1 + 2|) ≥ 2, reached at z1 = 0."""
    eye = np.eye(2)
    assert least_residual_bound(eye, np.array([-2.0, 0.0]), np.zeros(2), np.ones(2)) == pytest.approx(1.0, rel=1e-12)
    assert least_residual_bound(eye, np.array([-2.0, 0.0]), np.zeros(2), np.full(2, 3.0)) <= 0.0
    jac = np.array([[1.0], [1.0]])
    assert least_residual_bound(jac, np.array([-2.0, 2.0]), np.array([-1.0]), np.array([1.0])) == pytest.approx(2.0, rel=1e-12)


@pytest.mark.parametrize("grams", [36.0, 40.0, 80.0])
def test_a_payload_proven_unbalanceable_is_infeasible_when_solved(design, grams):
    solver = _solver(design)
    parameters = {**solver.parameters, solver.payload.name: grams * 1e-3}
    assert unbalanceable(solver.designer, None, parameters, solver.bounds)  # the certificate settles it
    assert solver.probe(grams * 1e-3) is None
    assert not _solver(design).at(grams * 1e-3).feasible  # and the full solve agrees


@pytest.mark.parametrize("grams", [0.0, 31.0, 34.0])
def test_a_balanceable_payload_is_solved_in_full(design, grams):
    solver = _solver(design)
    parameters = {**solver.parameters, solver.payload.name: grams * 1e-3}
    assert not unbalanceable(solver.designer, None, parameters, solver.bounds)
    probed = solver.probe(grams * 1e-3)
    assert probed is not None and probed.feasible
    assert probed == _solver(design).at(grams * 1e-3)  # the same numbers as a new solver's


def test_a_payload_solved_again_from_the_same_start_gives_the_same_setting(design):
    """The remembered setting is the one a new solve from the same start returns, and the
    start that follows it (the last feasible adjustments) is the same too."""
    kept, fresh = _solver(design), _solver(design)
    first = [kept.at(m) for m in (0.010, 0.020, 0.030)]
    kept._last = {}  # noqa: SLF001 - start again from the file's initial values
    again = [kept.at(m) for m in (0.010, 0.020, 0.030)]
    assert all(a is b for a, b in zip(first, again))  # remembered, not solved again
    assert again == [fresh.at(m) for m in (0.010, 0.020, 0.030)]
    assert kept._last == fresh._last  # noqa: SLF001


def test_the_widest_range_search_settles_its_infeasible_probes_by_the_certificate(design, monkeypatch):
    """The bisection toward 34.77 g halves a step of a few grams down to 1e-9 of the unit
    (≈ 25 halvings, about half of them beyond the limit: each ran the closest-design
    restarts before). The least residual beyond the limit grows linearly with the excess
    payload, so it lies within the certificate's rounding margin (1e-12 of the terms, on a
    tolerance of 1e-9) of the tolerance on at most a halving or two; every other probe
    beyond the limit is settled by the certificate: at most 5 restarts, whatever the machine."""
    from counterpoise.designer.closest import Closest
    from counterpoise.payload.widest import widest_range
    from counterpoise.payload.schedule import schedule

    solver = _solver(design)
    plan = schedule(solver, 0.0, 0.031)
    calls = []
    real = Closest.least_squares_multistart
    monkeypatch.setattr(Closest, "least_squares_multistart", lambda self, *a, **k: calls.append(1) or real(self, *a, **k))
    widest, _ = widest_range(solver, plan)
    m_c2 = design.solution.values[next(s for s in design.solution.values if s.variable == "m_c2")]
    assert widest.upper == pytest.approx(m_c2 * 50 / 200, rel=1e-6)
    assert len(calls) <= 5
