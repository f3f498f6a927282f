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
    return b.settings(ideal_springs=True)  # the textbook spring (its ends meet upright): ideal


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


# --------------------------------------------------------------------------------------
# Denavit-Hartenberg rows
# --------------------------------------------------------------------------------------


def test_dh_row_is_rot_x_trans_x_rot_z_trans_z():
    """A DH row places a frame exactly as its four elementary transforms written out."""
    import numpy as np

    from counterpoise import dh, translate
    from counterpoise.mechanics import Mechanics
    from counterpoise.model.mechanism import Point

    def frame_of(*transforms):
        b = ProblemBuilder("dh")
        b.parameter("L", "0.3 m").subsystem("s", q=("-180 deg", "180 deg"))
        b.frame("link", *transforms)
        b.body("tip", frame="link", mass="1 kg", com=("0.1 m", "0.2 m", "0.05 m"))
        problem = b.build()
        mech = Mechanics(problem, {"L": 0.3}, {}, {"q": 0.7}, (0.0, -9.81, 0.0))
        return np.array(mech.position(Point("link", problem.bodies[0].com.position)), dtype=float)

    row = frame_of(dh(a="L", alpha="30 deg", d="0.05 m", theta="q"))
    written = frame_of(rotate("x", "30 deg"), translate("L"), rotate("z", "q"), translate(0, 0, "0.05 m"))
    assert row == pytest.approx(written, abs=1e-15)


def test_dh_row_in_a_seed_file_gives_the_same_design():
    """spherical_chain_3r.toml writes links 2 and 3 as DH rows: h_i = m_i g/k_i still."""
    from conftest import solved, value

    result = solved("spherical_chain_3r", (("settings.ideal_springs", "true"),))  # the paper's springs
    assert value(result, "h_2", "mm") == pytest.approx(7.848, rel=1e-6)


# --------------------------------------------------------------------------------------
# Coupled coordinates: closed chains as expressions of the independent coordinates
# --------------------------------------------------------------------------------------


def parallelogram(coupled: bool) -> ProblemBuilder:
    """A crank (m1 = 0.5 kg at r = 0.1 m, length L = 0.3 m) carries a coupler (m2 = 0.8 kg)
    whose centre of mass sits c = 0.12 m along it. In a parallelogram the coupler keeps its
    orientation: its frame turns by psi = −theta relative to the crank (a coupled
    coordinate). Gravity then sees m1 r + m2 L on the crank, not c, and a counter-mass at
    b = 0.2 m behind the pivot needs M = (m1 r + m2 L)/b = 1.45 kg. If the coupler turned with
    the crank instead, its c would add to the lever: M = (m1 r + m2 (L + c))/b = 1.93 kg."""
    b = ProblemBuilder("parallelogram", direction=(0, -1, 0))
    b.parameter("L", "0.3 m").parameter("c", "0.12 m")
    b.subsystem("crank_sub", q=("-180 deg", "180 deg"), coupled={"psi": "-q"} if coupled else None)
    b.frame("crank", rotate("z", "q"))
    b.frame("coupler", {"translate": ["L", 0, 0]}, rotate("z", "psi" if coupled else "0 deg"), parent="crank")
    b.body("crank", frame="crank", mass="0.5 kg", com=("0.1 m", 0, 0))
    b.body("coupler", frame="coupler", mass="0.8 kg", com=("c", 0, 0))
    b.variable("M", "0 kg", "10 kg")
    b.counter_mass("cm", frame="crank", mass="M", position=("-0.2 m", 0, 0))
    return b


@pytest.mark.parametrize(("coupled", "expected"), [(True, 1.45), (False, 1.93)])
def test_coupled_coordinate_keeps_the_coupler_level(coupled, expected):
    result = design(parallelogram(coupled).build())
    assert result.status.value == "optimal"
    assert result.verification.residual_ratio <= 1e-9
    (m,) = result.solution.values.values()
    assert m == pytest.approx(expected, rel=1e-6)


def test_coupled_coordinate_must_use_its_subsystems_coordinates():
    from counterpoise.errors import ProblemFileError

    with pytest.raises(ProblemFileError) as info:
        parallelogram(True).build(overrides={"subsystems.crank_sub.coupled.psi": "-q_other"})
    assert info.value.key == "subsystems.crank_sub.coupled.psi"
    assert "unknown name 'q_other'" in info.value.message


