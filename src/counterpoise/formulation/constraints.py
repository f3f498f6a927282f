"""Design constraints as rows of an NLP/LP, and their values at a design.

A :class:`~counterpoise.model.constraints.Constraint` ``lower ≤ E ≤ upper`` becomes, per
scenario, rows ``lbg ≤ g(z, p) ≤ ubg`` (scaled by the bounds' size):

- named quantities at home (``force_home``, ``x_home``, ``added_mass()``...) are exact
  CasADi expressions of the design: one row;
- a workspace extreme (``force_max(s)``...) enters linearly with the sign that its bound
  limits (the resolver checks it), so ``E(max_q F) ≤ U`` is exactly ``E(F(q)) ≤ U`` for
  every q: one row per sampled configuration of the spring's subsystem (random points
  and the corners of its box, or of the configuration manifold for closed loops) and per
  configuration the dense check found to be worse (:func:`dense_extremes`; the designers
  add those and solve again, a bounded number of rounds).

The same functions evaluate the constraints at a design with numpy (:func:`evaluate`):
the values in design.csv, with the extremes from the dense sample.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..mechanics import Mechanics, casadi_functions
from ..mechanics.cable import LENGTH_FLOOR, spring_quantities  # noqa: F401 - LENGTH_FLOOR re-exported
from ..mechanics.kinematics import dot, sub
from ..mechanics.sampling import configurations
from ..model import expr as ex
from ..model.constraints import COUNTER_MASS_HOME, FORCE_LIMIT, SPRING_EXTREMES, Constraint
from ..model.elements import ZeroFreeLengthSpring
from ..model.functions import NUMPY_FUNCTIONS
from ..model.problem import Problem

#: sampled configurations per coordinate of a spring's subsystem for its workspace extremes
#: (plus the corners of the box)
SAMPLES_PER_COORDINATE = 32
#: scaled rows may miss their bound by this much in the polishing steps (rounding)
CONSTRAINT_SLACK = 1e-9
#: a constraint is active when its value is within this share of its scale from a bound
ACTIVE_TOLERANCE = 1e-6
#: a sampled constraint is violated at the dense check's extreme beyond this share of its scale
VIOLATION_TOLERANCE = 1e-7
#: verification rounds: add the violating configurations and solve again, at most this often
MAX_ROUNDS = 4

Extra = Mapping[tuple[str, str], np.ndarray]  # (spring, scenario) -> configurations (N, n_q)


def spring_force_length(mech: Mechanics, spring: ZeroFreeLengthSpring) -> tuple[Any, Any]:
    """(pull, distance between the ends) of ``spring`` (:func:`spring_quantities`)."""
    q = spring_quantities(mech, spring)
    return q["force"], q["length"]


#: the order of a spring's quantities in the rows' mapped functions
QUANTITIES = ("force", "length", "wrap")


def functions(mech: Mechanics, extreme: Any = None) -> dict[str, Any]:
    """The named quantities of ``mech`` (any backend) as expression functions; a workspace
    extreme is ``extreme`` (a symbol or a number)."""
    p = mech.problem
    springs = {s.name: s for s in p.springs}
    masses = {c.name: c for c in p.counter_masses}
    out: dict[str, Any] = dict(mech.functions)
    out["total_mass"] = ex.NameArgs(mech.total_mass)
    out["com_distance"] = ex.NameArgs(mech.com_distance)
    out["added_mass"] = ex.NameArgs(lambda: mech.added_mass())
    out["added_inertia"] = ex.NameArgs(lambda: mech.added_inertia())
    out["force_home"] = ex.NameArgs(lambda s: spring_force_length(mech, springs[s])[0])
    out["length_home"] = ex.NameArgs(lambda s: spring_force_length(mech, springs[s])[1])
    for name, axis in COUNTER_MASS_HOME.items():
        out[name] = ex.NameArgs(lambda c, i=axis: mech.position(masses[c].position)[i])
    for name in SPRING_EXTREMES:
        out[name] = ex.NameArgs(lambda s: extreme)
    return out


def environment(mech: Mechanics, fns: Mapping[str, Any], expr: Any = None) -> dict[str, Any]:
    """``mech``'s names plus the report quantities (which constraints may use): those
    ``expr`` uses, directly or through other report quantities (all of them without ``expr``:
    evaluating every report quantity after every solve of a study cost more than the solve)."""
    env = dict(mech.env)
    report = mech.problem.report
    wanted: set[str] | None = None
    if expr is not None:
        by_name = {q.name: q for q in report}
        wanted, todo = set(), [n for n in ex.names(expr) if n in by_name]
        while todo:
            name = todo.pop()
            if name not in wanted:
                wanted.add(name)
                todo.extend(n for n in ex.names(by_name[name].expr) if n in by_name)
    for q in report:
        if wanted is None or q.name in wanted:
            env[q.name] = ex.evaluate(q.expr, env, fns)
    return env


def scale(c: Constraint) -> float:
    """The size a constraint's rows are divided by: its largest bound (SI), or 1."""
    size = max(abs(c.lower or 0.0), abs(c.upper or 0.0))
    return size if size > 0 else 1.0


