"""The tuning law: each ``tune`` variable's setting from forces measured on the built machine.

A table of tolerance corners is keyed by deviations nobody measures. The law instead reads
the built balancer (docs/robust.md, "The tuning law"):

1. at the factory setting t₀, with the mechanism clamped at a stated pose, a spring scale
   hooked at a stated point reads the holding force y₀ (one reading per tune variable: the
   residual ∂V/∂q_j of a stated joint, divided by the scale's lever);
2. each tune variable k is turned by a stated step Δ_k and the readings are taken again, y_k;
3. the setting is t = t₀ − S⁻¹ y₀ with S[:, k] = (y_k − y₀)/Δ_k: the secant of the readings.
   With one variable per reading (S diagonal): t_k = t₀_k − Δ_k y₀/(y_k − y₀).

**Exact for affine tuning.** When the residual is affine in the tune variables (a spring end's
coordinate, a counter-mass's lever at a fixed mass: checked on the CasADi expression), the
built machine's residual is r(t) = r₀ + T (t − t₀) for *its* deviations δ, whatever they are;
the readings are R r, so S = R T exactly and R r(t) = 0. If the deviation is one the tuning can
balance (r₀ = T u for some u: the tuning table's corners are re-balanced to rounding, and for a
residual multi-affine in δ every point of the box is then too, its value being a convex
combination of corner values in each δ in turn), r(t) = T (u − (RT)⁻¹ R T u) = 0: the whole
residual vanishes at every configuration, not only at the readings. The readings are chosen
where R T is best conditioned (a greedy pivoted QR over candidate poses). A residual that is not
affine in t leaves an error of the second order in the step, |t − t*| ≤ ½ max|∂²y/∂t²| |t* − t₀|
(|t* − t₀| + |Δ|)/|∂y/∂t| per variable: the procedure is repeated from the new setting, and the
check below reports what is left.

The check (:func:`check`) draws random as-built machines uniformly in the tolerance box,
simulates the readings and the law on each, and evaluates the residual ratio left on a dense
grid of configurations: "ideal springs" (each spring pulls k'·d: its string set for the part
as measured, step 1 of the procedure), and "real springs" where a spring's string is left set
for the nominal part: a part k', F0' then adds the constant force F0' − k'·F0/k along its cable,
which no anchor height removes.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..mechanics import NUMPY_FUNCTIONS, Mechanics
from ..mechanics.kinematics import dot, sub
from .affine import Decomposition, grid

#: candidate poses per coordinate, one coordinate moved at a time from home
CANDIDATES_PER_COORDINATE = 9
#: a candidate reading within this share of the best one is as good (the earlier is taken)
TIE = 1e-3
#: complex step for spring length gradients
STEP = 1e-20
#: residual evaluations per CasADi call of the check (machines × configurations)
BATCH = 50_000


@dataclass(frozen=True)
class Reading:
    """One reading of the procedure: the holding force of a joint at a stated pose."""

    block: int
    subsystem: str
    scenario: str
    pose: tuple[tuple[str, float], ...]  # (coordinate, SI) of the block's coordinates
    coordinate: str  # the joint held
    index: int  # the joint's index among the block's coordinates
    body: str  # the point where the scale is hooked (a body's or payload's mass centre); "" for a slider
    lever: float  # m from the joint's axis to that point (1 for a slider: the force is read)
    revolute: bool


@dataclass(frozen=True)
class Law:
    """The tuning law of a design (module docstring)."""

    tune: tuple[str, ...]
    slots: tuple[int, ...]  # the tune variables' entries of the (scaled) design vector
    scale: np.ndarray  # z = x/scale for those entries
    factory: np.ndarray  # t₀, SI
    steps: np.ndarray  # Δ, SI
    readings: tuple[Reading, ...]
    slope: np.ndarray  # (readings, tune) nominal change of each reading (N) per SI unit of each variable
    affine: bool  # the residual is affine in the tune variables: the law is exact
    pairs: tuple[int, ...] | None  # one reading per variable (S diagonal): the reading of each

    def setting(self, y0: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """t = t₀ − S⁻¹ y₀ with S from the readings ``y0`` (m,) and ``ys`` (n_t, m), SI."""
        S = (ys - y0[None, :]).T / self.steps[None, :]
        return np.asarray(self.factory - np.linalg.solve(S, y0), dtype=float)


def _readings(decomposition: Decomposition, readings: Sequence[Reading], z: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The holding force (N) of each reading at the design ``z`` and parameters ``p``."""
    blocks = decomposition.formulation.blocks
    out = np.empty(len(readings))
    for i, r in enumerate(readings):
        q = np.array([v for _, v in r.pose])
        out[i] = float(np.array(blocks[r.block].residual(q, z, p)).reshape(-1)[r.index]) / r.lever
    return out


