"""The kinematic sketch (plots/mechanism.py) draws a closed loop assembled in every pose."""

from __future__ import annotations

import math

import numpy as np

from conftest import PROBLEMS

from counterpoise import load_problem
from counterpoise.mechanics.closure import closure, scenario_base
from counterpoise.plots.mechanism import _loop_segments, _poses


def test_every_pose_of_a_four_bar_is_assembled():
    problem = load_problem(PROBLEMS / "fourbar_springs.toml")
    main, ghosts = _poses(problem, None)
    c = closure(problem, "fourbar", scenario_base(problem, problem.scenarios[0].name))
    # the crank turns through its full circle: drawn at three quarter points, not at 0 and 360 deg twice
    assert sorted(round(math.degrees(g["theta2"])) for g in ghosts) == [90, 180, 270]
    for pose in [main, *ghosts]:
        q = np.array([[pose[name] for name in c.names]])
        assert np.abs(c.gaps(q)).max() <= 1e-9
        for _, a, _, b in _loop_segments(problem, pose, {v.name: v.initial for v in problem.variables}):
            assert np.linalg.norm(a - b) <= 1e-9  # the two half-links meet at the opened joint


def test_frames_at_a_crank_angle_solve_the_loop_and_refuse_a_dependent_coordinate():
    import pytest

    from counterpoise.cli.mechanism import AtError, parse_at

    problem = load_problem(PROBLEMS / "fourbar_counter_mass.toml")
    coordinates, variables = parse_at(problem, ["theta2=90 deg"])
    assert coordinates["theta2"] == pytest.approx(math.pi / 2)
    for _, a, _, b in _loop_segments(problem, coordinates, variables):
        assert np.linalg.norm(a - b) <= 1e-9
    with pytest.raises(AtError, match="'theta3' is a dependent coordinate of a closed loop"):
        parse_at(problem, ["theta3=10 deg"])
