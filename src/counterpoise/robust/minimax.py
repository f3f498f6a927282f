"""The robust design with geometry variables: a minimax NLP in CasADi, corners as scenarios.

When a free design variable moves a point (a spring end, a counter-mass lever), the
residual is no longer affine in the design and the counterpart is not convex. It is then
solved by IPOPT in epigraph form, every corner of the tolerance box a scenario of the
deviation parameters (:mod:`.perturb`):

    minimise objective(z) [+ weight · ρ]
    subject to −ρ ≤ r(q_s; z, δ_c)/T ≤ ρ   for every sampled q_s, coordinate and corner c
               (ρ ≤ limit in ``limit`` mode), bounds of z, masses and stiffnesses ≥ 0.

At each sampled configuration the residual is affine in the deviations, so its largest
absolute value over the box lies at a corner: the corners make the worst case exact (box
shape). An ellipsoid holds |r₀| + ‖s‖₂ ≤ ρ T instead (first order, exact without products
of one element's deviations; with them, its bounding box, said so). Initial-tension tolerances are
not in the NLP (their term depends on the geometry through |∂d/∂q|); the reported band,
measured afterwards, includes them. A directly attached spring also keeps its length within
L0 + slack margin ≤ d − c ≤ L_max at every sample and every corner of its own point deviations
(:mod:`.direct`), as the nominal minimax designer does; its residual is not affine in those
point deviations, so the corners are then a sampled minimax, not an exact worst case. A local
optimum, started from the nominal design.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..solvers.base import Bounds, Status
from ..solvers.ipopt import IPOPT_DEFAULTS, IpoptBackend
from .affine import Decomposition
from .constraints import CornerConstraints
from .direct import DirectLengths

#: configurations per coordinate and block in the NLP (× corners: its rows)
SAMPLES_PER_COORDINATE = 48
#: corners enumerated at most (2ⁿ for n deviations)
MAX_CORNERS = 1024
#: random designs at which two rows must agree bit for bit to count as one (:meth:`RobustMinimax._distinct`)
REPEAT_PROBES = 2
#: the ellipsoid's ‖s‖₂ is √(Σ s² + (ELLIPSOID_FLOOR·T)²): differentiable where every change
#: vanishes, conservative by at most this share of the reference torque
ELLIPSOID_FLOOR = 1e-9


@dataclass(frozen=True)
class MinimaxResult:
    z: np.ndarray
    status: Status
    solver_status: str
    ratio: float
    seconds: float
    iterations: int


def first_of_repeats(values: np.ndarray) -> list[int]:
    """The rows of ``values`` (rows × probes) that do not repeat an earlier row bit for bit,
    in order: of each set of equal rows, the first. A row with a value that is not finite
    at a probe is kept whatever it equals (NaN compares with nothing)."""
    finite = np.all(np.isfinite(values), axis=1)
    index = np.flatnonzero(finite)
    _, first = np.unique(values[finite], axis=0, return_index=True)
    return sorted([int(index[i]) for i in first] + [int(i) for i in np.flatnonzero(~finite)])


class RobustMinimax:
    """The minimax NLP of a decomposition (built once per mode)."""

    def __init__(
        self, decomposition: Decomposition, mode: str, weight: float, seed: int, constraints: CornerConstraints | None = None, shape: str = "box"
    ) -> None:
        """``constraints``: the design constraints, held at every tolerance corner. ``shape``:
        ``ellipsoid`` holds |r₀| + ‖s‖₂ ≤ ρ T at each sampled configuration (s_i the change at
        δ_i = +t_i, exact for an affine residual) instead of every corner, when no element has
        several deviations (their products would need the box: it is used then, and said)."""
        import casadi as ca

        f = decomposition.formulation
        devs = decomposition.deviations
        #: the worst case held: "ellipsoid" (first order, exact without products) or "box" (every corner)
        self.shape = "ellipsoid" if shape == "ellipsoid" and not decomposition.groups else "box"
        if self.shape == "box" and 2 ** len(devs) > MAX_CORNERS:
            raise ValueError(f"{len(devs)} deviations: {2 ** len(devs)} corners is more than {MAX_CORNERS} for the minimax NLP")
        self.f = f
        layout = f.parameters
        offsets = []
        for signs in itertools.product((-1, 1), repeat=len(devs) if self.shape == "box" else 0):
            off = np.zeros(layout.size)
            for d, s in zip(devs, signs):
                i = layout.base_names.index(d.parameter)
                for c in range(len(decomposition.problem.scenarios)):
                    off[c * layout.stride + 3 + i] = s * d.half_width
            offsets.append(off)
        self.offsets = offsets if self.shape == "box" else []
        # per block: coordinates sampled on a grid of about SAMPLES_PER_COORDINATE × n_q points
        # (closed loops: n_q independent coordinates, assembled on the configuration manifold)
        self.q = [decomposition.configurations(SAMPLES_PER_COORDINATE * len(decomposition.names(k)), seed)[k] for k in range(len(f.blocks))]
        self.rho = ca.SX.sym("rho")
        self.mode = mode
        self.weight = weight
        self._decomposition = decomposition
        self._backend: IpoptBackend | None = None
        self._reference: np.ndarray | None = None
        self.constraints = constraints
        self._lbg_c = self._ubg_c = np.zeros(0)
        self._deviation_values = np.zeros(0)
        #: directly attached springs' length rows at every corner of their points (None: no such spring)
        self.lengths = DirectLengths(decomposition) if any(s.direct is not None for s in decomposition.problem.springs) else None

    def _build(self, z0: np.ndarray, p: np.ndarray) -> None:
        import casadi as ca

        f = self.f
        rows = []
        kinds, torques = [], []
        for b, block in enumerate(f.blocks):
            qb = self.q[b]
            torque = np.abs(self._decomposition.along(b, qb, np.array(block.gravity_torque.map(len(qb))(qb.T, z0, p)).T).T)  # (n_q, N)
            for j, name in enumerate(self._decomposition.names(b)):
                kinds.append(self._decomposition.problem.coordinate[name].unit.dimension == "")
                torques.append(float(torque[j].max(initial=0.0)))
        reference = {k: max((t for t, kk in zip(torques, kinds) if kk == k), default=1.0) or 1.0 for k in (True, False)}
        i = 0
        for b, block in enumerate(f.blocks):
            qb = self.q[b]
            raw = block.residual.map(len(qb))
            n_rows = len(self._decomposition.names(b))

            def mapped(q: Any, z: Any, p: Any, b: int = b, qb: np.ndarray = qb, raw: Any = raw) -> Any:
                """The block's residual at ``qb`` (n, N); closed loops: along the manifold (n_i, N)."""
                return self._decomposition.along_symbolic(b, qb, raw(q, z, p))

            if self.shape == "ellipsoid":
                r0 = mapped(ca.DM(qb.T), f.z, f.p)
                changes = [mapped(ca.DM(qb.T), f.z, f.p + ca.DM(self._decomposition.p_at(np.zeros(f.p.numel()), unit))) - r0 for unit in np.eye(len(self._decomposition.deviations)).tolist()]
                for j in range(n_rows):
                    scale = reference[kinds[i + j]]
                    spread = ca.sqrt(sum(c[j, :].T ** 2 for c in changes) + (ELLIPSOID_FLOOR * scale) ** 2) if changes else 0
                    rows += [self.rho - (r0[j, :].T + spread) / scale, self.rho - (spread - r0[j, :].T) / scale]
                i += n_rows
                continue
            for off in self.offsets:
                r = mapped(ca.DM(qb.T), f.z, f.p + ca.DM(off))  # (n_q, N)
                for j in range(n_rows):
                    scaled = r[j, :].T / reference[kinds[i + j]]
                    rows += [self.rho - scaled, self.rho + scaled]
            i += n_rows
        if self.lengths is not None:  # directly attached springs within their lengths at every corner of their points
            rows += self.lengths.symbolic(self.q)
        corner_rows = ca.vertcat(*rows)
        keep = self._distinct(corner_rows, z0, p)
        rows = [corner_rows[keep]]
        self.n_rows = len(keep)
        self.n_signs = int(f.nonnegative.numel())
        if self.constraints is not None:
            g_c, self._lbg_c, self._ubg_c = self.constraints.symbolic_rows()
        else:
            g_c, self._lbg_c, self._ubg_c = ca.SX(0, 1), np.zeros(0), np.zeros(0)
        g = ca.vertcat(*rows, f.nonnegative, g_c)
        objective = f.objective + (self.weight * self.rho if self.mode == "minimise" else 0)
        options = {**IPOPT_DEFAULTS, "tol": 1e-9}
        self._backend = IpoptBackend({"x": ca.vertcat(f.z, self.rho), "p": f.p, "f": objective, "g": g}, options, "robust_minimax")

    def _deviation_mask(self) -> np.ndarray:
        """The entries of the parameter vector that hold a deviation (one per deviation and scenario)."""
        mask = np.zeros(self.f.parameters.size, dtype=bool)
        for i in range(len(self._decomposition.deviations)):
            mask[self._decomposition.parameter_index(i)] = True
        return mask

    def _distinct(self, g: Any, z0: np.ndarray, p: np.ndarray) -> list[int]:
        """The rows of ``g`` that are not a repeat of an earlier row: two corners often give
        the same row (a point deviation across the plane of a planar mechanism moves the
        spring's length by the same amount at + and −), and a repeated row doubles IPOPT's
        work for nothing. Rows are compared by value, bit for bit, at REPEAT_PROBES random
        designs and parameters around (z0, p), the deviations' entries at p's (the NLP is
        solved at them: :meth:`solve` builds it again when they change)."""
        import casadi as ca

        f = self.f
        fn = ca.Function("corner_rows", [f.z, self.rho, f.p], [g])
        rng = np.random.default_rng(0)
        fixed = self._deviation_mask()
        self._deviation_values = p[fixed].copy()
        probes = []
        for _ in range(REPEAT_PROBES):
            z = z0 + (np.abs(z0) + 1e-3) * rng.uniform(-0.1, 0.1, z0.size)
            pr = np.where(fixed, p, p + (np.abs(p) + 1e-3) * rng.uniform(-0.01, 0.01, p.size))
            probes.append(np.array(fn(z, rng.uniform(0.1, 1.0), pr)).reshape(-1))
        return first_of_repeats(np.stack(probes, axis=1))

    def solve(self, z0: np.ndarray, p: np.ndarray, lbz: np.ndarray, ubz: np.ndarray, limit: float) -> MinimaxResult:
        if self._backend is not None and not np.array_equal(p[self._deviation_mask()], self._deviation_values):
            self._backend = None  # the repeated rows were found at other deviation values
        if self._backend is None:
            self._build(z0, p)
        backend = self._backend
        if backend is None:
            raise RuntimeError("robust minimax: the NLP was not built")
        upper = limit if self.mode == "limit" else np.inf
        b = Bounds(
            np.concatenate([lbz, [0.0]]),
            np.concatenate([ubz, [upper]]),
            np.concatenate([np.zeros(self.n_rows + self.n_signs), self._lbg_c]),
            np.concatenate([np.full(self.n_rows + self.n_signs, np.inf), self._ubg_c]),
        )
        start = upper if np.isfinite(upper) else 1.0
        out = backend.solve(np.concatenate([z0, [start]]), p, b)
        return MinimaxResult(out.z[:-1], out.status, out.solver_status, float(out.z[-1]), out.solve_time, out.iterations)
