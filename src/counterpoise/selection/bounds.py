"""A certified lower bound, per part, on the worst residual ratio of a directly attached spring.

The worst ratio over every configuration is at least the worst over any finite subset of
them; the bound uses a subset of the minimax designer's own samples (so it is also a lower
bound on the designer's sampled ratio, not only on the true worst case). With one spring
(see :mod:`.screening`) the residual at configuration q and coordinate j is

    r_j(z, T) = G_j + k A_j(z) − T B_j(z),   A_j = u·u'_j,  B_j = u·u'_j / |u|,

with u = a − b the vector between the attachment points and u'_j = ∂u/∂q_j. When every
attachment coordinate is an affine expression of the geometry variables z and no frame
depends on them, u and u'_j are affine in z (exactly: u(z) = u(z₀) + U (z − z₀)), so over a
box of z of half-widths h, |u − u_c| ≤ ρ = Σ_i |U_i| h_i and |u'_j − u'_c| ≤ ρ'_j, whence

    |d − |u_c|| ≤ ρ,   |B_j − B_c| ≤ ΔB_j = 2 ρ (|u'_c| + ρ') / (2 |u_c| − ρ) + ρ'

(Dunkl–Williams: |u/|u| − v/|v|| ≤ 2 |u − v| / (|u| + |v|); infinite when ρ ≥ |u_c|). The offset T = k (c + L₀) − F₀
lies in the interval the cable's bounds and the part's lengths on the bound's configurations
allow (with d between |u_c| − ρ and |u_c| + ρ). Writing r_j = G_j + F B_j with F = k d − T the
spring's force (|k |u_c| − T| ≤ F_lim, the least of F₀ + k (L_max − L₀ + ρ), the force at the
longest length, and its largest value over the offset interval),
|r_j| ≥ |a_j − T b_j| − E_j with a_j = G_j + k |u_c| B_c, b_j = B_c and
E_j = k ρ (|B_c| + ΔB_j) + F_lim ΔB_j, and the cell's bound is min over that T interval of
max_j (|a_j − T b_j| − E_j), a convex function of T: bisection, then the value at the
interval's midpoint less max_j |b_j| × half its width (a rigorous lower bound of the
minimum). An empty T interval certifies that the part cannot stay within its lengths in
that cell. Branch and bound: every cell whose bound is below the threshold (the incumbent)
is split in 2ⁿ; a part's bound is the least over its leaves. The rest of the mechanism (G)
must not depend on the geometry variables.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..mechanics import NUMPY_FUNCTIONS, Mechanics
from ..mechanics.kinematics import sub
from ..mechanics.sampling import configurations
from ..model import expr as ex
from ..mechanics.sampling import STEP
from ..verify.residuals import frame_names

#: configurations per coordinate of the bound (a subset of the minimax designer's samples)
BOUND_CONFIGURATIONS = 16
#: initial cells per geometry axis
BOUND_CELLS = 3
#: bisection steps of the offset (the bound loses max|b| × the final half width)
BOUND_BISECTION = 16
#: (part, cell) pairs evaluated at once (memory bound)
BOUND_CHUNK = 4000
#: cells of all parts kept open at most (the lowest bounds are refined first beyond it)
BOUND_MAX_CELLS = 60000
#: slack on lengths and cable bounds (m): the NLP meets its constraints to its tolerance
LENGTH_SLACK = 1e-6
#: relative safety on each bound (floating-point rounding of the affine reconstruction)
ROUNDING = 1e-7


@dataclass
class Bounds:
    """Per part (catalogue row): a certified lower bound (inf: cannot stay within its lengths)."""

    value: np.ndarray
    cells: int  # (part, cell) bounds evaluated
    open_cells: int  # cells still below the threshold when the refinement stopped
    depth: int  # refinement levels reached
    seconds: float
    configurations: int = 0  # configurations the bound uses


def _affine(e: ex.Expr, variables: set[str]) -> bool:
    free = lambda x: not (ex.names(x) & variables)  # noqa: E731
    if isinstance(e, (ex.Num, ex.Name)):
        return True
    if isinstance(e, ex.Neg):
        return _affine(e.operand, variables)
    if isinstance(e, ex.BinOp):
        if e.op in "+-":
            return _affine(e.left, variables) and _affine(e.right, variables)
        if e.op == "*":
            return _affine(e.left, variables) and _affine(e.right, variables) and (free(e.left) or free(e.right))
        if e.op == "/":
            return _affine(e.left, variables) and free(e.right)
    return free(e)


def certifiable(ctx: Any) -> str:
    """Empty when the bound applies to the screening context, else why not."""
    if len(ctx.springs) != 1:
        return "the bound covers one spring per slot"
    if not ctx.rest_fixed:
        return "the rest of the mechanism depends on the geometry variables"
    if ctx.others:
        return "the bound covers a single scenario"
    variables = set(ctx.names)
    frames = frame_names(ctx.problem)
    for point in ctx.springs[0].ends:
        if frames[point.frame] & variables or not all(_affine(t, variables) for t in point.position):
            return "the attachment points are not affine in the geometry variables"
    return ""


def _samples(ctx: Any, designer: Any) -> np.ndarray:
    """The minimax designer's samples of the slot's subsystem (drawn as it draws them), a subset."""
    from ..designer.minimax import SAMPLES_PER_COORDINATE

    rng = np.random.default_rng(ctx.problem.settings.seed + 5)
    mine = None
    for block in designer.formulation.blocks:
        q = configurations(ctx.problem, block.subsystem, SAMPLES_PER_COORDINATE * len(block.coordinates), rng)
        if block.subsystem == ctx.subsystem and mine is None:
            mine = q
    if mine is None:  # not among the designer's blocks: the screening's own configurations
        return np.asarray(ctx.q)
    want = BOUND_CONFIGURATIONS * mine.shape[1]
    if len(mine) <= want:
        return mine
    order = np.lexsort(mine.T[::-1])
    return mine[order[np.unique(np.linspace(0, len(mine) - 1, want).round().astype(int))]]


def _vectors(ctx: Any, q: np.ndarray, designs: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """u (n_g, N, 3) and ∂u/∂q (n_g, N, n_q, 3) by complex step, at each design."""
    problem = ctx.problem
    names = [c.name for c in problem.subsystem_coordinates(ctx.subsystem)]
    n, n_q = q.shape
    stacked = np.tile(q.astype(complex), (n_q, 1))
    for j in range(n_q):
        stacked[j * n : (j + 1) * n, j] += 1j * STEP
    coords = {name: stacked[None, :, i] for i, name in enumerate(names)}
    coords.update({c.name: c.home for c in problem.coordinates if c.name not in coords})
    n_g = len(next(iter(designs.values())))
    var = {k: np.full((n_g, 1), v) for k, v in ctx.home.items()}
    var.update({k: np.asarray(v, dtype=float)[:, None] for k, v in designs.items()})
    mech = Mechanics(problem, ctx.base, var, coords, ctx.gravity, NUMPY_FUNCTIONS)
    s = ctx.springs[0]
    u = np.stack([np.broadcast_to(np.asarray(x, dtype=complex), (n_g, n * n_q)) for x in sub(mech.position(s.ends[0]), mech.position(s.ends[1]))], axis=-1)
    value = u.real[:, :n]
    grad = (u.imag / STEP).reshape(n_g, n_q, n, 3).transpose(0, 2, 1, 3)
    return value, grad


def part_bounds(ctx: Any, designer: Any, threshold: float, budget: float, rows: np.ndarray | None = None, max_depth: int | None = None) -> Bounds:
    """Certified lower bounds per part (see the module docstring), refined while a cell's
    bound is below ``threshold``, for at most ``budget`` (part, cell) bounds (deterministic,
    unlike a time limit) and ``max_depth`` levels."""
    t0 = time.perf_counter()
    q = _samples(ctx, designer)
    n, n_q = q.shape
    names = list(ctx.names)
    n_v = len(names)
    lower = np.array([ctx.problem.variable[v].lower for v in names])
    upper = np.array([ctx.problem.variable[v].upper for v in names])
    z0 = (lower + upper) / 2
    width = np.maximum(upper - lower, 1e-300)
    # u, u' at z0 and the exact affine directions U_i, U'_i (one design per variable)
    designs = {v: np.array([z0[i]] + [z0[i] + (width[i] if j == i else 0.0) for j in range(n_v)]) for i, v in enumerate(names)}
    u, du = _vectors(ctx, q, designs)
    if ctx.columns is not None:  # a group's rows only (selection.groups.direct_groups)
        du = du[:, :, ctx.columns]
        n_q = du.shape[2]
    u0, du0 = u[0], du[0]
    U = (u[1:] - u0) / width[:, None, None]  # (n_v, N, 3)
    dU = (du[1:] - du0) / width[:, None, None, None]  # (n_v, N, n_q, 3)
    from .screening import energy_arrays

    g, _ = energy_arrays(ctx.problem, ctx.subsystem, q, {k: np.array([v]) for k, v in ctx.home.items()}, ctx.base, ctx.gravity, ctx.springs, True, ctx.exclude, ctx.columns)
    G = g.reshape(-1) / ctx.reference  # type: ignore[union-attr]  # (N n_q,): energy_arrays gives G with rest=True
    norm_U = np.linalg.norm(U, axis=-1)  # (n_v, N)
    norm_dU = np.linalg.norm(dU, axis=-1)  # (n_v, N, n_q)
    p = ctx.parts
    n_parts = len(p["k"])
    rows = np.arange(n_parts) if rows is None else rows
    c_box = ctx.boxes[0]
    t_steps = np.arange(BOUND_CELLS) + 0.5
    mesh = np.meshgrid(*[lower[i] + width[i] * t_steps / BOUND_CELLS for i in range(n_v)], indexing="ij")
    centres0 = np.stack([m.ravel() for m in mesh], axis=-1) if n_v else np.zeros((1, 0))
    half0 = width / (2 * BOUND_CELLS)

    def cell_arrays(centre: np.ndarray, level: np.ndarray) -> tuple[np.ndarray, ...]:
        """Per cell: d_c ± ρ (C, N), b = B_c and the B error (C, M), scaled by the reference."""
        h = half0[None, :] / 2.0 ** level[:, None]  # (C, n_v)
        dz = centre - z0
        uc = u0[None] + np.einsum("pv,vnc->pnc", dz, U)  # (C, N, 3)
        duc = du0[None] + np.einsum("pv,vnjc->pnjc", dz, dU)  # (C, N, n_q, 3)
        rho = (h @ norm_U.reshape(n_v, -1)).reshape(len(centre), n) * (1 + ROUNDING)
        drho = (h @ norm_dU.reshape(n_v, -1)).reshape(len(centre), n, n_q) * (1 + ROUNDING)
        nu = np.linalg.norm(uc, axis=-1)
        ndu = np.linalg.norm(duc, axis=-1)
        B = np.einsum("pnc,pnjc->pnj", uc, duc) / np.maximum(nu, 1e-300)[:, :, None]
        # Dunkl–Williams: |u/|u| − v/|v|| ≤ 2 |u − v| / (|u| + |v|), and |u| ≥ |u_c| − ρ
        eB = np.where((rho < nu)[:, :, None], 2 * rho[:, :, None] * (ndu + drho) / np.maximum(2 * nu - rho, 1e-300)[:, :, None] + drho, np.inf)
        c = len(centre)
        return nu, rho, B.reshape(c, -1) / ctx.reference, eB.reshape(c, -1) / ctx.reference

    def evaluate(part: np.ndarray, cell: np.ndarray, arrays: tuple[np.ndarray, ...]) -> np.ndarray:
        """r_j = G_j + F B_j with F = k d − T the spring's force: over the cell
        |r_j| ≥ |G_j + (k d_c − T) B_j| − k ρ (|B_j| + ΔB_j) − F_lim ΔB_j, F_lim bounding |k d_c − T|."""
        nu, rho, B, eB = (x[cell] for x in arrays)
        k, l0, f0, lmax = (p[x][part] for x in ("k", "l0", "f0", "lmax"))
        c_lo = np.maximum(c_box[0], (nu - rho).max(axis=1) - lmax) - LENGTH_SLACK
        c_hi = np.minimum(c_box[1], (nu + rho).min(axis=1) - l0) + LENGTH_SLACK
        t_lo, t_hi = k * (c_lo + l0) - f0, k * (c_hi + l0) - f0
        kd = np.repeat(k[:, None] * nu, n_q, axis=1)  # (P, M), configuration-major like B
        rk = np.repeat(k[:, None] * rho, n_q, axis=1)
        # |k d_c − T| over the offset interval, and at most the force at the longest length
        f_lim = np.minimum((f0 + k * (lmax - l0 + LENGTH_SLACK))[:, None] + rk, np.maximum(np.abs(kd - t_lo[:, None]), np.abs(kd - t_hi[:, None])))
        a = G[None, :] + kd * B
        b = B
        with np.errstate(invalid="ignore"):
            e = np.nan_to_num(rk * (np.abs(B) + eB) + f_lim * eB, nan=np.inf)
        lo, hi = t_lo.copy(), np.maximum(t_lo, t_hi)
        idx = np.arange(len(part))
        for _ in range(BOUND_BISECTION):
            mid = 0.5 * (lo + hi)
            res = a - mid[:, None] * b
            j = np.argmax(np.abs(res) - e, axis=1)
            rising = np.sign(res[idx, j]) * (-b[idx, j]) > 0
            hi = np.where(rising, mid, hi)
            lo = np.where(rising, lo, mid)
        mid = 0.5 * (lo + hi)
        value = (np.abs(a - mid[:, None] * b) - e).max(axis=1) - np.abs(b).max(axis=1) * (hi - lo) / 2
        value = np.maximum(value, 0.0) * (1 - ROUNDING)
        return np.where(c_lo <= c_hi, value, np.inf)

    evaluated = 0  # (part, cell) bounds computed so far, against ``budget``

    def run(part: np.ndarray, centre: np.ndarray, level: np.ndarray, parent: np.ndarray) -> np.ndarray:
        """Each cell's bound; cells left when the time is up keep ``parent`` (their parent's, valid)."""
        key = np.round((centre - lower) / (half0 / 2.0 ** level[:, None]) if n_v else centre).astype(np.int64)
        _, first, cell = np.unique(np.column_stack([level, key]), axis=0, return_index=True, return_inverse=True)
        arrays = cell_arrays(centre[first], level[first])
        cell = cell.ravel()
        nonlocal evaluated
        out = parent.copy()
        for s in range(0, len(part), BOUND_CHUNK):
            if evaluated >= budget and (s or level[0] > 0):  # the first chunk always runs
                break
            evaluated += min(BOUND_CHUNK, len(part) - s)
            sl = slice(s, s + BOUND_CHUNK)
            out[sl] = evaluate(part[sl], cell[sl], arrays)
        return out

    part = np.repeat(rows, len(centres0))
    centre = np.tile(centres0, (len(rows), 1))
    level = np.zeros(len(part))
    bound = run(part, centre, level, np.zeros(len(part)))
    closed = np.full(n_parts, np.inf)  # least bound of each part's leaves at or above the threshold
    depth = 0
    children = np.array(np.meshgrid(*[[-0.5, 0.5]] * n_v, indexing="ij")).reshape(n_v, -1).T if n_v else np.zeros((1, 0))
    while True:
        done = bound >= threshold
        np.minimum.at(closed, part[done], bound[done])
        part, centre, level, bound = part[~done], centre[~done], level[~done], bound[~done]
        if not len(part) or not n_v or evaluated >= budget or (max_depth is not None and depth >= max_depth):
            break
        if len(part) * len(children) > BOUND_MAX_CELLS:
            keep = np.argsort(bound)[: BOUND_MAX_CELLS // len(children)]
            rest = np.setdiff1d(np.arange(len(part)), keep)
            np.minimum.at(closed, part[rest], bound[rest])  # left unrefined: their bound stands
            part, centre, level, bound = part[keep], centre[keep], level[keep], bound[keep]
        h = half0[None, :] / 2.0 ** level[:, None]
        centre = (centre[:, None, :] + children[None, :, :] * h[:, None, :]).reshape(-1, n_v)
        part = np.repeat(part, len(children))
        level = np.repeat(level + 1, len(children))
        bound = run(part, centre, level, np.repeat(bound, len(children)))
        depth += 1
    value = closed.copy()
    np.minimum.at(value, part, bound)
    value[np.setdiff1d(np.arange(n_parts), rows)] = np.nan  # not bounded
    return Bounds(value, evaluated, len(part), depth, time.perf_counter() - t0, n)