def sample(problem: Problem, spring: ZeroFreeLengthSpring, scenario: str, rng: np.random.Generator) -> np.ndarray:
    """Sampled configurations of the spring's subsystem (its coordinates' order): (N, n_q)."""
    if spring.subsystem is None:
        return np.zeros((1, 0))
    coords = problem.subsystem_coordinates(spring.subsystem)
    if problem.subsystem_loops(spring.subsystem):
        from ..mechanics.closure import manifold_configurations, scenario_base  # only for closed loops (~3 ms to import)

        n_i = sum(1 for c in coords if not c.dependent)
        return manifold_configurations(problem, spring.subsystem, SAMPLES_PER_COORDINATE * n_i, rng, scenario_base(problem, scenario)).q
    return configurations(problem, spring.subsystem, SAMPLES_PER_COORDINATE * len(coords), rng)


@dataclass(frozen=True)
class RowGroup:
    """The rows of one constraint in one scenario."""

    constraint: Constraint
    scenario: str
    start: int
    stop: int
    scale: float
    #: workspace extremes: the spring and the configurations of its rows (N, n_q)
    spring: str | None = None
    configurations: np.ndarray | None = None


@dataclass
class ConstraintRows:
    """Every constraint's rows: ``g`` (CasADi), their bounds and where each constraint is."""

    g: Any
    lbg: np.ndarray
    ubg: np.ndarray
    groups: list[RowGroup] = field(default_factory=list)
    #: dense configurations per (spring, scenario), drawn once (see :func:`dense_sample`)
    dense: dict[tuple[str, str], np.ndarray] = field(default_factory=dict)

    @property
    def count(self) -> int:
        return int(self.lbg.size)

    def margins(self) -> Any:
        """Scaled slack of every finite side (≥ 0 when the rows hold, to rounding)."""
        import casadi as ca

        parts = []
        lo, hi = np.isfinite(self.lbg), np.isfinite(self.ubg)
        for i in range(self.count):
            if lo[i]:
                parts.append(self.g[i] - self.lbg[i] + CONSTRAINT_SLACK)
            if hi[i]:
                parts.append(self.ubg[i] - self.g[i] + CONSTRAINT_SLACK)
        return ca.vertcat(*parts) if parts else ca.SX(0, 1)

    def sensitivity(self, group: RowGroup, multipliers: np.ndarray | None) -> float:
        """∂(optimal objective)/∂(active bound), SI: −Σ λ of the group's rows / scale."""
        if multipliers is None or multipliers.size < self.count:
            return float("nan")
        return float(-np.sum(multipliers[group.start : group.stop]) / group.scale)