def build(
    decomposition: Decomposition,
    z: np.ndarray,
    p: np.ndarray,
    tune: Sequence[str],
    scenario: str,
    spans: Mapping[str, float],
    steps: Mapping[str, float] | None = None,
) -> Law:
    """The law for the design ``z`` (scaled, the tune variables at their factory setting) in
    ``scenario``: readings chosen among candidate poses of its blocks, ``spans`` the tuning
    range of each variable (SI, the trial step is a round quarter of it unless ``steps``)."""
    f = decomposition.formulation
    d = f.design
    problem = decomposition.problem
    slots = tuple(i for i, slot in enumerate(d.slots) if slot.variable in tune and (slot.scenario is None or problem.setting(scenario) == slot.scenario))
    names = tuple(d.slots[i].variable for i in slots)
    scale = np.array([d.scale[i] for i in slots])
    factory = np.array([z[i] * d.scale[i] for i in slots])
    step = []
    for k, name in enumerate(names):
        v = problem.variable[name]
        given = (steps or {}).get(name)
        delta = given if given is not None else _round_step(v.unit.from_si(max(spans.get(name, 0.0), 1e-3 * (v.upper - v.lower)) / 4)) * v.unit.to_si
        if factory[k] + delta > v.upper:
            delta = -delta
        step.append(delta)
    # candidate rows: (block, configuration, coordinate) of the scenario's blocks
    candidates: list[tuple[int, np.ndarray, int]] = []
    rows: list[np.ndarray] = []
    affine = True
    for b, block in enumerate(f.blocks):
        if block.scenario != scenario:
            continue
        coords = [problem.coordinate[n] for n in block.coordinates]
        lo = np.array([c.lower for c in coords])
        hi = np.array([c.upper for c in coords])
        home = np.array([min(max(c.home, c.lower), c.upper) for c in coords])
        poses = []
        for j in range(len(coords)):
            # nearest home first: of readings as good as each other, the one nearest home is taken
            for value in sorted(np.linspace(lo[j], hi[j], CANDIDATES_PER_COORDINATE), key=lambda x: abs(x - home[j])):
                q = home.copy()
                q[j] = value
                poses.append(q)
        poses.insert(0, home.copy())
        if len(coords) <= 3:
            poses += list(grid(lo, hi, 5 ** len(coords), np.random.default_rng(0)))
        torque = max(float(np.abs(np.array(block.gravity_torque(q, z, p))).max()) for q in poses) or 1.0
        for q in poses:
            base = np.array(block.residual(q, z, p)).reshape(-1)
            moved = [np.array(block.residual(q, z + np.eye(z.size)[i], p)).reshape(-1) for i in slots]
            for j in range(len(coords)):
                candidates.append((b, q, j))
                rows.append(np.array([(m[j] - base[j]) / scale[k] for k, m in enumerate(moved)]) / torque)
        if not _affine(decomposition, b, np.array(poses), z, p, slots, np.array(step) / scale, torque):
            affine = False
    J = np.array(rows) if rows else np.zeros((0, len(slots)))
    chosen: list[int] = []
    work = J.copy()
    for _ in range(len(slots)):
        norms = np.linalg.norm(work, axis=1)
        if not norms.size or norms.max() <= 0:
            break
        best = int(np.flatnonzero(norms >= (1 - TIE) * norms.max())[0])
        chosen.append(best)
        u = work[best] / norms[best]
        work = work - np.outer(work @ u, u)
    x = d.to_x(z)
    variables = {slot.variable: float(x[i]) for i, slot in enumerate(d.slots) if slot.scenario is None or slot.scenario == problem.setting(scenario)}
    readings = tuple(_reading(decomposition, *candidates[i], variables) for i in chosen)
    # the nominal slope, N per SI unit of each variable: the readings' change over the trial step
    y0 = _readings(decomposition, readings, z, p)
    slope = np.zeros((len(readings), len(slots)))
    for k, i in enumerate(slots):
        moved = z.copy()
        moved[i] += step[k] / scale[k]
        slope[:, k] = (_readings(decomposition, readings, moved, p) - y0) / step[k]
    pairs = _pairs(slope)
    return Law(names, slots, scale, factory, np.array(step), readings, slope, affine, pairs)


