"""Loop closure: the configuration manifold of a subsystem with closed loops.

For a subsystem whose coordinates split into independent ones q_i (with ranges) and
dependent ones q_d (solved), the closure equations of its loops (:mod:`counterpoise.model.loops`)

    h(q_i, q_d) = 0        (per loop, 3 point rows: the joint's two points coincide, or for a
                            prismatic joint (p_a − p_b) × axis = 0; then the orientation rows:
                            a revolute axis keeps its direction in frame b (3), a prismatic
                            joint keeps the frames' relative rotation (9))

define the configuration manifold. :class:`Closure` builds h and its Jacobian once (at one
scenario's parameter values) and solves it for many configurations at once:

- **The assembled home** (:meth:`Closure._home`): the file's homes are starting guesses.
  The point rows are closed first; the orientation targets are then given (``axis_b``) or
  measured and snapped onto exact directions (:func:`_snap`); Gauss-Newton with truncated-SVD
  steps then corrects every dependent coordinate on every row, and the mobility
  n − rank ∂h/∂q is checked there. Homes rounded to a few digits give the configuration
  exact ones give, also for over-constrained loops (docs/loops.md#the-home).
- **Newton with a rank-revealing pseudo-inverse**: Δq_d = −(∂h/∂q_d)⁺ h. Redundant rows (a
  planar loop's out-of-plane rows, identically zero) only add zero singular values, which
  the pseudo-inverse drops; nobody has to remove equations.
- **Continuation from home**: every configuration is reached along the straight segment
  from the home configuration in q_i, in small steps, each predicted along the tangent
  dq_d/dq_i and corrected by Newton. Steps are small against the ranges
  (:data:`STEPS_PER_RANGE`), so the solution stays on the assembly branch of home.
- **Input errors**: a loop that does not close at home, too few degrees of freedom at home,
  a configuration of the ranges that cannot be assembled (the first one met from home is
  named), and a singular configuration (∂h/∂q_d loses rank: the dependent coordinates are not
  determined there, and the generalized force along the manifold is not defined) are
  :class:`ProblemFileError` naming the loop; messages at home state the home used.
- **Tangent**: dq_d/dq_i = −(∂h/∂q_d)⁺ ∂h/∂q_i (implicit function theorem), used for the
  residual along the manifold (:mod:`counterpoise.formulation.manifold`,
  :mod:`counterpoise.verify.manifold`).

Scaling: point rows are divided by the loop's size (the largest distance of a frame origin
or a loop point from the ground origin at home), so every row is dimensionless and
:data:`CLOSURE_TOLERANCE` is relative.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ProblemFileError
from ..model.loops import PRISMATIC_JOINT, REVOLUTE_JOINT, SPHERICAL_JOINT
from ..model.units import MAX_LENGTH_M
from ..model.mechanism import GROUND
from ..model.problem import Problem
from .energy import Mechanics
from .kinematics import matvec, sub
from .sampling import STEP  # the complex step of the closure Jacobian

#: Largest scaled closure gap (gap / loop size; axis rows as is) of an assembled configuration.
CLOSURE_TOLERANCE = 1e-11
#: Gauss-Newton iterations that measure the gap of a loop that cannot close at home.
LEAST_SQUARES_ITERATIONS = 200
LEAST_SQUARES_HALVINGS = 40
#: Gauss-Newton iterations of the home solve on every closure row (from the homes, which
#: are accurate to a few digits: it converges in a handful).
HOME_ITERATIONS = 60
#: An orientation target measured at a rounded home (a revolute axis in frame b, a prismatic
#: joint's relative rotation) within this angle (rad, 0.057 deg) of an exact direction (a
#: coordinate axis, or the revolute axis's own coordinates in frame a) is snapped onto it.
AXIS_SNAP = 1e-3
#: Chord iterations (the Jacobian of the prediction kept) of a dense sample's corrections
#: before a configuration goes on with full Newton steps.
CHORD_ITERATIONS = 8
#: Newton corrections per continuation step (each converges quadratically from the predictor).
NEWTON_ITERATIONS = 12
#: Continuation steps over a path as long as the whole range of a coordinate (fewer for shorter paths).
STEPS_PER_RANGE = 32
#: Before a configuration is declared impossible, its path is retried with this many times more steps.
REFINE = 4
#: The grid whose nodes start the Newton corrections of many configurations has at most about
#: this many nodes (per axis: its n_i-th root, at least GRID_MIN_NODES, at most GRID_MAX_PER_AXIS:
#: 129 for one independent coordinate, 34 for two, 10 for three).
GRID_NODES = 1200
GRID_MAX_PER_AXIS = 4 * STEPS_PER_RANGE + 1
GRID_MIN_NODES = 5
#: Above this many nodes (many independent coordinates) every configuration is continued from home instead.
GRID_MAX_NODES = 20_000
#: A Newton correction from a grid node's prediction larger than this × the prediction's
#: change is suspected of leaving the branch: that configuration is continued from home.
BRANCH_CORRECTION = 0.5
#: ... or than this (SI: rad, or m for a sliding dependent coordinate): a second-order
#: correction where the tangent vanishes (a rocker at its extreme) is not a change of branch.
BRANCH_FLOOR = 1e-3
#: Singular values of ∂h/∂q_d below RANK_TOLERANCE × the largest are zero (redundant rows).
RANK_TOLERANCE = 1e-9
#: A configuration is singular when σ_min/σ_max of ∂h/∂q_d (its n_d largest singular
#: values) is below this: the dependent coordinates are (nearly) undetermined there.
SINGULAR_CONDITIONING = 1e-6
#: Results of :meth:`Closure.solve` kept per closure (by their independent coordinates): the
#: after-solve checks draw the same dense sample once per spring.
SOLVED_CACHE = 8
#: Continuation steps of the assembly check on each edge of the box of ranges.
CHECK_STEPS = STEPS_PER_RANGE
#: Loop sizes below this (m) are taken as this (a loop of zero size still gets a scale).
MIN_SIZE = 1e-6


@dataclass(frozen=True)
class ManifoldPoints:
    """Configurations on the manifold.

    ``q``: every coordinate of the subsystem (its order), (N, n); ``tangent``: dq_d/dq_i,
    (N, n_d, n_i); ``conditioning``: σ_min/σ_max of ∂h/∂q_d, (N,).
    """

    q: np.ndarray
    tangent: np.ndarray
    conditioning: np.ndarray


class Closure:
    """The closure equations of one subsystem at fixed base-parameter values (SI)."""

    def __init__(self, problem: Problem, subsystem: str, base: Mapping[str, float]) -> None:
        self.problem = problem
        self.subsystem = subsystem
        self.base = dict(base)
        self.loops = problem.subsystem_loops(subsystem)
        coords = problem.subsystem_coordinates(subsystem)
        self.names = [c.name for c in coords]
        self.independent = np.array([i for i, c in enumerate(coords) if not c.dependent], dtype=int)
        self.dependent = np.array([i for i, c in enumerate(coords) if c.dependent], dtype=int)
        self.lower = np.array([coords[i].lower for i in self.independent])
        self.upper = np.array([coords[i].upper for i in self.independent])
        #: the file's homes (starting guesses); ``home`` becomes the assembled home
        self.given = np.array([c.home for c in coords])
        self.home = self.given.copy()
        self.size = max(MIN_SIZE, _size(self._mechanics(self.home[None, :]), self.loops))
        if not self.size <= MAX_LENGTH_M:  # a length of 1e308 mm in a frame: out of range, not an overflow
            raise ProblemFileError(
                problem.path,
                f"loops.{self.loops[0].name}",
                f"the loop's points and frames reach {self.size:.3g} m from the origin at home: out of range "
                f"(beyond {MAX_LENGTH_M:g} m, 1000 km; check the lengths of its frames' translations and of the parameters they use)",
            )
        #: the orientation targets: a revolute joint's axis in frame b (3,), a prismatic
        #: joint's rotation of frame a in frame b (3, 3); empty while the points are closed first
        self.targets: dict[str, np.ndarray] = {}
        self.snapped: set[str] = set()  # loops whose target was snapped onto an exact direction
        self._grid: tuple[np.ndarray, ManifoldPoints] | None = None
        self._solved: dict[tuple[tuple[int, ...], bytes], ManifoldPoints] = {}  # solve()'s results by their q_i
        self.m = self._row_count()
        self.home = self._home()
        self.m = self._row_count()

    def _row_count(self) -> int:
        return sum(3 + (3 * (len(self.targets[loop.name].ravel()) // 3) if loop.name in self.targets else 0) for loop in self.loops)

    # -- equations -------------------------------------------------------------------
    def _mechanics(self, q: Any) -> Mechanics:
        return Mechanics(self.problem, self.base, {}, {name: q[:, i] for i, name in enumerate(self.names)}, [0.0, 0.0, 0.0])

    def _rows(self, q: Any) -> Any:
        """h at configurations q (N, n), real or complex: (N, m).

        Per loop: the point rows (spherical, revolute: p_a − p_b; prismatic: (p_a − p_b) ×
        the axis in world, the two points may slide along it), over the loop's size; then,
        once the targets are set, the orientation rows (revolute: R_a axis − R_b axis_b;
        prismatic: the columns of R_a − R_b R_ba)."""
        mech = self._mechanics(q)
        rows = []
        n_conf = q.shape[0]
        for loop in self.loops:
            gap = sub(mech.position(loop.a), mech.position(loop.b))
            ra, _ = mech.pose(loop.a.frame)
            if loop.joint == PRISMATIC_JOINT:
                u = matvec(ra, mech.vector(loop.axis))  # type: ignore[arg-type]  # a prismatic or revolute loop joint always has its axis
                gap = [gap[1] * u[2] - gap[2] * u[1], gap[2] * u[0] - gap[0] * u[2], gap[0] * u[1] - gap[1] * u[0]]
            rows += [np.broadcast_to(g, (n_conf,)) / self.size for g in gap]
            target = self.targets.get(loop.name)
            if target is None:
                continue
            rb, _ = mech.pose(loop.b.frame)
            if loop.joint == REVOLUTE_JOINT:
                rows += [np.broadcast_to(v, (n_conf,)) for v in sub(matvec(ra, mech.vector(loop.axis)), matvec(rb, list(target)))]  # type: ignore[arg-type]  # a prismatic loop joint always has its axis
            else:
                for col in range(3):
                    rows += [np.broadcast_to(v, (n_conf,)) for v in sub([ra[r][col] for r in range(3)], matvec(rb, list(target[:, col])))]
        return np.stack(rows, axis=1)

    def _orientation_targets(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """The orientation targets measured at configuration q (n,): each revolute axis in
        frame b, each prismatic joint's rotation of frame a in frame b."""
        mech = self._mechanics(q[None, :])
        out: dict[str, np.ndarray] = {}
        for loop in self.loops:
            if loop.joint == SPHERICAL_JOINT:
                continue
            ra = _matrix(mech.pose(loop.a.frame)[0])
            rb = _matrix(mech.pose(loop.b.frame)[0])
            if loop.joint == REVOLUTE_JOINT:
                out[loop.name] = rb.T @ ra @ _column(mech.vector(loop.axis))  # type: ignore[arg-type]  # a prismatic or revolute loop joint always has its axis
            else:
                out[loop.name] = rb.T @ ra
        return out

    def _given_targets(self) -> dict[str, np.ndarray]:
        """Targets the file gives exactly (``axis_b``), and snapped ones (:func:`_snap`)."""
        mech = self._mechanics(self.home[None, :])
        out: dict[str, np.ndarray] = {}
        for loop in self.loops:
            if loop.axis_b is not None:
                v = _column(mech.vector(loop.axis_b))
                out[loop.name] = v / np.linalg.norm(v)
        return out

    def equations(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """h (N, m) and ∂h/∂q (N, m, n) at configurations q (N, n), by complex step (every
        perturbed copy of q in one evaluation: the cost is in the number of calls)."""
        n_conf, n = q.shape
        stacked = np.tile(q.astype(complex), (n + 1, 1))
        for j in range(n):
            stacked[(j + 1) * n_conf : (j + 2) * n_conf, j] += 1j * STEP
        rows = self._rows(stacked)
        h = rows[:n_conf].real
        jac = (rows[n_conf:].imag / STEP).reshape(n, n_conf, -1).transpose(1, 2, 0)
        return h, np.ascontiguousarray(jac)

    def gaps(self, q: np.ndarray) -> np.ndarray:
        """Distance (m) between the two points of each loop: (N, number of loops)."""
        mech = self._mechanics(q)
        out = [np.linalg.norm(np.stack([np.broadcast_to(g, (q.shape[0],)) for g in sub(mech.position(loop.a), mech.position(loop.b))], axis=1), axis=1) for loop in self.loops]
        return np.stack(out, axis=1)

    # -- solving ---------------------------------------------------------------------
    def _newton(self, q: np.ndarray, active: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Newton on q_d for the rows ``active``; returns (q, converged, last Jacobian)."""
        d = self.dependent
        done = np.zeros(q.shape[0], dtype=bool)
        jac = np.zeros((q.shape[0], self.m, q.shape[1]))
        with np.errstate(all="ignore"):
            for _ in range(NEWTON_ITERATIONS + 1):
                h, jac = self.equations(q)
                err = np.abs(h).max(axis=1) if self.m else np.zeros(q.shape[0])
                done = (err <= CLOSURE_TOLERANCE) | ~active
                if done.all():
                    break
                step = _least_squares(jac[:, :, d], h[:, :, None])[:, :, 0]
                q[:, d] -= np.where(done[:, None], 0.0, step)
        bad = ~np.isfinite(q).all(axis=1)
        q[bad] = self.home
        return q, done & ~bad, jac

    def _chord(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Newton's chord method from good predictions q (N, n): ∂h/∂q_d taken once at the
        prediction, then only h per iteration (one evaluation instead of n + 1), then the full
        Jacobian at the result (its tangent and conditioning). Configurations it does not close
        within CHORD_ITERATIONS go on with :meth:`_newton`. Returns (q, converged, Jacobian)."""
        d = self.dependent
        n_conf = q.shape[0]
        with np.errstate(all="ignore"):
            h, jac = self.equations(q)
            jd = jac[:, :, d]
            normal = np.einsum("kmd,kme->kde", jd, jd)
            normal += RANK_TOLERANCE**2 * np.trace(normal, axis1=1, axis2=2)[:, None, None] * np.eye(len(d))
            finite = np.isfinite(normal).all(axis=(1, 2)) & (np.abs(np.linalg.det(np.nan_to_num(normal))) > 0)
            inverse = np.zeros_like(normal)
            if finite.any():
                inverse[finite] = np.linalg.inv(normal[finite])
            for _ in range(CHORD_ITERATIONS):
                active = finite & (np.abs(h).max(axis=1) > CLOSURE_TOLERANCE)
                if not active.any():
                    break
                step = np.einsum("kde,ke->kd", inverse, np.einsum("kmd,km->kd", jd, h))
                q[:, d] -= np.where(active[:, None], step, 0.0)
                h = np.asarray(self._rows(q)).real
            h, jac = self.equations(q)
        ok = np.isfinite(q).all(axis=1) & np.isfinite(h).all(axis=1) & (np.abs(h).max(axis=1) <= CLOSURE_TOLERANCE)
        if not ok.all():  # the chord did not settle there: full Newton from where it is (or from the prediction)
            redo = ~ok
            start = np.where(np.isfinite(q[redo]).all(axis=1)[:, None], q[redo], self.home)
            q_r, ok_r, jac_r = self._newton(start.copy(), np.ones(int(redo.sum()), dtype=bool))
            q[redo], ok[redo], jac[redo] = q_r, ok_r, jac_r
        return q, ok & np.ones(n_conf, dtype=bool), jac

    def _home(self) -> np.ndarray:
        """The assembled home: every dependent coordinate corrected on every closure equation.

        1. Newton on the point rows from the file's homes (a loop that cannot close there
           is an input error naming the least-squares gap).
        2. The orientation targets: given (``axis_b``), or measured there and snapped onto
           an exact direction within :data:`AXIS_SNAP` (:func:`_snap`): homes rounded to a
           few digits then assemble the configuration their exact values would.
        3. Gauss-Newton with rank-revealing steps on all rows (points and orientations), so
           a coordinate that only the orientation rows see is corrected too.
        4. The mobility at the assembled home: n − rank ∂h/∂q must leave room for every
           independent coordinate, and ∂h/∂q_d must determine the dependent ones.
        """
        q = self._close_points()
        measured = self._orientation_targets(q[0])
        given = self._given_targets()
        snapped = {name: t for name, t in ((name, _snap(v, self._axis_a(name))) for name, v in measured.items()) if t is not None}
        self.targets = {**measured, **snapped, **given}
        self.m = self._row_count()
        assembled, ok = self._gauss_newton(q)
        if not ok and snapped:  # a snapped direction the geometry does not have: keep the measured one
            self.targets = {**measured, **given}
            self.m = self._row_count()
            assembled, ok = self._gauss_newton(q)
        else:
            self.snapped = set(snapped) - set(given)
        if not ok:
            loop = next((lp for lp in self.loops if lp.name in given), self.loops[0])
            raise ProblemFileError(
                self.problem.path,
                f"loops.{loop.name}",
                f"the loop cannot close at home ({self.home_text()}): its points meet but the joint's axes do not line up "
                f"(check axis_b against the frames, and the homes of the dependent coordinates)",
            )
        self._check_mobility(assembled)
        return assembled[0]

    def _axis_a(self, name: str) -> np.ndarray | None:
        """A revolute loop's axis in frame a's coordinates (numbers), None for a prismatic loop."""
        loop = next(lp for lp in self.loops if lp.name == name)
        if loop.joint != REVOLUTE_JOINT:
            return None
        return _column(self._mechanics(self.given[None, :]).vector(loop.axis))  # type: ignore[arg-type]  # a prismatic or revolute loop joint always has its axis

    def home_text(self, q: np.ndarray | None = None) -> str:
        """'home theta2 = 0 deg' (the independent coordinates' homes, in their units)."""
        q = self.given if q is None else q
        return "home " + self.describe(q[self.independent])

    def _close_points(self) -> np.ndarray:
        """Step 1 of :meth:`_home`: (1, n), the point rows closed from the file's homes."""
        q = self.given[None, :].copy()
        q, ok, _ = self._newton(q, np.ones(1, dtype=bool))
        if ok[0]:
            return q
        # the least-squares gap: Gauss-Newton on to the closest the loop comes to closing
        gaps = self.gaps(self.given[None, :])[0]
        with np.errstate(all="ignore"):
            q = self.given[None, :].copy()
            for _ in range(LEAST_SQUARES_ITERATIONS):  # damped: halve the step until the gap shrinks
                h, jac = self.equations(q)
                step = _least_squares(jac[:, :, self.dependent], h[:, :, None])[:, :, 0]
                if not np.isfinite(step).all():
                    break
                for _ in range(LEAST_SQUARES_HALVINGS):
                    trial = q.copy()
                    trial[:, self.dependent] -= step
                    if float(np.sum(self._rows(trial).real ** 2)) < float(np.sum(h**2)):
                        q = trial
                        break
                    step = 0.5 * step
                else:
                    break
        closed = np.isfinite(q).all() and float(np.abs(self._rows(q).real).max(initial=0.0)) <= CLOSURE_TOLERANCE
        if closed:  # Newton from the homes stalled, the damped steps closed it: take that
            return q
        gaps = self.gaps(q)[0] if np.isfinite(q).all() else gaps
        worst = int(np.argmax(gaps)) if len(gaps) else 0
        loop = self.loops[worst]
        raise ProblemFileError(
            self.problem.path,
            f"loops.{loop.name}",
            f"the loop cannot close at home ({self.home_text()}): its points stay about {_mm(gaps[worst])} apart at best "
            f"(check the lengths and the homes of the dependent coordinates, which pick the assembly branch)",
        )

    def _gauss_newton(self, q: np.ndarray) -> tuple[np.ndarray, bool]:
        """Gauss-Newton on q_d over every row from q (1, n), each step the minimum-norm
        least-squares step through the SVD truncated at RANK_TOLERANCE (redundant rows of an
        over-constrained loop are dropped, not fought), halved until ‖h‖ shrinks."""
        q = q.copy()
        d = self.dependent
        with np.errstate(all="ignore"):
            for _ in range(HOME_ITERATIONS):
                h, jac = self.equations(q)
                if not (np.isfinite(h).all() and np.isfinite(jac).all()):
                    return q, False
                if float(np.abs(h).max(initial=0.0)) <= CLOSURE_TOLERANCE:
                    return q, True
                step = np.linalg.lstsq(jac[0][:, d], h[0], rcond=RANK_TOLERANCE)[0]
                now = float(np.sum(h**2))
                for _ in range(LEAST_SQUARES_HALVINGS):
                    trial = q.copy()
                    trial[0, d] -= step
                    if float(np.sum(self._rows(trial).real ** 2)) < now:
                        q = trial
                        break
                    step = 0.5 * step
                else:
                    break
        return q, bool(np.isfinite(q).all() and float(np.abs(self._rows(q).real).max(initial=0.0)) <= CLOSURE_TOLERANCE)

    def _check_mobility(self, q: np.ndarray) -> None:
        """Input errors at the assembled home q (1, n): fewer degrees of freedom than
        independent coordinates (n − rank ∂h/∂q < n_i), or dependent coordinates that the
        loops do not determine (σ_min/σ_max of ∂h/∂q_d below SINGULAR_CONDITIONING)."""
        _, jac = self.equations(q)
        sigma = np.linalg.svd(np.nan_to_num(jac[0], nan=0.0, posinf=0.0, neginf=0.0), compute_uv=False)
        rank = int(np.sum(sigma > RANK_TOLERANCE * sigma[0])) if sigma.size and sigma[0] > 0 else 0
        mobility = len(self.names) - rank
        where = self.home_text(q[0])
        if mobility < len(self.independent):
            hint = ""
            if set(self.targets) - self.snapped - {lp.name for lp in self.loops if lp.axis_b is not None}:
                hint = (
                    "; an over-constrained loop needs its joint axes exact, and an axis measured at a rounded home is not: "
                    "give each revolute loop's axis_b (its axis in frame b's coordinates)"
                )
            raise ProblemFileError(
                self.problem.path,
                f"loops.{self.loops[0].name}",
                f"the loops leave {mobility} degree(s) of freedom at the assembled {where}, fewer than the "
                f"{len(self.independent)} independent coordinates: the ranges go beyond the mechanism's mobility{hint}",
            )
        _, cond = self.tangent(jac)
        if cond[0] < SINGULAR_CONDITIONING:
            raise ProblemFileError(
                self.problem.path,
                f"loops.{self.loops[0].name}",
                f"the mechanism is singular at the assembled {where}: the loops do not determine the dependent coordinates there "
                f"(the closure's Jacobian in them loses rank: a change point, a dead centre, or too few loops for the dependent coordinates)",
            )

    def tangent(self, jac: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(dq_d/dq_i (N, n_d, n_i), conditioning (N,)) from ∂h/∂q (N, m, n)."""
        jd = jac[:, :, self.dependent]
        with np.errstate(all="ignore"):
            normal = np.einsum("kmd,kme->kde", jd, jd)
            eig = np.linalg.eigvalsh(normal)
            cond = np.sqrt(np.clip(eig[:, 0], 0.0, None) / np.where(eig[:, -1] > 0, eig[:, -1], np.inf))
            tangent = -_least_squares(jd, jac[:, :, self.independent])
        return np.nan_to_num(tangent), cond

    def solve(self, qi: np.ndarray) -> ManifoldPoints:
        """Configurations with independent coordinates ``qi`` (N, n_i) on the branch of home.

        Few configurations are continued from home (:meth:`continued`). Many are started
        from the nearest node of a grid over the box of ranges, itself continued from home,
        predicted along the node's tangent and corrected by Newton; a configuration whose
        correction fails, or moves further than half the prediction's change (and than
        BRANCH_FLOOR), is continued from home instead. Raises ProblemFileError naming the first configuration (nearest home along
        its path) that cannot be assembled or is singular.
        """
        qi = np.atleast_2d(np.asarray(qi, dtype=float))
        key = (qi.shape, qi.tobytes())
        found = self._solved.get(key)
        if found is not None:  # the same draws again (one dense sample per spring, say): solved once
            return ManifoldPoints(found.q.copy(), found.tangent.copy(), found.conditioning.copy())
        points = self._solve(qi)
        if len(self._solved) >= SOLVED_CACHE:
            self._solved.pop(next(iter(self._solved)))
        self._solved[key] = points
        return ManifoldPoints(points.q.copy(), points.tangent.copy(), points.conditioning.copy())

    def _solve(self, qi: np.ndarray) -> ManifoldPoints:
        n_i = len(self.independent)
        per_axis = self._per_axis()
        if per_axis**n_i > GRID_MAX_NODES:
            return self.continued(qi)
        nodes, grid = self.grid()
        spacing = np.where(self.upper > self.lower, (self.upper - self.lower) / (per_axis - 1), 1.0)
        index = np.clip(np.rint((qi - self.lower) / spacing).astype(int), 0, per_axis - 1)
        flat = np.ravel_multi_index(tuple(index.T), (per_axis,) * n_i)
        q = grid.q[flat].copy()
        step = qi - nodes[flat]
        q[:, self.independent] = qi
        guess = q[:, self.dependent] + np.einsum("kdi,ki->kd", grid.tangent[flat], step)
        q[:, self.dependent] = guess
        q, ok, jac = self._chord(q)
        # a correction as large as the prediction's whole change means Newton may have left the branch
        moved = np.abs(q[:, self.dependent] - guess).max(axis=1) if len(self.dependent) else np.zeros(qi.shape[0])
        predicted = np.abs(np.einsum("kdi,ki->kd", grid.tangent[flat], step)).max(axis=1) if len(self.dependent) else moved
        ok &= moved <= np.maximum(BRANCH_CORRECTION * predicted, BRANCH_FLOOR)
        tangent, cond = self.tangent(jac)
        ok &= cond >= SINGULAR_CONDITIONING
        if not ok.all():
            redo = self.continued(qi[~ok])
            q[~ok], tangent[~ok], cond[~ok] = redo.q, redo.tangent, redo.conditioning
        return ManifoldPoints(q, tangent, cond)

    def _per_axis(self) -> int:
        return max(GRID_MIN_NODES, min(GRID_MAX_PER_AXIS, int(GRID_NODES ** (1.0 / max(len(self.independent), 1)))))

    def grid(self) -> tuple[np.ndarray, ManifoldPoints]:
        """(nodes (G, n_i), their configurations): a grid over the box of independent
        ranges, continued from home, solved once (it is also the assembly check)."""
        if self._grid is None:
            per_axis = self._per_axis()
            axes = [np.linspace(lo, hi, per_axis) for lo, hi in zip(self.lower, self.upper)]
            nodes = np.array(list(itertools.product(*axes)), dtype=float).reshape(-1, len(self.independent))
            self._grid = (nodes, self.continued(nodes))
        return self._grid

    def continued(self, qi: np.ndarray, steps_per_range: int = STEPS_PER_RANGE) -> ManifoldPoints:
        """Configurations ``qi`` (N, n_i), each continued along the segment from home."""
        qi = np.atleast_2d(np.asarray(qi, dtype=float))
        n_conf = qi.shape[0]
        span = np.where(self.upper > self.lower, self.upper - self.lower, 1.0)
        start = self.home[self.independent]
        delta = qi - start
        steps = max(1, int(math.ceil(steps_per_range * float(np.abs(delta / span).max(initial=0.0)))))
        q = np.tile(self.home, (n_conf, 1))
        jac_home = self.equations(self.home[None, :])[1]
        tangent, _ = self.tangent(jac_home)
        tangent = np.repeat(tangent, n_conf, axis=0)
        # orientation of ∂h/∂q_d, carried along: det(Pᵀ ∂h/∂q_d) > 0 with P the polar factor of the
        # previous step's ∂h/∂q_d; it turns ≤ 0 when the path crosses a singular configuration
        # between two steps (a change point, which the conditioning at the steps may not see)
        polar = np.repeat(_polar(jac_home[:, :, self.dependent]), n_conf, axis=0)
        failed_at = np.full(n_conf, np.inf)
        singular_at = np.full(n_conf, np.inf)
        active = np.ones(n_conf, dtype=bool)
        cond = np.ones(n_conf)
        for s in range(1, steps + 1):
            t = s / steps
            step = delta / steps
            q[:, self.independent] = np.where(active[:, None], start + t * delta, q[:, self.independent])
            q[:, self.dependent] += np.where(active[:, None], np.einsum("kdi,ki->kd", tangent, step), 0.0)
            q, ok, jac = self._newton(q, active)
            lost = active & ~ok
            failed_at[lost] = t
            active &= ok
            new_tangent, new_cond = self.tangent(jac)
            tangent = np.where(active[:, None, None], new_tangent, tangent)
            cond = np.where(active, new_cond, cond)
            jd = jac[:, :, self.dependent]
            with np.errstate(all="ignore"):
                crossed = np.linalg.det(np.einsum("kmd,kme->kde", polar, jd)) <= 0
            polar = np.where(active[:, None, None], _polar(jd), polar)
            bent = active & ((new_cond < SINGULAR_CONDITIONING) | crossed)
            singular_at[bent] = np.minimum(singular_at[bent], t)
            if not active.any():
                break
        lost = np.isfinite(failed_at) | np.isfinite(singular_at)
        if lost.any() and steps_per_range == STEPS_PER_RANGE:
            redo = self.continued(qi[lost], STEPS_PER_RANGE * REFINE)  # raises if the finer path fails too
            q[lost], tangent[lost], cond[lost] = redo.q, redo.tangent, redo.conditioning
        elif lost.any():
            self._raise(start, delta, failed_at, singular_at, steps)
        return ManifoldPoints(q, tangent, cond)

    def _raise(self, start: np.ndarray, delta: np.ndarray, failed_at: np.ndarray, singular_at: np.ndarray, steps: int) -> None:
        """The input error for the configuration nearest home (in range fractions) that failed."""
        span = np.where(self.upper > self.lower, self.upper - self.lower, 1.0)
        length = np.abs(delta / span).max(axis=1)
        fail_dist = np.where(np.isfinite(failed_at), failed_at * length, np.inf)
        sing_dist = np.where(np.isfinite(singular_at), singular_at * length, np.inf)
        singular = sing_dist.min() <= fail_dist.min()
        k = int(np.argmin(sing_dist if singular else fail_dist))
        t = singular_at[k] if singular else failed_at[k]
        qi = start + t * delta[k]
        where = self.describe(qi)
        if singular:
            raise ProblemFileError(
                self.problem.path,
                f"loops.{self.loops[0].name}",
                f"the mechanism is singular at {where}: the loops do not determine the dependent coordinates there "
                f"(the closure's Jacobian in them loses rank: a change point or a dead centre, met going out from {self.home_text()}); "
                f"narrow the ranges to keep away from it",
            )
        # the least-squares gap where the continuation stopped, from the last assembled configuration
        before = start + max(0.0, t - 1.0 / steps) * delta[k]
        q = self.solve_from(before, qi)
        gaps = self.gaps(q[None, :])[0]
        worst = int(np.argmax(gaps))
        raise ProblemFileError(
            self.problem.path,
            f"loops.{self.loops[worst].name}",
            f"the loop cannot be assembled at {where} (closure gap {_mm(gaps[worst])}): "
            f"the ranges go beyond the mechanism's mobility on the branch of {self.home_text()}",
        )

    def solve_from(self, before: np.ndarray, qi: np.ndarray) -> np.ndarray:
        """Least-squares closure at ``qi`` from the configuration solved at ``before`` (no error)."""
        old = np.seterr(all="ignore")
        try:
            q = np.tile(self.home, (1, 1))
            q[0, self.independent] = before
            q, *_ = self._newton(q, np.ones(1, dtype=bool))
            q[0, self.independent] = qi
            q, *_ = self._newton(q, np.ones(1, dtype=bool))
        finally:
            np.seterr(**old)
        return q[0]

    def describe(self, qi: np.ndarray) -> str:
        """'theta2 = 190 deg' (the independent coordinates, in their units)."""
        coords = self.problem.subsystem_coordinates(self.subsystem)
        parts = []
        for j, i in enumerate(self.independent):
            c = coords[i]
            parts.append(f"{c.name} = {c.unit.from_si(float(qi[j])):.6g} {c.unit.symbol}".rstrip())
        return ", ".join(parts)

    def corners(self) -> np.ndarray:
        """Every corner of the box of independent ranges: (2^n_i, n_i)."""
        return np.array(list(itertools.product(*zip(self.lower, self.upper))), dtype=float).reshape(-1, len(self.independent))


def _matrix(rot: Any) -> np.ndarray:
    """A pose's 3 × 3 rotation (entries numbers or one-element arrays) as an array."""
    return np.array([[float(np.ravel(rot[r][c])[0]) for c in range(3)] for r in range(3)], dtype=float)


def _column(v: Sequence[Any]) -> np.ndarray:
    return np.array([float(np.ravel(c)[0]) for c in v], dtype=float)


def _snap(target: np.ndarray, axis_a: np.ndarray | None) -> np.ndarray | None:
    """The exact direction a measured orientation target stands for, or None.

    A revolute axis in frame b (3,): the nearest of ±x, ±y, ±z and ± the axis's own
    coordinates in frame a, if within AXIS_SNAP rad. A prismatic joint's rotation (3, 3):
    the nearest signed permutation (frames aligned up to quarter turns), if every entry is
    within AXIS_SNAP of it. Homes are accurate to a few digits (1e-3 deg moves a target by
    ~1e-5 rad), so an over-constrained mechanism built on exact directions keeps them.
    """
    if target.ndim == 1:
        candidates = [np.eye(3)[k] * sign for k in range(3) for sign in (1.0, -1.0)]
        if axis_a is not None and np.linalg.norm(axis_a) > 0:
            unit = axis_a / np.linalg.norm(axis_a)
            candidates += [unit, -unit]
        unit_t = target / np.linalg.norm(target)
        best = min(candidates, key=lambda c: float(np.linalg.norm(unit_t - c)))
        return best.copy() if float(np.linalg.norm(unit_t - best)) <= AXIS_SNAP else None
    rounded = np.rint(target)
    if np.abs(target - rounded).max() <= AXIS_SNAP and np.allclose(rounded @ rounded.T, np.eye(3)) and np.linalg.det(rounded) > 0:
        return rounded
    return None


def _polar(a: np.ndarray) -> np.ndarray:
    """The orthonormal polar factor U Vᵀ of each (m, n_d) matrix of ``a`` (N, m, n_d)."""
    with np.errstate(all="ignore"):
        u, _, vt = np.linalg.svd(np.nan_to_num(a), full_matrices=False)
    return np.einsum("kmd,kde->kme", u, vt)


def _least_squares(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched least-squares solutions x of a x = b, (N, m, n) and (N, m, k) -> (N, n, k).

    Through the normal equations (n × n, n = number of dependent coordinates): redundant
    rows of a (identically zero ones, or repeats) change nothing, and a configuration where
    a loses rank is caught by the conditioning test before its tangent is used. A tiny
    multiple of the trace keeps an exactly singular matrix solvable (the step is then checked).
    """
    normal = np.einsum("kmd,kme->kde", a, a)
    ridge = RANK_TOLERANCE**2 * np.trace(normal, axis1=1, axis2=2)[:, None, None] * np.eye(a.shape[2])
    rhs = np.einsum("kmd,kmj->kdj", a, b)
    try:
        return np.linalg.solve(normal + ridge, rhs)
    except np.linalg.LinAlgError:  # a zero Jacobian (the trace is 0 too): the pseudo-inverse
        return np.linalg.pinv(normal) @ rhs


def _size(mech: Mechanics, loops: Sequence[Any]) -> float:
    """The loop's size: the largest distance of a loop point or of a frame origin on the way from ground."""
    size = 0.0
    for loop in loops:
        for point in (loop.a, loop.b):
            size = max(size, _norm(mech.position(point)))
            frame = point.frame
            while frame is not None and frame != GROUND:
                size = max(size, _norm(mech.pose(frame)[1]))
                frame = mech.problem.frame[frame].parent
    return size


def _norm(v: Sequence[Any]) -> float:
    """|v| of a vector whose entries are numbers or one-element arrays."""
    return math.hypot(*(float(np.ravel(c)[0]) for c in v))  # no overflow for huge entries


def _mm(metres: float) -> str:
    return f"{metres * 1e3:.4g} mm"


_CACHE: dict[tuple[int, str, tuple[tuple[str, float], ...]], Closure] = {}
_CACHE_SIZE = 16


def geometry_parameters(problem: Problem, subsystem: str) -> tuple[str, ...]:
    """The base parameters the manifold of ``subsystem`` depends on, in the problem's order.

    The names in its loops' points and in the transforms of their frames and every ancestor,
    derived parameters expanded to the base ones they use. A payload's mass, a spring's rate
    or a counter-mass's lever is not among them, so a closure is shared by every value of
    those (a payload schedule re-solves no manifold), while a changed link length builds a
    new one.
    """
    found = _GEOMETRY.get((id(problem), subsystem))
    if found is not None and found[0] is problem:
        return found[1]
    from ..model import expr as ex

    used: set[str] = set()
    for loop in problem.subsystem_loops(subsystem):
        for point in (loop.a, loop.b):
            for tree in point.position:
                used |= ex.names(tree)
            name: str | None = point.frame
            while name is not None and name != GROUND:
                f = problem.frame[name]
                used |= f.names()
                name = f.parent
    derived = {p.name: p.expr for p in problem.parameters if not p.is_base}
    todo = [n for n in used if n in derived]
    while todo:
        for n in ex.names(derived[todo.pop()]):  # type: ignore[arg-type]  # a derived parameter has its expr
            if n not in used:
                used.add(n)
                if n in derived:
                    todo.append(n)
    names = tuple(p.name for p in problem.base_parameters if p.name in used)
    if len(_GEOMETRY) >= _CACHE_SIZE:
        _GEOMETRY.pop(next(iter(_GEOMETRY)))
    _GEOMETRY[(id(problem), subsystem)] = (problem, names)
    return names


_GEOMETRY: dict[tuple[int, str], tuple[Problem, tuple[str, ...]]] = {}


def geometry_key(problem: Problem, subsystem: str, base: Mapping[str, float]) -> tuple[tuple[str, float], ...]:
    """The values of :func:`geometry_parameters` in ``base``: equal keys, one manifold."""
    return tuple((n, float(base[n])) for n in geometry_parameters(problem, subsystem) if n in base)


def closure(problem: Problem, subsystem: str, base: Mapping[str, float]) -> Closure:
    """The :class:`Closure` of ``subsystem`` at these base parameters (built once per
    values of its geometry parameters, :func:`geometry_parameters`)."""
    key = (id(problem), subsystem, geometry_key(problem, subsystem, base))
    found = _CACHE.get(key)
    if found is None or found.problem is not problem:
        if len(_CACHE) >= _CACHE_SIZE:
            _CACHE.pop(next(iter(_CACHE)))
        found = _CACHE[key] = Closure(problem, subsystem, base)
    return found


def manifold_configurations(problem: Problem, subsystem: str, samples: int, rng: np.random.Generator, base: Mapping[str, float]) -> ManifoldPoints:
    """``samples`` random configurations of the independent coordinates plus the corners of
    their box (while there are at most ``MAX_CORNERS``), solved on the branch of home at
    ``base``: the manifold's counterpart of :func:`counterpoise.mechanics.sampling.configurations`."""
    from .sampling import MAX_CORNERS

    c = closure(problem, subsystem, base)
    n_i = len(c.independent)
    qi = c.lower + (c.upper - c.lower) * rng.random((samples, n_i))
    if 2**n_i <= MAX_CORNERS:
        qi = np.vstack([qi, c.corners()])
    return c.solve(qi)


def along_manifold(problem: Problem, subsystem: str, q: np.ndarray, base: Mapping[str, float], values: np.ndarray) -> np.ndarray:
    """Generalized forces ``values`` (N, n) of every coordinate at the assembled
    configurations ``q`` (N, n), projected along the manifold onto the independent
    coordinates: (N, n_i), r_i = g_i + (dq_d/dq_i)ᵀ g_d. An open chain's are returned as is."""
    if not problem.subsystem_loops(subsystem):
        return values
    c = closure(problem, subsystem, base)
    _, jac = c.equations(np.asarray(q, dtype=float))
    tangent, _ = c.tangent(jac)
    return values[:, c.independent] + np.einsum("kdi,kd->ki", tangent, values[:, c.dependent])


def independent_names(problem: Problem, subsystem: str) -> list[str]:
    """The coordinates :func:`along_manifold` keeps (every one of an open chain)."""
    return [c.name for c in problem.subsystem_coordinates(subsystem) if not c.dependent]


def check_assembly(problem: Problem) -> None:
    """Input errors of the loops at the file's values: a loop that does not close at home,
    an edge of the box of ranges that cannot be assembled, a singular configuration on it.

    On the grid of :meth:`Closure.grid` (every node continued from home along its segment;
    the box's edges and corners are nodes), or along every edge of the box when the grid
    would be too large. Raises
    ProblemFileError; returns None when every loop assembles.
    """
    if not problem.loops:
        return
    seen: set[tuple[str, tuple[tuple[str, float], ...]]] = set()  # one check per manifold
    for scenario in problem.scenarios:
        base = scenario_base(problem, scenario.name)
        for sub in problem.subsystems:
            if not problem.subsystem_loops(sub.name):
                continue
            c = closure(problem, sub.name, base)
            key = (sub.name, geometry_key(problem, sub.name, base))
            if key not in seen:
                seen.add(key)
                if c._per_axis() ** len(c.independent) <= GRID_MAX_NODES:
                    c.grid()  # the grid over the box: continued from home, its edges and corners included
                else:
                    c.solve(edge_points(c))


def scenario_base(problem: Problem, scenario: str) -> dict[str, float]:
    """Base-parameter values (SI) of ``scenario``: the file's values with the scenario's own."""
    base = {p.name: float(p.value) for p in problem.base_parameters if p.value is not None}
    for s in problem.scenarios:
        if s.name == scenario:
            base.update({k: float(v) for k, v in s.parameters.items()})
    return base


def edge_points(c: Closure, per_range: int = CHECK_STEPS) -> np.ndarray:
    """Points along every edge of the box of independent ranges, plus its corners."""
    corners = c.corners()
    out = [corners]
    n_i = len(c.independent)
    t = np.linspace(0.0, 1.0, per_range + 1)
    for j in range(n_i):
        for corner in corners:
            if corner[j] != c.lower[j]:
                continue
            line = np.tile(corner, (len(t), 1))
            line[:, j] = c.lower[j] + t * (c.upper[j] - c.lower[j])
            out.append(line)
    return np.vstack(out)
