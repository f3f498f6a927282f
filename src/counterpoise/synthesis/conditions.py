"""The exact balance conditions of a superstructure: linear equalities on the weights of
its element classes (:mod:`.structure`).

For every (subsystem, scenario, payload setting) the energy of the mechanism plus the
chosen elements, V = V₀ + Σ_c Σ_f w_{c,f} φ_{c,f}, must be constant. On an open chain
whose angles are affine in the coordinates with integer coefficients, every φ and V₀ is a
trigonometric polynomial (a polynomial in a slider) of a degree the certificate reads off
the expression trees (:func:`counterpoise.verify.certificate.degrees`, here of the chain
with a representative spring on every pair and a counter-mass on every site): on the
certificate's grid (2n + 1 angles per revolute coordinate of degree n, n + 1 Chebyshev
nodes per prismatic one) the transform gives every coefficient exactly. V is constant
**everywhere** exactly when every non-constant coefficient vanishes: each is one row
(the cosine and the sine of each frequency, in J), and rows that no class and not the
mechanism can produce are left out.

Otherwise (closed loops, a coordinate the certificate does not cover) the features are
sampled on configurations (of the loop's manifold), centred, and the rank of the sampled
span kept (SVD): exact at the samples, and standing for the whole manifold only as far as
the sampled rank has saturated (docs/loops.md); each such block says so in the proof.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np

from ..mechanics.energy import Mechanics
from ..model import expr as ex
from ..model.elements import CounterMass, ZeroFreeLengthSpring
from ..model.mechanism import Point
from ..model.problem import Problem
from ..verify.certificate import NotCertifiable, degrees
from .structure import SPRING, ElementClass, class_features, feature_scales

#: largest product grid of one subsystem's exact conditions (configurations)
MAX_GRID = 200_000
#: a coefficient below this share of its feature's largest value on the grid is rounding
COEFFICIENT_NOISE = 1e-10
#: sampled conditions: configurations per block (at least), and the rank tolerance
SAMPLES = 256
RANK_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Setting:
    """A payload setting the adjustments are made for (one when there is no payload)."""

    label: str  # '' or 'm_tool = 31 g'
    payload: str | None
    mass: float | None


@dataclass(frozen=True)
class Block:
    """The conditions of one (subsystem, scenario, setting): rows ``start:stop``."""

    subsystem: str
    scenario: str
    setting: int
    exact: bool
    reason: str  # why sampled ('' when exact)
    start: int
    stop: int
    grid: int  # configurations evaluated


@dataclass(frozen=True)
class Conditions:
    """Σ_c matrix[c] @ w_c(setting of the row) + fixed = 0, row by row."""

    matrix: dict[int, np.ndarray]  # class index -> (rows, features)
    fixed: np.ndarray  # (rows,): the mechanism's own coefficients (J)
    names: tuple[str, ...]  # each row's term
    blocks: tuple[Block, ...]
    settings: tuple[Setting, ...]

    @property
    def rows(self) -> int:
        return len(self.fixed)

    @property
    def exact(self) -> bool:
        return all(b.exact for b in self.blocks)

    def setting_rows(self, setting: int) -> np.ndarray:
        return np.concatenate([np.arange(b.start, b.stop) for b in self.blocks if b.setting == setting] or [np.zeros(0, dtype=int)])


def settings(problem: Problem) -> tuple[Setting, ...]:
    """The payload range's two ends (its only one when they are equal), or one setting."""
    if not problem.payloads:
        return (Setting("", None, None),)
    p = problem.payloads[0]
    ends = [p.lower] if p.upper == p.lower else [p.lower, p.upper]
    return tuple(Setting(f"{p.name} = {p.label(m)}", p.name, m) for m in ends)


def _representatives(problem: Problem, classes: tuple[ElementClass, ...]) -> Problem:
    """The problem with one spring per pair and one counter-mass per site (at the regions'
    origins): the superstructure whose degrees bound every candidate's."""
    zero = (ex.Num(0.0), ex.Num(0.0), ex.Num(0.0))
    springs = list(problem.springs)
    masses = list(problem.counter_masses)
    for c in classes:
        if c.kind == SPRING:
            springs.append(ZeroFreeLengthSpring(f"_candidate{c.index}", ex.Num(1.0), (Point(c.frames[0], zero), Point(c.frames[1], zero)), c.subsystem))
        else:
            masses.append(CounterMass(f"_candidate{c.index}", ex.Num(1.0), Point(c.frames[0], zero), None, c.subsystem))
    return replace(problem, springs=tuple(springs), counter_masses=tuple(masses))