#: second differences of the residual in the tune variables below this share of the largest
#: gravity torque are rounding: the residual is affine in them
AFFINE_TOLERANCE = 1e-9


def _affine(decomposition: Decomposition, b: int, q: np.ndarray, z: np.ndarray, p: np.ndarray, slots: Sequence[int], steps: np.ndarray, torque: float) -> bool:
    """Whether the residual of block ``b`` is affine in the tune slots (numerically: every
    second difference over the trial steps, at the poses ``q``, nominal and at the all-plus
    corner, is rounding). A symbolic test misses cancellations (a ground-fixed orientation
    written as R Rᵀ leaves h² (cos² + sin²) in the expression, constant in q)."""
    fn = decomposition.formulation.blocks[b].residual.map(len(q))
    n = len(slots)
    for pv in (p, decomposition.p_at(p, [1.0] * len(decomposition.deviations))):

        def r(*moves: int) -> np.ndarray:
            zz = z.copy()
            for k in moves:
                zz[slots[k]] += steps[k]
            return np.array(fn(q.T, zz, pv))

        r0 = r()
        for a in range(n):
            for c in range(a, n):
                second = r(a, c) - r(a) - r(c) + r0 if a != c else r(a, a) - 2 * r(a) + r0
                if np.abs(second).max(initial=0.0) > AFFINE_TOLERANCE * torque:
                    return False
    return True


def _pairs(slope: np.ndarray) -> tuple[int, ...] | None:
    """The reading each variable is set from when the slope matrix is diagonal up to a
    permutation (a variable moves one reading only), else None."""
    if slope.shape[0] != slope.shape[1] or not slope.size:
        return None
    out = []
    for k in range(slope.shape[1]):
        column = np.abs(slope[:, k])
        i = int(np.argmax(column))
        if np.delete(column, i).max(initial=0.0) > 1e-9 * column[i] or np.delete(np.abs(slope[i]), k).max(initial=0.0) > 1e-9 * column[i]:
            return None
        out.append(i)
    return tuple(out) if len(set(out)) == len(out) else None


def _reading(decomposition: Decomposition, b: int, q: np.ndarray, j: int, variables: Mapping[str, float]) -> Reading:
    """A reading at pose ``q`` of block ``b``, joint ``j``: where to hook the scale (the mass
    centre that moves fastest with the joint) and its lever."""
    f = decomposition.formulation
    problem = decomposition.problem
    block = f.blocks[b]
    name = block.coordinates[j]
    revolute = problem.coordinate[name].unit.dimension == ""
    pose = tuple(zip(block.coordinates, (float(x) for x in q)))
    if not revolute:
        return Reading(b, block.subsystem, block.scenario, pose, name, j, "", 1.0, False)
    gravity, base = f.parameters.scenario_values(f.parameters.values())[block.scenario]
    home = {c.name: c.home for c in problem.coordinates}
    h = 1e-6
    best, lever = "", 0.0
    for body in problem.bodies:
        ends = []
        for sign in (1.0, -1.0):
            coords = {**home, **dict(pose)}
            coords[name] += sign * h
            ends.append(np.array(Mechanics(problem, base, variables, coords, gravity, NUMPY_FUNCTIONS).position(body.com), dtype=float))
        speed = float(np.linalg.norm((ends[0] - ends[1]) / (2 * h)))
        if speed > lever * (1 + 1e-9):
            best, lever = body.name, speed
    return Reading(b, block.subsystem, block.scenario, pose, name, j, best, lever if lever > 0 else 1.0, True)


def _round_step(value: float) -> float:
    """1, 2 or 5 × 10^k at or below ``value`` (> 0), in the display unit."""
    if not value > 0:
        return 1.0
    exponent = math.floor(math.log10(value))
    for m in (5.0, 2.0, 1.0):
        if m * 10**exponent <= value:
            return m * 10**exponent
    return 10.0**exponent


# -- the check at random as-built machines -------------------------------------------------------


@dataclass(frozen=True)
class Check:
    """The law applied at random as-built machines: the largest residual ratio left."""

    samples: int
    ideal: float  # each spring's string set for the part as measured (it pulls k'·d)
    real: float  # NaN when no spring has an initial tension; the strings left set for the nominal part
    worst_sample: tuple[float, ...]  # the deviations (SI or fractions) of the worst ideal sample
    settings_range: Mapping[str, tuple[float, float]]  # the law's settings over the samples (SI)
    real_samples: int = 0  # the machines the "real springs" figure is taken on


