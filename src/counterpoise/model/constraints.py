"""Design constraints: ``lower ≤ expression ≤ upper`` on quantities of the design.

A :class:`Constraint` is an expression tree (whitelisted, :mod:`.expr`) over design
variables, parameters, report quantities and the *named quantities* of the mechanism
(:data:`CONSTRAINT_FUNCTIONS`), with SI bounds. The file's ``[constraints.<name>]`` and the
force limit of every spring that has one (``springs.<name>.max_force``, see
:func:`force_limit`) are both constraints: one machinery carries them into every designer
(:mod:`counterpoise.formulation.constraints`).

Named quantities (their arguments are names, not values):

- ``force_home(s)``, ``length_home(s)``: spring ``s``'s pull and the distance between its
  ends (``from`` to ``to``) at the home configuration; exact.
- ``force_max(s)``, ``force_min(s)``, ``length_max(s)``, ``length_min(s)``: their extremes
  over the workspace (every configuration of the spring's subsystem); ``wrap_max(s)``,
  ``wrap_min(s)``: those of the arc its cable wraps on a pulley of radius > 0 (rad). They
  enter on sampled configurations and at the extremes the verification finds (see
  docs/constraints.md).
- ``x_home(c)``, ``y_home(c)``, ``z_home(c)``: a counter-mass's world position at home.
- ``added_mass()``, ``added_inertia()``: the objective's Σ M_j and Σ M_j d_j².
- ``total_mass(subsystem)``, ``com_distance(subsystem[, frame])``: as in report quantities.
"""

from __future__ import annotations

from dataclasses import dataclass

from .expr import Call, Expr, Name
from .units import DisplayUnit

#: named quantities of a spring at home (exact)
SPRING_HOME = frozenset({"force_home", "length_home"})
#: extremes of a spring's quantities over the workspace: name -> (quantity, side)
SPRING_EXTREMES = {
    "force_max": ("force", "max"),
    "force_min": ("force", "min"),
    "length_max": ("length", "max"),
    "length_min": ("length", "min"),
    "wrap_max": ("wrap", "max"),
    "wrap_min": ("wrap", "min"),
}
#: a counter-mass's world coordinates at home: name -> axis index
COUNTER_MASS_HOME = {"x_home": 0, "y_home": 1, "z_home": 2}
#: totals of the design, called without arguments
TOTALS = frozenset({"added_mass", "added_inertia"})
#: every function a constraint expression may call besides the math and report functions
CONSTRAINT_FUNCTIONS = frozenset(SPRING_HOME | set(SPRING_EXTREMES) | set(COUNTER_MASS_HOME) | TOTALS)

#: kinds of constraints
FILE = "constraint"  # [constraints.<name>]
FORCE_LIMIT = "force_limit"  # a spring's largest force
REALISATION = "realisation"  # a limit of the spring as built (docs/build.md#realisation-limits)


@dataclass(frozen=True)
class Constraint:
    """``lower ≤ expr ≤ upper`` (SI; None: no such side) in every scenario."""

    name: str
    expr: Expr
    lower: float | None
    upper: float | None
    unit: DisplayUnit
    description: str = ""
    kind: str = FILE
    #: force limits: the spring (and where the limit comes from)
    spring: str | None = None

    def extreme(self) -> Call | None:
        """The one workspace-extreme call in the expression, if any (the resolver allows one)."""
        found = extreme_calls(self.expr)
        return found[0] if found else None


def extreme_calls(tree: Expr) -> list[Call]:
    from .expr import calls

    return [c for c in calls(tree) if c.func in SPRING_EXTREMES]


def force_limit(spring: str, limit: float, unit: DisplayUnit, source: str) -> Constraint:
    """The constraint ``force_max(spring) ≤ limit`` (named ``<spring>.max_force``)."""
    return Constraint(
        f"{spring}.max_force",
        Call("force_max", (Name(spring),)),
        None,
        limit,
        unit,
        f"largest force of spring {spring} ({source})",
        FORCE_LIMIT,
        spring,
    )