def _base(problem: Problem, scenario_index: int, setting: Setting) -> dict[str, float]:
    scenario = problem.scenarios[scenario_index]
    base = {p.name: float(p.value) for p in problem.base_parameters if p.value is not None}
    base.update({k: float(v) for k, v in scenario.parameters.items()})
    if setting.payload is not None and setting.mass is not None:
        base[setting.payload] = setting.mass
    return base


def _term(freq: np.ndarray, revolute: list[str], prismatic: list[str]) -> str:
    """'theta_a + 2 theta_b' and 'T2(s)' parts of a coefficient's name."""
    parts = []
    for f, name in zip(freq[: len(revolute)], revolute):
        f = int(f)
        if f == 0:
            continue
        sign = "-" if f < 0 else "+"
        mag = "" if abs(f) == 1 else f"{abs(f)} "
        parts.append((sign, f"{mag}{name}"))
    angle = ""
    for i, (sign, text) in enumerate(parts):
        angle += (("-" if sign == "-" else "") if i == 0 else f" {sign} ") + text
    slider = "·".join(f"T{int(d)}({name})" for d, name in zip(freq[len(revolute) :], prismatic) if d)
    return angle + ("|" + slider if slider else "")


def _exact_block(problem: Problem, subsystem: str, found: dict[str, int]) -> tuple[np.ndarray, tuple[int, ...], list[tuple[str, str, int, int]]]:
    """The grid (N, n_q), its shape, and per kept coefficient (kind, name, flat index, ...)."""
    coords = problem.subsystem_coordinates(subsystem)
    nodes = []
    for c in coords:
        n = found[c.name]
        if c.unit.dimension == "":
            nodes.append(2 * np.pi * np.arange(2 * n + 1) / (2 * n + 1))
        elif c.upper == c.lower or n == 0:
            nodes.append(np.array([0.5 * (c.lower + c.upper)]))
        else:
            x = np.cos(np.pi * (np.arange(n + 1) + 0.5) / (n + 1))
            nodes.append(0.5 * (c.lower + c.upper) + 0.5 * (c.upper - c.lower) * x)
    shape = tuple(len(v) for v in nodes)
    grid = np.array(list(itertools.product(*nodes)), dtype=float).reshape(-1, len(coords))
    return grid, shape, []


def _transform(values: np.ndarray, problem: Problem, subsystem: str, shape: tuple[int, ...]) -> tuple[np.ndarray, list[str]]:
    """Rows (cosine and sine coefficient of each frequency, in the values' unit) of the
    trigonometric (and Chebyshev) polynomials through the columns of ``values`` on the
    exact grid, without the constant term; and each row's name."""
    coords = problem.subsystem_coordinates(subsystem)
    revolute = [j for j, c in enumerate(coords) if c.unit.dimension == ""]
    prismatic = [j for j, c in enumerate(coords) if c.unit.dimension != ""]
    cols = values.shape[1]
    c = values.reshape(*shape, cols).astype(complex)
    for j in revolute:
        c = np.fft.fft(c, axis=j) / shape[j]
    for j in prismatic:
        n = shape[j] - 1
        if n > 0:
            x = np.cos(np.pi * (np.arange(n + 1) + 0.5) / (n + 1))
            inverse = np.linalg.inv(np.polynomial.chebyshev.chebvander(x, n))
            c = np.moveaxis(np.tensordot(inverse, c, axes=([1], [j])), 0, j)
    flat = c.reshape(-1, cols)
    index = np.indices(shape).reshape(len(shape), -1).T
    freq = np.empty_like(index)
    for j in range(len(shape)):
        freq[:, j] = np.fft.fftfreq(shape[j], 1.0 / shape[j]).round().astype(int)[index[:, j]] if j in revolute else index[:, j]
    order = revolute + prismatic
    freq = freq[:, order]
    names_r = [coords[j].name for j in revolute]
    names_p = [coords[j].name for j in prismatic]
    rows, names = [], []
    for k in range(len(flat)):
        f = freq[k]
        rev, pri = f[: len(revolute)], f[len(revolute) :]
        nonzero = np.flatnonzero(rev)
        if nonzero.size:
            if rev[nonzero[0]] < 0:
                continue
            term = _term(f, names_r, names_p)
            angle, _, slider = term.partition("|")
            tail = f"·{slider}" if slider else ""
            rows.append(2.0 * flat[k].real)
            names.append(f"cos({angle}){tail}")
            rows.append(-2.0 * flat[k].imag)
            names.append(f"sin({angle}){tail}")
        elif pri.any():
            rows.append(flat[k].real)
            names.append(_term(f, names_r, names_p).lstrip("|"))
    return (np.array(rows) if rows else np.zeros((0, cols))), names


