"""Kinematics and potential energy, written once for every numeric backend.

:class:`Mechanics` evaluates frame poses, positions, masses and the potential energy

    V(q) = Σ_bodies −m g·p  +  Σ_counter-masses −M g·p  +  Σ_springs ½ k |a − b|²

from the problem's expression trees. The values it is given decide the backend: floats,
numpy arrays (real, or complex for complex-step derivatives in :mod:`counterpoise.verify`)
or CasADi SX symbols (to build the NLP in :mod:`counterpoise.formulation`). The physics therefore
exists in one place, and the verification exercises the very code the optimiser used.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from ..model import expr as ex
from ..model.mechanism import GROUND, Point, Rotation
from ..model.problem import Problem
from ..model.functions import NUMPY_FUNCTIONS, Functions
from .kinematics import IDENTITY, Mat, Scalar, Vec, add, add_all, dot, mul, matmul, matvec, rotation_matrix, sub, unit_vector


class Mechanics:
    """Positions and energies of one problem for one set of values.

    ``base_parameters``: SI values of the literal parameters (a scenario's values);
    ``variables``: values of the design variables; ``coordinates``: values of the
    coordinates (arrays evaluate many configurations at once); ``gravity``: the gravity
    vector (m/s²). Derived parameters are evaluated here, so a study that changes a base
    parameter sees every parameter built on it change too.
    """

    def __init__(
        self,
        problem: Problem,
        base_parameters: Mapping[str, Scalar],
        variables: Mapping[str, Scalar],
        coordinates: Mapping[str, Scalar],
        gravity: Sequence[Scalar],
        functions: Functions = NUMPY_FUNCTIONS,
    ) -> None:
        self.problem = problem
        self.functions = functions
        self.gravity = list(gravity)
        env: dict[str, Scalar] = {}
        for p in problem.parameters:
            env[p.name] = base_parameters[p.name] if p.is_base else ex.evaluate(p.expr, env, functions)  # type: ignore[arg-type]
        env.update(variables)
        env.update(coordinates)
        self.env = env
        self._poses: dict[str, tuple[Mat, Vec]] = {}

    def value(self, tree: ex.Expr) -> Scalar:
        return ex.evaluate(tree, self.env, self.functions)

    def vector(self, trees: Sequence[ex.Expr]) -> Vec:
        return [self.value(t) for t in trees]

    # -- kinematics ----------------------------------------------------------------
    def pose(self, frame: str, upto: int | None = None) -> tuple[Mat, Vec]:
        """World rotation and origin of ``frame`` (after its first ``upto`` transforms)."""
        if frame == GROUND:
            return IDENTITY, [0.0, 0.0, 0.0]
        if upto is None and frame in self._poses:
            return self._poses[frame]
        f = self.problem.frame[frame]
        rot, origin = self.pose(f.parent) if f.parent is not None else (IDENTITY, [0.0, 0.0, 0.0])
        for t in f.transforms[:upto]:
            if isinstance(t, Rotation):
                rot = matmul(rot, rotation_matrix(self.axis(t), self.value(t.angle), self.functions))
            else:
                step = matvec(rot, self.vector(t.vector))
                origin = [add(o, d) for o, d in zip(origin, step)]
        if upto is None:
            self._poses[frame] = (rot, origin)
        return rot, origin

    def axis(self, rotation: Rotation) -> Vec:
        """Unit axis of a rotation (literal axes arrive normalised from the loader)."""
        if all(isinstance(c, ex.Num) for c in rotation.axis):
            return self.vector(rotation.axis)
        return unit_vector(self.vector(rotation.axis), self.functions)

    def position(self, point: Point) -> Vec:
        rot, origin = self.pose(point.frame)
        return [add(o, d) for o, d in zip(origin, matvec(rot, self.vector(point.position)))]

    # -- energy --------------------------------------------------------------------
    def gravity_energy(self, mass: Scalar, point: Point) -> Scalar:
        return mul(-1.0, mul(mass, dot(self.gravity, self.position(point))))

    def energy_terms(self, subsystem: str | None = None) -> tuple[Scalar, Scalar]:
        """(energy of the given bodies, energy of the balancers) of ``subsystem`` (all if None).

        The bodies alone are the unbalanced mechanism; balancers are counter-masses and springs.
        """
        p = self.problem

        def mine(element_subsystem: str | None) -> bool:
            return subsystem is None or element_subsystem == subsystem

        bodies = add_all([self.gravity_energy(self.value(b.mass), b.com) for b in p.bodies if mine(b.subsystem)])
        balancers = [self.gravity_energy(self.value(c.mass), c.position) for c in p.counter_masses if mine(c.subsystem)]
        for s in p.springs:
            if mine(s.subsystem):
                d = sub(self.position(s.ends[0]), self.position(s.ends[1]))
                if s.direct is None:
                    balancers.append(mul(0.5, mul(self.value(s.stiffness), dot(d, d))))
                else:  # a real spring through a cable: F0·x + ½ k x², x = |d| − cable − L0
                    m = s.direct
                    x = self.functions["sqrt"](dot(d, d)) - self.value(m.cable) - self.value(m.free_length)
                    balancers.append(add(mul(self.value(m.initial_tension), x), mul(0.5, mul(self.value(s.stiffness), mul(x, x)))))
        return bodies, add_all(balancers)

    def energy(self, subsystem: str | None = None) -> Scalar:
        """Potential energy of ``subsystem`` (all elements if None)."""
        return add(*self.energy_terms(subsystem))

    # -- mass properties -----------------------------------------------------------
    def masses(self, subsystem: str) -> list[tuple[Scalar, Point]]:
        p = self.problem
        out = [(self.value(b.mass), b.com) for b in p.bodies if b.subsystem == subsystem]
        out += [(self.value(c.mass), c.position) for c in p.counter_masses if c.subsystem == subsystem]
        return out

    def total_mass(self, subsystem: str) -> Scalar:
        return add_all([m for m, _ in self.masses(subsystem)])

    def com_distance(self, subsystem: str, frame: str = GROUND) -> Scalar:
        """Distance from ``frame``'s origin to the subsystem's centre of mass."""
        items = self.masses(subsystem)
        total = add_all([m for m, _ in items])
        moment = [0.0, 0.0, 0.0]
        for m, point in items:
            moment = [add(a, mul(m, b)) for a, b in zip(moment, self.position(point))]
        com = [c / total for c in moment]
        d = sub(com, self.pose(frame)[1])
        return self.functions["sqrt"](dot(d, d))

    def arm_squared(self, index: int) -> Scalar:
        """d_j² of counter-mass ``index``: squared distance from its joint's axis."""
        cm = self.problem.counter_masses[index]
        if cm.joint is None:
            return 0.0
        frame, i = cm.joint
        rot, origin = self.pose(frame, upto=i)
        t = self.problem.frame[frame].transforms[i]
        axis = matvec(rot, self.axis(t))  # type: ignore[arg-type]
        rel = sub(self.position(cm.position), origin)
        along = dot(axis, rel)
        return add(dot(rel, rel), mul(-1.0, mul(along, along)))

    def added_mass(self) -> Scalar:
        return add_all([self.value(c.mass) for c in self.problem.counter_masses])

    def added_inertia(self) -> Scalar:
        """Σ M_j d_j² (with d_j² rather than d_j, smooth where d_j = 0)."""
        return add_all([mul(self.value(c.mass), self.arm_squared(j)) for j, c in enumerate(self.problem.counter_masses)])