def build_rows(formulation: Any, extra: Extra | None = None) -> ConstraintRows:
    """The rows of every constraint of ``formulation.problem`` (see the module docstring).
    ``extra``: configurations to add per (spring, scenario), found by the dense check."""
    import casadi as ca

    f = formulation
    problem: Problem = f.problem
    rng = np.random.default_rng(problem.settings.seed + 11)
    cas = casadi_functions()
    springs = {s.name: s for s in problem.springs}
    rows: list[Any] = []
    lbg: list[float] = []
    ubg: list[float] = []
    groups: list[RowGroup] = []
    home = {k.name: k.home for k in problem.coordinates}
    samples: dict[tuple[str, str], np.ndarray] = {}
    mapped: dict[tuple[str, str], Any] = {}
    for c, scenario in enumerate(problem.scenarios):
        gravity, base = f.parameters.split(f.p, c)
        variables = f.design.symbols(f.x, scenario.name)
        mech = Mechanics(problem, base, variables, home, gravity, cas)
        for con in problem.constraints:
            e = ca.SX.sym("extreme")
            fns = functions(mech, e)
            value = ex.evaluate(con.expr, environment(mech, fns, con.expr), fns)
            s = scale(con)
            start = len(lbg)
            call = con.extreme()
            if call is None:
                rows.append(ca.SX(value) / s)
                lbg.append(con.lower / s if con.lower is not None else -np.inf)
                ubg.append(con.upper / s if con.upper is not None else np.inf)
                groups.append(RowGroup(con, scenario.name, start, start + 1, s))
                continue
            spring = springs[call.args[0].id]  # type: ignore[union-attr]  # the loader checked the argument is a name
            key = (spring.name, scenario.name)
            if key not in samples:
                q = sample(problem, spring, scenario.name, rng)
                if extra and key in extra and len(extra[key]):
                    q = np.vstack([q, np.asarray(extra[key], dtype=float).reshape(-1, q.shape[1])])
                samples[key] = q
                names = [k.name for k in problem.subsystem_coordinates(spring.subsystem)] if spring.subsystem else []
                qs = ca.SX.sym("q", len(names))
                moving = Mechanics(problem, base, variables, {**home, **{n: qs[i] for i, n in enumerate(names)}}, gravity, cas)
                state = spring_quantities(moving, spring)
                fun = ca.Function("spring_extremes", [qs, f.z, f.p], [ca.vertcat(*(state[name] for name in QUANTITIES))])
                mapped[key] = fun.map(q.shape[0])(ca.DM(q.T), f.z, f.p)  # (3, N)
            q = samples[key]
            quantity = SPRING_EXTREMES[call.func][0]
            values = mapped[key][QUANTITIES.index(quantity), :].T  # (N, 1)
            offset = ca.substitute(ca.SX(value), e, ca.SX(0))
            slope = ca.jacobian(ca.SX(value), e)
            rows.append((offset + slope * values) / s)
            n = q.shape[0]
            lbg += [con.lower / s if con.lower is not None else -np.inf] * n
            ubg += [con.upper / s if con.upper is not None else np.inf] * n
            groups.append(RowGroup(con, scenario.name, start, start + n, s, spring.name, q))
    g = ca.vertcat(*rows) if rows else ca.SX(0, 1)
    return ConstraintRows(g, np.array(lbg, dtype=float), np.array(ubg, dtype=float), groups)


# -- values at a design (numpy) --------------------------------------------------------


@dataclass(frozen=True)
class ConstraintValue:
    """A constraint at a design, in one scenario (SI)."""

    name: str
    scenario: str
    value: float
    lower: float | None
    upper: float | None
    #: 'lower', 'upper' or '' (within ACTIVE_TOLERANCE × scale); 'violated' beyond VIOLATION_TOLERANCE
    active: str
    #: ∂(optimal objective)/∂(active bound) in SI (objective units per constraint unit), from
    #: the solver's multipliers; NaN when the solver gave none
    sensitivity: float
    constraint: Constraint
    #: workspace extremes: the configuration of the extreme (coordinate name -> SI value)
    configuration: dict[str, float] | None = None
    #: an infeasible constrained design: how much (SI) the elastic problem relaxed this
    #: constraint by, in the design reported (0: not relaxed)
    relaxed: float = 0.0
    #: a [robust] design: the tolerance corner where the constraint is closest to (or beyond)
    #: its bounds, as text ("rate spring_1 +10 %"; "nominal"); "" for a design without [robust]
    corner: str = ""


def _extreme(problem: Problem, spring: ZeroFreeLengthSpring, quantity: str, side: str, base: Mapping[str, float], gravity: Sequence[float],
             variables: Mapping[str, float], q: np.ndarray) -> tuple[float, int, np.ndarray]:
    """(extreme value, index of its configuration, all values) of a spring's force or
    length over the configurations ``q`` (N, n_q)."""
    home = {k.name: k.home for k in problem.coordinates}
    names = [k.name for k in problem.subsystem_coordinates(spring.subsystem)] if spring.subsystem else []
    coords = {**home, **{n: q[:, i] for i, n in enumerate(names)}}
    mech = Mechanics(problem, base, variables, coords, gravity, NUMPY_FUNCTIONS)
    values = np.broadcast_to(np.asarray(spring_quantities(mech, spring)[quantity], dtype=float), (q.shape[0],))
    i = int(np.nanargmax(values) if side == "max" else np.nanargmin(values))
    return float(values[i]), i, values


