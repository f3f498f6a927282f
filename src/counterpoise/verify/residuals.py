"""Generalized balance residuals ∂V/∂q by complex step, on the numpy backend.

The derivative is taken by complex step on :class:`counterpoise.mechanics.Mechanics` — the
same energy code the NLP was built from, but neither CasADi's derivatives nor the sampled
configurations of the compression — so it is exact to rounding and catches a compression
that sampled too little.

**Built once, evaluated per design.** The energy is a sum of element terms (a body or a
counter-mass: −m g·p; a spring: ½ k |a − b|²). When an element's geometry (its frames and
points) does not depend on the design, and its mass or stiffness does not depend on the
coordinates, its residual is ``factor(design) × B(q)``: :class:`SubsystemResiduals`
computes B by complex step once for the fixed configurations and then evaluates any design
as a weighted sum of these arrays. Other elements (a counter-mass at a variable distance,
a frame moved by a variable) are evaluated per design, by complex step on the whole
element energy. Either way the configurations are processed in chunks of
:data:`CHUNK_CONFIGURATIONS` configurations, so memory stays bounded for long chains; the arrays
B are kept only while they fit in :data:`CACHE_BYTES`.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..mechanics import NUMPY_FUNCTIONS, Mechanics
from ..mechanics.sampling import MAX_CORNERS, STEP, configurations  # noqa: F401 - re-exported
from ..model import expr as ex
from ..model.elements import CounterMass, ZeroFreeLengthSpring
from ..model.mechanism import GROUND, Body, Point
from ..model.problem import Problem

#: configurations evaluated at once (one coordinate perturbed at a time)
CHUNK_CONFIGURATIONS = 4096
#: the per-element arrays of one subsystem are kept between designs up to this size
CACHE_BYTES = 96 * 2**20


def _small_imaginary(z: Any) -> bool:
    return np.iscomplexobj(z) and bool(np.all(np.abs(np.imag(z)) <= 1e-100))


class _Functions(dict[str, Any]):
    """numpy functions, with sin and cos specialised for complex-step arguments and
    remembered per argument array (a joint angle is the same array in every perturbation
    that leaves it alone)."""

    def __init__(self) -> None:
        super().__init__(NUMPY_FUNCTIONS)
        self._memo: dict[tuple[str, int], tuple[Any, Any]] = {}
        self["sin"] = lambda z: self._remember("sin", z)
        self["cos"] = lambda z: self._remember("cos", z)

    def forget_except(self, kept: set[int]) -> None:
        """Drop the remembered values of every argument but those whose id is in ``kept``."""
        self._memo = {key: hit for key, hit in self._memo.items() if key[1] in kept}

    def _remember(self, name: str, z: Any) -> Any:
        if not isinstance(z, np.ndarray):
            return np.sin(z) if name == "sin" else np.cos(z)
        key = (name, id(z))
        hit = self._memo.get(key)
        if hit is not None and hit[0] is z:
            return hit[1]
        value = _complex_step(name, z)
        self._memo[key] = (z, value)  # keeps z alive, so its id is not reused
        return value


#: numpy functions remembering sin and cos per argument array, for any evaluation that
#: reuses its coordinate arrays (the realisation limits' scenarios)
RememberingFunctions = _Functions


def _complex_step(name: str, z: np.ndarray) -> np.ndarray:
    """sin(a + ib) = sin a cosh b + i cos a sinh b, and for a complex step b (|b| ≤ 1e-100)
    cosh b = 1 and sinh b = b exactly in floating point: two real functions instead of four."""
    if not _small_imaginary(z):
        return np.sin(z) if name == "sin" else np.cos(z)
    a, b = np.real(z), np.imag(z)
    if name == "sin":
        return np.sin(a) + 1j * (b * np.cos(a))
    return np.cos(a) - 1j * (b * np.sin(a))


#: the poses kept per chunk of configurations: at most this many, the least recently used
#: dropped first (a study of a length adds new poses at every point), and at most this
#: many bytes of their arrays (a long chain's poses at thousands of configurations)
POSE_ENTRIES = 64
POSE_BYTES = 16 * 2**20


class _ChunkInputs:
    """What the designs evaluated on one chunk of configurations share: the coordinate arrays
    (``real``, and each with its complex step in ``perturbed``), the functions remembering
    sin and cos of them, the rotation matrices of their angles and the frames' poses.

    A pose is kept under what it is computed from (:meth:`SubsystemResiduals._pose_key`:
    the frame, which coordinate carries the step, the values of the parameters and
    variables): a pose found here is the very array the same arithmetic would give again,
    so a design whose parameters leave a frame alone (a study of the last link's length, a
    counter-mass) reuses it. At most :data:`POSE_ENTRIES` poses and :data:`POSE_BYTES`
    bytes are kept, the least recently used dropped first."""

    def __init__(self, q: np.ndarray, real: dict[str, np.ndarray], perturbed: dict[str, np.ndarray]) -> None:
        self.q, self.real, self.perturbed = q, real, perturbed
        self.functions = _Functions()
        self.rotations: dict[Any, Any] = {}
        self.kept = {id(a) for a in (*real.values(), *perturbed.values())}
        self._poses: OrderedDict[tuple[Any, ...], tuple[tuple[Any, Any], int]] = OrderedDict()
        self._bytes = 0

    def pose(self, key: tuple[Any, ...] | None) -> tuple[Any, Any] | None:
        found = None if key is None else self._poses.get(key)
        if found is None:
            return None
        self._poses.move_to_end(key)  # type: ignore[arg-type]  # found: not None
        return found[0]

    def keep_pose(self, key: tuple[Any, ...] | None, pose: tuple[Any, Any]) -> None:
        if key is None:
            return
        size = sum(getattr(v, "nbytes", 8) for row in pose[0] for v in row) + sum(getattr(v, "nbytes", 8) for v in pose[1])
        if size > POSE_BYTES:
            return
        old = self._poses.pop(key, None)
        if old is not None:
            self._bytes -= old[1]
        self._poses[key] = (pose, size)
        self._bytes += size
        while len(self._poses) > POSE_ENTRIES or self._bytes > POSE_BYTES:
            _, (_, dropped) = self._poses.popitem(last=False)
            self._bytes -= dropped


class _Element:
    """One energy term: a body, a counter-mass or a spring, and how its residual is evaluated."""

    def __init__(self, problem: Problem, element: Any, is_body: bool, frames: Mapping[str, frozenset[str]]) -> None:
        self.element = element
        self.is_body = is_body
        self.spring = hasattr(element, "ends")
        self.points: tuple[Point, ...] = element.ends if self.spring else ((element.com if is_body else element.position),)
        self.factor: ex.Expr = element.stiffness if self.spring else element.mass
        coordinates = {c.name for c in problem.coordinates}
        variables = set(problem.variable)
        #: every name its frames and points depend on
        self.geometry: set[str] = set().union(*(ex.names(t) for p in self.points for t in p.position), *(frames[p.frame] for p in self.points))
        factor = ex.names(self.factor)
        #: the frames its points are in, and their ancestors
        self.chain: frozenset[str] = frozenset().union(*(_chain(problem, p.frame) for p in self.points))
        #: the coordinates its energy depends on (its residual is 0 for the others)
        self.moves_with = (self.geometry | factor) & coordinates
        #: residual = factor(design, parameters) × an array fixed by the configurations and the geometry
        #: (a real spring through a cable is not: its energy is not k × a function of the geometry)
        self.separable = not factor & coordinates and not self.geometry & variables and getattr(element, "direct", None) is None
        #: ... with a literal factor: such arrays are summed into one
        self.constant = self.separable and not factor

    def energy(self, mech: Mechanics, unit_factor: bool) -> Any:
        """The element's energy (per unit factor if ``unit_factor``)."""
        factor = 1.0 if unit_factor else mech.value(self.factor)
        if self.spring:
            return mech.spring_energy(self.element, factor)
        return mech.gravity_energy(factor, self.points[0])


