"""Seed 003 (Woo, Seo, Yi 2019): the spring-only design and its adjustment by moving the
springs' insertion points (problems/woo2019_springs.toml; hand derivation in
docs/seeds.md#woo-springs, g = 9.81).

With the 1280 g drill, A1 = 1762 g and A5 = -2790.5 g (docs/derivations.md#woo-2019). Every
attachment distance is 50 mm at the nominal payload, so eqs. (18)-(19) give
    k1 = g A1 l1/(s11 s12) = 9.81 * 1.762 * 0.2 / 0.05^2 = 1382.82 N/m,
    k2 = g |A5| l5/(|s21| s22) = 9.81 * 2.7905 * 0.1 / 0.05^2 = 1094.99 N/m,
and eq. (23) moves the insertion points by dS12 = alpha l1 g/(k1 s11), dS22 = alpha l3 g/(k2 |s21|).
"""

from __future__ import annotations

import pytest

from conftest import solved, value

G = 9.81
A1, A5 = 1.762, -2.7905  # kg
L1, L3, L5, S = 0.2, 0.2, 0.1, 0.05  # m


def _row(result, payload_g: float):
    for s in result.payload.schedule.rows:
        if abs(s.payload * 1e3 - payload_g) < 1e-9:
            return {k: v * 1e3 for k, v in s.values.items()}
    raise KeyError(payload_g)


@pytest.fixture
def result():
    return solved("woo2019_springs")


def test_balanced_over_the_range(result):
    assert result.status.value == "optimal", result.message
    assert result.verification.residual_ratio <= 1e-9
    assert result.payload.schedule.feasible
    assert result.payload.checked == pytest.approx((0.0, 0.122))


def test_spring_rates_eqs_18_19(result):
    assert value(result, "k1", "N/mm") == pytest.approx(G * A1 * L1 / S**2 / 1000, rel=1e-7)  # 1.38282
    assert value(result, "k2", "N/mm") == pytest.approx(G * -A5 * L5 / S**2 / 1000, rel=1e-7)  # 1.09499


@pytest.mark.parametrize("payload", [0.0, 62.0, 122.0])
def test_insertion_points_eq_23(result, payload):
    k1, k2 = value(result, "k1") * 1000, value(result, "k2") * 1000  # N/m
    row = _row(result, payload)
    alpha = payload * 1e-3
    assert row["s12"] == pytest.approx(50 + 1000 * alpha * L1 * G / (k1 * S), rel=1e-7)
    assert row["s22"] == pytest.approx(50 + 1000 * alpha * L3 * G / (k2 * S), rel=1e-7)


def test_travel_at_122_g(result):
    """3.462 mm on link 1, 4.372 mm on link 5: a few millimetres for the whole hybrid range."""
    row = _row(result, 122)
    assert row["s12"] - 50 == pytest.approx(3.462, abs=1e-3)
    assert row["s22"] - 50 == pytest.approx(4.372, abs=1e-3)


def test_schedule_is_linear(result):
    lines = {line.variable: line for line in result.payload.schedule.lines}
    assert set(lines) == {"s12", "s22"}
    k1 = value(result, "k1") * 1000
    assert lines["s12"].slope == pytest.approx(L1 * G / (k1 * S), rel=1e-7)  # m per kg
    assert lines["s12"].intercept == pytest.approx(0.05, rel=1e-9)
