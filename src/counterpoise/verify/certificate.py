"""An exact certificate of balance, where the residual is a trigonometric polynomial.

For ZFL springs, rigid bodies and counter-masses on frames that turn by angles which are
affine in the revolute coordinates with **integer** coefficients (``q_b``, ``q_a + q_b``,
``-q_c + pi/2``), the energy ``V`` of a subsystem — and so its residual ∂V/∂q — is a
trigonometric polynomial in each revolute coordinate, of a degree read off the
expression trees (:func:`degrees`):

- the degree of a revolute coordinate in a point's position is the sum of the |integer
  coefficients| of that coordinate over the rotation angles of the point's frame chain;
- a prismatic coordinate may enter translations (and points) affinely: degree ≤ 1 in a
  position;
- a body or counter-mass (−m g·p) has the degree of its point; a ZFL spring (½ k |a − b|²)
  at most deg(a) + deg(b) in a revolute coordinate (|a|² keeps only the translations'
  products with the rest of the chain, of degree ≤ deg(a)) and 2·max(deg(a), deg(b)) in a
  prismatic one.

The residual is then sampled on the product grid of 2n+1 equally spaced angles per
revolute coordinate of degree n (n+1 Chebyshev nodes per prismatic coordinate of degree
n over its range) with the dense check's own evaluator (:class:`.residuals.SubsystemResiduals`,
complex step on the mechanics) and transformed (numpy's FFT; the Chebyshev interpolation
matrix). The interpolation is exact, so Σ |coefficients| bounds |residual| over **every**
configuration (every angle, the prismatic ranges), not only over sampled ones; a design
whose coefficients vanish to rounding is balanced everywhere.

The bound is set against the dense check's reference (:mod:`.checks`): the largest
|gravity torque| of the unbalanced mechanism over the coordinate box, here the largest
value of its own exact polynomial at :data:`REFERENCE_SAMPLES` random configurations of
the box plus its corners (a lower bound of the box maximum, so the residual ratio is a
certified *upper* bound of the true one).

Not certifiable (:func:`plan` returns None and the dense check is used): closed loops,
directly attached springs (a square root), a rotation angle with a non-integer or
symbolic coefficient of a coordinate or with a prismatic coordinate, a revolute
coordinate inside a translation or a point, a coordinate inside a nonlinear function, a
mass or stiffness that depends on a coordinate, a rotation axis that does, and more than
:data:`MAX_GRID` grid configurations.
"""

from __future__ import annotations

import itertools
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ExpressionError
from ..model import expr as ex
from ..model.mechanism import GROUND, Point, Rotation, Translation
from ..model.problem import Problem
from ..designer.checks import PRISMATIC, REVOLUTE, CoordinateCheck, Verification
from ..mechanics.sampling import configurations
from .residuals import SubsystemResiduals, energy_scale_if_needed

if TYPE_CHECKING:
    from ..designer.solution import Solution

EXACT = "exact"
SAMPLED = "sampled"
#: configurations of the box on which the reference torque's exact polynomial is evaluated
REFERENCE_SAMPLES = 512
#: largest product grid (configurations) per subsystem; above it the dense check is cheaper
MAX_GRID = 4096
#: largest polynomial degree of a prismatic coordinate
MAX_PRISMATIC_DEGREE = 2
_CACHE_SIZE = 4
_cache: dict[int, tuple["weakref.ref[Problem]", Any]] = {}


class NotCertifiable(Exception):
    """The residual is not (provably) a trigonometric polynomial; the message says why."""


# -- degrees, from the expression trees ------------------------------------------------
def _affine(tree: ex.Expr, coordinates: frozenset[str]) -> dict[str, float | None]:
    """Coefficients of the coordinates in ``tree`` if it is affine in them: a number, or
    None when the coefficient is symbolic (it names a parameter). Raises
    :class:`NotCertifiable` when a coordinate enters nonlinearly."""
    found = ex.names(tree) & coordinates
    if not found:
        return {}
    if isinstance(tree, ex.Name):
        return {tree.id: 1.0}
    if isinstance(tree, ex.Neg):
        return _scaled(_affine(tree.operand, coordinates), -1.0)
    if isinstance(tree, ex.BinOp):
        if tree.op in ("+", "-"):
            out = dict(_affine(tree.left, coordinates))
            for k, v in _scaled(_affine(tree.right, coordinates), 1.0 if tree.op == "+" else -1.0).items():
                old = out.get(k, 0.0)
                out[k] = None if old is None or v is None else old + v
            return out
        if tree.op == "*":
            for this, other in ((tree.left, tree.right), (tree.right, tree.left)):
                if not ex.names(other) & coordinates:
                    return _scaled(_affine(this, coordinates), _number(other))
        if tree.op == "/" and not ex.names(tree.right) & coordinates:
            scale = _number(tree.right)
            return _scaled(_affine(tree.left, coordinates), None if not scale else 1.0 / scale)
    raise NotCertifiable(f"coordinate {sorted(found)[0]!r} enters an expression nonlinearly")


