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

Several scenarios (a payload range's samples, working modes) are screened together: each
scenario's configurations follow the previous one's in the arrays (the part, its offset and
the geometry are common to all; adjustable variables are not screened).

From each part's best grid design a compass search (vectorised over parts) improves its
geometry. A part's *screened ratio* is that of a real design (its lengths within limits on
the screening configurations), not a lower bound; the certified bound is :mod:`.bounds`
(docs/catalogues.md says what each guarantees).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..mechanics import NUMPY_FUNCTIONS, Mechanics
from ..mechanics.kinematics import dot, sub
from ..model import expr as ex
from ..model.elements import ZeroFreeLengthSpring
from ..model.parts import SpringSlot
from ..model.problem import Problem
from ..mechanics.sampling import STEP
from ..verify.residuals import frame_names

#: geometry grid points of one spring's screening (all axes together), at most
GRID_POINTS = 1728
#: per-spring grid points when pairs of geometries are screened (pairs grow as its square)
PAIR_GRID_POINTS = 125
#: configurations per subsystem on which parts are screened (a uniform grid for one coordinate)
SCREEN_CONFIGURATIONS = 25
#: compass-search rounds from each part's best grid design (each: ± a step along every
#: geometry variable; the step halves when no move improves)
COMPASS_ROUNDS = 14
#: bisection steps of the exact one-dimensional offset (interval shrinks by 2**-steps)
BISECTION_STEPS = 30
#: (part, geometry) pairs evaluated at once (memory bound)
CHUNK_PAIRS = 20000
#: after each compass round, parts whose screened ratio exceeds this multiple of the best
#: part's stop moving (they keep the ratio reached)
COMPASS_KEEP = 4.0
#: Gram determinants below this are singular (the two springs' offset directions coincide)
SINGULAR = 1e-300


@dataclass
class Screen:
    """Per part (catalogue row): screened ratio and its screened design."""

    supported: bool
    reason: str = ""
    ratio: np.ndarray = field(default_factory=lambda: np.zeros(0))  # inf: no feasible grid design
    start: list[dict[str, float]] = field(default_factory=list)  # variable -> value of the best grid design
    geometries: int = 0
    configurations: int = 0
    pairs: bool = False
    evaluated: int = 0  # (part, geometry) combinations screened
    infeasible: int = 0  # parts with no grid geometry within their lengths
    pruned_by: dict[str, int] = field(default_factory=dict)  # limit -> parts pruned by it (screening)
    context: Any = None  # the screening's arrays and parts (for the bound of .bounds)


def _names_of(problem: Problem, point: Any, frames: Mapping[str, frozenset[str]]) -> set[str]:
    return set().union(*(ex.names(t) for t in point.position)) | set(frames[point.frame])


def _structure(problem: Problem, slot: SpringSlot, exclude: frozenset[str], grid_only: frozenset[str] | None) -> tuple[str, list[Any], dict[str, str], list[str], list[set[str]], set[str]] | str:
    """(slot, its springs, spring -> cable variable, grid variables, per-spring geometry
    variables, variables the rest of the mechanism depends on),
    or the reason screening does not apply. ``exclude``: springs left out of the rest (they
    do not act on the screened rows); ``grid_only``: the variables that can matter (None: all)."""
    if len(problem.scenarios) > 1 and any(v.adjustable for v in problem.variables):
        return "screening needs design variables shared by every scenario (none adjustable)"
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
        if s.slot != slot.name and s.name not in exclude:
            other |= (_names_of(problem, s.ends[0], frames) | _names_of(problem, s.ends[1], frames) | ex.names(s.stiffness)) & variables
    cables: dict[str, str] = {}
    for s in springs:
        if s.direct is None:  # excluded above
            continue
        names = ex.names(s.direct.cable) & variables
        if isinstance(s.direct.cable, ex.Name) and names:
            cables[s.name] = s.direct.cable.id
        elif names:
            return "screening needs each cable to be a variable of its own or fixed"
        for v in names:
            used[v] = used.get(v, 0) + 1
    for v in cables.values():
        if used[v] > 1 or v in other or any(v in g for g in geometry):
            return f"cable variable {v} also sets other lengths"
    grid = sorted((variables if grid_only is None else variables & grid_only) - set(cables.values()))
    if grid_only is not None:
        other &= grid_only
    return slot.name, springs, cables, grid, geometry, other


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
    from ..mechanics.sampling import configurations

    return configurations(problem, subsystem, SCREEN_CONFIGURATIONS * len(coords), np.random.default_rng(seed))


