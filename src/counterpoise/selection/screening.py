"""Screening every part of a directly attached slot at once (numpy over parts × geometries × configurations).

A directly attached spring i pulls with F_i = F0 + k (d_i − c_i − L0) = k d_i − T_i, with
T_i = k (c_i + L0) − F0 (``c_i`` its cable). Its generalized force is F_i ∂d_i/∂q, so the
balance residual of a design is

    r(q) = G(q; z) + k Σ_i d_i ∂d_i/∂q − Σ_i T_i ∂d_i/∂q,

with G the rest (bodies, counter-masses, other springs) and z the geometry (every design
variable but the cables). For a fixed geometry the part enters only through its rate k and
the offsets T_i, and r is *affine* in T_i. A cable variable that appears nowhere else ranges
over its bounds, cut down by the part's lengths on the sampled configurations
(L0 ≤ d_i − c_i ≤ L_max), so T_i ranges over an interval per (part, geometry), possibly empty.

One spring: the best offset of each (part, grid geometry) pair is a one-dimensional convex
minimax problem, solved exactly by bisection on the slope (vectorised over all pairs);
the part's screened ratio is the best over its grid. Two springs of one part with
separate geometry variables: each spring's arrays are computed once on its own grid and
all unordered pairs of grid geometries are screened per part (symmetry), the two offsets
by box-constrained least squares (a feasible point: an upper estimate of that pair's best).

The *bound* of a part is its best grid value minus what a finer geometry could gain,
estimated from the grid itself: half the largest change of the part's value between
neighbouring grid points along each axis, summed over the axes (a Lipschitz estimate of
the value function over one grid cell). It is an estimate, not a certificate: a steeper
value function between grid points, or a part feasible only between grid points, escapes it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..mechanics import NUMPY_FUNCTIONS, Mechanics
from ..mechanics.kinematics import dot, sub
from ..model import expr as ex
from ..model.problem import Problem
from ..verify.residuals import STEP, frame_names

#: geometry grid points of one spring's screening (all axes together), at most
GRID_POINTS = 1728
#: per-spring grid points when pairs of geometries are screened (pairs grow as its square)
PAIR_GRID_POINTS = 216
#: configurations per subsystem on which parts are screened (a uniform grid for one coordinate)
SCREEN_CONFIGURATIONS = 25
#: zoom rounds around each part's best grid point (3^n points at half the spacing each)
ZOOM_ROUNDS = 5
#: bisection steps of the exact one-dimensional offset (interval shrinks by 2**-steps)
BISECTION_STEPS = 30
#: (part, geometry) pairs evaluated at once (memory bound)
CHUNK_PAIRS = 20000
#: a spring's lengths on the grid must meet the part's limits within this (m)
LENGTH_SLACK = 0.0


@dataclass
class Screen:
    """Per part (catalogue row): screened ratio, estimated bound and the best grid design."""

    supported: bool
    reason: str = ""
    ratio: np.ndarray = field(default_factory=lambda: np.zeros(0))  # inf: no feasible grid design
    bound: np.ndarray = field(default_factory=lambda: np.zeros(0))
    start: list[dict[str, float]] = field(default_factory=list)  # variable -> value of the best grid design
    geometries: int = 0
    configurations: int = 0
    pairs: bool = False
    evaluated: int = 0  # (part, geometry) combinations screened
    infeasible: int = 0  # parts with no grid geometry within their lengths


def _names_of(problem: Problem, point: Any, frames: Mapping[str, frozenset[str]]) -> set[str]:
    return set().union(*(ex.names(t) for t in point.position)) | set(frames[point.frame])


def _structure(problem: Problem) -> tuple[str, list[Any], dict[str, str], list[str], list[set[str]]] | str:
    """(slot, its springs, spring -> cable variable, grid variables, per-spring geometry variables),
    or the reason screening does not apply."""
    if len(problem.slots) != 1:
        return "screening needs exactly one slot"
    if len(problem.scenarios) != 1:
        return "screening needs a single scenario"
    slot = problem.slots[0]
    springs = [s for s in problem.springs if s.slot == slot.name]
    if not springs or any(s.direct is None or s.subsystem is None for s in springs):
        return "screening needs directly attached springs in a subsystem"
    variables = set(problem.variable)
    frames = frame_names(problem)
    used: dict[str, int] = {}
    geometry: list[set[str]] = []
    for s in springs:
        g = (_names_of(problem, s.ends[0], frames) | _names_of(problem, s.ends[1], frames)) & variables
        geometry.append(g)
    other = set()
    for b in problem.bodies:
        other |= (_names_of(problem, b.com, frames) | ex.names(b.mass)) & variables
    for c in problem.counter_masses:
        other |= (_names_of(problem, c.position, frames) | ex.names(c.mass)) & variables
    for s in problem.springs:
        if s.slot != slot.name:
            other |= (_names_of(problem, s.ends[0], frames) | _names_of(problem, s.ends[1], frames) | ex.names(s.stiffness)) & variables
    cables: dict[str, str] = {}
    for s in springs:
        names = ex.names(s.direct.cable) & variables
        if isinstance(s.direct.cable, ex.Name) and names:
            cables[s.name] = s.direct.cable.id
        elif names:
            return "screening needs each cable to be a variable of its own or fixed"
        for v in names:
            used[v] = used.get(v, 0) + 1
    for s, v in cables.items():
        if used[v] > 1 or v in other or any(v in g for g in geometry):
            return f"cable variable {v} also sets other lengths"
    grid = sorted((variables - set(cables.values())))
    return slot.name, springs, cables, grid, geometry


def _grid(problem: Problem, names: Sequence[str], points: int) -> tuple[dict[str, np.ndarray], list[np.ndarray]]:
    """A full factorial grid over the variables' boxes: values (n,) per variable and the axes."""
    n = max(2, int(math.floor(points ** (1.0 / max(len(names), 1)) + 1e-9)))
    axes = [np.linspace(problem.variable[v].lower, problem.variable[v].upper, n) for v in names]
    if not names:
        return {}, []
    mesh = np.meshgrid(*axes, indexing="ij")
    return {v: m.ravel() for v, m in zip(names, mesh)}, axes


