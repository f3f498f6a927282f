"""After a solve: a designed helical extension spring for every free-stiffness spring.

Each spring of the problem with a ``stiffness`` (no ``slot``) gets its requirement from the
solved design over the dense sample of the workspace (the same random configurations plus
box corners, or configuration-manifold samples for closed loops, that catalogue parts are
checked on, drawn here from the mechanics layer; a payload range: every payload of its
schedule):

- behind a pulley (the default mount, docs/springs.md): the cable outside the pulley is
  d = |from − to| long and the spring pulls F = k·d, so the working forces are k·d_min to
  k·d_max; the design chooses its initial tension F0 ≤ k (d_min − slack_margin) (the
  cable never goes slack) and its length is L = d + L0 − F0/k;
- directly attached (``mount = "direct"``): the spring is d − cable long, pulls
  F = F0 + k (d − cable − L0) with the file's initial tension F0 and free length L0, and
  must be wound with that F0 and fit that L0 (the hooks take up what the body leaves).

Each spring's envelope is the file's (``max_length``, ``max_outer_diameter``,
``max_body_length``; a direct mount's ``max_length``), and where the file gives none, a
default tied to the mechanism's size (:func:`mechanism_size`, :data:`LENGTH_SHARE`,
:data:`DIAMETER_SHARE`).

:func:`designed_springs` returns one :class:`DesignedSpring` per spring and scenario, and
one with ``scenario = "all"`` per spring when there are several scenarios (extremes over
all of them: the one spring that is made).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, TypeGuard

import numpy as np

from .design import Envelope, Requirement, SpringDesign, design

if TYPE_CHECKING:
    from ..io.cache import BuiltEntry

#: the seed offset of the dense sample (the one catalogue parts are checked on)
SEED_OFFSET = 11
#: scenario label of a spring's extremes over every scenario
ALL = "all"
#: scenarios evaluated at once (memory: CHUNK × verify_samples values per spring)
CHUNK = 64
#: rates that differ by less than this share are one rate (rounding of a shared variable)
RATE_SPREAD = 1e-9
#: the default envelope (docs/springs.md, "Envelope"): a designed spring's working length,
#: hooks included, at most this many times the mechanism's size (:func:`mechanism_size`)
LENGTH_SHARE = 2.0
#: and its outer diameter at most this share of it
DIAMETER_SHARE = 0.1


@dataclass(frozen=True)
class DesignedSpring:
    """A free-stiffness spring, its working range in one scenario (or ``all``) and the
    helical spring designed for it (SI)."""

    spring: str
    scenario: str
    mount: str  # "pulley" or "direct"
    distance_min: float  # between the attachment points
    distance_max: float
    cable: float  # directly attached: the cable in series (0 behind a pulley)
    design: SpringDesign

    @property
    def ok(self) -> bool:
        return self.design.ok

    @property
    def force_min(self) -> float:
        """The smallest working force of the wound spring (of the requirement when none
        could be designed)."""
        return self._force(self.design.requirement.force_min)

    @property
    def force_max(self) -> float:
        return self._force(self.design.requirement.force_max)

    def _force(self, force: float) -> float:
        return self.design.wound_force(force) if self.design.ok else force

    @property
    def length_min(self) -> float:
        """The spring's own length (hooks included) at the shortest distance."""
        return self.design.length_min

    @property
    def length_max(self) -> float:
        return self.design.length_max

    @property
    def margin_slack(self) -> float:
        """Extension at the shortest distance, (F_min − F0)/k (m; ≥ 0: the spring stays
        extended and pulls as the balance needs; < 0: the cable goes slack; behind a pulley
        a design keeps it ≥ the slack margin)."""
        return (self.force_min - self.design.initial_tension) / self.design.rate

    @property
    def margin_load(self) -> float:
        return self.design.max_force - self.force_max

    @property
    def margin_length(self) -> float:
        return self.design.max_length - self.length_max


def free_springs(problem: Any) -> list[Any]:
    """The springs of ``problem`` whose stiffness is given or designed (no catalogue slot)."""
    return [s for s in problem.springs if s.slot is None]


