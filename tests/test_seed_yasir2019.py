"""Seed 001 (Yaşır, Kiper, Dede, van der Wijk 2019): the 2URRR-URR endoscope holder.

Every number below was re-derived by hand (docs/derivations.md, section Yaşır 2019) from the paper's
equations; here it is reproduced by problem files run through the general engine.
Tolerance 0.1 %.
"""

from __future__ import annotations

import pytest

from conftest import solved, value


class TestCounterMassOnly:
    """Table 1: one leg, link masses neglected, 400 g at the tip; eqs. (1)-(3)."""

    @pytest.fixture
    def result(self):
        return solved("yasir2019_counter_mass")

    def test_optimal_and_verified(self, result):
        assert result.status.value == "optimal"
        assert result.verification.residual_ratio <= 1e-9
        assert result.verification.configurations >= 10_000

    @pytest.mark.parametrize(
        ("name", "expected"),
        [("M_c", 400.0), ("M_b", 1950.0), ("M_a", 3712.5)],  # M_c = m_c r_c/b_c, M_b = (m_c+M_c) r_b/b_b, ...
    )
    def test_counter_masses(self, result, approx, name, expected):
        assert value(result, name, "g") == approx(expected)

    def test_added_mass(self, result, approx):
        assert result.solution.added_mass == approx(6.0625)
        assert value(result, "added_mass_three_legs", "kg") == approx(18.1875)  # "18 kg"


class TestHybridSameSpring:
    """Table 2: three legs, two counter-masses and one spring each, one k for all legs."""

    @pytest.fixture
    def result(self):
        return solved("yasir2019_hybrid")

    def test_optimal_and_verified(self, result):
        assert result.status.value == "optimal"
        assert result.verification.residual_ratio <= 1e-9
        # each of the three legs is checked on its own 10,000 random configurations + corners
        assert {c.subsystem for c in result.verification.checks} == {"side_left", "side_right", "middle"}
        assert result.verification.configurations >= 3 * 10_000

    @pytest.mark.parametrize(
        ("name", "unit", "expected"),
        [
            ("k", "N/mm", 0.5161),
            ("rho_side", "1", 0.4206),
            ("rho_middle", "1", 0.1587),
            ("M_c_side", "g", 293.8),
            ("M_b_side", "g", 1649.8),
            ("M_c_middle", "g", 297.9),
            ("M_b_middle", "g", 1568.0),
            ("M_a_side", "g", 2388.9),
            ("M_a_middle", "g", 2396.9),
            ("M_a_total", "g", 7174.6),
            ("g_at_side", "mm", 134.0),
            ("g_at_middle", "mm", 133.5),
        ],
    )
    def test_reported_values(self, result, approx, name, unit, expected):
        assert value(result, name, unit) == approx(expected)

    def test_spring_balances_each_leg_as_a_pendulum(self, result):
        """Eq. (9) as a cross-check: k f^2 = M_a g g_at for every leg, with the solved numbers."""
        k = value(result, "k") * 1e3  # N/m
        f = 0.078
        for leg in ("side", "middle"):
            M_a = value(result, f"M_a_{leg}") * 1e-3
            g_at = value(result, f"g_at_{leg}") * 1e-3
            assert k * f**2 == pytest.approx(M_a * 9.81 * g_at, rel=1e-9)

    def test_identical_legs_do_not_repeat_conditions(self, result):
        # 3 legs x 3 coordinates = 9 block conditions; the two side legs coincide -> 6
        assert result.solution.stats.conditions == 6


class TestFreeExtensions:
    """The hybrid side leg with b_b in [40, 120] mm and b_c in [100, 250] mm free."""

    def test_zero_inertia_weight_pushes_extensions_to_upper_bounds(self):
        from counterpoise.report import design_table

        result = solved("yasir2019_free_extensions")
        assert result.status.value == "optimal"
        assert result.verification.residual_ratio <= 1e-9
        table = design_table(result).set_index("name")
        assert table.loc["b_b", "active_bound"] == "upper"
        assert table.loc["b_c", "active_bound"] == "upper"
        assert table.loc["b_b", "value"] == pytest.approx(120.0)
        assert table.loc["b_c", "value"] == pytest.approx(250.0)
        assert value(result, "added_mass", "g") < 1943.6  # the paper's M_b + M_c
        # at the bounds the counter-masses follow eqs. (1)-(2): M_c = (m_c g_c + m_pay g_pay)/b_c
        assert value(result, "M_c", "g") == pytest.approx((63.2 * 90.7 + 291.2 * 182.1) / 250, rel=1e-6)

    def test_positive_inertia_weight_moves_extensions_inside(self):
        from counterpoise.report import design_table

        result = solved("yasir2019_free_extensions", (("objective.inertia_weight", "200 1/m^2"),))
        assert result.status.value == "optimal"
        assert result.verification.residual_ratio <= 1e-9
        table = design_table(result).set_index("name")
        for name, (lo, hi) in {"b_b": (40, 120), "b_c": (100, 250)}.items():
            assert table.loc[name, "active_bound"] == ""
            assert lo < table.loc[name, "value"] < hi
        # M_b's moment is fixed once M_c is, so min M_b (1 + w b_b^2) gives b_b = 1/sqrt(w)
        assert table.loc["b_b", "value"] == pytest.approx(1e3 / 200**0.5, rel=1e-6)
