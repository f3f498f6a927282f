"""Features for spatial and multi-mode problems, on small mechanisms built in code.

The seed reproductions are in test_seed_spherical2019.py and test_seed_essomba2021.py;
here each feature of the format is checked against a result derived in its docstring.
"""

from __future__ import annotations

import pytest

from counterpoise import ProblemBuilder, design, rotate

G = 9.81


def lever_with_spring_and_counter_mass(stiffness_weight: str) -> ProblemBuilder:
    """A pendulum (m = 1 kg at r = 0.2 m) that a counter-mass M at b = 0.2 m behind the pivot
    and a spring k from f = 0.1 m above the pivot to f along the link can balance together:
    g (m r − M b) = k f² (identities I1 and I2 of docs/derivations.md).

    Objective M + w k: with w = 0 the spring does everything (M = 0, k = m g r/f² = 196.2 N/m);
    with w = 1 kg/(N/m) a spring costs 196.2 kg against M = m r/b = 1 kg, so k = 0."""
    b = ProblemBuilder("lever", direction=(0, -1, 0))
    b.parameter("m", "1 kg").parameter("r", "0.2 m").parameter("arm", "0.2 m").parameter("f", "0.1 m")
    b.subsystem("arm_sub", q=("-180 deg", "180 deg"))
    b.frame("link", rotate("z", "q"))
    b.body("tip", frame="link", mass="m", com=("r", 0, 0))
    b.variable("M", "0 kg", "10 kg").variable("k", "0 N/m", "1000 N/m")
    b.counter_mass("cm", frame="link", mass="M", position=("-arm", 0, 0))
    b.spring("s", "k", ("ground", (0, "f", 0)), ("link", ("f", 0, 0)))
    b.objective(stiffness_weight=stiffness_weight)
    return b


def test_without_stiffness_weight_the_spring_does_everything():
    result = design(lever_with_spring_and_counter_mass("0 kg/(N/m)").build())
    assert result.status.value == "optimal"
    values = {s.variable: v for s, v in result.solution.values.items()}
    assert values["M"] == pytest.approx(0.0, abs=1e-9)
    assert values["k"] == pytest.approx(1 * G * 0.2 / 0.1**2, rel=1e-6)


def test_stiffness_weight_switches_an_unneeded_spring_off():
    result = design(lever_with_spring_and_counter_mass("1 kg/(N/m)").build())
    assert result.status.value == "optimal"
    values = {s.variable: v for s, v in result.solution.values.items()}
    assert values["k"] == pytest.approx(0.0, abs=1e-9)
    assert values["M"] == pytest.approx(1.0, rel=1e-6)
    assert result.solution.objective == pytest.approx(1.0, rel=1e-6)


def test_stiffness_weight_needs_mass_per_stiffness():
    from counterpoise.errors import ProblemFileError

    with pytest.raises(ProblemFileError) as info:
        lever_with_spring_and_counter_mass("1 kg").build()
    assert info.value.key == "objective.stiffness_weight"