def _screen_configurations(problem: Problem, subsystem: str, seed: int) -> np.ndarray:
    coords = problem.subsystem_coordinates(subsystem)
    lo = np.array([c.lower for c in coords])
    hi = np.array([c.upper for c in coords])
    if len(coords) == 1:
        return np.linspace(lo, hi, SCREEN_CONFIGURATIONS)
    from ..verify.residuals import configurations

    return configurations(problem, subsystem, SCREEN_CONFIGURATIONS * len(coords), np.random.default_rng(seed))


def _arrays(problem: Problem, subsystem: str, q: np.ndarray, variables: Mapping[str, np.ndarray], base: Mapping[str, float], gravity: Sequence[float], springs: Sequence[Any]) -> tuple[np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """G (n_g, N, n_q) with the slot's springs removed, and per spring (d (n_g, N), ∂d/∂q (n_g, N, n_q))."""
    names = [c.name for c in problem.subsystem_coordinates(subsystem)]
    n, n_q = q.shape
    stacked = np.tile(q.astype(complex), (n_q, 1))
    for j in range(n_q):
        stacked[j * n : (j + 1) * n, j] += 1j * STEP
    coords = {name: stacked[None, :, i] for i, name in enumerate(names)}
    coords.update({c.name: c.home for c in problem.coordinates if c.name not in coords})
    var = {k: np.asarray(v, dtype=float)[:, None] for k, v in variables.items()}
    n_g = max((len(v) for v in variables.values()), default=1)
    mech = Mechanics(problem, base, var, coords, gravity, NUMPY_FUNCTIONS)
    bodies, balancers = mech.energy_terms(subsystem)
    energy = np.broadcast_to(np.asarray(bodies + balancers, dtype=complex), (n_g, n * n_q))
    g = (energy.imag / STEP).reshape(n_g, n_q, n).transpose(0, 2, 1)
    out = {}
    for s in springs:
        d = sub(mech.position(s.ends[0]), mech.position(s.ends[1]))
        squared = np.broadcast_to(np.asarray(dot(d, d), dtype=complex), (n_g, n * n_q))
        length = np.sqrt(np.maximum(squared.real[:, :n], 0.0))
        grad = (squared.imag / STEP).reshape(n_g, n_q, n).transpose(0, 2, 1) / (2 * np.maximum(length, 1e-12)[:, :, None])
        out[s.name] = (length, grad)
    return g, out


def best_offset(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """min over T in [lo, hi] of max_j |a_j − T b_j| (convex in T), per row: (T, value).

    Bisection on the sign of the slope of the active term; rows (P, M)."""
    lo, hi = lo.copy(), hi.copy()
    idx = np.arange(a.shape[0])
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        res = a - mid[:, None] * b
        j = np.argmax(np.abs(res), axis=1)
        rising = np.sign(res[idx, j]) * (-b[idx, j]) > 0
        hi = np.where(rising, mid, hi)
        lo = np.where(rising, lo, mid)
    t = 0.5 * (lo + hi)
    return t, np.abs(a - t[:, None] * b).max(axis=1)


def _part_arrays(slot: Any) -> dict[str, np.ndarray]:
    a = slot.catalogue.arrays
    k, l0, f0 = a["rate"], a["free_length"], a["initial_tension"]
    lmax = np.minimum(a["max_length"], l0 + (a["max_load"] - f0) / k)
    return {"k": k, "l0": l0, "f0": f0, "lmax": lmax}


def _offset_interval(p: Mapping[str, np.ndarray], rows: np.ndarray, d_min: np.ndarray, d_max: np.ndarray, cable: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Offsets T = k (c + L0) − F0 allowed per (row, geometry): cable in its box and
    L0 ≤ d − c ≤ L_max on the configurations. Shapes (len(rows), n_g)."""
    k, l0, f0, lmax = (p[x][rows, None] for x in ("k", "l0", "f0", "lmax"))
    c_lo = np.maximum(cable[0], d_max[None, :] - lmax)
    c_hi = np.minimum(cable[1], d_min[None, :] - l0)
    return k * (c_lo + l0) - f0, k * (c_hi + l0) - f0


def _offset_pairs(p: Mapping[str, np.ndarray], rows: np.ndarray, d_min: np.ndarray, d_max: np.ndarray, cable: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """As :func:`_offset_interval`, for part ``rows[i]`` at geometry i (elementwise)."""
    k, l0, f0, lmax = (p[x][rows] for x in ("k", "l0", "f0", "lmax"))
    c_lo = np.maximum(cable[0], d_max - lmax)
    c_hi = np.minimum(cable[1], d_min - l0)
    return k * (c_lo + l0) - f0, k * (c_hi + l0) - f0


def _lipschitz_gain(values: np.ndarray, shape: Sequence[int]) -> np.ndarray:
    """Per part (rows of ``values`` (P, n_g) on a grid of ``shape``): Σ over axes of half
    the largest change between neighbouring feasible grid points."""
    grid = values.reshape((values.shape[0], *shape))
    gain = np.zeros(values.shape[0])
    for axis in range(1, grid.ndim):
        if grid.shape[axis] < 2:
            continue
        a = np.take(grid, range(grid.shape[axis] - 1), axis=axis)
        b = np.take(grid, range(1, grid.shape[axis]), axis=axis)
        diff = np.where(np.isfinite(a) & np.isfinite(b), np.abs(a - b), 0.0)
        gain += 0.5 * diff.reshape(values.shape[0], -1).max(axis=1, initial=0.0)
    return gain


def screen(problem: Problem, designer: Any, parameters: Mapping[str, float]) -> Screen:
    """Screen every part of the problem's single directly attached slot (see the module docstring).

    ``parameters``: any part's parameters (only the scenario's base values and gravity are used).
    """
    structure = _structure(problem)
    if isinstance(structure, str):
        return Screen(False, structure)
    slot_name, springs, cables, grid_names, geometry = structure
    slot = problem.slots[0]
    if len(springs) > 2:
        return Screen(False, "screening covers one or two springs per slot")
    f = designer.formulation
    p = f.parameters.values(parameters)
    gravity, base = f.parameters.scenario_values(p)[problem.scenarios[0].name]
    base = dict(base)
    base[slot_name] = 0.0
    base[f"{slot_name}:initial_tension"] = 0.0
    subsystem = springs[0].subsystem
    if any(s.subsystem != subsystem for s in springs):
        return Screen(False, "screening needs the slot's springs in one subsystem")
    reference = designer.reference[True] or designer.reference[False] or 1.0
    if any(problem.coordinate[c.name].unit.dimension != "" for c in problem.subsystem_coordinates(subsystem)) and any(
        problem.coordinate[c.name].unit.dimension == "" for c in problem.subsystem_coordinates(subsystem)
    ):
        return Screen(False, "screening needs coordinates of one kind (all revolute or all prismatic)")
    q = _screen_configurations(problem, subsystem, problem.settings.seed + 17)
    parts = _part_arrays(slot)
    n_parts = len(slot.catalogue)
    home = {v.name: v.initial for v in problem.variables}
    cable_box = {s.name: ((problem.variable[cables[s.name]].lower, problem.variable[cables[s.name]].upper) if s.name in cables else None) for s in springs}
    if len(springs) == 1:
        return _screen_one(problem, springs[0], q, grid_names, base, gravity, home, cables, cable_box, parts, n_parts, reference, subsystem)
    own = [sorted(g - set(cables.values())) for g in geometry]
    if set(own[0]) & set(own[1]) or set(grid_names) - set(own[0]) - set(own[1]) or len(own[0]) != len(own[1]):
        return Screen(False, "pair screening needs each spring's geometry variables of its own")
    return _screen_pairs(problem, springs, q, own, base, gravity, home, cables, cable_box, parts, n_parts, reference, subsystem)


def _fixed_cable(problem: Problem, spring: Any, base: Mapping[str, float], gravity: Sequence[float], home: Mapping[str, float]) -> float:
    mech = Mechanics(problem, base, dict(home), {c.name: c.home for c in problem.coordinates}, gravity)
    return float(mech.value(spring.direct.cable))


def _ls_values(gflat, aflat, bflat, bb, ab, gb, k, t_lo, t_hi, i, j) -> tuple[np.ndarray, np.ndarray]:
    """Worst residual with the least-squares offset clipped into its interval (a feasible
    offset: an upper estimate of the pair's best), for parts ``i`` at geometries ``j``."""
    t = np.clip((gb[j] + k[i] * ab[j]) / np.maximum(bb[j], 1e-300), t_lo, t_hi)
    r = gflat[j] + k[i, None] * aflat[j] - t[:, None] * bflat[j]
    return t, np.abs(r).max(axis=1)


def _one_spring_arrays(problem, spring, q, variables, base, gravity, reference, subsystem):
    g, springs = _arrays(problem, subsystem, q, variables, base, gravity, [spring])
    d, grad = springs[spring.name]
    n_g = d.shape[0]
    gflat = np.broadcast_to(g.reshape(g.shape[0], -1), (n_g, g.shape[1] * g.shape[2])) / reference
    aflat = (d[:, :, None] * grad).reshape(n_g, -1) / reference
    bflat = grad.reshape(n_g, -1) / reference
    dots = (np.einsum("gm,gm->g", bflat, bflat), np.einsum("gm,gm->g", aflat, bflat), np.einsum("gm,gm->g", gflat, bflat))
    return d, gflat, aflat, bflat, dots


def _screen_one(problem, spring, q, grid_names, base, gravity, home, cables, cable_box, parts, n_parts, reference, subsystem) -> Screen:
    values, axes = _grid(problem, grid_names, GRID_POINTS)
    n_g = len(next(iter(values.values()))) if values else 1
    variables = {**{k: np.full(n_g, v) for k, v in home.items()}, **values}
    d, gflat, aflat, bflat, (bb, ab, gb) = _one_spring_arrays(problem, spring, q, variables, base, gravity, reference, subsystem)
    box = cable_box[spring.name] or (_fixed_cable(problem, spring, base, gravity, home),) * 2
    rows = np.arange(n_parts)
    k = parts["k"]
    t_lo, t_hi = _offset_interval(parts, rows, d.min(axis=1), d.max(axis=1), box)
    feasible = t_lo <= t_hi
    value = np.full((n_parts, n_g), np.inf)
    pr, gr = np.nonzero(feasible)
    for s in range(0, len(pr), CHUNK_PAIRS):
        i, j = pr[s : s + CHUNK_PAIRS], gr[s : s + CHUNK_PAIRS]
        _, value[i, j] = _ls_values(gflat, aflat, bflat, bb, ab, gb, k, t_lo[i, j], t_hi[i, j], i, j)
    best = np.argmin(value, axis=1)
    ratio = value[rows, best]
    evaluated = len(pr)
    # zoom: around each part's best point, a 3^n grid at half the spacing, repeatedly
    centre = np.array([[variables[v][b] for v in grid_names] for b in best]) if grid_names else np.zeros((n_parts, 0))
    step = np.array([(a[1] - a[0]) / 2 if len(a) > 1 else 0.0 for a in axes])
    lower = np.array([problem.variable[v].lower for v in grid_names])
    upper = np.array([problem.variable[v].upper for v in grid_names])
    live = np.flatnonzero(np.isfinite(ratio))
    offsets = np.array(list(np.ndindex(*([3] * len(grid_names))))) - 1 if grid_names else np.zeros((1, 0))
    best_t = np.full(n_parts, np.nan)
    for _ in range(ZOOM_ROUNDS):
        if not live.size or not grid_names:
            break
        pts = np.clip(centre[live][:, None, :] + offsets[None, :, :] * step, lower, upper)  # (L, 3^n, n)
        flat = pts.reshape(-1, len(grid_names))
        n_z = flat.shape[0]
        zv = {**{v: np.full(n_z, x) for v, x in home.items()}, **{v: flat[:, c] for c, v in enumerate(grid_names)}}
        dz, gz, az, bz, (bbz, abz, gbz) = _one_spring_arrays(problem, spring, q, zv, base, gravity, reference, subsystem)
        owner = np.repeat(live, offsets.shape[0])
        lo_z, hi_z = _offset_pairs(parts, owner, dz.min(axis=1), dz.max(axis=1), box)
        ok = lo_z <= hi_z
        vz = np.full(n_z, np.inf)
        jj = np.flatnonzero(ok)
        _, vz[jj] = _ls_values(gz, az, bz, bbz, abz, gbz, k, lo_z[jj], hi_z[jj], owner[jj], jj)
        evaluated += len(jj)
        vz = vz.reshape(len(live), -1)
        pick = np.argmin(vz, axis=1)
        better = vz[np.arange(len(live)), pick] < ratio[live]
        ratio[live[better]] = vz[np.arange(len(live)), pick][better]
        centre[live[better]] = pts[np.arange(len(live)), pick][better]
        step = step / 2
    # the exact offset (bisection) at each part's best point
    if live.size:
        cv = {**{v: np.full(len(live), x) for v, x in home.items()}, **{v: centre[live, c] for c, v in enumerate(grid_names)}}
        dz, gz, az, bz, _ = _one_spring_arrays(problem, spring, q, cv, base, gravity, reference, subsystem)
        idx = np.arange(len(live))
        lo_z, hi_z = _offset_pairs(parts, live, dz.min(axis=1), dz.max(axis=1), box)
        t, v = best_offset(gz + k[live, None] * az, bz, lo_z, np.maximum(lo_z, hi_z))
        ratio[live] = np.minimum(ratio[live], v)
        best_t[live] = t
    start = []
    for i in range(n_parts):
        design = {v: float(centre[i, c]) for c, v in enumerate(grid_names)}
        if spring.name in cables and np.isfinite(best_t[i]):
            design[cables[spring.name]] = float((best_t[i] + parts["f0"][i]) / k[i] - parts["l0"][i])
        start.append(design)
    return Screen(True, "", ratio, np.full(n_parts, -np.inf), start, n_g, q.shape[0], False, int(evaluated), int((~np.isfinite(ratio)).sum()))


def _screen_pairs(problem, springs, q, own, base, gravity, home, cables, cable_box, parts, n_parts, reference, subsystem) -> Screen:
    """Two springs of one part, each with its own geometry variables: all unordered pairs of grid geometries."""
    per = []
    for s, names in zip(springs, own):
        values, axes = _grid(problem, names, PAIR_GRID_POINTS)
        n_g = len(next(iter(values.values()))) if values else 1
        variables = {**{k: np.full(n_g, v) for k, v in home.items()}, **values}
        g, arr = _arrays(problem, subsystem, q, variables, base, gravity, [s])
        d, grad = arr[s.name]
        per.append((values, n_g, d, grad, g))
    # G does not depend on the springs' own variables: take it from the first grid's first point
    gflat = per[0][4][0].reshape(-1) / reference
    same = all(np.array_equal(per[0][0][a], per[1][0][b]) for a, b in zip(own[0], own[1])) and per[0][2].shape == per[1][2].shape
    n_g = per[0][1]
    if same:
        i1, i2 = np.triu_indices(n_g)
    else:
        i1, i2 = (x.ravel() for x in np.meshgrid(np.arange(per[0][1]), np.arange(per[1][1]), indexing="ij"))
    a1 = (per[0][2][:, :, None] * per[0][3]).reshape(per[0][1], -1) / reference
    a2 = (per[1][2][:, :, None] * per[1][3]).reshape(per[1][1], -1) / reference
    b1 = per[0][3].reshape(per[0][1], -1) / reference
    b2 = per[1][3].reshape(per[1][1], -1) / reference
    boxes = [cable_box[s.name] or (_fixed_cable(problem, s, base, gravity, home),) * 2 for s in springs]
    rows = np.arange(n_parts)
    lo1, hi1 = _offset_interval(parts, rows, per[0][2].min(axis=1), per[0][2].max(axis=1), boxes[0])
    lo2, hi2 = _offset_interval(parts, rows, per[1][2].min(axis=1), per[1][2].max(axis=1), boxes[1])
    ok1, ok2 = lo1 <= hi1, lo2 <= hi2
    ratio = np.full(n_parts, np.inf)
    gain = np.zeros(n_parts)
    start: list[dict[str, float]] = [{} for _ in range(n_parts)]
    evaluated = 0
    # per part: the pairs both of whose geometries are feasible
    b11 = np.einsum("gm,gm->g", b1, b1)
    b22 = np.einsum("gm,gm->g", b2, b2)
    for i in range(n_parts):
        mask = ok1[i, i1] & ok2[i, i2]
        if not mask.any():
            continue
        j1, j2 = i1[mask], i2[mask]
        k = parts["k"][i]
        a = gflat[None, :] + k * (a1[j1] + a2[j2])
        # least squares for (T1, T2): minimise |a − T1 b1 − T2 b2|², then clipped into the boxes
        s11, s22 = b11[j1], b22[j2]
        s12 = np.einsum("pm,pm->p", b1[j1], b2[j2])
        r1 = np.einsum("pm,pm->p", a, b1[j1])
        r2 = np.einsum("pm,pm->p", a, b2[j2])
        det = s11 * s22 - s12 * s12
        det = np.where(np.abs(det) > 1e-300, det, 1e-300)
        t1 = np.clip((r1 * s22 - r2 * s12) / det, lo1[i, j1], hi1[i, j1])
        t2 = np.clip((r2 - s12 * t1) / np.maximum(s22, 1e-300), lo2[i, j2], hi2[i, j2])
        v = np.abs(a - t1[:, None] * b1[j1] - t2[:, None] * b2[j2]).max(axis=1)
        evaluated += len(v)
        best = int(np.argmin(v))
        ratio[i] = v[best]
        design = {n: float(per[0][0][n][j1[best]]) for n in own[0]}
        design.update({n: float(per[1][0][n][j2[best]]) for n in own[1]})
        for s, t in zip(springs, (t1[best], t2[best])):
            if s.name in cables:
                design[cables[s.name]] = float((t + parts["f0"][i]) / k - parts["l0"][i])
        start[i] = design
    return Screen(True, "", ratio, np.full(n_parts, -np.inf), start, n_g, q.shape[0], True, evaluated, int((~np.isfinite(ratio)).sum()))


def screened_order(screen: Screen) -> np.ndarray:
    """Parts with a feasible grid design, most promising (smallest screened ratio) first."""
    finite = np.flatnonzero(np.isfinite(screen.ratio))
    return finite[np.argsort(screen.ratio[finite], kind="stable")]