def sample(problem: Any, base: Mapping[str, float], samples: int, seed: int) -> dict[str, np.ndarray]:
    """Per subsystem: ``samples`` random configurations plus the corners of its box, on
    the configuration manifold (geometry ``base``) for closed loops. The same draws as the
    sample catalogue parts are checked on (:func:`counterpoise.selection.geometry.sample_configurations`,
    for one geometry), from the mechanics layer alone: the after-solve path imports no part search.

    ``counterpoise solve`` keeps the draws on disk (:mod:`counterpoise.io.cache`, kind
    :data:`KEPT_KIND`): its later runs of the same file read them instead of drawing them
    again (and of importing ``numpy.random``, ~10 ms)."""
    entry = _kept_entry(problem, base, samples, seed)

    def valid(found: object) -> TypeGuard[dict[str, np.ndarray]]:
        return _valid(found, problem, samples)

    kept = entry.fetch(valid) if entry is not None else None
    if kept is not None:
        return kept
    from ..mechanics.closure import manifold_configurations
    from ..mechanics.sampling import configurations

    rng = np.random.default_rng(seed)
    out = {}
    for s in problem.subsystems:
        if problem.subsystem_loops(s.name):
            out[s.name] = manifold_configurations(problem, s.name, samples, rng, base).q
        else:
            out[s.name] = configurations(problem, s.name, samples, rng)
    if entry is not None:
        entry.keep(out)
    return out


#: the kind of :mod:`counterpoise.io.cache`'s built entries that hold a problem's dense sample
KEPT_KIND = "workspace"


def _kept_entry(problem: Any, base: Mapping[str, float], samples: int, seed: int) -> BuiltEntry | None:
    """The disk entry of a sample, or None when built objects are not kept in this process
    (anything but the console script's ``solve``). The geometry ``base`` counts only where
    the problem has closed loops (an open chain's draws do not use it)."""
    from ..io.cache import built_entry
    from ..model.digest import digest

    geometry = digest({str(k): float(v) for k, v in base.items()}) if problem.loops else ""
    return built_entry(KEPT_KIND, problem, str(samples), str(seed), geometry)


def _valid(kept: object, problem: Any, samples: int) -> TypeGuard[dict[str, np.ndarray]]:
    """Whether ``kept`` is a sample of ``problem``'s subsystems as :func:`sample` draws it."""
    if not isinstance(kept, dict) or list(kept) != [s.name for s in problem.subsystems]:
        return False
    for s in problem.subsystems:
        q = kept[s.name]
        if type(q) is not np.ndarray or q.dtype != np.float64 or q.ndim != 2 or q.shape[1] != len(problem.subsystem_coordinates(s.name)) or q.shape[0] < samples:
            return False
    return True


def distances(problem: Any, springs: list[Any], q: Mapping[str, np.ndarray], variables: Mapping[str, Any], base: Mapping[str, Any], gravity: Any) -> dict[str, np.ndarray]:
    """|from − to| of each spring: (designs, configurations) arrays, designs (scenarios)
    along axis 0 as in ``variables`` and ``base`` ((n, 1) arrays)."""
    from ..mechanics import NUMPY_FUNCTIONS, Mechanics
    from ..mechanics.kinematics import dot, sub

    out: dict[str, np.ndarray] = {}
    mechs: dict[Any, Any] = {}
    for spring in springs:
        key = spring.subsystem
        if key not in mechs:
            if key is not None:
                coords = {c.name: q[key][None, :, i] for i, c in enumerate(problem.subsystem_coordinates(key))}
            else:  # fixed to ground at both ends: one column
                coords = {c.name: np.array([[c.home]]) for c in problem.coordinates}
            mechs[key] = Mechanics(problem, base, variables, coords, gravity, NUMPY_FUNCTIONS)
        mech = mechs[key]
        v = sub(mech.position(spring.ends[0]), mech.position(spring.ends[1]))
        out[spring.name] = np.sqrt(np.maximum(np.atleast_2d(np.asarray(dot(v, v), dtype=float)), 0.0))
    return out