def _scaled(coefficients: dict[str, float | None], scale: float | None) -> dict[str, float | None]:
    return {k: None if v is None or scale is None else v * scale for k, v in coefficients.items()}


def _number(tree: ex.Expr) -> float | None:
    """The value of a tree of numbers and constants (None when it names a parameter or a
    variable: a symbolic coefficient)."""
    if ex.names(tree) - set(ex.CONSTANTS):
        return None
    try:
        return float(ex.evaluate(tree, {}, {"sqrt": np.sqrt, "sin": np.sin, "cos": np.cos, "tan": np.tan, "exp": np.exp, "log": np.log, "abs": abs}))
    except (ArithmeticError, ValueError, KeyError, TypeError, ExpressionError):
        return None


def degrees(problem: Problem, subsystem: str) -> dict[str, int]:
    """The degree of each coordinate of ``subsystem`` in its energy (see the module);
    raises :class:`NotCertifiable`."""
    if problem.subsystem_loops(subsystem):
        raise NotCertifiable("closed loops")
    coords = problem.subsystem_coordinates(subsystem)
    names = frozenset(c.name for c in problem.coordinates)
    revolute = {c.name for c in problem.coordinates if c.unit.dimension == ""}
    frames: dict[str, dict[str, int]] = {GROUND: {}}

    def translation(vector: Any, where: str) -> dict[str, int]:
        out: dict[str, int] = {}
        for tree in vector:
            for name in _affine(tree, names):
                if name in revolute:
                    raise NotCertifiable(f"revolute coordinate {name!r} inside a translation ({where})")
                out[name] = 1
        return out

    def frame_degrees(name: str) -> dict[str, int]:
        if name not in frames:
            frame = problem.frame[name]
            out = dict(frame_degrees(frame.parent)) if frame.parent is not None else {}
            for t in frame.transforms:
                if isinstance(t, Rotation):
                    if any(ex.names(a) & names for a in t.axis):
                        raise NotCertifiable(f"a rotation axis of frame {name!r} depends on a coordinate")
                    for c, v in _affine(t.angle, names).items():
                        if c not in revolute:
                            raise NotCertifiable(f"prismatic coordinate {c!r} in a rotation angle of frame {name!r}")
                        if v is None or v != round(v):
                            raise NotCertifiable(f"coordinate {c!r} has a non-integer coefficient in a rotation angle of frame {name!r}")
                        out[c] = out.get(c, 0) + abs(int(round(v)))
                elif isinstance(t, Translation):
                    for c in translation(t.vector, f"frame {name!r}"):
                        out[c] = max(out.get(c, 0), 1)
            frames[name] = out
        return frames[name]

    def point(p: Point, where: str) -> dict[str, int]:
        out = dict(frame_degrees(p.frame))
        for c in translation(p.position, where):
            out[c] = max(out.get(c, 0), 1)
        return out

    total = {c.name: 0 for c in coords}

    def add(found: dict[str, int]) -> None:
        for c, n in found.items():
            if c in total:
                total[c] = max(total[c], n)

    for group in (problem.bodies, problem.counter_masses):
        for e in group:
            if e.subsystem != subsystem:
                continue
            if ex.names(e.mass) & names:
                raise NotCertifiable(f"the mass of {e.name!r} depends on a coordinate")
            add(point(e.com if hasattr(e, "com") else e.position, e.name))
    for s in problem.springs:
        if s.subsystem != subsystem:
            continue
        if s.direct is not None:
            raise NotCertifiable(f"spring {s.name!r} is attached directly")
        if not s.exact:
            raise NotCertifiable(f"spring {s.name!r} runs over a pulley of radius > 0 without a pin")
        if ex.names(s.stiffness) & names:
            raise NotCertifiable(f"the stiffness of {s.name!r} depends on a coordinate")
        a, b = point(s.ends[0], s.name), point(s.ends[1], s.name)
        add({c: (a.get(c, 0) + b.get(c, 0) if c in revolute else 2 * max(a.get(c, 0), b.get(c, 0))) for c in set(a) | set(b)})
    for c in coords:
        if c.name not in revolute and total[c.name] > MAX_PRISMATIC_DEGREE:
            raise NotCertifiable(f"prismatic coordinate {c.name!r} of degree {total[c.name]}")
    return total