# --------------------------------------------------------------------------------------
# Repeated structure: [repeat.<name>]
# --------------------------------------------------------------------------------------

MASSES = [0.30, 0.25, 0.2, 0.18, 0.15, 0.12, 0.1, 0.09, 0.08, 0.06, 0.05, 0.04]  # kg
STIFFNESSES = [400, 300, 250, 200, 180, 150, 120, 100, 90, 80, 60, 50]  # N/m
TWISTS = [90, 40, 65, 75, 30, 55, 80, 45, 60, 35, 70, 50]  # deg; the first turns axis 1 horizontal


def chain_text(n: int) -> str:
    values = {
        "i": list(range(1, n + 1)),
        "parent": ["ground"] + [f"link{i}" for i in range(1, n)],
        "alpha": [f"{a} deg" for a in TWISTS[:n]],
        "m": [f"{m} kg" for m in MASSES[:n]],
        "k": [f"{k} N/m" for k in STIFFNESSES[:n]],
    }
    inline = ", ".join(f"{key} = {list_toml(v)}" for key, v in values.items())
    return f"""
[problem]
name = "spherical_chain_{n}"
[gravity]
acceleration = "9.81 m/s^2"
direction = [0, 0, -1]
[subsystems.chain]
description = "coordinates come from the repeat"
[settings]
ideal_springs = true
verify_samples = 2000
verify_tolerance = 1e-9
[repeat.links]
values = {{ {inline} }}
[repeat.links.parameters]
"m{{i}}" = "{{m}}"
"k{{i}}" = "{{k}}"
[repeat.links.subsystems.chain.coordinates."q{{i}}"]
range = ["-180 deg", "180 deg"]
[repeat.links.frames."link{{i}}"]
parent = "{{parent}}"
transforms = [{{ dh = {{ a = 0, alpha = "{{alpha}}", d = 0, theta = "q{{i}}" }} }}]
[repeat.links.bodies."link{{i}}"]
frame = "link{{i}}"
mass = "m{{i}}"
com = ["20 mm", "-15 mm", "60 mm"]
[repeat.links.variables."h{{i}}"]
lower = "0 mm"
upper = "100 mm"
[repeat.links.springs."s{{i}}"]
stiffness = "k{{i}}"
from = {{ frame = "ground", point = [0, 0, "h{{i}}"] }}
to = {{ frame = "link{{i}}", point = ["20 mm", "-15 mm", "60 mm"] }}
"""


def list_toml(items: list) -> str:
    return "[" + ", ".join(str(v) if isinstance(v, int) else f'"{v}"' for v in items) + "]"


def test_repeat_writes_a_twelve_link_spherical_chain():
    """Twelve links from one template; each needs h_i = m_i g / k_i (seed 002, eqs. 11-18)."""
    from counterpoise.io.loader import load_problem_text

    problem = load_problem_text(chain_text(12), "chain12")
    assert [c.name for c in problem.coordinates] == [f"q{i}" for i in range(1, 13)]
    assert problem.frame["link7"].parent == "link6"
    result = design(problem)
    assert result.status.value == "optimal"
    assert result.verification.residual_ratio <= 1e-9
    values = {s.variable: v for s, v in result.solution.values.items()}
    for i, (m, k) in enumerate(zip(MASSES, STIFFNESSES), start=1):
        assert values[f"h{i}"] == pytest.approx(m * G / k, rel=1e-6)


@pytest.mark.parametrize(
    ("edit", "key", "fragment"),
    [
        (lambda t: t.replace("i = [1, 2, 3]", "i = [1, 2]"), "repeat.links.values", "different lengths"),
        (lambda t: t.replace('frame = "link{i}"\nmass', 'frame = "link{j}"\nmass'), "repeat.links.bodies.link{i}.frame", "unknown placeholder '{j}'"),
        (lambda t: t + '[bodies.link2]\nframe = "link2"\nmass = "1 kg"\ncom = [0, 0, 0]\n', "bodies.link2", "defined twice"),
    ],
    ids=["unequal_lists", "unknown_placeholder", "defined_twice"],
)
def test_repeat_errors_name_the_key(edit, key, fragment):
    from counterpoise.errors import ProblemFileError
    from counterpoise.io.loader import load_problem_text

    with pytest.raises(ProblemFileError) as info:
        load_problem_text(edit(chain_text(3)), "chain3")
    assert info.value.key == key
    assert fragment in info.value.message
