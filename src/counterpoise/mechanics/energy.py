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
from typing import Any

from ..model import expr as ex
from ..model.elements import ZeroFreeLengthSpring
from ..model.mechanism import GROUND, Point, Rotation
from ..model.problem import Problem
from ..model.functions import NUMPY_FUNCTIONS, Functions
from .kinematics import _NUMBER, IDENTITY, Mat, Scalar, Vec, add, add_all, dot, mul, matmul, matvec, rotation_matrix, sub, unit_vector


#: rotation matrices remembered per transform in a shared ``rotations`` memo (the latest angles)
ROTATIONS_KEPT = 2
#: world rotations (a parent's rotation times a transform's) remembered per transform, for
#: arrays of at most PRODUCT_SIZE values (a certificate's grid, not a dense check's chunk)
PRODUCTS_KEPT = 8
PRODUCT_SIZE = 1024


class Mechanics:
    """Positions and energies of one problem for one set of values.

    ``base_parameters``: SI values of the literal parameters (a scenario's values);
    ``variables``: values of the design variables; ``coordinates``: values of the
    coordinates (arrays evaluate many configurations at once); ``gravity``: the gravity
    vector (m/s²); ``poses``: world poses already known for these values (they are not
    recomputed); ``rotations``: a memo of rotation matrices (and of their products with a parent's rotation) shared between instances. Derived parameters are evaluated here, so a study that changes a base
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
        poses: Mapping[str, tuple[Mat, Vec]] | None = None,
        rotations: dict[Any, Any] | None = None,
    ) -> None:
        self.problem = problem
        self.functions = functions
        self.gravity = list(gravity)
        env: dict[str, Scalar] = {}
        for p in problem.parameters:
            env[p.name] = base_parameters[p.name] if p.is_base else ex.evaluate(p.expr, env, functions)  # type: ignore[arg-type]  # a derived parameter has its expr
        env.update(variables)
        env.update(coordinates)
        self.env = env
        self._poses: dict[str, tuple[Mat, Vec]] = dict(poses or {})  # known poses (e.g. of frames a perturbation leaves alone)
        self._rotations = rotations  # shared by instances whose angles may be the very same arrays

    def moved(self, coordinates: Mapping[str, Scalar], poses: Mapping[str, tuple[Mat, Vec]] | None = None) -> "Mechanics":
        """The same problem, parameters, variables, gravity, functions and rotation memo at
        other values of some ``coordinates``: the very values a new instance would hold (the
        parameters are evaluated before the coordinates enter, so they are this instance's),
        without evaluating the parameters again."""
        out = Mechanics.__new__(Mechanics)
        out.problem, out.functions, out.gravity = self.problem, self.functions, self.gravity
        env = dict(self.env)
        env.update(coordinates)
        out.env = env
        out._poses = dict(poses or {})
        out._rotations = self._rotations
        return out

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
        # ancestors first, root down, so that a long chain never recurses deeply
        chain, parent = [], f.parent
        while parent is not None and parent != GROUND and parent not in self._poses:
            chain.append(parent)
            parent = self.problem.frame[parent].parent
        for name in reversed(chain):
            self.pose(name)
        rot, origin = self.pose(f.parent) if f.parent is not None else (IDENTITY, [0.0, 0.0, 0.0])
        for i, t in enumerate(f.transforms[:upto]):
            if isinstance(t, Rotation):
                rot = self._rotated(frame, i, rot, self.rotation(frame, i, t))
            else:
                step = matvec(rot, self.vector(t.vector))
                origin = [add(o, d) for o, d in zip(origin, step)]
        if upto is None:
            self._poses[frame] = (rot, origin)
        return rot, origin

    def _rotated(self, frame: str, index: int, rot: Mat, matrix: Mat) -> Mat:
        """``matmul(rot, matrix)``, remembered in the shared ``rotations`` memo for the very
        same two matrices (found by identity: a parent's kept pose and a remembered rotation,
        as when a study point changes only a length), for at most :data:`PRODUCTS_KEPT` pairs
        per transform and arrays of at most :data:`PRODUCT_SIZE` values."""
        memo = self._rotations
        if memo is None:
            return matmul(rot, matrix)
        key = ("product", frame, index)
        hits = memo.get(key)
        if hits is not None:
            for a, b, product in hits:
                if a is rot and b is matrix:
                    return product
        product = matmul(rot, matrix)
        if all(getattr(v, "size", 1) <= PRODUCT_SIZE for row in product for v in row):
            memo[key] = ((rot, matrix, product), *(hits or ())[: PRODUCTS_KEPT - 1])
        return product

    def rotation(self, frame: str, index: int, t: Rotation) -> Mat:
        """Rotation matrix of transform ``index`` of ``frame`` (remembered in ``rotations``
        for the same angle value when the axis is literal)."""
        angle = self.value(t.angle)
        if self._rotations is None or not all(isinstance(c, ex.Num) for c in t.axis):
            return rotation_matrix(self.axis(t), angle, self.functions)
        # the latest ROTATIONS_KEPT angles of this transform, found by identity (a complex
        # step alternates the real and the perturbed array of one coordinate)
        hits = self._rotations.get((frame, index))
        if hits is not None:
            for hit in hits:
                if hit[0] is angle:
                    return hit[1]
        matrix = rotation_matrix(self.axis(t), angle, self.functions)
        self._rotations[(frame, index)] = ((angle, matrix), *(hits or ())[: ROTATIONS_KEPT - 1])
        return matrix

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
        """−m g·p. The components of p along which gravity is a literal 0 are not computed:
        ``mul`` would drop them (the same value as ``dot(gravity, position(point))``)."""
        gravity = self.gravity
        rot, origin = self.pose(point.frame)
        local = self.vector(point.position)
        world = [0.0 if isinstance(g, _NUMBER) and g == 0.0 else add(o, dot(row, local)) for g, o, row in zip(gravity, origin, rot)]
        return mul(-1.0, mul(mass, dot(gravity, world)))

    def spring_energy(self, s: ZeroFreeLengthSpring, stiffness: Scalar | None = None) -> Scalar:
        """A spring's energy. ``stiffness`` replaces k.

        - behind a pulley that pulls k·d (a point pulley, or a pin of the same radius):
          ½ k |a − b|² (zero free length);
        - behind a pulley of radius r > 0 without a pin: ½ k (ℓ − ℓ*)², ℓ the cable's path
          over the pulley (:mod:`.cable`), ℓ* the spring's ``zero_length`` variable;
        - a real spring through a cable (direct mount): F0·x + ½ k x², x = |a − b| − cable − L0;
        - as built (:attr:`~counterpoise.model.elements.ZeroFreeLengthSpring.built`): F0·x + ½ k x²
          while x = path + offset > 0, else 0 (the coils close, the cable goes slack)."""
        k = self.value(s.stiffness) if stiffness is None else stiffness
        if s.built is not None:
            b = s.built
            x = add(self.spring_path(s), self.value(b.offset))
            value = add(mul(self.value(b.initial_tension), x), mul(0.5, mul(k, mul(x, x))))
            return self.functions["where_positive"](x, value)
        d = sub(self.position(s.ends[0]), self.position(s.ends[1]))
        if s.direct is None:
            p = s.pulley
            if p is None or p.exact or p.zero_length is None:
                return mul(0.5, mul(k, dot(d, d)))
            x = add(self.spring_path(s), mul(-1.0, self.env[p.zero_length]))
            return mul(0.5, mul(k, mul(x, x)))
        m = s.direct
        x = self.functions["sqrt"](dot(d, d)) - self.value(m.cable) - self.value(m.free_length)
        return add(mul(self.value(m.initial_tension), x), mul(0.5, mul(k, mul(x, x))))

    def spring_path(self, s: ZeroFreeLengthSpring) -> Scalar:
        """The length a spring's extension follows: the cable's path over its pulley (and
        pin) for a pulley of radius > 0 (:func:`.cable.cable`), else the distance |a − b|."""
        p = s.pulley
        if s.direct is None and p is not None and p.radius > 0.0:
            from .cable import cable

            return cable(self, s).path
        d = sub(self.position(s.ends[0]), self.position(s.ends[1]))
        return self.functions["sqrt"](dot(d, d))

    def energy_terms(self, subsystem: str | None = None) -> tuple[Scalar, Scalar]:
        """(energy of the given bodies, energy of the balancers) of ``subsystem`` (all if None).

        The bodies alone are the unbalanced mechanism; balancers are counter-masses and springs.
        """
        p = self.problem

        def mine(element_subsystem: str | None) -> bool:
            return subsystem is None or element_subsystem == subsystem

        bodies = add_all([self.gravity_energy(self.value(b.mass), b.com) for b in p.bodies if mine(b.subsystem)])
        balancers = [self.gravity_energy(self.value(c.mass), c.position) for c in p.counter_masses if mine(c.subsystem)]
        balancers += [self.spring_energy(s) for s in p.springs if mine(s.subsystem)]
        return bodies, add_all(balancers)

    def energy_magnitude(self, subsystem: str | None = None) -> Scalar:
        """Σ |energy| of every element of ``subsystem``: the size of the terms that cancel in
        a balanced design, hence the scale of the rounding noise its residual carries."""
        p = self.problem
        abs_ = self.functions["abs"]
        terms = [abs_(self.gravity_energy(self.value(b.mass), b.com)) for b in p.bodies if subsystem in (None, b.subsystem)]
        terms += [abs_(self.gravity_energy(self.value(c.mass), c.position)) for c in p.counter_masses if subsystem in (None, c.subsystem)]
        for s in p.springs:
            if subsystem in (None, s.subsystem):
                a, b = self.position(s.ends[0]), self.position(s.ends[1])
                # ½k(|a|² + |b|²) bounds every term of ½k|a − b|²
                terms.append(abs_(mul(0.5, mul(self.value(s.stiffness), add(dot(a, a), dot(b, b))))))
        return add_all(terms)

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
        axis = matvec(rot, self.axis(t))  # type: ignore[arg-type]  # a counter-mass joint is a rotation
        rel = sub(self.position(cm.position), origin)
        along = dot(axis, rel)
        return add(dot(rel, rel), mul(-1.0, mul(along, along)))

    def added_mass(self) -> Scalar:
        return add_all([self.value(c.mass) for c in self.problem.counter_masses])

    def added_stiffness(self) -> Scalar:
        """Σ k_s over springs (a spring shared by several attachments counts each time)."""
        return add_all([self.value(s.stiffness) for s in self.problem.springs])

    def added_inertia(self) -> Scalar:
        """Σ M_j d_j² (with d_j² rather than d_j, smooth where d_j = 0)."""
        return add_all([mul(self.value(c.mass), self.arm_squared(j)) for j, c in enumerate(self.problem.counter_masses)])
