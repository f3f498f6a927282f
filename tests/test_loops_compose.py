"""Closed loops composed with the other features (issue 13's rule, docs/loops.md):
payload ranges, catalogue slots, directly attached springs and studies that vary a loop's
geometry. Every expected number is derived by hand in the test."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from counterpoise.io.loader import load_problem_text
from counterpoise.pipeline import design

ROOT = Path(__file__).resolve().parents[1]
FOURBAR = (ROOT / "problems" / "fourbar_counter_mass.toml").read_text(encoding="utf-8")

#: the acceptance's bound on the manifold residual (docs/loops.md)
MANIFOLD_RATIO = 1e-9

# the four-bar of problems/fourbar_counter_mass.toml (SI)
M2, P2, M3, A, P3, B, M4, P4, C = 0.3, 0.06, 0.8, 0.12, 0.15, 0.3, 0.4, 0.125, 0.25
E2, E4 = 0.100, 0.120
#: first moments the crank's and the rocker's counter-masses must cancel, without payload
C2 = M2 * P2 + M3 * A * (1 - P3 / B)
C4 = M3 * P3 * C / B + M4 * P4


def _payload_fourbar(u: str, top: str) -> str:
    """The four-bar with a payload on the coupler, u from A along AB, over 0..top, and
    counter-masses whose levers (behind the ground pivots) are adjusted per payload."""
    s = FOURBAR.replace('name = "fourbar_counter_mass"', 'name = "fourbar_payload"')
    s = s.replace("[subsystems.fourbar]", f'u = {{ value = "{u}" }}\n\n[subsystems.fourbar]')
    head, _ = s.split("[variables]")
    return head + f'''[payloads.tool]
frame = "coupler"
position = ["u", 0, 0]
range = ["0 g", "{top}"]

[variables]
M_crank = {{ lower = "0 kg", upper = "10 kg", initial = "1 kg" }}
M_rocker = {{ lower = "0 kg", upper = "10 kg", initial = "1 kg" }}
dL2 = {{ lower = "0 mm", upper = "50 mm", adjustable = true, nominal = "0 mm", travel = "50 mm" }}
dL4 = {{ lower = "0 mm", upper = "50 mm", adjustable = true, nominal = "0 mm", travel = "50 mm" }}

[counter_masses.crank_cm]
frame = "crank"
mass = "M_crank"
position = ["-(e2 + dL2)", 0, 0]

[counter_masses.rocker_cm]
frame = "rocker"
mass = "M_rocker"
position = ["-(e4 + dL4)", 0, 0]
'''


def test_a_payload_range_on_a_four_bar_is_scheduled_on_the_manifold():
    # A payload P on the coupler, u from A, adds P·(a e^{iθ2} + u e^{iθ3}) to the first
    # moment; with the loop equation that is P·a(1 − u/b) e^{iθ2} + P·u c/b e^{iθ4} + const.
    # At the nominal payload 0 the levers are pinned (dL = 0): M_crank = C2/e2, M_rocker = C4/e4.
    # At P: M_crank (e2 + dL2) = C2 + P a (1 − u/b), so dL2 = e2 P a (1 − u/b)/C2, and
    # dL4 = e4 P u (c/b)/C4: both linear in P.
    u, top = 0.2, 0.2
    r = design(load_problem_text(_payload_fourbar("200 mm", "200 g"), "fourbar_payload.toml"))
    assert r.optimal, r.message
    assert r.verification.residual_ratio <= MANIFOLD_RATIO
    shared = r.payload.shared()
    assert shared["M_crank"] == pytest.approx(C2 / E2, rel=1e-9)
    assert shared["M_rocker"] == pytest.approx(C4 / E4, rel=1e-9)
    rows = r.payload.schedule.rows + r.payload.schedule.between
    assert len(rows) > 10
    for row in rows:
        assert row.feasible, row.message
        assert row.residual_ratio <= MANIFOLD_RATIO
        p = row.payload
        assert row.values["dL2"] == pytest.approx(E2 * p * A * (1 - u / B) / C2, rel=1e-7, abs=1e-12)
        assert row.values["dL4"] == pytest.approx(E4 * p * u * (C / B) / C4, rel=1e-7, abs=1e-12)
    top_row = max(rows, key=lambda s: s.payload)
    assert top_row.payload == pytest.approx(top)
    assert top_row.values["dL4"] == pytest.approx(E4 * top * u * (C / B) / C4, rel=1e-9)  # 26.67 mm


SPRINGS = (ROOT / "problems" / "fourbar_springs.toml").read_text(encoding="utf-8")
#: fixed rates of the directly attached springs, and their free lengths (SI)
K2, K4, L2, L4 = 100.0, 100.0, 0.040, 0.020
R_CRANK, S_ROCKER = 0.060, 0.100


def _direct_fourbar(rocker_max: str) -> str:
    """fourbar_springs.toml with directly attached springs of fixed rates whose anchor
    heights are designed; initial tension k·L0 makes each one act as a zero-free-length
    spring while its length stays within [L0, L_max]. Where a rocker's spring passes its
    shortest (the rocker upright), |h4 − s| ≥ L0 splits the anchors into two intervals; the
    initial values pick the upper one."""
    head, _ = SPRINGS.split("[variables]")
    return head + f'''[variables]
h2 = {{ lower = "50 mm", upper = "150 mm", initial = "110 mm" }}
h4 = {{ lower = "50 mm", upper = "200 mm", initial = "140 mm" }}

[springs.crank_spring]
stiffness = "{K2} N/m"
from = {{ frame = "ground", point = [0, "h2", 0] }}
to = {{ frame = "crank", point = ["r", 0, 0] }}
mount = "direct"
free_length = "{L2 * 1000} mm"
initial_tension = "{K2 * L2} N"
max_length = "200 mm"

[springs.rocker_spring]
stiffness = "{K4} N/m"
from = {{ frame = "ground", point = ["d", "h4", 0] }}
to = {{ frame = "rocker", point = ["s", 0, 0] }}
mount = "direct"
free_length = "{L4 * 1000} mm"
initial_tension = "{K4 * L4} N"
max_length = "{rocker_max}"

[objective]
mass_weight = 0
'''


def test_directly_attached_springs_on_a_four_bar_are_designed_on_the_manifold():
    # With F0 = k·L0 the energy is ½ k d² + const (a zero-free-length spring), so exact
    # balance needs k h r = g C2 and k h s = g C4 (docs/loops.md), i.e. anchor heights
    # h2 = 107.91 mm and h4 = 147.15 mm. On the manifold the rocker swings between 75.3° and
    # 140.8°, so its spring (from h4 above O4 to s = 100 mm out) stays between h4 − s = 47 mm
    # (at 90°) and 114 mm long (at 140.8°): an L_max of 130 mm holds there, whereas a full turn
    # of the rocker (the open box) would reach h4 + s = 247 mm.
    g = 9.81
    r = design(load_problem_text(_direct_fourbar("130 mm"), "fourbar_direct.toml"))
    assert r.optimal, r.message
    values = {slot.variable: v for slot, v in r.solution.values.items()}
    assert values["h2"] == pytest.approx(g * C2 / (K2 * R_CRANK), rel=1e-6)
    assert values["h4"] == pytest.approx(g * C4 / (K4 * S_ROCKER), rel=1e-6)
    assert r.verification.residual_ratio <= 1e-6
    assert r.solution.sampled_ratio <= 1e-6
