"""The model layer: typed, frozen descriptions of a balancing problem.

Nothing here solves anything. :mod:`.units` and :mod:`.expr` give quantities and
whitelisted expression trees; :mod:`.mechanism` the mechanism (coordinates, subsystems,
frames, bodies); :mod:`.elements` what a design may add; :mod:`.problem` the whole problem
(parameters, variables, scenarios, objective). Problems are made from files or code by
:mod:`counterpoise.io`.
"""

from __future__ import annotations

from .constraints import Constraint
from .elements import CounterMass, ZeroFreeLengthSpring
from .mechanism import GROUND, Body, Coordinate, Frame, Point, Rotation, Subsystem, Translation
from .problem import Gravity, Objective, Parameter, Problem, ReportQuantity, Scenario, Settings, Variable

__all__ = [
    "GROUND",
    "Body",
    "Constraint",
    "Coordinate",
    "CounterMass",
    "Frame",
    "Gravity",
    "Objective",
    "Parameter",
    "Point",
    "Problem",
    "ReportQuantity",
    "Rotation",
    "Scenario",
    "Settings",
    "Subsystem",
    "Translation",
    "Variable",
    "ZeroFreeLengthSpring",
]