def _refine(problem: Problem, spring: ZeroFreeLengthSpring, quantity: str, side: str, base: Mapping[str, float], gravity: Sequence[float],
            variables: Mapping[str, float], q0: np.ndarray, value: float) -> tuple[float, np.ndarray]:
    """The dense sample's extreme polished by a pattern search within the box (open chains):
    steps of ± h along each coordinate, h halved when no step improves, from the dense
    sample's spacing down to 1e-12 of the range. Between dense points the extreme is then
    found to rounding, wherever it is smooth."""
    coords = problem.subsystem_coordinates(spring.subsystem)  # type: ignore[arg-type]  # only springs in a subsystem have extremes
    lo = np.array([c.lower for c in coords])
    hi = np.array([c.upper for c in coords])
    n = len(coords)
    span = np.where(hi > lo, hi - lo, 0.0)
    h = span / max(2.0, problem.settings.verify_samples ** (1.0 / max(n, 1)))
    best, best_value = np.asarray(q0, dtype=float).copy(), value
    sign = 1.0 if side == "max" else -1.0
    steps = np.vstack([np.eye(n), -np.eye(n)])
    for _ in range(200):
        if not np.any(h > 1e-12 * span):
            break
        trial = np.clip(best + steps * h, lo, hi)
        v, i, values = _extreme(problem, spring, quantity, side, base, gravity, variables, trial)
        if sign * (v - best_value) > 0:
            best, best_value = trial[i], v
        else:
            h = h / 2
    return best_value, best


def dense_sample(problem: Problem, spring: ZeroFreeLengthSpring, scenario: str, samples: int | None = None) -> np.ndarray:
    """The dense configurations on which extremes are checked (the verification's count)."""
    rng = np.random.default_rng(problem.settings.seed + 13)
    n = samples if samples is not None else problem.settings.verify_samples
    if spring.subsystem is None:
        return np.zeros((1, 0))
    if problem.subsystem_loops(spring.subsystem):
        from ..mechanics.closure import manifold_configurations, scenario_base  # only for closed loops

        return manifold_configurations(problem, spring.subsystem, n, rng, scenario_base(problem, scenario)).q
    return configurations(problem, spring.subsystem, n, rng)


#: a workspace extreme is polished by the pattern search only when its constraint is within
#: this share of its bound's scale (:func:`scale`) of the bound, or beyond it
REFINE_MARGIN = 0.05


def _value(problem: Problem, con: Constraint, base: Mapping[str, float], variables: Mapping[str, float], home: Mapping[str, float],
           gravity: Sequence[float], extreme_value: float | None) -> float:
    """The constraint's value at the design, with ``extreme_value`` for its workspace extreme."""
    mech = Mechanics(problem, base, variables, home, gravity, NUMPY_FUNCTIONS)
    fns = functions(mech, extreme_value)
    with np.errstate(all="ignore"):
        try:
            return float(ex.evaluate(con.expr, environment(mech, fns, con.expr), fns))
        except (ArithmeticError, ValueError):
            return float("nan")


def _margin(problem: Problem, con: Constraint, base: Mapping[str, float], variables: Mapping[str, float], home: Mapping[str, float],
            gravity: Sequence[float], extreme_value: float) -> float:
    """How far inside its bounds the constraint is (relative to :func:`scale`; < 0: violated)."""
    value = _value(problem, con, base, variables, home, gravity, extreme_value)
    if not np.isfinite(value):
        return -np.inf
    s = scale(con)
    room = [np.inf]
    if con.upper is not None:
        room.append((con.upper - value) / s)
    if con.lower is not None:
        room.append((value - con.lower) / s)
    return float(min(room))


def evaluate(problem: Problem, solution: Any, rows: ConstraintRows | None, multipliers: np.ndarray | None,
             dense: Mapping[tuple[str, str], np.ndarray] | None = None) -> tuple[ConstraintValue, ...]:
    """Every constraint at ``solution`` (a :class:`~counterpoise.designer.solution.Solution`),
    per scenario: home quantities exactly, extremes over the sampled rows and the dense
    configurations ``dense`` (per (spring, scenario); default: :func:`dense_sample`)."""
    springs = {s.name: s for s in problem.springs}
    home = {k.name: k.home for k in problem.coordinates}
    groups = {(g.constraint.name, g.scenario): g for g in (rows.groups if rows is not None else [])}
    out = []
    for scenario in problem.scenarios:
        gravity, base = solution.scenario_parameters[scenario.name]
        variables = solution.variable_values(scenario.name)
        for con in problem.constraints:
            call = con.extreme()
            configuration = None
            extreme_value = None
            if call is not None:
                spring = springs[call.args[0].id]  # type: ignore[union-attr]  # the loader checked the argument is a name
                quantity, side = SPRING_EXTREMES[call.func]
                group = groups.get((con.name, scenario.name))
                key = (spring.name, scenario.name)
                cache = rows.dense if rows is not None else {}
                rows_q = group.configurations if group is not None and group.configurations is not None else None
                if dense and key in dense:
                    cache[key] = dense[key]
                elif key not in cache:
                    cache[key] = dense_sample(problem, spring, scenario.name)
                qs = [cache[key]]
                if rows_q is not None:
                    qs.append(rows_q)
                q = np.vstack([x.reshape(-1, qs[0].shape[1]) for x in qs]) if qs[0].shape[1] else qs[0]
                found, i, _ = _extreme(problem, spring, quantity, side, base, gravity, variables, q)
                best = q[i]
                # polish the dense extreme only where it matters: a constraint within REFINE_MARGIN
                # of its bound (or beyond it); far inside, the few per mille the pattern search
                # adds between dense points cannot reach the bound (and it costs more than the solve)
                refine = spring.subsystem is not None and not problem.subsystem_loops(spring.subsystem)
                if refine and _margin(problem, con, base, variables, home, gravity, found) > REFINE_MARGIN:
                    refine = False
                if refine:
                    found, best = _refine(problem, spring, quantity, side, base, gravity, variables, best, found)
                extreme_value = found
                names = [k.name for k in problem.subsystem_coordinates(spring.subsystem)] if spring.subsystem else []
                configuration = {n: float(best[j]) for j, n in enumerate(names)}
            value = _value(problem, con, base, variables, home, gravity, extreme_value)
            s = scale(con)
            group = groups.get((con.name, scenario.name))
            sensitivity = rows.sensitivity(group, multipliers) if rows is not None and group is not None else float("nan")
            out.append(ConstraintValue(con.name, scenario.name, value, con.lower, con.upper, _active(value, con, s), sensitivity, con, configuration))
    return tuple(out)