def _chain(problem: Problem, frame: str | None) -> frozenset[str]:
    """``frame`` and its ancestors (not the ground)."""
    out: set[str] = set()
    while frame is not None and frame != GROUND and frame not in out:
        out.add(frame)
        frame = problem.frame[frame].parent
    return frozenset(out)


def frame_names(problem: Problem) -> dict[str, frozenset[str]]:
    """Every name (coordinate, variable, parameter) the pose of each frame depends on."""
    out: dict[str, frozenset[str]] = {GROUND: frozenset()}

    def names(name: str) -> frozenset[str]:
        if name not in out:
            frame = problem.frame[name]
            out[name] = frame.names() | (names(frame.parent) if frame.parent is not None else frozenset())
        return out[name]

    for name in problem.frame:
        names(name)
    return out


class SubsystemResiduals:
    """∂V/∂q of one subsystem in one scenario at fixed configurations ``q``, for any design.

    ``evaluate(variables)`` returns (residual, unbalanced gravity torque), each (N, n_q):
    the design's ∂V/∂q, and that of the given bodies alone. Coordinate j is perturbed on
    its own: frames that do not move with it keep their real poses, computed once, and
    elements that do not move with it contribute 0 to column j.
    """

    def __init__(
        self,
        problem: Problem,
        subsystem: str,
        q: np.ndarray,
        cache: bool = True,
    ) -> None:
        self.problem = problem
        self.subsystem = subsystem
        self.q = q
        self.names = [c.name for c in problem.subsystem_coordinates(subsystem)]
        self.frames = frame_names(problem)
        mine: list[tuple[Body | CounterMass | ZeroFreeLengthSpring, bool]] = [(b, True) for b in problem.bodies if b.subsystem == subsystem]
        mine += [(c, False) for c in problem.counter_masses if c.subsystem == subsystem]
        mine += [(s, False) for s in problem.springs if s.subsystem == subsystem]
        self.elements = [_Element(problem, e, is_body, self.frames) for e, is_body in mine]
        self.used_frames: list[str] = []  # the elements' frames and their ancestors, parents first
        for e in self.elements:
            for point in e.points:
                chain: list[str] = []
                frame: str | None = point.frame
                while frame is not None and frame != GROUND and frame not in self.used_frames and frame not in chain:
                    chain.append(frame)
                    frame = problem.frame[frame].parent
                self.used_frames.extend(reversed(chain))
        #: base parameters the arrays depend on (through the geometry): the arrays are rebuilt when they change
        self.geometry_parameters = _base_parameters(problem, set().union(*(e.geometry for e in self.elements if e.separable)))
        self.constant = [e for e in self.elements if e.constant]
        separable = [e for e in self.elements if e.separable and not e.constant]
        self.separable = [e for e in separable if e.is_body] + [e for e in separable if not e.is_body]  # bodies first
        self.separable_bodies = sum(e.is_body for e in separable)
        self.per_design = [e for e in self.elements if not e.separable]
        n, n_q = q.shape
        self.chunks = [slice(i, min(i + CHUNK_CONFIGURATIONS, n)) for i in range(0, n, CHUNK_CONFIGURATIONS)] if n_q else []
        size = (len(self.constant) + 2 * len(self.separable) + 2) * n * n_q * 8  # per element, and composed
        self._arrays: list[tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None
        self._element_parameters: list[tuple[str, ...]] | None = None
        self._element_arrays: list[Any] = []
        self.cache = cache and size <= CACHE_BYTES
        self._chunk_inputs: dict[tuple[int, int], _ChunkInputs] = {}
        coordinates = {c.name for c in problem.coordinates}
        #: the parameters and variables each frame's pose depends on (:meth:`_pose_key`)
        self._pose_names = {f: tuple(sorted(self.frames[f] - coordinates)) for f in self.used_frames}
        self._plans: dict[tuple[_Element, ...], list[tuple[int, str, list[tuple[int, _Element]], list[str]]]] = {}  # :meth:`_plan`
        #: the reference's box maxima on these configurations, kept by the dense check
        #: (:func:`counterpoise.verify.check._box_loads`) for as long as this evaluator lives
        self.box_state: dict[str, Any] = {}

    # -- complex step --------------------------------------------------------------
    def _inputs(self, rows: slice) -> _ChunkInputs:
        """The coordinate arrays of the configurations ``rows`` (real, and each with its complex
        step), the functions remembering sin and cos of them and the poses and rotations
        computed from them (:class:`_ChunkInputs`): the same objects for every design, so a
        design whose geometry changed (a study of a length) reuses the sines and cosines of
        the joint angles and the poses of the frames the change leaves alone. Other
        remembered values (of this design's own arrays) are dropped, so the memory stays
        that of the coordinates and the bounded poses."""
        key = (rows.start, rows.stop)
        found = self._chunk_inputs.get(key)
        if found is None or found.q is not self.q:  # a manifold's configurations are solved again when its geometry changes
            q = self.q[rows]
            real = {name: np.ascontiguousarray(q[:, i]) for i, name in enumerate(self.names)}
            perturbed = {name: real[name] + 1j * STEP for name in self.names}
            found = _ChunkInputs(self.q, real, perturbed)
            self._chunk_inputs[key] = found
        found.functions.forget_except(found.kept)
        return found

    def _columns(
        self,
        elements: Sequence[_Element],
        variables: Mapping[str, float],
        base: Mapping[str, float],
        gravity: Sequence[float],
        rows: slice,
        unit_factor: Sequence[bool],
        slots: Sequence[int],
        n_slots: int,
    ) -> np.ndarray:
        """∂(energy)/∂q of each element (per unit factor where ``unit_factor``) at the
        configurations ``rows``, added into ``out[slots[k]]`` for element k: (n_slots, n, n_q)."""
        q = self.q[rows]
        n, n_q = q.shape
        out = np.zeros((n_slots, n, n_q))
        if not elements:
            return out
        chunk = self._inputs(rows)
        real, perturbed, functions, rotations = chunk.real, chunk.perturbed, chunk.functions, chunk.rotations
        still = Mechanics(self.problem, base, variables, real, gravity, functions, rotations=rotations)
        env = still.env
        values: dict[str, tuple[Any, ...] | None] = {}  # per frame: the values its pose is computed from
        for j, name, moving, needed in self._plan(elements):
            # the poses of these frames at these values, computed before (a frame that does
            # not move with this coordinate has its pose in the unperturbed configurations)
            keys = {f: self._pose_key(f, name, env, values) for f in needed}
            known = {f: pose for f in needed if (pose := chunk.pose(keys[f])) is not None}
            # the values a new Mechanics of these coordinates would hold (env: the parameters,
            # the variables, then the coordinates), without evaluating the parameters again
            mech = still.moved({name: perturbed[name]}, known)
            for f in needed:  # parents first: each computed from its parent's pose, as Mechanics does
                if f not in known:
                    chunk.keep_pose(keys[f], mech.pose(f))
            for k, e in moving:
                energy = e.energy(mech, unit_factor[k])
                if np.iscomplexobj(energy):
                    out[slots[k]][:, j] += np.imag(energy) / STEP
        return out

    def _plan(self, elements: Sequence[_Element]) -> list[tuple[int, str, list[tuple[int, _Element]], list[str]]]:
        """Per coordinate j that moves one of ``elements``: (j, its name, the (index, element)
        pairs that move with it, the frames their poses need, parents first); kept per list
        of elements (keyed on the elements themselves, not their ids: a pickled evaluator
        keeps its plans with its elements)."""
        key = tuple(elements)
        found = self._plans.get(key)
        if found is None:
            found = []
            for j, name in enumerate(self.names):
                moving = [(k, e) for k, e in enumerate(elements) if name in e.moves_with]
                if moving:
                    found.append((j, name, moving, [f for f in self.used_frames if any(f in e.chain for _, e in moving)]))
            self._plans[key] = found
        return found

    def _pose_key(self, frame: str, perturbed: str, env: Mapping[str, Any], values: dict[str, tuple[Any, ...] | None] | None = None) -> tuple[Any, ...] | None:
        """What the pose of ``frame`` is computed from when coordinate ``perturbed`` carries its
        complex step: the frame, the perturbed coordinate if the pose moves with it, and the
        values (each with its sign: −0.0 is not 0.0) of the parameters and variables it
        depends on. None when one is not a plain number (the pose is not kept).
        ``values``: the frames' values already read from this ``env`` (filled in)."""
        found = values.get(frame, ()) if values is not None else ()
        if found == ():
            found = self._pose_values(frame, env)
            if values is not None:
                values[frame] = found
        if found is None:
            return None
        return (frame, perturbed if perturbed in self.frames[frame] else None, *found)

    def _pose_values(self, frame: str, env: Mapping[str, Any]) -> tuple[Any, ...] | None:
        out: list[Any] = []
        for name in self._pose_names[frame]:
            if name not in env:  # a constant (pi)
                continue
            v = env[name]
            if not isinstance(v, (float, int)):
                return None
            out.append((v, math.copysign(1.0, v)))
        return tuple(out)

    def _element_columns(self, elements: Sequence[_Element], base: Mapping[str, float], gravity: Sequence[float], rows: slice) -> np.ndarray:
        """∂(energy)/∂q of each of ``elements`` at the configurations ``rows``, per unit
        factor except for literal-factor ones: (len(elements), n, n_q)."""
        # the design's variables do not enter these arrays: any value will do
        variables = {v.name: v.initial for v in self.problem.variables}
        return self._columns(elements, variables, base, gravity, rows, [not e.constant for e in elements], list(range(len(elements))), len(elements))

    def _fixed_arrays(self, base: Mapping[str, float], gravity: Sequence[float], rows: slice) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per chunk: (literal-factor bodies, literal-factor balancers, one array per other separable element)."""
        columns = self._element_columns([*self.constant, *self.separable], base, gravity, rows)
        return self._compose(list(columns), rows)

    def _compose(self, arrays: Sequence[np.ndarray], rows: slice) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Σ literal-factor bodies, Σ literal-factor balancers, stack of the others) from one
        array per element of ``[*self.constant, *self.separable]``."""
        n_constant = len(self.constant)
        shape = (rows.stop - rows.start, len(self.names))
        bodies, balancers = np.zeros(shape), np.zeros(shape)
        for e, array in zip(self.constant, arrays[:n_constant]):
            (bodies if e.is_body else balancers).__iadd__(array)
        rest = arrays[n_constant:]
        return bodies, balancers, (np.stack(rest) if rest else np.zeros((0, *shape)))

    def _arrays_of(self, index: int, base: Mapping[str, float], gravity: Sequence[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not self.cache:
            return self._fixed_arrays(base, gravity, self.chunks[index])
        elements = [*self.constant, *self.separable]
        if self._element_parameters is None:
            self._element_parameters = [_base_parameters(self.problem, e.geometry) for e in elements]
            self._element_arrays = [None] * len(elements)
        # each element's arrays are rebuilt only when gravity or a parameter of its own
        # geometry changes: a study of one link's length rebuilds that link's elements only
        keys = [(tuple(gravity), tuple(base[name] for name in names)) for names in self._element_parameters]
        stale = [k for k, key in enumerate(keys) if self._element_arrays[k] is None or self._element_arrays[k][0] != key]
        if stale or self._arrays is None:
            if stale:
                fresh = [self._element_columns([elements[k] for k in stale], base, gravity, rows) for rows in self.chunks]
                for position, k in enumerate(stale):
                    self._element_arrays[k] = (keys[k], [chunk[position] for chunk in fresh])
            self._arrays = [self._compose([self._element_arrays[k][1][c] for k in range(len(elements))], rows) for c, rows in enumerate(self.chunks)]
        return self._arrays[index]

    # -- one design ----------------------------------------------------------------
    def evaluate(self, variables: Mapping[str, float], base: Mapping[str, float], gravity: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """(residual, unbalanced gravity torque) of a design: ``variables``, base parameters
        ``base`` and ``gravity`` (SI). The arrays are rebuilt only when gravity or a base
        parameter the geometry depends on changes: a study of masses reuses them."""
        n, n_q = self.q.shape
        residual, torque = np.zeros((n, n_q)), np.zeros((n, n_q))
        real = Mechanics(self.problem, base, variables, {}, gravity, NUMPY_FUNCTIONS)
        factors = [float(real.value(e.factor)) for e in self.separable]
        k = self.separable_bodies
        body_factors, balancer_factors = np.array(factors[:k]), np.array(factors[k:])
        for index, rows in enumerate(self.chunks):
            bodies, balancers, separable = self._arrays_of(index, base, gravity)
            t, r = torque[rows], residual[rows]  # views, filled in place
            t[...] = bodies
            r[...] = balancers
            flat = separable.reshape(len(separable), t.size)
            if k:
                t += (body_factors @ flat[:k]).reshape(t.shape)
            if len(separable) > k:
                r += (balancer_factors @ flat[k:]).reshape(r.shape)
            if self.per_design:
                slots = [0 if e.is_body else 1 for e in self.per_design]
                columns = self._columns(self.per_design, variables, base, gravity, rows, [False] * len(slots), slots, 2)
                for slot, column in enumerate(columns):
                    (t if slot == 0 else r).__iadd__(column)
            r += t
        return residual, torque


def residuals(
    problem: Problem, subsystem: str, q: np.ndarray, variables: dict[str, float], base: dict[str, float], gravity: tuple[float, float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """∂V/∂q at each row of ``q`` by complex step, for the design and for the bodies alone.

    Returns (residual, unbalanced gravity torque), each (N, n_q). One-off use; the dense
    check keeps a :class:`SubsystemResiduals` per problem and reuses it.
    """
    return SubsystemResiduals(problem, subsystem, q, cache=False).evaluate(variables, base, gravity)


def _base_parameters(problem: Problem, names: set[str]) -> tuple[str, ...]:
    """The base parameters among ``names``, and those the derived parameters among them use."""
    parameter = {p.name: p for p in problem.parameters}
    out: set[str] = set()
    todo = [n for n in names if n in parameter]
    while todo:
        p = parameter[todo.pop()]
        if p.is_base:
            out.add(p.name)
        elif p.expr is not None:
            todo += [n for n in ex.names(p.expr) if n in parameter and n not in out]
    return tuple(sorted(out))


#: Configurations on which the energy scale of the noise floor is taken.
ENERGY_SCALE_SAMPLES = 256
#: The energy scale is skipped when every coordinate carries more than this share of the
#: largest gravity torque of its subsystem and every residual is below SCALE_RESIDUAL of it.
SCALE_LOAD_SPREAD = 1e-6
SCALE_RESIDUAL = 1e-9


def energy_scale_if_needed(
    problem: Problem, subsystem: str, q: np.ndarray, residual: np.ndarray, loads: np.ndarray, variables: Any, base: Any, gravity: Any
) -> float:
    """The energy scale of the noise floor (:mod:`.checks`), or 0 when it cannot matter
    (shared by the dense check, :mod:`.check`, and the certificate, :mod:`.certificate`).

    It matters only where gravity's torque may itself be rounding noise: a coordinate that
    gravity loads far less than the others (or not at all), or a residual that is not far
    below the gravity torque (noise measured against noise, or a design that fails anyway).
    A well-loaded, balanced subsystem skips it (it costs a full energy evaluation).
    """
    top = float(loads.max(initial=0.0))
    if top > 0 and np.all(loads > SCALE_LOAD_SPREAD * top) and np.all(residual <= SCALE_RESIDUAL * top):
        return 0.0
    # the size of the terms whose rounding noise a residual that is zero in exact
    # arithmetic keeps (a few hundred configurations show it well enough)
    return energy_scale(problem, subsystem, q[:ENERGY_SCALE_SAMPLES], variables, base, gravity)


def energy_scale(
    problem: Problem, subsystem: str, q: np.ndarray, variables: dict[str, float], base: dict[str, float], gravity: tuple[float, float, float]
) -> float:
    """Largest Σ |energy of each element| of the subsystem over the rows of ``q`` (J): the
    size of the terms whose rounding noise a residual that is zero in exact arithmetic keeps."""
    names = [c.name for c in problem.subsystem_coordinates(subsystem)]
    coords = {name: q[:, i].astype(float) for i, name in enumerate(names)}
    with np.errstate(all="ignore"):
        values = np.abs(np.asarray(Mechanics(problem, base, variables, coords, gravity, NUMPY_FUNCTIONS).energy_magnitude(subsystem), dtype=float))
    finite = values[np.isfinite(values)]
    return float(finite.max(initial=0.0))


#: The reference of the residual ratios is the largest |gravity torque| over the *box* of
#: coordinates, not over the samples: the best samples are refined by projected Newton
#: steps on exact CasADi derivatives until the value gains less than this (relative).
BOX_MAXIMUM_TOLERANCE = 1e-8
#: samples (the largest |torque| of each coordinate) from which the maximum is refined; in a
#: study the maximiser found for the previous values is a further start (the better climbs)
BOX_MAXIMUM_STARTS = 1
#: Newton iterations per start; and halvings of a step that does not increase the value
BOX_MAXIMUM_ITERATIONS = 30
BOX_MAXIMUM_HALVINGS = 20
#: above this many coordinates in a subsystem, third derivatives are skipped (projected
#: gradient steps instead of Newton steps)
BOX_MAXIMUM_NEWTON_COORDINATES = 12
#: a curvature below this share of the largest is flat (a ridge of maxima)
CURVATURE_FLOOR = 1e-9


class BoxMaximum:
    """The largest |∂V/∂q_j| of the given bodies alone (the unbalanced mechanism) over the
    coordinate box of one subsystem, for each coordinate j.

    Built once per problem and subsystem: the body energy as a CasADi expression of the
    coordinates, the design variables, the base parameters and gravity, with its first,
    second and (for up to :data:`BOX_MAXIMUM_NEWTON_COORDINATES` coordinates) third
    derivatives in the coordinates. :meth:`refine` climbs from given starting
    configurations (the best samples) by projected Newton steps with a backtracking line
    search, so the result is never below the starts and is the box maximum (a local one
    near the best sample) to :data:`BOX_MAXIMUM_TOLERANCE`.
    """

    def __init__(self, problem: Problem, subsystem: str) -> None:
        import casadi as ca

        from ..model.functions import casadi_functions

        coords = problem.subsystem_coordinates(subsystem)
        self.lower = np.array([c.lower for c in coords], dtype=float)
        self.upper = np.array([c.upper for c in coords], dtype=float)
        self.base_names = [p.name for p in problem.base_parameters]
        self.variable_names = [v.name for v in problem.variables]
        n = len(coords)
        q = ca.SX.sym("q", n)
        z = ca.SX.sym("z", len(self.variable_names))
        p = ca.SX.sym("p", len(self.base_names))
        g = ca.SX.sym("g", 3)
        mech = Mechanics(
            problem,
            {name: p[i] for i, name in enumerate(self.base_names)},
            {name: z[i] for i, name in enumerate(self.variable_names)},
            {c.name: q[i] for i, c in enumerate(coords)},
            [g[0], g[1], g[2]],
            casadi_functions(),
        )
        bodies, _ = mech.energy_terms(subsystem)
        torque = ca.gradient(ca.SX(bodies), q) if n else ca.SX(0, 1)
        hessian = ca.jacobian(torque, q)
        outputs = [torque, hessian]
        self.newton = 0 < n <= BOX_MAXIMUM_NEWTON_COORDINATES
        if self.newton:
            outputs += [ca.jacobian(hessian[j, :].T, q) for j in range(n)]
        self._torque = ca.Function("torque", [q, z, p, g], [torque])
        self._derivatives = ca.Function("torque_derivatives", [q, z, p, g], outputs)
        self._maps: dict[tuple[str, int], Any] = {}

    def _arguments(self, variables: Mapping[str, float], base: Mapping[str, float], gravity: Sequence[float]) -> tuple[np.ndarray, ...]:
        z = np.array([float(variables[name]) for name in self.variable_names])
        p = np.array([float(base[name]) for name in self.base_names])
        return z, p, np.asarray(gravity, dtype=float)

    def refine(
        self, starts: np.ndarray, variables: Mapping[str, float], base: Mapping[str, float], gravity: Sequence[float], which: Sequence[int] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The largest |torque j| reached from the starts ``starts[k, j]`` (configuration k of
        coordinate j, shape (K, n, n)), for the coordinates ``which`` (all by default) at
        once: at least the best start's value (NaN for the others); and where it is reached,
        (n, n) with column j for coordinate j. Only the best start of each coordinate climbs."""
        args = self._arguments(variables, base, gravity)
        k, n = starts.shape[0], starts.shape[1]
        chosen = np.arange(n) if which is None else np.asarray(which, dtype=int)
        columns = np.clip(np.concatenate([starts[i][chosen].T for i in range(k)], axis=1), self.lower[:, None], self.upper[:, None])
        coordinate = np.tile(chosen, k)  # the coordinate each column climbs
        with np.errstate(all="ignore"):
            values, reached = self._climb(columns, coordinate, args)
        best = np.full(n, np.nan)
        where = np.full((n, n), np.nan)
        for j in chosen:
            mine = np.flatnonzero((coordinate == j) & np.isfinite(values))
            if mine.size:
                i = mine[np.argmax(values[mine])]
                best[j], where[:, j] = values[i], reached[:, i]
        return best, where

    def _mapped(self, name: str, function: Any, m: int) -> Any:
        """``function`` evaluated at m columns in one call (built once per width)."""
        key = (name, m)
        if key not in self._maps:
            self._maps[key] = function.map(m)
        return self._maps[key]

    def _values(self, columns: np.ndarray, coordinate: np.ndarray, args: tuple[np.ndarray, ...]) -> np.ndarray:
        m = columns.shape[1]
        torque = np.asarray(self._mapped("torque", self._torque, m)(columns, *args)).reshape(-1, m)
        return torque[coordinate, np.arange(m)]

    def _climb(self, columns: np.ndarray, coordinate: np.ndarray, args: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray]:
        """Projected Newton ascent of |torque c_i| from column i, all columns at once (one
        CasADi call per step: the trial point's derivatives serve the next step)."""
        lo, hi = self.lower, self.upper
        width = np.where(hi > lo, hi - lo, 0.0)
        n, m = columns.shape
        derivatives = self._mapped("derivatives", self._derivatives, m)

        def evaluate(q: np.ndarray) -> list[np.ndarray]:
            return [np.asarray(x) for x in derivatives(q, *args)]

        q = columns.copy()
        out = evaluate(q)
        start = out[0][coordinate, np.arange(m)]
        sign = np.where(start >= 0, 1.0, -1.0)
        f = sign * start
        active = np.isfinite(f)
        # several starts of one coordinate: the best one climbs (the sorted values, as np.unique
        # gives them; np.unique imports numpy.ma on its first call, ~20 ms of a single solve)
        for c in sorted(set(coordinate.tolist())):
            mine = np.flatnonzero((coordinate == c) & active)
            if mine.size > 1:
                best = mine[np.argmax(f[mine])]
                active[mine] = False
                active[best] = True
        for _ in range(BOX_MAXIMUM_ITERATIONS):
            if not active.any():
                break
            steps = np.zeros_like(q)
            for i in np.flatnonzero(active):
                j = coordinate[i]
                gradient = sign[i] * out[1][j, i * n : (i + 1) * n]
                x = q[:, i]
                held = ((x <= lo) & (gradient <= 0)) | ((x >= hi) & (gradient >= 0)) | (width == 0)
                free = ~held
                if not free.any() or not np.any(gradient[free]):
                    active[i] = False
                    continue
                g_free = gradient[free]
                step = np.zeros(n)
                if self.newton:
                    # Newton on the curved directions; along flat or upward-curved ones (a ridge
                    # of maxima: a torque that depends on a sum of angles) a gradient step of
                    # the largest curvature's scale
                    curvature = -sign[i] * out[2 + j][:, i * n : (i + 1) * n][np.ix_(free, free)]
                    w, v = np.linalg.eigh(0.5 * (curvature + curvature.T))
                    scale = max(float(np.abs(w).max()), np.finfo(float).tiny)
                    along = v.T @ g_free
                    step[free] = v @ np.where(w > CURVATURE_FLOOR * scale, along / np.where(w > 0, w, 1.0), along / scale)
                    if 0.5 * float(g_free @ step[free]) <= BOX_MAXIMUM_TOLERANCE * abs(f[i]):
                        active[i] = False  # the quadratic model gains less than the tolerance: converged
                        continue
                else:  # ascent along the gradient, scaled to the box
                    step[free] = g_free * width[free] / np.abs(g_free).max()
                steps[:, i] = step
            # backtracking line search, every climbing column at once
            alpha = np.where(active, 1.0, 0.0)
            searching = active.copy()
            for _ in range(BOX_MAXIMUM_HALVINGS):
                if not searching.any():
                    break
                trial = np.clip(q + alpha * steps, lo[:, None], hi[:, None])
                trial_out = evaluate(trial)
                value = sign * trial_out[0][coordinate, np.arange(m)]
                better = searching & (value > f)
                gain = np.where(better, value - f, 0.0)
                for c in np.flatnonzero(better):
                    q[:, c] = trial[:, c]
                    out[0][:, c] = trial_out[0][:, c]
                    for block in range(1, len(out)):
                        out[block][:, c * n : (c + 1) * n] = trial_out[block][:, c * n : (c + 1) * n]
                f = np.where(better, value, f)
                active &= ~(better & (gain <= BOX_MAXIMUM_TOLERANCE * np.abs(f)))
                searching &= ~better
                alpha = np.where(searching, alpha * 0.5, alpha)
            active &= ~searching  # no increase along the step: done
        return f, q
