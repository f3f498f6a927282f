"""Dense, independent check that a design is balanced.

For every (subsystem, scenario) the residual ∂V/∂q is evaluated on ``verify_samples``
random configurations plus every corner of the coordinate box (:mod:`.residuals`), and
set against the forces gravity puts on the unbalanced mechanism (:mod:`.checks`).
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING, Any, TypeGuard

import numpy as np

from ..model.problem import Problem
from ..designer.checks import PRISMATIC, REVOLUTE, CoordinateCheck, Verification
from ..model import expr as ex
from ..model.tilt import tilt_extremes, tilted_directions
from .manifold import ManifoldResiduals
from ..mechanics.sampling import configurations
from .residuals import BOX_MAXIMUM_STARTS, BoxMaximum, SubsystemResiduals, _base_parameters, energy_scale_if_needed

#: Residual evaluators of the problems checked last (a study verifies one problem many times).
_CACHE_SIZE = 4
_cache: dict[int, tuple["weakref.ref[Problem]", dict[tuple[Any, ...], list[tuple[str, str, SubsystemResiduals]]]]] = {}

if TYPE_CHECKING:
    from ..designer.solution import Solution
    from ..io.cache import BuiltEntry


def evaluators(solution: "Solution", samples: int | None = None, seed: int | None = None) -> list[tuple[str, str, SubsystemResiduals]]:
    """(scenario, subsystem, evaluator) of every pair, built once per problem, sample count
    and seed, and reused by later checks of the same problem (the configurations do not
    depend on parameter values; each evaluator rebuilds its arrays when the geometry does).
    Under ``counterpoise solve`` they are kept on disk after their first check and a later
    solve of the same content takes them from there (:func:`kept_entry`; not those of a
    closed loop's manifold)."""
    problem = solution.problem
    settings = problem.settings
    seed = settings.seed + 1 if seed is None else seed
    n = settings.verify_samples if samples is None else samples
    entry = _cache.get(id(problem))
    if entry is None or entry[0]() is not problem:
        if len(_cache) >= _CACHE_SIZE:
            _cache.pop(next(iter(_cache)))
        entry = (weakref.ref(problem), {})
        _cache[id(problem)] = entry
    found = entry[1].get((n, seed))
    if found is None:
        kept = kept_entry(problem, n, seed)
        found = kept.fetch(_evaluators_of) if kept is not None else None
        if found is None:
            rng = np.random.default_rng(seed)  # the draws follow (scenario, subsystem) order, as always
            found = []
            for scenario in _checked_scenarios(problem):
                for sub in problem.subsystems:
                    if problem.subsystem_loops(sub.name):  # closed loops: on the configuration manifold
                        found.append((scenario.name, sub.name, ManifoldResiduals(problem, sub.name, n, rng, scenario.name)))  # type: ignore[arg-type]  # ManifoldResiduals answers SubsystemResiduals' evaluate
                        continue
                    q = configurations(problem, sub.name, n, rng)
                    found.append((scenario.name, sub.name, SubsystemResiduals(problem, sub.name, q)))
            if kept is not None and all(type(e) is SubsystemResiduals for *_, e in found):
                _to_keep[id(found)] = (found, kept)
        entry[1][(n, seed)] = found
    return found


# -- evaluators kept on disk by counterpoise solve (counterpoise.io.cache) --------------------

#: the kind of :mod:`counterpoise.io.cache`'s built entries that hold a problem's evaluators
KEPT_KIND = "evaluators"
#: evaluators built in this process and not yet kept: kept after their first check, with
#: the arrays and box maxima it computed (by id of the list :func:`evaluators` returns,
#: which is held here, so that its id is not another's)
_to_keep: dict[int, tuple[list[tuple[str, str, SubsystemResiduals]], BuiltEntry]] = {}


def kept_entry(problem: Problem, samples: int, seed: int) -> BuiltEntry | None:
    """The disk entry of a problem's evaluators, or None when they are not kept in this
    process (anything but the console script's ``solve``)."""
    from ..io.cache import built_entry

    return built_entry(KEPT_KIND, problem, str(samples), str(seed), shared={"problem": problem}, reducers={SubsystemResiduals: _reduce_residuals}, casadi=True)


def _evaluators_of(found: object) -> TypeGuard[list[tuple[str, str, SubsystemResiduals]]]:
    """Whether ``found`` is a kept list of evaluators (what :func:`evaluators` builds)."""
    return isinstance(found, list) and all(isinstance(e, tuple) and len(e) == 3 and type(e[2]) is SubsystemResiduals for e in found)


def _keep(found: list[tuple[str, str, SubsystemResiduals]]) -> None:
    """Keep ``found`` on disk once, after its first check (see :data:`_to_keep`)."""
    pending = _to_keep.get(id(found))
    if pending is None or pending[0] is not found:
        return
    del _to_keep[id(found)]
    pending[1].keep(found)


def _reduce_residuals(evaluator: SubsystemResiduals) -> tuple[Any, ...]:
    """An evaluator without what it rebuilds on use: the per-chunk coordinate inputs (with
    their remembered sines and cosines) and the composed arrays (sums of the per-element
    arrays, which are kept), and without the box maxima its checks found."""
    state = dict(evaluator.__dict__)
    state["_chunk_inputs"] = {}
    state["_arrays"] = None
    # the box maximum's functions, not what its checks found nor where (the refined maxima and
    # the maximisers a later check starts from): a later solve, with other options or designs,
    # starts as a cold one would, so its numbers never depend on an earlier run
    box = evaluator.box_state
    state["box_state"] = {k: box[k] for k in ("maximum", "bases", "variables") if k in box}
    if "maximum" in box:
        state["box_state"]["found"] = {}
    return (_restore_residuals, (state,))


def _restore_residuals(state: dict[str, Any]) -> SubsystemResiduals:
    evaluator = SubsystemResiduals.__new__(SubsystemResiduals)
    evaluator.__dict__.update(state)
    return evaluator


def _checked_scenarios(problem: Problem) -> tuple[Any, ...]:
    """The scenarios the dense check evaluates: all of them, except that the nodes of a tilt
    grid that differ only in their tilt are checked once, each configuration at its worst tilt of the
    whole tilt box (:func:`_at_worst_tilts`), which covers every node."""
    if not problem.tilts:
        return problem.scenarios
    seen, out = set(), []
    for s in problem.scenarios:
        key = (s.setting, s.upright, tuple(sorted(s.parameters.items()))) if s.upright is not None else s.name
        if key not in seen:
            seen.add(key)
            out.append(s)
    return tuple(out)


#: how a design is checked: ``auto`` the exact certificate (:mod:`.certificate`) where it
#: applies and proves balance, else the dense check; ``dense`` the dense check always
CHECKS = ("auto", "dense")


def check(solution: "Solution", mode: str = "dense") -> Verification:
    """The verification of ``solution`` by ``mode`` (one of :data:`CHECKS`): with ``auto``
    the certificate's (``certificate`` = ``exact``) when the residual is a trigonometric
    polynomial and its coefficients prove balance, else the dense check's (``sampled``)."""
    if mode not in CHECKS:
        raise ValueError(f"check must be one of {', '.join(CHECKS)}, got {mode!r}")
    if mode == "auto":
        from .certificate import certify

        found = certify(solution)
        if found is not None:
            return found
    return verify(solution)


def verify(solution: "Solution", samples: int | None = None, seed: int | None = None) -> Verification:
    """Check ``solution`` on random configurations plus corners, per (subsystem, scenario)."""
    problem = solution.problem
    checks = []
    found = []
    tilted = {s.name: s for s in problem.scenarios if s.upright is not None and problem.tilts}
    tilts: dict[tuple[str, str], np.ndarray] = {}
    torque_tilts: dict[tuple[str, str], np.ndarray] = {}
    for scenario, subsystem, evaluator in evaluators(solution, samples, seed):
        variables = solution.variable_values(scenario)
        gravity, base = solution.scenario_parameters[scenario]
        balanced_by: np.ndarray | None = None
        if scenario in tilted:
            r, angles, t, torque_angles, balanced_by = _at_worst_tilts(problem, tilted[scenario], evaluator, variables, base)
            tilts[(scenario, subsystem)] = angles
            torque_tilts[(scenario, subsystem)] = torque_angles
        else:
            r, t = evaluator.evaluate(variables, base, gravity)
        kinds = [REVOLUTE if problem.coordinate[name].unit.dimension == "" else PRISMATIC for name in evaluator.names]
        sampled = np.array([np.abs(t[:, j]).max() for j in range(t.shape[1])])
        found.append((scenario, subsystem, evaluator, variables, gravity, base, r, t, kinds, sampled, balanced_by))
    # the coordinates that may set the reference of their kind (see .checks) get their box maximum
    top: dict[str, float] = {}
    for *_, kinds, sampled, _ in found:
        for kind, load in zip(kinds, sampled):
            if np.isfinite(load):
                top[kind] = max(top.get(kind, 0.0), float(load))
    for scenario, subsystem, evaluator, variables, gravity, base, r, t, kinds, sampled, balanced_by in found:
        q = evaluator.q  # after evaluate: a manifold is solved again when the geometry changed
        # column by column: r and t are transposed views, and a column is contiguous
        columns = [np.abs(r[:, j]) for j in range(r.shape[1])]
        residual = np.array([c.max() for c in columns])  # NaN if any is NaN
        candidates = np.array([load >= REFERENCE_CANDIDATE * top.get(kind, 0.0) and load > 0 for kind, load in zip(kinds, sampled)], dtype=bool)
        if (scenario, subsystem) in tilts:
            # each configuration at its own worst tilt: the box maximum over the coordinates is
            # climbed at the gravity of the best configuration's tilt, coordinate by coordinate
            loads = sampled.copy()
            upright = tilted[scenario].upright
            for col in np.flatnonzero(candidates):
                if upright is None:
                    break
                at = torque_tilts[(scenario, subsystem)][int(np.nanargmax(np.abs(t[:, col]))), col]
                g_col = upright.acceleration * tilted_directions(upright.direction, problem.tilts, at[None, :])[0]
                only = np.zeros_like(candidates)
                only[col] = True
                loads[col] = _box_loads(problem, subsystem, scenario, evaluator, t, sampled, only, variables, base, tuple(float(x) for x in g_col))[col]
        else:
            loads = _box_loads(problem, subsystem, scenario, evaluator, t, sampled, candidates, variables, base, gravity)
        forces = r - t if balanced_by is None else balanced_by  # under a tilt: each at its own worst tilt
        balancers = np.array([np.abs(forces[:, j]).max() for j in range(r.shape[1])])
        scale = energy_scale_if_needed(problem, subsystem, q, residual, loads, variables, base, gravity)
        for j, name in enumerate(evaluator.names):
            column = columns[j]
            worst = int(np.nanargmax(column)) if not np.isnan(column).all() else 0
            checks.append(
                CoordinateCheck(
                    subsystem=subsystem,
                    scenario=scenario,
                    coordinate=name,
                    kind=kinds[j],
                    max_residual=float(residual[j]),
                    max_gravity_torque=float(loads[j]),
                    max_balancer_force=float(balancers[j]),
                    energy_scale=scale,
                    configurations=int(q.shape[0]),
                    worst_configuration=tuple(float(v) for v in q[worst]),
                    worst_tilt=tuple(float(a) for a in tilts[(scenario, subsystem)][worst, j]) if (scenario, subsystem) in tilts else (),
                )
            )
    if _to_keep:
        _keep(evaluators(solution, samples, seed))
    return Verification(tuple(checks), problem.settings.verify_tolerance)


def _at_worst_tilts(
    problem: Problem, scenario: Any, evaluator: SubsystemResiduals, variables: Any, base: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(residual, its tilts, unbalanced gravity torque, its tilts, balancers' force) of a
    tilting-base scenario: for each configuration and coordinate, each at the tilt of the box
    where its magnitude is largest (:func:`~counterpoise.model.tilt.tilt_extremes`); the
    tilts (N, n_coordinates, n_tilts).

    Gravity enters the energy linearly, so r(q, g) = r(q, 0) + Σₖ gₖ [r(q, eₖ) − r(q, 0)]
    exactly: four evaluations give every configuration its residual as a function of the
    tilt, whose extremes over the box are found per configuration (the box's vertices and
    the edges' and faces' stationary points, not a random tilt: issue 32)."""
    upright = scenario.upright
    r0, t0 = evaluator.evaluate(variables, base, (0.0, 0.0, 0.0))
    rk, tk = [], []
    for k in range(3):
        unit = [0.0, 0.0, 0.0]
        unit[k] = 1.0
        r_unit, t_unit = evaluator.evaluate(variables, base, tuple(unit))
        rk.append(r_unit - r0)
        tk.append(t_unit - t0)
    n, m = r0.shape
    angles = np.zeros((n, m, len(problem.tilts)))
    torque_angles = np.zeros((n, m, len(problem.tilts)))
    r, t, balancers = np.empty((n, m)), np.empty((n, m)), np.empty((n, m))
    for j in range(m):
        slope_r = np.column_stack([x[:, j] for x in rk])
        slope_t = np.column_stack([x[:, j] for x in tk])
        with np.errstate(invalid="ignore"):
            r[:, j], angles[:, j] = tilt_extremes(upright.acceleration, upright.direction, problem.tilts, r0[:, j], slope_r)
            t[:, j], torque_angles[:, j] = tilt_extremes(upright.acceleration, upright.direction, problem.tilts, t0[:, j], slope_t)
            balancers[:, j], _ = tilt_extremes(upright.acceleration, upright.direction, problem.tilts, r0[:, j] - t0[:, j], slope_r - slope_t)
    return r, angles, t, torque_angles, balancers


#: coordinates whose sampled largest gravity torque is at least this share of the largest of
#: their kind may set the reference (refining raises a sampled maximum by well under 1 %
#: with the default samples), and get their box maximum; the others keep the sampled one
REFERENCE_CANDIDATE = 0.9
#: refined box maxima kept per evaluator (a study of a body mass refines once per value)
_BOX_CACHE_SIZE = 64


def _box_loads(
    problem: Problem,
    subsystem: str,
    scenario: str,
    evaluator: SubsystemResiduals,
    t: np.ndarray,
    sampled: np.ndarray,
    candidates: np.ndarray,
    variables: Any,
    base: Any,
    gravity: Any,
) -> np.ndarray:
    """Largest |gravity torque| of each coordinate: for the ``candidates`` (those that may
    set the reference) the box maximum, refined from the best samples
    (:class:`~.residuals.BoxMaximum`); for the others the sampled maximum. Kept per
    evaluator for the values the bodies depend on, so designs that differ only in their
    balancers (a study of spring or counter-mass values) reuse it."""
    if not candidates.any() or not np.all(np.isfinite(sampled)) or isinstance(evaluator, ManifoldResiduals):
        return sampled  # on a loop's manifold the reference is the sampled maximum (docs/loops.md)
    state = evaluator.box_state
    if "maximum" not in state:
        used = set().union(*(e.geometry | ex.names(e.factor) for e in evaluator.elements if e.is_body))
        state["maximum"] = BoxMaximum(problem, subsystem)
        state["bases"] = _base_parameters(problem, used)
        state["variables"] = tuple(sorted(used & set(problem.variable)))
        state["found"] = {}
    key = (scenario, tuple(candidates), tuple(gravity), tuple(base[n] for n in state["bases"]), tuple(variables[n] for n in state["variables"]))
    found = state["found"]
    if key not in found:
        magnitude = np.abs(t)
        if BOX_MAXIMUM_STARTS == 1:
            best = np.argmax(magnitude, axis=0)[None, :]
        else:
            k = min(BOX_MAXIMUM_STARTS, t.shape[0])
            best = np.argpartition(magnitude, t.shape[0] - k, axis=0)[-k:]  # (K, n): the best samples of each coordinate
        starts = evaluator.q[best]
        previous = state.setdefault("maximisers", {}).get((scenario, tuple(candidates)))
        if previous is not None:  # where the maximum was for the previous values: usually one Newton step away
            starts = np.concatenate([starts, np.nan_to_num(previous.T, nan=0.0)[None]])
        refined, where = state["maximum"].refine(starts, variables, base, gravity, np.flatnonzero(candidates))
        state["maximisers"][(scenario, tuple(candidates))] = where
        loads = sampled.copy()
        ok = candidates & np.isfinite(refined)
        loads[ok] = np.maximum(sampled[ok], refined[ok])
        if len(found) >= _BOX_CACHE_SIZE:
            found.pop(next(iter(found)))
        found[key] = loads
    return found[key]