def energy_arrays(
    problem: Problem,
    subsystem: str,
    q: np.ndarray,
    variables: Mapping[str, np.ndarray],
    base: Mapping[str, float],
    gravity: Sequence[float],
    springs: Sequence[Any],
    rest: bool = True,
    exclude: frozenset[str] = frozenset(),
    columns: np.ndarray | None = None,
) -> tuple[np.ndarray | None, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """G (n_g, N, n_q): ∂V/∂q of everything but ``springs`` and ``exclude`` (None unless
    ``rest``), and per spring of ``springs`` (d (n_g, N), ∂d/∂q (n_g, N, n_q)), by complex
    step; ``columns``: only these coordinates' derivatives (their indices in the subsystem)."""
    names = [c.name for c in problem.subsystem_coordinates(subsystem)]
    n, n_q = q.shape
    stacked = np.tile(q.astype(complex), (n_q, 1))
    for j in range(n_q):
        stacked[j * n : (j + 1) * n, j] += 1j * STEP
    coords: dict[str, np.ndarray | float] = {name: stacked[None, :, i] for i, name in enumerate(names)}
    coords.update({c.name: c.home for c in problem.coordinates if c.name not in coords})
    var = {k: np.asarray(v, dtype=float)[:, None] for k, v in variables.items()}
    n_g = max((len(v) for v in variables.values()), default=1)
    mech = Mechanics(problem, base, var, coords, gravity, NUMPY_FUNCTIONS)
    g = None
    if rest:
        mine = {s.name for s in springs}
        terms = [mech.gravity_energy(mech.value(b.mass), b.com) for b in problem.bodies if b.subsystem == subsystem]
        terms += [mech.gravity_energy(mech.value(c.mass), c.position) for c in problem.counter_masses if c.subsystem == subsystem]
        terms += [mech.spring_energy(s) for s in problem.springs if s.subsystem == subsystem and s.name not in mine and s.name not in exclude]
        energy = np.broadcast_to(np.asarray(sum(terms), dtype=complex), (n_g, n * n_q))
        g = (energy.imag / STEP).reshape(n_g, n_q, n).transpose(0, 2, 1)
        if columns is not None:
            g = g[:, :, columns]
    out = {}
    for s in springs:
        d = sub(mech.position(s.ends[0]), mech.position(s.ends[1]))
        squared = np.broadcast_to(np.asarray(dot(d, d), dtype=complex), (n_g, n * n_q))
        length = np.sqrt(np.maximum(squared.real[:, :n], 0.0))
        grad = (squared.imag / STEP).reshape(n_g, n_q, n).transpose(0, 2, 1) / (2 * np.maximum(length, 1e-12)[:, :, None])
        out[s.name] = (length, grad if columns is None else grad[:, :, columns])
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


def _part_arrays(slot: SpringSlot) -> dict[str, np.ndarray]:
    a = slot.catalogue.arrays
    k, l0, f0 = a["rate"], a["free_length"], a["initial_tension"]
    lmax = np.minimum(a["max_length"], l0 + (a["max_load"] - f0) / k)
    return {"k": k, "l0": l0, "f0": f0, "lmax": lmax, "max_load": a["max_load"], "max_length": a["max_length"]}


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


def _prune_reasons(p: Mapping[str, np.ndarray], rows: np.ndarray, d_min: np.ndarray, d_max: np.ndarray, cable: tuple[float, float]) -> dict[str, int]:
    """Why each part of ``rows`` fits no grid geometry: at its least infeasible geometry, the
    spring cannot reach its free length with the shortest cable (``free length``), or its
    stroke / the longest cable stretches it beyond the longest admissible length, set by its
    ``max length`` or by its ``max load``."""
    out: dict[str, int] = {}
    if not rows.size:
        return out
    k, l0, f0, lmax = (p[x][rows, None] for x in ("k", "l0", "f0", "lmax"))
    c_lo = np.maximum(cable[0], d_max[None, :] - lmax)
    c_hi = np.minimum(cable[1], d_min[None, :] - l0)
    g = np.argmin(c_lo - c_hi, axis=1)
    i = np.arange(len(rows))
    short = (d_min[g] - l0[:, 0]) < cable[0]
    stroke = (d_max[g] - lmax[:, 0]) > (d_min[g] - l0[:, 0])
    by_load = (l0 + (p["max_load"][rows, None] - f0) / k)[:, 0] < p["max_length"][rows]
    label = np.where(short & ~stroke, "free length", np.where(by_load, "max load", "max length"))
    for name in label[i]:
        out[str(name)] = out.get(str(name), 0) + 1
    return out


@dataclass
class _Context:
    problem: Problem
    springs: list[Any]
    q: np.ndarray
    base: dict[str, float]
    gravity: Sequence[float]
    home: dict[str, float]
    cables: dict[str, str]
    boxes: list[tuple[float, float]]
    parts: dict[str, np.ndarray]
    reference: float
    subsystem: str
    names: list[str]  # geometry variables searched
    rest_fixed: bool  # G does not depend on the geometry variables (computed once)
    #: residual rows screened: these coordinates' (indices in the subsystem; None: all) ...
    columns: np.ndarray | None = None
    #: ... on which these springs (of other slot groups) do not act: left out of G
    exclude: frozenset[str] = frozenset()
    #: the further scenarios' (base, gravity): their configurations follow the first's
    others: tuple[tuple[dict[str, float], Sequence[float]], ...] = ()
    _rest: np.ndarray | None = None

    def arrays(self, designs: Mapping[str, np.ndarray], springs: Sequence[Any] | None = None) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
        """G (n, M) and per spring (d (n, N), A = d ∂d/∂q (n, M), B = ∂d/∂q (n, M)), scaled by the
        reference; with several scenarios, each scenario's configurations one after the other."""
        n = len(next(iter(designs.values()))) if designs else 1
        variables = {**{k: np.full(n, v) for k, v in self.home.items()}, **designs}
        springs = self.springs if springs is None else springs
        scenarios = [(self.base, self.gravity), *self.others]
        if self.rest_fixed and self._rest is None:
            home = {k: np.array([v]) for k, v in self.home.items()}
            rest = [energy_arrays(self.problem, self.subsystem, self.q, home, b, g, self.springs, True, self.exclude, self.columns)[0] for b, g in scenarios]
            self._rest = np.concatenate([g.reshape(1, -1) for g in rest], axis=1) / self.reference  # type: ignore[union-attr]  # energy_arrays gives G with rest=True
        parts = [energy_arrays(self.problem, self.subsystem, self.q, variables, b, g, springs, not self.rest_fixed, self.exclude, self.columns) for b, g in scenarios]
        if self.rest_fixed:
            gflat = np.broadcast_to(self._rest, (n, self._rest.shape[1]))  # type: ignore[arg-type, union-attr]  # set above whenever rest_fixed
        else:
            flat = [np.broadcast_to(g.reshape(g.shape[0], -1), (n, g.shape[1] * g.shape[2])) for g, _ in parts]  # type: ignore[union-attr]  # G is given with rest=True (not rest_fixed)
            gflat = (flat[0] if len(flat) == 1 else np.concatenate(flat, axis=1)) / self.reference
        out = []
        for s in springs:
            if len(parts) == 1:
                d, grad = parts[0][1][s.name]
            else:
                d = np.concatenate([np.broadcast_to(arr[s.name][0], (n, arr[s.name][0].shape[1])) for _, arr in parts], axis=1)
                grad = np.concatenate([np.broadcast_to(arr[s.name][1], (n, *arr[s.name][1].shape[1:])) for _, arr in parts], axis=1)
            out.append((d, (d[:, :, None] * grad).reshape(n, -1) / self.reference, grad.reshape(n, -1) / self.reference))
        return gflat, out

    def evaluate(self, rows: np.ndarray, designs: Mapping[str, np.ndarray], exact: bool = False) -> tuple[np.ndarray, list[np.ndarray]]:
        """Worst screened residual ratio of part ``rows[i]`` at design i, and each spring's offset.

        One spring: the offset is exact (bisection) when ``exact``, else least squares clipped
        into its interval; two springs: least squares clipped. inf: outside the part's lengths."""
        gflat, arr = self.arrays(designs)
        k = self.parts["k"][rows]
        a = gflat + k[:, None] * sum(x[1] for x in arr)
        bounds = [_offset_pairs(self.parts, rows, d.min(axis=1), d.max(axis=1), box) for (d, _, _), box in zip(arr, self.boxes)]
        ok = np.all([lo <= hi for lo, hi in bounds], axis=0)
        bs = [x[2] for x in arr]
        if len(bs) == 1:
            lo, hi = bounds[0]
            hi = np.maximum(lo, hi)
            if exact:
                t, value = best_offset(a, bs[0], lo, hi)
            else:
                t = np.clip(np.einsum("nm,nm->n", a, bs[0]) / np.maximum(np.einsum("nm,nm->n", bs[0], bs[0]), SINGULAR), lo, hi)
                value = np.abs(a - t[:, None] * bs[0]).max(axis=1)
            offsets = [t]
        else:
            gram = {(i, j): np.einsum("nm,nm->n", bs[i], bs[j]) for i in range(2) for j in range(i, 2)}
            rhs = [np.einsum("nm,nm->n", a, b) for b in bs]
            t1, t2 = _two_offsets(gram[(0, 0)], gram[(1, 1)], gram[(0, 1)], rhs[0], rhs[1], bounds)
            value = np.abs(a - t1[:, None] * bs[0] - t2[:, None] * bs[1]).max(axis=1)
            offsets = [t1, t2]
        return np.where(ok, value, np.inf), offsets

    def compass(self, rows: np.ndarray, centre: np.ndarray, value: np.ndarray, step: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
        """Compass search of each part's design from ``centre`` (n, n_vars); returns (centre, value, evaluations)."""
        n_v = len(self.names)
        lower = np.array([self.problem.variable[v].lower for v in self.names])
        upper = np.array([self.problem.variable[v].upper for v in self.names])
        moves = np.vstack([np.eye(n_v), -np.eye(n_v)])
        step = np.tile(step, (len(rows), 1))
        count = 0
        for _ in range(COMPASS_ROUNDS):
            moving = np.flatnonzero(value <= COMPASS_KEEP * value.min(initial=np.inf))
            trial = np.clip(centre[moving, None, :] + moves[None, :, :] * step[moving, None, :], lower, upper)  # (n, 2 n_v, n_v)
            flat = trial.reshape(-1, n_v)
            owner = np.repeat(rows[moving], 2 * n_v)
            v, _ = self.evaluate(owner, {name: flat[:, c] for c, name in enumerate(self.names)})
            count += len(v)
            v = v.reshape(len(moving), -1)
            pick = np.argmin(v, axis=1)
            best = v[np.arange(len(moving)), pick]
            better = best < value[moving]
            centre[moving[better]] = trial[np.arange(len(moving)), pick][better]
            value[moving[better]] = best[better]
            step[moving[~better]] /= 2
        return centre, value, count

    def finish(self, rows: np.ndarray, centre: np.ndarray, n_parts: int) -> tuple[np.ndarray, list[dict[str, float]]]:
        """Screened ratio (exact offset for one spring) and the design (cables included) of each part."""
        ratio = np.full(n_parts, np.inf)
        start: list[dict[str, float]] = [{} for _ in range(n_parts)]
        if not rows.size:
            return ratio, start
        designs = {name: centre[:, c] for c, name in enumerate(self.names)}
        value, offsets = self.evaluate(rows, designs, exact=True)
        ratio[rows] = value
        k, f0, l0 = (self.parts[x][rows] for x in ("k", "f0", "l0"))
        for n, i in enumerate(rows):
            design = {name: float(centre[n, c]) for c, name in enumerate(self.names)}
            for s, t in zip(self.springs, offsets):
                if s.name in self.cables and np.isfinite(t[n]):
                    design[self.cables[s.name]] = float((t[n] + f0[n]) / k[n] - l0[n])
            start[i] = design
        return ratio, start


def _two_offsets(
    s11: np.ndarray, s22: np.ndarray, s12: np.ndarray, r1: np.ndarray, r2: np.ndarray, bounds: Sequence[tuple[ArrayLike, ArrayLike]]
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares offsets of two springs, clipped into their intervals (the second
    re-solved for the clipped first)."""
    (lo1, hi1), (lo2, hi2) = bounds
    det = s11 * s22 - s12 * s12
    det = np.where(np.abs(det) > SINGULAR, det, SINGULAR)
    t1 = np.clip((r1 * s22 - r2 * s12) / det, lo1, np.maximum(lo1, hi1))
    t2 = np.clip((r2 - s12 * t1) / np.maximum(s22, SINGULAR), lo2, np.maximum(lo2, hi2))
    return t1, t2


def screen(
    problem: Problem,
    designer: Any,
    parameters: Mapping[str, float],
    slot: str | None = None,
    coordinates: frozenset[str] | None = None,
    exclude: frozenset[str] = frozenset(),
    variables: frozenset[str] | None = None,
) -> Screen:
    """Screen every part of a directly attached slot (see the module docstring).

    ``parameters``: the parameters of any part of ``slot`` (only the scenario's base values
    and gravity are used; other slots' parts stay as given). ``slot``: the slot screened
    (default: the problem's only one). ``coordinates``: only these coordinates' residual
    rows are screened (a group of slots, :func:`.groups.direct_groups`), on which the
    springs ``exclude`` do not act (they are left out); ``variables``: the design variables
    those rows involve (the others are not gridded).
    """
    if slot is None and len(problem.slots) != 1:
        return Screen(False, "screening needs exactly one slot")
    chosen = problem.slots[0] if slot is None else next(s for s in problem.slots if s.name == slot)
    structure = _structure(problem, chosen, exclude, variables)
    if isinstance(structure, str):
        return Screen(False, structure)
    slot_name, springs, cables, grid_names, geometry, other = structure
    if len(springs) > 2:
        return Screen(False, "screening covers one or two springs per slot")
    subsystem = springs[0].subsystem
    if any(s.subsystem != subsystem for s in springs):
        return Screen(False, "screening needs the slot's springs in one subsystem")
    kinds = {problem.coordinate[c.name].unit.dimension == "" for c in problem.subsystem_coordinates(subsystem)}
    if len(kinds) != 1:
        return Screen(False, "screening needs coordinates of one kind (all revolute or all prismatic)")
    f = designer.formulation
    p = f.parameters.values(parameters)
    scenarios = []
    for scenario_gravity, scenario_base in f.parameters.scenario_values(p).values():
        scenario_base = dict(scenario_base)
        scenario_base[slot_name] = 0.0  # the slot's springs are added per part: G is the rest
        scenario_base[f"{slot_name}:initial_tension"] = 0.0
        scenarios.append((scenario_base, scenario_gravity))
    (base, gravity), others = scenarios[0], tuple(scenarios[1:])
    reference = designer.reference[next(iter(kinds))] or 1.0
    home = {v.name: v.initial for v in problem.variables}
    boxes = []
    for s in springs:
        if s.name in cables:
            v = problem.variable[cables[s.name]]
            boxes.append((v.lower, v.upper))
        else:
            c = _fixed_cable(problem, s, base, gravity, home)
            boxes.append((c, c))
    q = _screen_configurations(problem, subsystem, problem.settings.seed + 17)
    names = [c.name for c in problem.subsystem_coordinates(subsystem)]
    mine = exclude & {s.name for s in problem.springs if s.subsystem == subsystem}
    columns = None
    if coordinates is not None and (set(names) - coordinates or mine):
        columns = np.array([i for i, c in enumerate(names) if c in coordinates], dtype=int)
    ctx = _Context(problem, springs, q, base, gravity, home, cables, boxes, _part_arrays(chosen), reference, subsystem, grid_names, not other, columns, frozenset(mine), others)
    n_parts = len(chosen.catalogue)
    if len(springs) == 1:
        return _screen_one(ctx, n_parts)
    own = [sorted(g - set(cables.values())) for g in geometry]
    if set(own[0]) & set(own[1]) or set(grid_names) - set(own[0]) - set(own[1]) or other:
        return Screen(False, "pair screening needs each spring's geometry variables of its own")
    return _screen_pairs(ctx, own, n_parts)


def _fixed_cable(problem: Problem, spring: Any, base: Mapping[str, float], gravity: Sequence[float], home: Mapping[str, float]) -> float:
    mech = Mechanics(problem, base, dict(home), {c.name: c.home for c in problem.coordinates}, gravity)
    return float(mech.value(spring.direct.cable))


def _screen_one(ctx: _Context, n_parts: int) -> Screen:
    values, axes = _grid(ctx.problem, ctx.names, GRID_POINTS)
    n_g = len(next(iter(values.values()))) if values else 1
    gflat, [(d, aflat, bflat)] = ctx.arrays(values)
    bb, ab, gb = (np.einsum("gm,gm->g", x, bflat) for x in (bflat, aflat, gflat))
    rows = np.arange(n_parts)
    k = ctx.parts["k"]
    t_lo, t_hi = _offset_interval(ctx.parts, rows, d.min(axis=1), d.max(axis=1), ctx.boxes[0])
    value = np.full((n_parts, n_g), np.inf)
    pr, gr = np.nonzero(t_lo <= t_hi)
    for s in range(0, len(pr), CHUNK_PAIRS):
        i, j = pr[s : s + CHUNK_PAIRS], gr[s : s + CHUNK_PAIRS]
        t = np.clip((gb[j] + k[i] * ab[j]) / np.maximum(bb[j], SINGULAR), t_lo[i, j], t_hi[i, j])
        value[i, j] = np.abs(gflat[j] + k[i, None] * aflat[j] - t[:, None] * bflat[j]).max(axis=1)
    best = np.argmin(value, axis=1)
    live = np.flatnonzero(np.isfinite(value[rows, best]))
    centre = np.array([[values[v][b] for v in ctx.names] for b in best[live]]).reshape(len(live), len(ctx.names))
    step = np.array([(a[1] - a[0]) / 2 if len(a) > 1 else 0.0 for a in axes])
    centre, _, count = ctx.compass(live, centre, value[live, best[live]], step)
    ratio, start = ctx.finish(live, centre, n_parts)
    dead = np.setdiff1d(rows, live)
    reasons = _prune_reasons(ctx.parts, dead, d.min(axis=1), d.max(axis=1), ctx.boxes[0])
    return Screen(True, "", ratio, start, n_g, ctx.q.shape[0], False, int(len(pr)) + count, n_parts - len(live), reasons, ctx)


def _screen_pairs(ctx: _Context, own: list[list[str]], n_parts: int) -> Screen:
    """Two springs of one part, each with its own geometry variables: every unordered pair
    of grid geometries, per part, by the 2-norm of the residual with least-squares offsets
    (closed form from Gram matrices: one product per pair, O(1) per part and pair)."""
    grids = []
    for s, names in zip(ctx.springs, own):
        values, axes = _grid(ctx.problem, names, PAIR_GRID_POINTS)
        gflat, [(d, a, b)] = ctx.arrays(values, [s])
        grids.append((values, axes, d, a, b))
    g = gflat[0]  # the rest does not depend on the springs' own variables
    (v1, axes1, d1, a1, b1), (v2, axes2, d2, a2, b2) = grids
    same = len(own[0]) == len(own[1]) and all(np.array_equal(v1[x], v2[y]) for x, y in zip(own[0], own[1]))
    n1, n2 = len(d1), len(d2)
    i1, i2 = np.triu_indices(n1) if same else (x.ravel() for x in np.meshgrid(np.arange(n1), np.arange(n2), indexing="ij"))
    A = a1[i1] + a2[i2]
    B1, B2 = b1[i1], b2[i2]
    dot = lambda x, y: np.einsum("pm,pm->p", x, y)  # noqa: E731
    gg, ga, aa = float(g @ g), A @ g, dot(A, A)
    gb1, gb2, ab1, ab2 = B1 @ g, B2 @ g, dot(A, B1), dot(A, B2)
    s11, s22, s12 = dot(B1, B1), dot(B2, B2), dot(B1, B2)
    rows = np.arange(n_parts)
    lo1, hi1 = _offset_interval(ctx.parts, rows, d1.min(axis=1), d1.max(axis=1), ctx.boxes[0])
    lo2, hi2 = _offset_interval(ctx.parts, rows, d2.min(axis=1), d2.max(axis=1), ctx.boxes[1])
    pid = np.full((n1, n2), -1)
    pid[i1, i2] = np.arange(len(i1))
    best_pair = np.full(n_parts, -1)
    evaluated = 0
    ok1, ok2 = lo1 <= hi1, lo2 <= hi2
    for i in rows:
        f1, f2 = np.flatnonzero(ok1[i]), np.flatnonzero(ok2[i])
        if not f1.size or not f2.size:
            continue
        sel = pid[np.ix_(f1, f2)].ravel()
        sel = sel[sel >= 0]  # unordered pairs only, when the springs are alike
        if not sel.size:
            continue
        k = ctx.parts["k"][i]
        j1, j2 = i1[sel], i2[sel]
        r1, r2 = gb1[sel] + k * ab1[sel], gb2[sel] + k * ab2[sel]
        bounds = ((lo1[i, j1], hi1[i, j1]), (lo2[i, j2], hi2[i, j2]))
        t1, t2 = _two_offsets(s11[sel], s22[sel], s12[sel], r1, r2, bounds)
        norm = gg + 2 * k * ga[sel] + k * k * aa[sel] - 2 * t1 * r1 - 2 * t2 * r2 + t1 * t1 * s11[sel] + t2 * t2 * s22[sel] + 2 * t1 * t2 * s12[sel]
        evaluated += len(sel)
        best_pair[i] = sel[int(np.argmin(norm))]
    live = np.flatnonzero(best_pair >= 0)
    pairs = best_pair[live]
    centre = np.hstack([np.array([[v1[x][j] for x in own[0]] for j in i1[pairs]]).reshape(len(live), -1), np.array([[v2[x][j] for x in own[1]] for j in i2[pairs]]).reshape(len(live), -1)])
    names = own[0] + own[1]
    ctx.names = names
    value, _ = ctx.evaluate(live, {n: centre[:, c] for c, n in enumerate(names)})
    step = np.array([(a[1] - a[0]) / 2 if len(a) > 1 else 0.0 for a in (*axes1, *axes2)])
    centre, _, count = ctx.compass(live, centre, value, step)
    ratio, start = ctx.finish(live, centre, n_parts)
    dead = np.setdiff1d(rows, live)
    reasons = _prune_reasons(ctx.parts, dead, d1.min(axis=1), d1.max(axis=1), ctx.boxes[0])
    return Screen(True, "", ratio, start, len(i1), ctx.q.shape[0], True, evaluated + count, n_parts - len(live), reasons, ctx)


def screened_order(screen: Screen) -> np.ndarray:
    """Parts with a feasible screened design, most promising (smallest screened ratio) first."""
    finite = np.flatnonzero(np.isfinite(screen.ratio))
    return finite[np.argsort(screen.ratio[finite], kind="stable")]