# -- the grid and its transform ----------------------------------------------------------
def _chebyshev(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Chebyshev nodes (first kind) on [-1, 1] for a polynomial of ``degree``, and the
    matrix that maps values at them to Chebyshev coefficients."""
    m = degree + 1
    x = np.cos(np.pi * (np.arange(m) + 0.5) / m)
    return x, np.linalg.inv(np.polynomial.chebyshev.chebvander(x, degree))


@dataclass
class _Axis:
    revolute: bool
    nodes: np.ndarray  # SI values of the coordinate on the grid
    inverse: np.ndarray | None = None  # prismatic: values -> Chebyshev coefficients
    lower: float = 0.0
    upper: float = 0.0
    degree: int = 0

    def basis(self, values: np.ndarray) -> np.ndarray:
        """The basis functions of the coefficients at ``values``: (M, len(nodes))."""
        m = len(self.nodes)
        if self.revolute:
            k = np.fft.fftfreq(m, 1.0 / m)  # frequencies in numpy's FFT order
            return np.exp(1j * np.outer(values, k))
        if self.upper == self.lower:
            return np.ones((len(values), 1))
        x = (2 * values - (self.lower + self.upper)) / (self.upper - self.lower)
        return np.polynomial.chebyshev.chebvander(np.clip(x, -1.0, 1.0), self.degree)


class SubsystemCertificate:
    """The grid, its evaluator and the reference samples of one (scenario, subsystem)."""

    def __init__(self, problem: Problem, scenario: str, subsystem: str, found: dict[str, int], rng: np.random.Generator) -> None:
        self.scenario, self.subsystem = scenario, subsystem
        coords = problem.subsystem_coordinates(subsystem)
        self.kinds = [REVOLUTE if c.unit.dimension == "" else PRISMATIC for c in coords]
        self.axes: list[_Axis] = []
        for c, kind in zip(coords, self.kinds):
            n = found[c.name]
            if kind == REVOLUTE:
                self.axes.append(_Axis(True, 2 * np.pi * np.arange(2 * n + 1) / (2 * n + 1)))
            elif c.upper == c.lower or n == 0:
                self.axes.append(_Axis(False, np.array([0.5 * (c.lower + c.upper)]), np.ones((1, 1)), c.lower, c.upper, 0))
            else:
                x, inverse = _chebyshev(n)
                self.axes.append(_Axis(False, 0.5 * (c.lower + c.upper) + 0.5 * (c.upper - c.lower) * x, inverse, c.lower, c.upper, n))
        self.shape = tuple(len(a.nodes) for a in self.axes)
        grid = np.array(list(itertools.product(*(a.nodes for a in self.axes))), dtype=float).reshape(-1, len(coords))
        self.evaluator = SubsystemResiduals(problem, subsystem, grid)
        self.samples = configurations(problem, subsystem, REFERENCE_SAMPLES, rng)
        basis = np.ones((len(self.samples), 1), dtype=complex)
        for j, axis in enumerate(self.axes):  # row-wise Kronecker product, in the grid's order
            b = axis.basis(self.samples[:, j])
            basis = (basis[:, :, None] * b[:, None, :]).reshape(len(self.samples), -1)
        # real and imaginary parts apart: Re(basis @ c) in two real products
        self.basis_real, self.basis_imag = np.ascontiguousarray(basis.real), np.ascontiguousarray(basis.imag)
        self.size = int(np.prod(self.shape))
        self._revolute = tuple(j for j, a in enumerate(self.axes) if a.revolute)
        self._scale = float(np.prod([len(self.axes[j].nodes) for j in self._revolute]))
        self._prismatic = tuple(j for j, a in enumerate(self.axes) if not a.revolute and len(a.nodes) > 1)

    def coefficients(self, values: np.ndarray) -> np.ndarray:
        """Coefficients (grid shape, columns) of the polynomials through the columns of
        ``values`` (N, columns) on the grid."""
        c = values.reshape(*self.shape, values.shape[1])
        if self._revolute:
            c = np.fft.fftn(c, axes=self._revolute) / self._scale
        return self.chebyshev(c)

    def chebyshev(self, c: np.ndarray) -> np.ndarray:
        """``c`` (grid shape, columns) with the values along each prismatic axis mapped to
        Chebyshev coefficients."""
        for j in self._prismatic:
            c = np.moveaxis(np.tensordot(self.axes[j].inverse, c, axes=([1], [j])), 0, j)  # type: ignore[arg-type]  # a prismatic axis has its inverse
        return c


@dataclass(frozen=True)
class ExactVerification(Verification):
    """A :class:`~.checks.Verification` whose ``max_residual`` figures are certified bounds
    over every configuration (the coefficients' sums), not sampled maxima."""

    certificate: str = EXACT

    def __post_init__(self) -> None:
        # the reference of each kind, once (a study point asks for it once per coordinate)
        object.__setattr__(self, "_references", {kind: Verification.reference(self, kind) for kind in {c.kind for c in self.checks}})

    def reference(self, kind: str) -> float:
        found: dict[str, float] = self.__dict__["_references"]
        return found[kind] if kind in found else Verification.reference(self, kind)


def certificate_of(verification: Verification) -> str:
    """``exact`` for a certified verification, ``sampled`` for the dense check's."""
    return getattr(verification, "certificate", SAMPLED)


class Certificate:
    """The certificates of every (scenario, subsystem) of one problem, built once."""

    def __init__(self, problem: Problem) -> None:
        self.problem = problem
        rng = np.random.default_rng(problem.settings.seed + 2)
        self.parts: list[SubsystemCertificate] = []
        for sub in problem.subsystems:
            found = degrees(problem, sub.name)
            if not found:
                continue  # no coordinates: nothing to check (as the dense check)
            size = int(np.prod([2 * n + 1 if c.unit.dimension == "" else n + 1 for c in problem.subsystem_coordinates(sub.name) for n in [found[c.name]]]))
            if size > MAX_GRID:
                raise NotCertifiable(f"subsystem {sub.name!r} needs {size} grid configurations (more than {MAX_GRID})")
            for scenario in problem.scenarios:
                self.parts.append(SubsystemCertificate(problem, scenario.name, sub.name, found, rng))
        kinds: dict[tuple[Any, ...], list[int]] = {}
        for k, part in enumerate(self.parts):
            kinds.setdefault((part.shape, tuple(part.kinds), part._revolute, part._prismatic), []).append(k)
        self.groups = [_Group([self.parts[k] for k in index], index) for index in kinds.values()]

    def verify(self, solution: "Solution") -> ExactVerification:
        """The certified verification of ``solution`` (whether or not it is balanced)."""
        problem = self.problem
        per_part: list[list[CoordinateCheck]] = [[] for _ in self.parts]
        for group in self.groups:
            found = group.evaluate(solution)
            # the samples along the last axis: numpy reduces a contiguous axis fast (a
            # maximum is exact in any order, and argmax takes the first maximum either way)
            both = np.ascontiguousarray(found.both.transpose(0, 2, 1))  # (parts, 2 n_q, samples)
            rs, ts = both[:, : group.n_q], both[:, group.n_q :]
            with np.errstate(invalid="ignore"):
                loads_all = np.abs(ts).max(axis=2)  # (parts, n_q)
                balancers_all = np.abs(rs - ts).max(axis=2)
                worst_all = np.argmax(np.abs(rs), axis=2)  # a NaN one first
            for g, part in enumerate(group.parts):
                variables, base, gravity = found.inputs[g]
                bound, loads = found.bound[g], loads_all[g]
                scale = energy_scale_if_needed(problem, part.subsystem, part.samples, bound, loads, variables, base, gravity)
                residuals, torques, forces = bound.tolist(), loads.tolist(), balancers_all[g].tolist()
                worst = worst_all[g].tolist()
                per_part[group.index[g]] = [
                    CoordinateCheck(
                        subsystem=part.subsystem,
                        scenario=part.scenario,
                        coordinate=name,
                        kind=part.kinds[j],
                        max_residual=residuals[j],
                        max_gravity_torque=torques[j],
                        max_balancer_force=forces[j],
                        energy_scale=scale,
                        configurations=part.size,
                        worst_configuration=tuple(part.samples[worst[j]].tolist()),
                    )
                    for j, name in enumerate(part.evaluator.names)
                ]
        return ExactVerification(tuple(c for checks in per_part for c in checks), problem.settings.verify_tolerance)


@dataclass(frozen=True)
class _Found:
    """One group's figures for a design, each with the parts first: the residual bound
    (parts, n_q), the residual and the gravity torque at the reference samples (parts,
    samples, 2 n_q: the residual's columns, then the torque's), and each part's
    (variables, base parameters, gravity)."""

    bound: np.ndarray
    both: np.ndarray
    inputs: list[tuple[Any, Any, Any]]


class _Group:
    """The parts of one problem whose grids have the same shape and kinds of axes: their
    transforms and reference products are done in one call each (numpy transforms each
    line and multiplies each matrix of a stack on its own, so every figure is the one the
    part alone gives, bit for bit)."""

    def __init__(self, parts: list[SubsystemCertificate], index: list[int]) -> None:
        first = parts[0]
        self.parts, self.index = parts, index
        self.n_q = len(first.kinds)
        self.shape = first.shape
        # numpy's fftn transforms the last of its axes first: the same 1-D transforms, in that order
        self.fft_axes = tuple(1 + j for j in reversed(first._revolute))
        self.scale = first._scale
        self.prismatic = first._prismatic
        self.basis_real = np.stack([p.basis_real for p in parts])
        self.basis_imag = np.stack([p.basis_imag for p in parts])
        for g, part in enumerate(parts):  # each part's bases become views of the stacks (kept once)
            part.basis_real, part.basis_imag = self.basis_real[g], self.basis_imag[g]

    def evaluate(self, solution: "Solution") -> _Found:
        n_q, size = self.n_q, self.parts[0].size
        values = np.empty((len(self.parts), size, 2 * n_q))
        inputs = []
        for g, part in enumerate(self.parts):
            variables = solution.variable_values(part.scenario)
            gravity, base = solution.scenario_parameters[part.scenario]
            r, t = part.evaluator.evaluate(variables, base, gravity)
            values[g, :, :n_q] = r
            values[g, :, n_q:] = t
            inputs.append((variables, base, gravity))
        c: np.ndarray = values.reshape(len(self.parts), *self.shape, 2 * n_q)
        if self.fft_axes:
            for axis in self.fft_axes:
                c = np.fft.fft(c, axis=axis)
            c = c / self.scale
        if self.prismatic:
            c = np.stack([part.chebyshev(c[g]) for g, part in enumerate(self.parts)])
        c = c.reshape(len(self.parts), size, 2 * n_q)
        bound = np.abs(c[:, :, :n_q]).sum(axis=1)
        if np.iscomplexobj(c):
            both = self.basis_real @ c.real - self.basis_imag @ c.imag
        else:
            both = self.basis_real @ c
        return _Found(bound, both, inputs)


def certificate(problem: Problem) -> Certificate | None:
    """The problem's :class:`Certificate`, built once per problem; None when not certifiable."""
    entry = _cache.get(id(problem))
    if entry is not None and entry[0]() is problem:
        return entry[1]
    try:
        found: Certificate | None = Certificate(problem)
    except NotCertifiable:
        found = None
    if len(_cache) >= _CACHE_SIZE:
        _cache.pop(next(iter(_cache)))
    _cache[id(problem)] = (weakref.ref(problem), found)
    return found


def why_not(problem: Problem) -> str | None:
    """Why ``problem`` is not certifiable (None if it is)."""
    try:
        Certificate(problem)
    except NotCertifiable as exc:
        return str(exc)
    return None


def certify(solution: "Solution") -> ExactVerification | None:
    """The exact verification of ``solution`` when its problem is certifiable and the
    certificate proves it balanced; None otherwise (then the dense check decides)."""
    found = certificate(solution.problem)
    if found is None:
        return None
    verification = found.verify(solution)
    return verification if verification.balanced else None
