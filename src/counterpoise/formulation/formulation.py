"""The design problem as CasADi symbols, independent of sampling and of the solver.

:class:`Formulation` turns a :class:`Problem` into the design vector z (scaled), the
parameter vector p, the objective, the sign constraints on masses and stiffnesses, and one
residual function r(q, z, p) = ∂V/∂q per (subsystem, scenario) block. Which exact
equalities stand for "r = 0 for every q" is the job of :mod:`.conditions`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..mechanics import Mechanics, casadi_functions
from ..model import expr as ex
from ..model.problem import Problem
from ..numeric import NumericFunction
from .layout import DesignLayout, ParameterLayout


@dataclass(frozen=True)
class Block:
    """Residual ∂V/∂q of one subsystem in one scenario, as CasADi functions of (q, z, p)."""

    subsystem: str
    scenario: str
    coordinates: tuple[str, ...]
    residual: Any  # casadi.Function (q, z, p) -> ∂V/∂q
    gravity_torque: Any  # casadi.Function (q, z, p) -> ∂V/∂q of the given bodies alone
    magnitude: Any  # casadi.Function (q, z, p) -> Σ |energy of each element| (scale of rounding noise)


class Formulation:
    """Symbols of the design problem: z, p, objective, sign constraints, residual blocks."""

    def __init__(self, problem: Problem) -> None:
        import casadi as ca

        self.problem = problem
        self.design = DesignLayout(problem)
        self.parameters = ParameterLayout(problem)
        self.z = ca.SX.sym("z", len(self.design))
        self.x = self.z * ca.DM(self.design.scale) if len(self.design) else self.z
        self.p = ca.SX.sym("p", self.parameters.size)
        functions = casadi_functions()

        self.blocks: list[Block] = []
        added_mass, added_inertia, added_stiffness = [], [], []
        nonnegative: dict[str, Any] = {}  # keyed by the expression's text: one row per distinct constraint
        home = {k.name: k.home for k in problem.coordinates}
        for c, scenario in enumerate(problem.scenarios):
            gravity, base = self.parameters.split(self.p, c)
            variables = self.design.symbols(self.x, scenario.name)
            mech = Mechanics(problem, base, variables, home, gravity, functions)
            added_mass.append(mech.added_mass())
            added_inertia.append(mech.added_inertia())
            added_stiffness.append(mech.added_stiffness())
            for expression in self._sign_constraints(mech):
                nonnegative.setdefault(str(expression), expression)
            for sub in problem.subsystems:
                q = ca.SX.sym("q", len(sub.coordinates))
                coords = {name: q[i] for i, name in enumerate(sub.coordinates)}
                block_mech = Mechanics(problem, base, variables, coords, gravity, functions)
                bodies, balancers = block_mech.energy_terms(sub.name)
                self.blocks.append(
                    Block(
                        sub.name,
                        scenario.name,
                        sub.coordinates,
                        ca.Function(f"r_{sub.name}_{scenario.name}", [q, self.z, self.p], [ca.gradient(bodies + balancers, q)]),
                        ca.Function(f"t_{sub.name}_{scenario.name}", [q, self.z, self.p], [ca.gradient(bodies, q)]),
                        ca.Function(f"e_{sub.name}_{scenario.name}", [q, self.z, self.p], [block_mech.energy_magnitude(sub.name)]),
                    )
                )
        n = len(problem.scenarios)
        self.added_mass = sum(added_mass) / n
        self.added_inertia = sum(added_inertia) / n
        w = problem.objective
        self.added_stiffness = sum(added_stiffness) / n
        self.objective = w.mass_weight * self.added_mass + w.inertia_weight * self.added_inertia
        if w.stiffness_weight:
            self.objective = self.objective + w.stiffness_weight * self.added_stiffness
        self.nonnegative = ca.vertcat(*nonnegative.values()) if nonnegative else ca.SX(0, 1)
        self.report_function = ca.Function("mass_report", [self.z, self.p], [self.objective, self.added_mass, self.added_inertia])
        #: the same evaluated on arrays (z, p) -> ((1, 1) objective, mass, inertia), fast (:mod:`counterpoise.numeric`)
        self.report_values = NumericFunction(self.report_function)

    def _sign_constraints(self, mech: Mechanics) -> list[Any]:
        """Masses and stiffnesses that depend on variables must stay ≥ 0 (≥ 0 rows of g)."""
        p = self.problem
        # substituted point masses may be negative (a least-norm split): only gravity's moments count
        substituted = {m.name for sub in p.substitutions for m in sub.masses}
        trees = [b.mass for b in p.bodies if b.name not in substituted]
        trees += [c.mass for c in p.counter_masses] + [s.stiffness for s in p.springs]
        out = []
        for tree in trees:
            if not ex.names(tree) & set(p.variable):
                continue  # fixed: checked by the loader
            if isinstance(tree, ex.Name) and p.variable[tree.id].lower >= 0:
                continue  # a bare variable with a non-negative lower bound
            out.append(mech.value(tree))
        return out