def _active(value: float, con: Constraint, s: float) -> str:
    if value != value:
        return ""
    if (con.upper is not None and value > con.upper + VIOLATION_TOLERANCE * s) or (con.lower is not None and value < con.lower - VIOLATION_TOLERANCE * s):
        return "violated"
    if con.upper is not None and abs(value - con.upper) <= ACTIVE_TOLERANCE * s:
        return "upper"
    if con.lower is not None and abs(value - con.lower) <= ACTIVE_TOLERANCE * s:
        return "lower"
    return ""


def violations(problem: Problem, values: Sequence[ConstraintValue]) -> dict[tuple[str, str], np.ndarray]:
    """Configurations to add per (spring, scenario): where a sampled constraint is violated."""
    springs = {s.name: s for s in problem.springs}
    out: dict[tuple[str, str], list[list[float]]] = {}
    for v in values:
        call = v.constraint.extreme()
        if call is None or v.active != "violated" or v.configuration is None or v.relaxed > 0:
            continue  # a relaxed one: the conflict's elastic design misses it on purpose
        spring = springs[call.args[0].id]  # type: ignore[union-attr]  # the loader checked the argument is a name
        if spring.subsystem is None:
            continue  # no coordinates: the rows already hold the one configuration there is
        names = [k.name for k in problem.subsystem_coordinates(spring.subsystem)]
        out.setdefault((spring.name, v.scenario), []).append([v.configuration[n] for n in names])
    return {k: np.array(x, dtype=float) for k, x in out.items()}


def merge(extra: Extra, add: Extra) -> dict[tuple[str, str], np.ndarray]:
    """``extra`` with the configurations ``add`` appended (per (spring, scenario))."""
    out = {k: np.asarray(v, dtype=float) for k, v in extra.items()}
    for k, v in add.items():
        out[k] = np.vstack([out[k], v]) if k in out else np.asarray(v, dtype=float)
    return out


def describe(problem: Problem, v: ConstraintValue) -> str:
    """'shoulder.max_force: 60 N at its upper bound (shoulder_lift=12.3 deg)' for status.txt."""
    u = v.constraint.unit
    bound = v.upper if v.active == "upper" else v.lower
    text = f"{v.name} = {u.from_si(v.value):.6g} {u.label}".rstrip()
    if v.constraint.kind == FORCE_LIMIT and v.active == "upper":
        text = f"{v.name}: spring {v.constraint.spring} pulls {u.from_si(v.value):.6g} {u.label}, its largest force"
    elif v.active in ("upper", "lower") and bound is not None:
        text += f" at its {v.active} bound"
    elif v.active == "violated":
        above = v.upper is not None and v.value > v.upper
        limit = v.upper if above else v.lower
        text += f" beyond its {'upper' if above else 'lower'} bound {u.from_si(limit):.6g} {u.label}" if limit is not None else " violated"
    if v.configuration:
        at = ", ".join(f"{n}={problem.coordinate[n].unit.from_si(x):.4g} {problem.coordinate[n].unit.label}".rstrip() for n, x in v.configuration.items())
        text += f" (at {at})"
    if v.corner:
        text += f" at the tolerance corner {v.corner}"
    if len(problem.scenarios) > 1:
        text += f" in scenario '{v.scenario}'"
    return text