def designed_springs(solution: Any, checked: Any = None, tuned: Mapping[str, Any] | None = None) -> tuple[DesignedSpring, ...]:
    """One :class:`DesignedSpring` per free-stiffness spring and scenario of ``checked``
    (the solution the working range is measured on: a payload design's schedule, one
    scenario per payload; None: ``solution`` itself), plus one per spring over ``all``
    scenarios when there are several. ``tuned``: per spring, the forces and distances it
    must also serve (a [robust] design's tuned corners, :mod:`counterpoise.robust.limits`).
    Empty when the problem has no such spring."""
    if not free_springs(solution.problem):
        return ()
    from ..mechanics import Mechanics

    checked = solution if checked is None else checked
    problem = checked.problem
    springs = free_springs(problem)
    # per spring: scenario -> (rate, d_min, d_max, cable, F0, L0)
    found: dict[str, dict[str, tuple[float, ...]]] = {s.name: {} for s in springs}
    # scenarios with the same values (working modes differ in gravity alone) are evaluated
    # once; scenarios that share a geometry of their closed loops share one sample
    unique: dict[tuple[Any, ...], str] = {}
    same: dict[str, str] = {}
    every: dict[str, tuple[dict[str, float], dict[str, float]]] = {}
    groups: dict[tuple[Any, ...], list[str]] = {}
    loops = [s.name for s in problem.subsystems if problem.subsystem_loops(s.name)]
    if loops:  # mechanics.closure (~3 ms to import) for closed loops only
        from ..mechanics.closure import geometry_key
    for sc in problem.scenarios:
        values, base = checked.variable_values(sc.name), checked.scenario_parameters[sc.name][1]
        key = (tuple(sorted(values.items())), tuple(sorted(base.items())))
        same[sc.name] = unique.setdefault(key, sc.name)
        every[sc.name] = (values, base)
        if same[sc.name] == sc.name:
            groups.setdefault(tuple(geometry_key(problem, name, base) for name in loops), []).append(sc.name)
    settings = problem.settings
    size = 0.0  # the mechanism's size: the largest over the scenarios
    for names in groups.values():
        q = sample(problem, every[names[0]][1], settings.verify_samples, settings.seed + SEED_OFFSET)
        for start in range(0, len(names), CHUNK):  # scenarios along axis 0, configurations along axis 1
            chunk = names[start : start + CHUNK]
            values = [every[name][0] for name in chunk]
            bases = [every[name][1] for name in chunk]
            gravity = checked.scenario_parameters[chunk[0]][0]  # positions do not depend on it
            variables = {k: np.array([[v[k]] for v in values]) for k in values[0]}
            base = {k: np.array([[b[k]] for b in bases]) for k in bases[0]}
            lengths = distances(problem, springs, q, variables, base, gravity)
            mech = Mechanics(problem, base, variables, {c.name: c.home for c in problem.coordinates}, gravity)
            size = max(size, mechanism_size(problem, mech))

            def each(tree: Any) -> np.ndarray:
                return np.broadcast_to(np.asarray(mech.value(tree), dtype=float).reshape(-1), (len(chunk),))

            for s in springs:
                d = np.broadcast_to(lengths[s.name], (len(chunk), lengths[s.name].shape[1]))
                columns = [each(s.stiffness), d.min(axis=1), d.max(axis=1)]
                nan = np.full(len(chunk), np.nan)
                if s.direct is None:
                    columns += [np.zeros(len(chunk)), nan, nan, nan]
                else:
                    longest = each(s.direct.max_length) if s.direct.max_length is not None else nan
                    columns += [each(s.direct.cable), each(s.direct.initial_tension), each(s.direct.free_length), longest]
                for j, name in enumerate(chunk):
                    found[s.name][name] = tuple(float(c[j]) for c in columns)
    out: list[DesignedSpring] = []
    for s in springs:
        rows = {sc.name: found[s.name][same[sc.name]] for sc in problem.scenarios}
        needs = {name: _requirement(s, *values[:6]) for name, values in rows.items()}
        if len(rows) > 1:  # the extremes over every scenario (the file's F0 and L0 are the first's)
            first = next(iter(needs.values()))
            rows[ALL] = (first.rate, min(v[1] for v in rows.values()), max(v[2] for v in rows.values()), *next(iter(rows.values()))[3:])
            needs[ALL] = replace(first, force_min=min(r.force_min for r in needs.values()), force_max=max(r.force_max for r in needs.values()))
        _widen_for_tuning((tuned or {}).get(s.name), needs, rows)
        rates = [r.rate for r in needs.values()]
        o = s.design
        made = design(needs.get(ALL, first_of(needs)), o.material, envelope(o, size, next(iter(rows.values()))[6]), o.rate_tolerance, o.min_safety_factor)
        if max(rates) - min(rates) > RATE_SPREAD * max(rates):
            why = f"its rate changes between scenarios ({min(rates):.6g}-{max(rates):.6g} N/m): no one spring has them all"
            made = SpringDesign(made.material, made.requirement, reasons=(why,), rate_tolerance=made.rate_tolerance)
        out.extend(_use(s, name, rows[name], needs[name], made) for name in rows)
    return tuple(out)