def conditions(problem: Problem, classes: tuple[ElementClass, ...], seed: int = 0) -> Conditions:
    """The balance conditions of ``problem`` with the element ``classes`` (see the module)."""
    all_settings = settings(problem)
    rng = np.random.default_rng(problem.settings.seed + 34 + seed)
    augmented = _representatives(problem, classes)
    parts: list[tuple[np.ndarray, list[str], Block, list[ElementClass]]] = []
    start = 0
    for sub in problem.subsystems:
        coords = problem.subsystem_coordinates(sub.name)
        if not coords:
            continue
        mine = [c for c in classes if c.subsystem == sub.name]
        reason = ""
        shape: tuple[int, ...] = ()
        try:
            found = degrees(augmented, sub.name)
            size = int(np.prod([2 * found[c.name] + 1 if c.unit.dimension == "" else found[c.name] + 1 for c in coords]))
            if size > MAX_GRID:
                raise NotCertifiable(f"{size} grid configurations (more than {MAX_GRID})")
            grid, shape, _ = _exact_block(problem, sub.name, found)
        except NotCertifiable as exc:
            reason = str(exc)
        for si, scenario in enumerate(problem.scenarios):
            for ti, setting in enumerate(all_settings):
                base = _base(problem, si, setting)
                gravity = np.array(scenario.gravity.vector, dtype=float)
                if not reason:
                    q = grid
                else:
                    q = _samples(problem, sub.name, base, max(SAMPLES, 4 * (sum(c.features for c in mine) + 1)), rng)
                n = len(q)
                mech = Mechanics(problem, base, {}, {c.name: q[:, j] for j, c in enumerate(coords)}, list(gravity))
                columns = [class_features(mech, c, n, gravity) for c in mine]
                fixed = np.real(np.broadcast_to(np.asarray(mech.energy(sub.name), dtype=complex), (n,))).astype(float)
                values = np.column_stack([*columns, fixed[:, None]]) if columns else fixed[:, None]
                magnitude = float(np.max(np.real(np.broadcast_to(np.asarray(mech.energy_magnitude(sub.name), dtype=complex), (n,)))))
                scale = np.concatenate([*(feature_scales(f, c, gravity) for f, c in zip(columns, mine)), [max(magnitude, 1e-12)]])
                if not reason:
                    rows, names = _transform(values, problem, sub.name, shape)
                    rows[np.abs(rows) <= COEFFICIENT_NOISE * scale] = 0.0
                    keep = np.flatnonzero(np.abs(rows).max(axis=1) > 0) if len(rows) else np.zeros(0, dtype=int)
                    rows, names = rows[keep], [names[i] for i in keep]
                else:
                    rows, names = _sampled_rows(values, scale)
                where = f"{sub.name}, {scenario.name}" + (f", {setting.label}" if setting.label else "")
                block = Block(sub.name, scenario.name, ti, not reason, reason, start, start + len(rows), n)
                parts.append((rows, [f"{where}: {t}" for t in names], block, mine))
                start += len(rows)
    total = start
    matrix = {c.index: np.zeros((total, c.features)) for c in classes}
    fixed = np.zeros(total)
    row_names: list[str] = []
    blocks = []
    for rows, block_names, block, mine in parts:
        col = 0
        for c in mine:
            matrix[c.index][block.start : block.stop] = rows[:, col : col + c.features]
            col += c.features
        fixed[block.start : block.stop] = rows[:, col]
        row_names += block_names
        blocks.append(block)
    return Conditions(matrix, fixed, tuple(row_names), tuple(blocks), all_settings)


def _samples(problem: Problem, subsystem: str, base: dict[str, float], count: int, rng: np.random.Generator) -> np.ndarray:
    if problem.subsystem_loops(subsystem):
        from ..mechanics.closure import manifold_configurations

        return manifold_configurations(problem, subsystem, count, rng, base).q
    from ..mechanics.sampling import configurations

    return configurations(problem, subsystem, count, rng)


def _sampled_rows(values: np.ndarray, scale: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The conditions 'equal at every sample': the rank of the centred, scaled samples
    (orthonormal combinations of the samples, in the values' unit)."""
    centred = values - values.mean(axis=0)
    u, s, _ = np.linalg.svd(centred / scale, full_matrices=False)
    rank = int(np.sum(s > RANK_TOLERANCE * s[0])) if s.size and s[0] > 0 else 0
    rows = u[:, :rank].T @ centred
    return rows, [f"sampled condition {i + 1}" for i in range(rank)]