def check(
    law: Law,
    decomposition: Decomposition,
    z: np.ndarray,
    p: np.ndarray,
    samples: int,
    seed: int,
    configurations: int,
    pretension: Mapping[str, float] | None = None,
    real_samples: int = 100,
) -> Check:
    """Draw ``samples`` as-built machines uniformly in the tolerance box (seeded), apply the
    law to each (simulated readings), and return the largest residual ratio left on about
    ``configurations`` configurations per block of the law's scenario. ``pretension``: each
    pulley spring's F0 (N) for the "real springs" figure (its string set for the nominal part),
    on the first ``real_samples`` machines. Evaluated in batches (one CasADi call per batch)."""
    devs = decomposition.deviations
    rng = np.random.default_rng(seed)
    signs = rng.uniform(-1.0, 1.0, size=(samples, len(devs)))
    P = np.stack([decomposition.p_at(p, row.tolist()) for row in signs], axis=1)  # (n_p, samples)
    blocks = [b for b, block in enumerate(decomposition.formulation.blocks) if block.scenario == law.readings[0].scenario] if law.readings else []
    q_all = decomposition.configurations(configurations, seed)
    reference = 1.0
    if blocks:
        reference = max(
            float(np.abs(np.array(decomposition.formulation.blocks[b].gravity_torque.map(len(q_all[b]))(q_all[b].T, z, p))).max()) for b in blocks
        ) or 1.0
    settings = _apply_all(law, decomposition, z, P)
    ideal, worst_at = 0.0, np.zeros(len(devs))
    batch = max(1, BATCH // max(1, max((len(q_all[b]) for b in blocks), default=1)))
    for start in range(0, samples, batch):
        stop = min(samples, start + batch)
        Z = np.repeat(z[:, None], stop - start, axis=1)
        Z[list(law.slots), :] = (settings[start:stop] / law.scale[None, :]).T
        worst = np.zeros(stop - start)
        for b in blocks:
            worst = np.maximum(worst, _dense(decomposition, b, q_all[b], Z, P[:, start:stop]))
        k = int(np.argmax(worst))
        if worst[k] / reference > ideal:
            ideal, worst_at = float(worst[k] / reference), signs[start + k] * np.array([d.half_width for d in devs])
    springs = [sp for sp in decomposition.problem.springs if (pretension or {}).get(sp.name) and sp.subsystem is not None]
    real = float("nan")
    if springs:
        real = 0.0
        for n in range(min(samples, real_samples)):
            extra = _constant_forces(decomposition, signs[n], pretension, springs)
            if not extra:
                continue
            pn = P[:, n]
            t_real = _apply(law, decomposition, z, pn, extra)
            zr = z.copy()
            zr[list(law.slots)] = t_real / law.scale
            for b in blocks:
                r = np.array(decomposition.formulation.blocks[b].residual.map(len(q_all[b]))(q_all[b].T, zr, pn)).T  # (N, n_q)
                r = r + _force_terms(decomposition, b, q_all[b], zr, pn, extra)
                real = max(real, float(np.abs(r).max()) / reference)
    ranges = {name: (float(settings[:, k].min()), float(settings[:, k].max())) for k, name in enumerate(law.tune)}
    return Check(samples, ideal, real, tuple(float(x) for x in worst_at), ranges, min(samples, real_samples) if springs else 0)


def _dense(decomposition: Decomposition, b: int, q: np.ndarray, Z: np.ndarray, P: np.ndarray) -> np.ndarray:
    """The largest |residual| of block ``b`` over configurations ``q`` (N, n_q), per column of
    ``Z``, ``P`` (one machine each)."""
    n, m = len(q), Z.shape[1]
    fn = decomposition.mapped(b, n * m)
    r = np.array(fn(np.tile(q.T, (1, m)), np.repeat(Z, n, axis=1), np.repeat(P, n, axis=1)))  # (n_q, n·m)
    return np.abs(r).reshape(r.shape[0], m, n).max(axis=(0, 2))


def _apply_all(law: Law, decomposition: Decomposition, z: np.ndarray, P: np.ndarray) -> np.ndarray:
    """The law's settings (samples, n_t) on the machines ``P`` (columns), from simulated readings."""
    m = P.shape[1]
    blocks = decomposition.formulation.blocks

    def read(zz: np.ndarray) -> np.ndarray:
        out = np.empty((m, len(law.readings)))
        Z = np.repeat(zz[:, None], m, axis=1)
        for i, r in enumerate(law.readings):
            q = np.array([v for _, v in r.pose])
            y = np.array(decomposition.mapped(r.block, m)(np.repeat(q[:, None], m, axis=1), Z, P))  # (n_q, m)
            out[:, i] = y[r.index] / r.lever
        return out

    y0 = read(z)
    ys = []
    for k, i in enumerate(law.slots):
        zz = z.copy()
        zz[i] += law.steps[k] / law.scale[k]
        ys.append(read(zz))
    Y = np.stack(ys, axis=1)  # (m, n_t, readings)
    S = (Y - y0[:, None, :]).transpose(0, 2, 1) / law.steps[None, None, :]  # (m, readings, n_t)
    return np.asarray(law.factory[None, :] - np.linalg.solve(S, y0[:, :, None])[:, :, 0], dtype=float)


def _apply(law: Law, decomposition: Decomposition, z: np.ndarray, p: np.ndarray, extra: Mapping[str, float] | None = None) -> np.ndarray:
    """The law's setting on the machine ``p`` (its deviations), from simulated readings."""
    def read(zz: np.ndarray) -> np.ndarray:
        y = _readings(decomposition, law.readings, zz, p)
        if extra:
            for i, r in enumerate(law.readings):
                q = np.array([v for _, v in r.pose])[None, :]
                y[i] += float(_force_terms(decomposition, r.block, q, zz, p, extra)[0, r.index]) / r.lever
        return y

    y0 = read(z)
    ys = []
    for k, i in enumerate(law.slots):
        zz = z.copy()
        zz[i] += law.steps[k] / law.scale[k]
        ys.append(read(zz))
    return law.setting(y0, np.array(ys))


def _constant_forces(decomposition: Decomposition, signs: np.ndarray, pretension: Mapping[str, float] | None, springs: Sequence[Any]) -> dict[str, float]:
    """Per spring: the constant force along its cable when its string is set for the nominal
    part: F0' − k'·F0/k = −(k' − k) F0/k (its initial tension's own scatter is not toleranced here)."""
    out = {}
    for s in springs:
        f0 = (pretension or {}).get(s.name, 0.0)
        shift = 0.0
        for d, sign in zip(decomposition.deviations, signs):
            t = d.tolerance
            if t.kind == "rate" and t.item == s.name:
                shift = sign * d.half_width if t.relative else math.nan  # relative: Δk/k; absolute needs k
        if math.isnan(shift):
            continue
        out[s.name] = -shift * f0
    return out


def _force_terms(decomposition: Decomposition, b: int, q: np.ndarray, z: np.ndarray, p: np.ndarray, forces: Mapping[str, float]) -> np.ndarray:
    """Σ_s c_s ∂d_s/∂q at configurations ``q`` (N, n_q) of block ``b``: a constant force c_s
    along each spring's cable (energy c_s·d_s)."""
    f = decomposition.formulation
    problem = decomposition.problem
    block = f.blocks[b]
    gravity, base = f.parameters.scenario_values(p)[block.scenario]
    x = f.design.to_x(z)
    variables = {slot.variable: float(x[i]) for i, slot in enumerate(f.design.slots) if slot.scenario is None or slot.scenario == problem.setting(block.scenario)}
    n, n_q = q.shape
    stacked = np.tile(q.astype(complex), (n_q, 1))
    for j in range(n_q):
        stacked[j * n : (j + 1) * n, j] += 1j * STEP
    home = {c.name: c.home for c in problem.coordinates}
    coords = {**home, **{name: stacked[:, i] for i, name in enumerate(block.coordinates)}}
    mech = Mechanics(problem, base, variables, coords, gravity, NUMPY_FUNCTIONS)
    out = np.zeros((n, n_q))
    for s in problem.springs:
        c = forces.get(s.name)
        if not c or s.subsystem != block.subsystem:
            continue
        v = sub(mech.position(s.ends[0]), mech.position(s.ends[1]))
        squared = np.broadcast_to(np.asarray(dot(v, v), dtype=complex), (n * n_q,))
        length = np.sqrt(np.maximum(squared.real[:n], 1e-300))
        grad = (squared.imag / STEP).reshape(n_q, n).T  # ∂(d²)/∂q
        out += c * grad / (2 * length[:, None])
    return out


def corners_of(n: int) -> list[tuple[int, ...]]:
    """Every corner of n deviations (±1)."""
    return list(itertools.product((-1, 1), repeat=n))