def _widen_for_tuning(envelope: Any, needs: dict[str, Requirement], rows: dict[str, tuple[float, ...]]) -> None:
    """A [robust] design with ``tune``: the spring that is made serves every tuned corner
    (its forces and distances there, ``envelope``: the robust report's, counterpoise.robust.limits),
    so the requirement of the spring made (and its distances: the cable) is widened to it."""
    if envelope is None:
        return
    key = ALL if ALL in needs else next(iter(needs))
    need = needs[key]
    needs[key] = replace(need, force_min=min(need.force_min, envelope.force_min), force_max=max(need.force_max, envelope.force_max))
    row = rows[key]
    rows[key] = (row[0], min(row[1], envelope.distance_min), max(row[2], envelope.distance_max), *row[3:])


def first_of(needs: dict[str, Requirement]) -> Requirement:
    return next(iter(needs.values()))


def envelope(options: Any, size: float, direct_max_length: float = math.nan) -> Envelope:
    """A spring's envelope: the file's limits (``options``: its ``SpringDesignOptions``; a
    direct mount's ``max_length``, m, NaN: none), and for the working length and the outer
    diameter the file leaves open, the defaults :data:`LENGTH_SHARE` and
    :data:`DIAMETER_SHARE` × the mechanism's ``size`` (m; none when the size is 0)."""
    longest = options.max_length
    if longest is None and math.isfinite(direct_max_length):
        longest = direct_max_length
    default = size > 0 and math.isfinite(size)
    if longest is None and default:
        longest = LENGTH_SHARE * size
    outer = options.max_outer_diameter
    if outer is None and default:
        outer = DIAMETER_SHARE * size
    return Envelope(max_outer_diameter=outer, max_body_length=options.max_body_length, max_length=longest)


def mechanism_size(problem: Any, mechanics: Any) -> float:
    """The mechanism's size (m): the largest distance between any two of its points at the
    pose of ``mechanics`` (the home configuration): the origins of its frames, the bodies'
    centres of mass, the springs' ends and the counter-masses. Values that are arrays
    (several scenarios at once) give the largest over all of them. 0.0 for fewer than two
    points."""
    points = [mechanics.pose(f.name)[1] for f in problem.frames]
    points += [mechanics.position(b.com) for b in problem.bodies]
    points += [mechanics.position(end) for spring in problem.springs for end in spring.ends]
    points += [mechanics.position(c.position) for c in problem.counter_masses]
    if len(points) < 2:
        return 0.0
    columns = [np.asarray(c, dtype=float).reshape(-1) for p in points for c in p]
    n = max(c.size for c in columns)
    xyz = np.stack([np.broadcast_to(c, (n,)) for c in columns]).reshape(len(points), 3, n)
    gaps = xyz[:, None, :, :] - xyz[None, :, :, :]
    return float(np.max(np.sqrt(np.sum(gaps * gaps, axis=2))))


def _requirement(spring: Any, k: float, d_min: float, d_max: float, cable: float, f0: float, l0: float) -> Requirement:
    margin = spring.slack_margin
    if spring.direct is None:
        return Requirement(rate=k, force_min=k * d_min, force_max=k * d_max, slack_margin=margin)
    x_min, x_max = max(d_min - cable - l0, 0.0), max(d_max - cable - l0, 0.0)  # tension only
    return Requirement(rate=k, force_min=f0 + k * x_min, force_max=f0 + k * x_max, initial_tension=f0, free_length=l0, slack_margin=margin)


def _use(spring: Any, scenario: str, values: tuple[float, ...], need: Requirement, made: SpringDesign) -> DesignedSpring:
    """The spring ``made`` in one scenario: its working range there (the wound spring's
    forces where the requirement's spring pulls ``need``, and its lengths at them)."""
    d_min, d_max, cable = values[1:4]
    made = replace(made, requirement=need)
    f0, L0 = made.initial_tension, made.free_length
    if spring.direct is None:  # the anchor sets the length: L = L0 + (F − F0)/k_w (NaN: no design)
        lo, hi = (made.wound_force(need.force_min), made.wound_force(need.force_max)) if made.ok else (math.nan, math.nan)
        lengths = (L0 + max(lo - f0, 0.0) / made.rate, L0 + (hi - f0) / made.rate)
    else:  # attached directly: the geometry sets the length, d − cable, not below L0
        lengths = (max(d_min - cable, L0), max(d_max - cable, L0))
    made = replace(made, length_min=lengths[0], length_max=lengths[1])
    return DesignedSpring(spring.name, scenario, "pulley" if spring.direct is None else "direct", d_min, d_max, cable, made)
