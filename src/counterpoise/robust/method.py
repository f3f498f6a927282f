"""The robust design method: tolerances of the built balancer, the robust counterpart and
the tuning table (docs/robust.md).

:class:`RobustMethod` wraps a problem's ordinary design method (the inner one) and:

1. designs the nominal balancer with the inner method, the ``tune`` variables held at their
   ``initial`` value (the factory setting);
2. with ``mode = "minimise"`` or ``"limit"``, solves the robust counterpart: when no free
   variable moves a point, an LP (box) or SOCP (ellipsoid) in the masses and stiffnesses,
   written with cvxpy (:mod:`.convex`); otherwise the minimax NLP over every corner of the
   box in CasADi/IPOPT (:mod:`.minimax`), started from the nominal design;
3. measures the worst case over the tolerance box of both designs, per tolerance kind and
   over all (:mod:`.affine`), on a dense grid of configurations;
4. with ``tune``, re-solves the ``tune`` variables at every corner of the tolerance box
   (every other variable held at the design's value; one designer of the perturbed problem,
   solved with each corner's deviations as parameter values) and verifies each corner
   densely: the tuning range of each variable and the tuning table.
"""

from __future__ import annotations

import copy
import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..designer.constrained import SLACK_TOLERANCE
from ..designer.convex import geometric_variables
from ..designer.methods import DesignMethod
from ..designer.options import SolveOptions
from ..designer.solution import Solution, build_solution
from ..errors import ProblemFileError
from ..formulation.constraints import MAX_ROUNDS, ConstraintValue, describe, scale, violations
from ..formulation.layout import Gravity3, Slot
from ..model.problem import Problem, bound_side
from ..model.robust import RobustSpec, Tolerance
from ..solvers.base import SolverOutput, Status
from .affine import LP_CONFIGURATIONS, Decomposition, Rows, worst, worst_corner
from .constraints import CornerConstraints, LinearRows
from .perturb import Deviation, corner_name, corner_text, perturbed
from .result import ON_MANIFOLD, SAMPLED_MINIMAX, Corner, RobustReport

if TYPE_CHECKING:
    from ..designer.designer import Designer
    from .limits import Envelope as LimitEnvelope
    from .limits import Margin, PulleySpring
    from .minimax import RobustMinimax

#: configurations per block on which the worst case of a design is measured
BAND_CONFIGURATIONS = 10_000
#: a deviation whose effect on every residual is below this share of the reference torque
#: changes nothing (rounding): it is not one of the tuned corners' signs
ZERO_EFFECT = 1e-12
#: configurations per (subsystem, corner) on which the tuned corners are verified
TUNE_VERIFY_SAMPLES = 2_000
#: a payload range: rounds of reserving an adjustment's travel for the tuning
RESERVE_ROUNDS = 3
#: a spring whose largest force times its longest distance is below this share of the largest
#: gravity torque carries nothing (a rate left at rounding level): it is not checked or built
UNUSED_SPRING = 1e-6
#: corners of the spring deviations checked against the hardware without tuning, at most
MAX_HARDWARE_CORNERS = 256
#: random machines inside the box the corners' worst case is checked against (directly attached
#: springs), on a grid of configurations per block and the dense sample's worst ones
SAMPLED_MACHINES = 200
SAMPLED_CONFIGURATIONS = 1000
SAMPLED_WORST = 50
#: a directly attached spring's length limit broken by less than this (m) on the dense sample
#: is rounding: the NLP holds it on its own samples, and between them d(q) curves by about
#: b·Δφ²/8 (0.01 mm for a 0.1 m lever and 48 samples over 100°)
LENGTH_TOLERANCE = 1e-5
#: random as-built machines the tuning law is checked on, and configurations per block for each
LAW_SAMPLES = 1000
LAW_CONFIGURATIONS = 500


#: the positional arguments of :func:`.convex.solve_robust` (rows, objective, signs, bounds,
#: mode, weight, limit, shape)
LPArguments = tuple[Rows, tuple[np.ndarray, float], tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray], str, float, float, str]


class RobustMethod(DesignMethod):
    """Robust design of a problem with ``[robust]`` around its inner design method."""

    def __init__(self, problem: Problem, inner: DesignMethod) -> None:
        if problem.robust is None:
            raise ValueError(f"{problem.name}: no [robust] table")
        self._problem = problem
        self.inner = inner
        self._source_key: tuple[Any, ...] = ()
        #: catalogue parts (:meth:`for_parts`): slot -> the chosen catalogue row, and the lines saying
        #: which rate tolerance each of their springs takes
        self._parts: dict[str, int] = {}
        self._part_text: tuple[str, ...] = ()
        self._variants: dict[tuple[Tolerance, ...], RobustMethod] = {}  # per set of the parts' tolerances
        self._prepare(problem)

    def _prepare(self, source: Problem) -> None:
        """The perturbed problem and its decomposition for ``source``: the problem itself, or
        (a payload range) the sampled problem the inner method designed, one scenario per
        payload sample. Built once per set of samples; the solvers built on it are reset."""
        key = tuple((s.name, tuple(sorted(s.parameters.items()))) for s in source.scenarios)
        if key == self._source_key:
            return
        self._source_key = key
        self.perturbed, self.deviations = perturbed(source)
        self.decomposition = Decomposition(self.perturbed, self.deviations, source)
        self._nonnegative: Any = None  # a CasADi Function (casadi ships no type information)
        self._tuner: Designer | None = None  # the designer of the tuning, built on first use
        self._minimax: RobustMinimax | None = None  # the minimax NLP (free geometry), built on first use
        self._constraints: CornerConstraints | None = None  # the constraints at every corner, built on first use
        self._held_values: dict[Slot, float] = {}  # the tuning's held variables (SI), of its last design
        self._torque = 0.0  # the largest gravity torque of the bands' rows (the scale of an unused spring)

    def with_spec(self, spec: RobustSpec) -> "RobustMethod":
        """The same method (its inner method and decomposition shared) for another ``[robust]``
        table of the same tolerances: a trade-off study varies the limit or the weight."""
        if spec.tolerances != self._spec().tolerances:
            raise ValueError("with_spec: the tolerances must stay the same")
        other = copy.copy(self)
        other._problem = replace(self.problem, robust=spec)
        other._tuner = None if spec.tune != self._spec().tune else self._tuner
        other._minimax = None if (spec.mode, spec.weight) != (self._spec().mode, self._spec().weight) else self._minimax
        return other

    def for_parts(self, rows: Mapping[str, int]) -> "RobustMethod":
        """The method for the catalogue parts ``rows`` (slot -> catalogue row) the parts layer
        chose: every spring of a slot takes its part's rate tolerance (the catalogue row's
        ``rate_tolerance``; where the row gives none, the file's ``tolerances.rate`` for the
        spring, else the slot's, docs/robust.md#catalogue-parts), and its part's limits at every
        corner (:meth:`_hardware`). One method per set of tolerances is kept, so that what it
        builds on first use (the corner constraints, the tuning designer) is built once; it
        takes the parts of each call."""
        spec = self._spec()
        given = {t.item: t for t in spec.tolerances if t.kind == "rate"}
        chosen: dict[str, Tolerance] = {}
        texts: list[str] = []
        for slot in self.problem.slots:
            if slot.name not in rows:
                continue
            i, cat = rows[slot.name], slot.catalogue
            part = cat.part_number[i]
            for name in slot.springs:
                if math.isfinite(cat.rate_tolerance[i]):
                    t, source = Tolerance("rate", name, float(cat.rate_tolerance[i]), True, f"catalogue {cat.name}"), f"the catalogue's rate_tolerance of part {part}"
                elif name in given:
                    t, source = given[name], f"the file's robust.tolerances.rate (catalogue {cat.name} gives none for part {part})"
                else:
                    t, source = Tolerance("rate", name, slot.rate_tolerance, True, f"slots.{slot.name}"), f"slot {slot.name}'s rate tolerance (catalogue {cat.name} gives none for part {part})"
                chosen[name] = t
                amount = f"±{100 * t.amount:g} %" if t.relative else f"±{t.amount:g} N/m"
                texts.append(f"spring {name} (part {part} of slot {slot.name}): rate tolerance {amount}, {source}")
        tolerances = tuple(chosen.pop(t.item) if t.kind == "rate" and t.item in chosen else t for t in spec.tolerances) + tuple(chosen.values())
        if tolerances not in self._variants:  # kept: its decomposition and solvers are built once
            problem = self.problem if tolerances == spec.tolerances else replace(self.problem, robust=replace(spec, tolerances=tolerances))
            self._variants[tolerances] = RobustMethod(problem, self.inner)
        other = self._variants[tolerances]
        other._parts, other._part_text = dict(rows), tuple(texts)  # the parts of this call (a variant is used only through here)
        return other

    @property
    def problem(self) -> Problem:
        return self._problem

    # -- the method ----------------------------------------------------------------
    def solve_with(self, options: SolveOptions) -> Solution:
        spec = self._spec()
        parameters = options.parameters
        held: dict[Slot | str, tuple[float, float]] = {**(options.bounds or {})}
        held.update({name: (self.problem.variable[name].initial, self.problem.variable[name].initial) for name in spec.tune})
        if self.problem.payloads:
            return self._solve_payloads(options, held)
        f = self.decomposition.formulation
        d = f.design
        p = f.parameters.values(parameters)
        lbz, ubz = d.bounds(held)
        if np.array_equal(lbz, ubz):  # every variable held (the tune ones at their factory setting): the design as given
            out0 = SolverOutput(lbz, Status.OPTIMAL, "every variable held", 0, 0.0, "none")
            given = build_solution(f, lbz, p, lbz, ubz, out0, "every variable is held: the design as given, judged by its dense check", 0, "no variable to solve for")
            nominal = replace(given, problem=self.problem, scenario_parameters=_without_deviations(given.scenario_parameters, self.deviations))
        else:
            nominal = self.inner.solve_with(replace(options, bounds=held))
        z_nom = np.clip(d.to_z(d.vector(nominal.values)), lbz, ubz)
        dense = self.decomposition.configurations(BAND_CONFIGURATIONS, self.problem.settings.seed)
        nominal_rows = self.decomposition.rows(dense, z_nom, [], p)
        bands = {"nominal": self._band(nominal_rows)}
        sampled = {"nominal": self._sampled(nominal_rows, z_nom, p)}
        at_worst = {"nominal": self._worst_corner(nominal_rows)}
        added = {"nominal": nominal.added_mass}
        objective = {"nominal": nominal.objective}
        base_objective: dict[str, float] = {}  # minimise: the file's objective, before weight × ρ
        lp_ratio, lp_seconds = float("nan"), 0.0
        design, z, status, message = nominal, z_nom, nominal.status, nominal.message
        cons = self._corner_constraints()
        corner_values: tuple[ConstraintValue, ...] = ()
        out: SolverOutput | None = None
        if spec.mode != "none":
            geometric = geometric_variables(self.problem)
            moving = [i for i, slot in enumerate(d.slots) if slot.variable in geometric and lbz[i] < ubz[i]]
            free = [i for i, slot in enumerate(d.slots) if slot.variable not in geometric and lbz[i] < ubz[i]]
            nonlinear = cons.nonlinear(free) if cons is not None else ()
            # a directly attached spring: its lengths are rows of their own at every corner (the
            # minimax NLP), and its residual is not affine in its points' deviations
            direct = [sp.name for sp in self.problem.springs if sp.direct is not None]
            if not moving and not free:
                return design.judged(Status.FAILED, f"[robust] mode = \"{spec.mode}\" needs a free mass or stiffness variable: every variable is held", "robust")
            for round_ in range(MAX_ROUNDS + 1):
                if moving or nonlinear or direct:  # free geometry, a nonlinear constraint or a direct spring: the minimax NLP over every corner
                    from .minimax import RobustMinimax

                    if self._minimax is None:
                        try:
                            self._minimax = RobustMinimax(self.decomposition, spec.mode, spec.weight, self.problem.settings.seed, cons, spec.shape)
                        except ValueError as exc:  # too many corners
                            what = "free geometry" if moving else "directly attached springs" if direct else "a nonlinear constraint"
                            return design.judged(Status.FAILED, f"robust design with {what}: {exc}; hold the geometry or tolerance fewer items", "robust")
                    mm = self._minimax.solve(z_nom, p, lbz, ubz, spec.limit)
                    z = np.clip(mm.z, lbz, ubz)
                    lp_ratio, lp_seconds = mm.ratio, mm.seconds
                    status = mm.status
                    out = SolverOutput(z, status, mm.solver_status, mm.iterations, mm.seconds, "ipopt")
                    why = (
                        f"directly attached spring{'s' if len(direct) > 1 else ''} {', '.join(direct)}"
                        if direct
                        else "free geometry" if moving else f"the nonlinear constraint{'s' if len(nonlinear) > 1 else ''} {', '.join(nonlinear)}"
                    )
                    over = "the tolerance corners" if self._minimax.shape == "box" else "the tolerance ellipsoid"
                    message = f"robust design (minimax NLP over {over}, IPOPT; {why})"
                    if status is not Status.OPTIMAL:
                        message = self._infeasible_text(mm.solver_status, cons) if status is Status.INFEASIBLE else f"robust minimax NLP: IPOPT {mm.solver_status}"
                        if direct and status is Status.INFEASIBLE:  # name the length limit and the corner where IPOPT stopped
                            _, broken = self._length_margins(z, p, dense)
                            if broken:
                                message = (
                                    f"robust design infeasible ({mm.solver_status}): no design within the bounds keeps the directly attached "
                                    f"spring{'s' if len(direct) > 1 else ''} {', '.join(direct)} within its lengths at every tolerance corner; "
                                    f"where IPOPT stopped: {broken}"
                                )
                    if self._minimax.shape == "ellipsoid":
                        summary = "minimax of |r| + ‖s‖₂ (the ellipsoid) on sampled configurations"
                    else:
                        summary = f"minimax over {len(self._minimax.offsets)} corners on sampled configurations"
                        if spec.shape == "ellipsoid":
                            summary += " (the ellipsoid's bounding box: an element has several deviations)"
                else:
                    z_ref = z_nom.copy()
                    z_ref[free] = 0.0
                    rows = self.decomposition.rows(self.decomposition.configurations(LP_CONFIGURATIONS, self.problem.settings.seed), z_ref, free, p)
                    from .convex import solve_robust

                    args: LPArguments = (rows, self._objective(z_ref, free, p), self._signs(z_ref, free, p), (lbz[free], ubz[free]), spec.mode, spec.weight, spec.limit, spec.shape)
                    linear = cons.linear_rows(z_ref, free, p) if cons is not None else None
                    lp = solve_robust(*args, design_rows=linear)
                    lp_ratio, lp_seconds = lp.ratio, lp.seconds
                    z = z_ref.copy()
                    z[free] = lp.dz
                    ok = lp.status == "optimal"
                    status = Status.OPTIMAL if ok else Status.INFEASIBLE
                    out = SolverOutput(z, status, lp.status, 0, lp.seconds, "cvxpy/clarabel")
                    message = f"robust design ({'LP' if spec.shape == 'box' else 'SOCP'}, cvxpy/Clarabel)"
                    if not ok:
                        message = self._infeasible_text(lp.status, cons)
                        if cons is not None and linear is not None:
                            conflict, relaxed = self._lp_conflict(args, linear, cons)
                            if conflict:  # report the design the message describes: the least relaxation's
                                message = conflict
                                z[free] = relaxed
                                out = SolverOutput(z, status, lp.status, 0, lp.seconds, "cvxpy/clarabel")
                    summary = f"robust counterpart on {rows.r0.size} sampled rows"
                design = build_solution(f, z, p, lbz, ubz, out, message, 0, summary)
                design = replace(design, problem=self.problem, scenario_parameters=_without_deviations(design.scenario_parameters, self.deviations))
                if cons is not None:
                    corner_values = cons.worst(design, self.perturbed)
                if cons is None or status is not Status.OPTIMAL:
                    break
                add = violations(self.perturbed, corner_values)
                if not add or round_ == MAX_ROUNDS:
                    break
                # a workspace extreme beyond its bound between the sampled rows at some corner: add
                # those configurations to the rows and solve again (as the designer's rounds do)
                cons = self._constraints = cons.refined(add)
                self._minimax = None
            robust_rows = self.decomposition.rows(dense, np.clip(z, lbz, ubz), [], p)
            bands["robust"] = self._band(robust_rows)
            sampled["robust"] = self._sampled(robust_rows, np.clip(z, lbz, ubz), p)
            at_worst["robust"] = self._worst_corner(robust_rows)
            added["robust"] = design.added_mass
            objective["robust"] = design.objective
            if spec.mode == "minimise":
                # the objective minimised: the file's objective + weight × the worst-case ratio
                # (the dense band, the figure reported), for both designs alike
                base_objective = dict(objective)
                objective = {key: value + spec.weight * bands[key]["all"] for key, value in objective.items()}
                design = replace(design, objective=objective["robust"])
        elif cons is not None and nominal.status is Status.OPTIMAL:
            corner_values = cons.worst(replace(nominal, problem=self.problem), self.perturbed)
        if corner_values:
            design = replace(design, constraints=corner_values)
        solver = "" if spec.mode == "none" or out is None else ("IPOPT" if out.solver == "ipopt" else "cvxpy/Clarabel")
        report = RobustReport(
            spec.mode, spec.shape, self.deviations, bands, added, objective, lp_ratio, lp_seconds, solver=solver, exactness=self._exactness(),
            base_objective=base_objective, weight=spec.weight, sampled={k: v for k, v in sampled.items() if v == v}, samples=SAMPLED_MACHINES,
            worst_corner={k: v for k, v in at_worst.items() if v}, part_tolerances=self._part_text,
        )
        breached = [v for v in corner_values if v.active == "violated"]
        if breached and status is Status.OPTIMAL:
            text = "; ".join(describe(self.perturbed, v) for v in breached[:3])
            if spec.mode == "none":
                status, message = Status.INFEASIBLE, (
                    f"the ordinary design breaks a constraint at a tolerance corner: {text}; [robust] mode = \"none\" does not "
                    "re-design for the tolerances: "
                    + ("with [slots] mode = \"limit\"/\"minimise\" is not combinable yet (docs/robust.md#catalogue-parts)" if self.problem.slots else "mode = \"limit\" or \"minimise\" keeps every constraint at every corner")
                )
            else:
                status, message = Status.FAILED, f"constraint violated at a tolerance corner between the sampled configurations after the verification rounds: {text}"
            return design.with_extra(report).judged(status, message, "robust")
        if spec.tune and status is Status.OPTIMAL:
            report = self._tune(design, z, p, dense, report, parameters)
            if report.tuning_status != "balanced":
                status, message = Status.INFEASIBLE, report.tuning_status
        elif status is Status.OPTIMAL:
            # no tuning: the design as built, at every corner of the deviations that move a
            # spring's force or ends, within its springs' hardware limits
            report = self._hardware(design, self._spring_corners(), report, tuned=False)
            if report.tuning_status:
                status, message = Status.INFEASIBLE, report.tuning_status
        if status is Status.OPTIMAL and any(sp.direct is not None for sp in self.problem.springs):
            report = self._direct_lengths(np.clip(z, lbz, ubz), p, self.decomposition.configurations(TUNE_VERIFY_SAMPLES, self.problem.settings.seed), report)
            if report.tuning_status not in ("", "balanced"):
                status, message = Status.INFEASIBLE, report.tuning_status
        key = "robust" if "robust" in bands else "nominal"
        bound = (
            ""
            if report.exactness == "exact"
            else " (a sampled minimax over the box's corners, not exact)"
            if report.exactness.startswith(SAMPLED_MINIMAX)
            else " (exact at the sampled manifold configurations)"
            if report.exactness.startswith(ON_MANIFOLD) and "bound" not in report.exactness and "first order" not in report.exactness
            else " (a bound)"
        )
        text = f"{message}: worst-case residual ratio {bands[key]['all']:.4g}{bound} over the tolerance {'box' if spec.shape == 'box' else 'ellipsoid'}"
        if key in sampled and sampled[key] == sampled[key]:
            text += f" (at {SAMPLED_MACHINES} random machines inside it: {sampled[key]:.4g})"
        if key == "robust":
            text += f" (nominal design {bands['nominal']['all']:.4g}); added mass {added['robust']:.6g} kg (nominal design {added['nominal']:.6g} kg)"
        if report.corners and report.tuning_status == "balanced":
            text += f"; tuned at {len(report.corners)} corners, largest residual ratio after tuning {report.tuned_residual:.2g}"
        binding = [v for v in corner_values if v.active in ("upper", "lower")]
        if binding:
            text += "; binding: " + "; ".join(describe(self.perturbed, v) for v in binding)
        design = design.with_extra(report)
        if status is not Status.OPTIMAL:
            if key == "robust" or report.tuning_status not in ("", "balanced"):
                return design.judged(status, message, "robust")  # the counterpart or the tuning failed: say which
            return design
        if key == "robust":
            return design.judged(status, text, "robust")  # the counterpart may leave the nominal unbalanced by choice
        return replace(design, message=text)  # the ordinary design: judged by its dense check as usual

    def _solve_payloads(self, options: SolveOptions, held: dict["Slot | str", tuple[float, float]]) -> Solution:
        """[robust] over a payload range (mode "none"): the design for the range (the inner
        payload method, the tune variables at their factory setting), its worst case over the
        tolerance box at every payload sample, and the tuning: at every corner one setting of
        the tune variables for all payloads, and each payload's adjustments within their travel
        (one designer of the sampled problem, the corner's deviations as parameters). When a
        corner needs an adjustment beyond its limit, that much travel is reserved: the range is
        designed again with the adjustment's bounds narrowed by it (at most RESERVE_ROUNDS
        times); what remains is infeasible, the corner, the payload and the limit named."""
        spec = self._spec()
        parameters = options.parameters
        payload = self.problem.payloads[0]
        reserve: dict[Slot | str, tuple[float, float]] = {}
        nominal: Solution | None = None
        report: RobustReport | None = None
        for round_ in range(RESERVE_ROUNDS + 1):
            nominal = self.inner.solve_with(replace(options, bounds={**held, **reserve}))
            verdict = nominal.verdict
            if (verdict.status if verdict is not None else nominal.status) is not Status.OPTIMAL:
                return nominal  # the range cannot be designed: the payload layer says why
            self._prepare(nominal.problem)
            f = self.decomposition.formulation
            d = f.design
            p = f.parameters.values(parameters)
            z = d.to_z(d.vector(nominal.values))
            dense = self.decomposition.configurations(BAND_CONFIGURATIONS, self.problem.settings.seed)
            bands = {"nominal": self._band(self.decomposition.rows(dense, z, [], p))}
            report = RobustReport("none", spec.shape, self.deviations, bands, {"nominal": nominal.added_mass}, {"nominal": nominal.objective}, exactness=self._exactness())
            setting_mass = {sc.setting or "": sc.parameters[payload.name] for sc in nominal.problem.scenarios}
            adjustments: dict[Slot, tuple[float, float]] = {}
            for slot in nominal.values:
                v = self.problem.variable[slot.variable]
                if v.adjustable and slot.scenario is not None:
                    at_nominal = setting_mass.get(slot.scenario) == payload.nominal
                    if at_nominal and v.nominal is not None:
                        adjustments[slot] = (v.nominal, v.nominal)  # pinned by the file at the nominal payload
                    elif at_nominal and spec.tune:
                        # the technician tunes with the nominal payload and the adjustment where the
                        # design puts it: the tune variables alone re-balance there (a unique setting)
                        adjustments[slot] = (nominal.values[slot], nominal.values[slot])
                    else:
                        adjustments[slot] = v.adjusted_bounds()
            if not spec.tune and not adjustments:
                break
            report = self._tune(nominal, z, p, dense, report, parameters, adjustments)
            if report.tuning_status == "balanced" or round_ == RESERVE_ROUNDS:
                break
            more = self._excess(report, adjustments, parameters)
            if not more:
                break  # not a matter of travel: the tune variables or the deviations' kind
            grown = False
            for name, (low, high) in more.items():
                lo, hi = reserve.get(name, self.problem.variable[name].adjusted_bounds())
                lo, hi = lo + low, hi - high
                if lo >= hi:
                    grown = False
                    break
                reserve[name] = (lo, hi)
                grown = True
            if not grown:
                break
        if nominal is None or report is None:  # pragma: no cover - the loop runs at least once
            raise RuntimeError("robust payload design: no round ran")
        masses = sorted(set(setting_mass.values()))
        unit = payload.unit
        reserved = "; ".join(_reserved_text(self.problem.variable[str(name)], lo, hi) for name, (lo, hi) in reserve.items())
        design = nominal.with_extra(report)
        base = nominal.verdict.message if nominal.verdict is not None else nominal.message
        where = f"at every payload sample ({', '.join(f'{unit.from_si(m):g}' for m in masses)} {unit.label})"
        if report.tuning_status not in ("", "balanced"):
            text = report.tuning_status + (f" ({reserved}, the most {RESERVE_ROUNDS} rounds allow)" if reserved else "")
            return design.judged(Status.INFEASIBLE, text, "robust")
        text = f"{base}; worst-case residual ratio {report.bands['nominal']['all']:.4g} over the tolerance {'box' if spec.shape == 'box' else 'ellipsoid'} {where}"
        if report.corners:
            text += f"; tuned at {len(report.corners)} corners {where}, largest residual ratio after tuning {report.tuned_residual:.2g}"
        if reserved:
            text += f"; {reserved}"
        return design.judged(Status.OPTIMAL, text, "robust")

    def _excess(self, report: RobustReport, adjustments: Mapping[Slot, tuple[float, float]], parameters: Mapping[str, float] | None) -> dict[str, tuple[float, float]]:
        """How far beyond its limits each adjustment goes at the corners that fail, when its
        limits are lifted (not a pinned one): name -> (below the lower, above the upper), SI."""
        if self._tuner is None:
            return {}
        tolerance = self.problem.settings.verify_tolerance
        out: dict[str, tuple[float, float]] = {}
        for c in report.corners:
            if c.after <= tolerance:
                continue
            wide: dict[Slot | str, tuple[float, float]] = {}
            for slot, (lo, hi) in adjustments.items():
                span = self.problem.variable[slot.variable].upper - self.problem.variable[slot.variable].lower
                wide[slot] = (lo, hi) if lo == hi else (lo - span, hi + span)
            held: dict[Slot | str, tuple[float, float]] = {slot: (v, v) for slot, v in self._held_values.items()}
            held.update(wide)
            overrides = {**(parameters or {}), **{d.parameter: s * d.half_width for d, s in zip(self.deviations, c.signs)}}
            solution = self._tuner.solve(parameters=overrides, bounds=held, certify=False)
            from ..verify.check import verify

            if not verify(solution).residual_ratio <= tolerance:
                return {}  # not re-balanced even with more travel: the tune variables' bounds or the kind of deviation
            for slot, (lo, hi) in adjustments.items():
                value = solution.values.get(slot)
                if value is None or lo == hi:
                    continue
                below, above = out.get(slot.variable, (0.0, 0.0))
                out[slot.variable] = (max(below, lo - value), max(above, value - hi))
        return {name: (max(a, 0.0), max(b, 0.0)) for name, (a, b) in out.items() if a > 0 or b > 0}

    def _payload_text(self, scenario: str) -> str:
        """' at camera = 8 kg': the payload of a scenario of the sampled problem ("" without one)."""
        if not self.problem.payloads or not scenario:
            return ""
        payload = self.problem.payloads[0]
        own = next((s for s in self.perturbed.scenarios if s.name == scenario), None)
        if own is None or payload.name not in own.parameters:
            return ""
        return f" at {payload.name} = {payload.unit.from_si(own.parameters[payload.name]):.6g} {payload.unit.label}"

    def _sampled(self, dense: Rows, z: np.ndarray, p: np.ndarray) -> float:
        """The largest residual ratio at SAMPLED_MACHINES random machines inside the box
        (seeded), pulley springs' initial tensions at their worst (their term is exact and
        separate): the check beside the corners with a directly attached spring (its
        residual is not affine in its points' deviations); NaN elsewhere (not computed). On
        SAMPLED_CONFIGURATIONS configurations per block and the SAMPLED_WORST of the dense
        sample ``dense`` where the corners' worst case is largest."""
        problem = self.problem
        if not any(sp.direct is not None for sp in problem.springs) or not self.deviations:
            return float("nan")
        coarse = self.decomposition.configurations(SAMPLED_CONFIGURATIONS, problem.settings.seed + 47)
        at_corners = worst(dense, np.zeros(0), self._spec().shape)
        q = []
        for b, qb in enumerate(dense.q):
            mine = np.flatnonzero(dense.block == b)
            per = max(len(mine) // max(len(qb), 1), 1)  # rows per configuration
            top = np.unique(np.argsort(-at_corners[mine])[: SAMPLED_WORST * per] // per)
            q.append(np.vstack([coarse[b], qb[top]]))
        rows = self.decomposition.rows(q, z, [], p, deviations=False)
        largest = self.decomposition.sampled(q, z, p, SAMPLED_MACHINES, problem.settings.seed + 47)
        # the dense sample's references (the largest gravity torque or force of each kind of coordinate)
        return float(np.max((largest + rows.tension) / dense.reference_of(rows.revolute)))

    def _direct_lengths(self, z: np.ndarray, p: np.ndarray, q: list[np.ndarray], report: RobustReport) -> RobustReport:
        """Each directly attached spring within its lengths (L0 + slack margin ≤ d − c ≤ L_max)
        at every corner of its point deviations, on the dense sample: else the design is
        infeasible, the corner named."""
        margins, broken = self._length_margins(z, p, q)
        if not broken:
            return replace(report, lengths=tuple(margins))
        status = f"infeasible: the design as built breaks the hardware at a tolerance corner: {broken}"
        return replace(report, lengths=tuple(margins), tuning_status=status)

    def _length_margins(self, z: np.ndarray, p: np.ndarray, q: list[np.ndarray]) -> tuple[list[Any], str]:
        """The directly attached springs' length margins over the corners, and the worst broken
        one as text ("" when none is)."""
        from .direct import DirectLengths

        margins = DirectLengths(self.decomposition).worst(z, p, q)
        broken = [m for m in margins if m.margin < -LENGTH_TOLERANCE]
        if not broken:
            return margins, ""
        m = min(broken, key=lambda m: m.margin)
        text = "goes slack (shorter than its free length + slack margin)" if m.limit == "slack" else "is stretched beyond its longest length"
        return margins, f"corner {m.corner}: spring {m.spring} {text} by {-m.margin * 1e3:.4g} mm"

    def _exactness(self) -> str:
        """What the bands are (docs/robust.md, "How the worst case is exact")."""
        spec = self._spec()
        direct = [sp.name for sp in self.problem.springs if sp.direct is not None]
        if direct:
            # the design holds the corners, the springs' lengths and max_force on sampled
            # configurations only (as the nominal minimax designer does); a point deviation of
            # the spring enters its length |a + δ − b| nonlinearly, so the worst case over the
            # box may lie between corners
            why = f"directly attached spring{'s' if len(direct) > 1 else ''} {', '.join(direct)}: its force and length limits held at every corner on sampled configurations"
            if self.decomposition.nonaffine:
                labels = ", ".join(self.deviations[i].label for i in self.decomposition.nonaffine)
                why += f"; the residual is not affine in {labels} (the spring's length)"
            return f"{SAMPLED_MINIMAX}: {why}"
        notes = []
        if self.problem.loops:
            # the residual along the manifold is the open chain's projected by dq_d/dq_i, which
            # no deviation changes (they are not loop geometry): multi-affine in them as before,
            # exact at each assembled configuration; the manifold itself is sampled
            notes.append(
                f"{ON_MANIFOLD} (about {BAND_CONFIGURATIONS} per subsystem and scenario, each assembled by the loop closure "
                "and the residual projected along it; nothing is claimed between them beyond that dense sample)"
            )
        if spec.shape != "box" and self.decomposition.groups:
            notes.append("a bound over the ellipsoid: the products of one element's deviations are bounded over its box")
        points = {t.item for t in spec.tolerances if t.kind == "point" and t.amount > 0}
        both = sorted(points & set(self.decomposition.tensions))
        if both:
            notes.append(f"first order in initial tension × point of spring{'s' if len(both) > 1 else ''} {', '.join(both)}")
        return "; ".join(notes) or "exact"

    def _corner_constraints(self) -> CornerConstraints | None:
        """The design constraints at every tolerance corner (None: the problem has none); built once."""
        if not self.problem.constraints:
            return None
        if self._constraints is None:
            try:
                self._constraints = CornerConstraints(self.decomposition)
            except ValueError as exc:  # too many corners: an input limit
                raise ProblemFileError(self.problem.path, "robust.tolerances", f"not combinable with [constraints]: {exc}; tolerance fewer items") from None
        return self._constraints

    def _lp_conflict(self, args: "LPArguments", linear: LinearRows, cons: CornerConstraints) -> tuple[str, np.ndarray]:
        """When the counterpart is infeasible with the constraints but feasible without them:
        the constraints the elastic LP had to relax, with the amount, and its design (the
        step of the free slots); ("", empty) when the constraints are not the cause."""
        from .convex import solve_robust

        none = ("", np.zeros(0))
        alone = solve_robust(*args)
        if alone.status != "optimal":
            return none
        elastic = solve_robust(*args, design_rows=linear, elastic=True)
        if elastic.status != "optimal" or not elastic.slack.size:
            return none
        parts = []
        for k, amount in enumerate(elastic.slack):
            if amount > SLACK_TOLERANCE:
                c = next(g.constraint for g in cons.rows.groups if g.constraint.name == cons.names[k])
                parts.append(f"{c.name} (missed by {c.unit.from_si(amount * scale(c)):.4g} {c.unit.label})".replace(" )", ")"))
        if not parts:
            return none
        spec = self._spec()
        need = f"robust.limit = {spec.limit:g}" if spec.mode == "limit" else "the bounds"
        text = (
            f"robust design infeasible: the constraints cannot all hold at every tolerance corner together with {need}: "
            + ", ".join(parts)
            + " (the smallest total relaxation, the design reported; relax or remove these"
            + (", or relax the limit)" if spec.mode == "limit" else ")")
        )
        return text, elastic.dz

    # -- pieces --------------------------------------------------------------------
    def _spec(self) -> RobustSpec:
        if self.problem.robust is None:
            raise ValueError(f"{self.problem.name}: no [robust] table")
        return self.problem.robust

    def _worst_corner(self, rows: Rows) -> str:
        """Where the worst case over the box is (:func:`~.affine.worst_corner`): the corner's
        deviations and the configuration, e.g. "rate s +10 % at phi = -50 deg"; "" over an
        ellipsoid or without deviations."""
        if self._spec().shape != "box" or not self.deviations or not rows.r0.size:
            return ""
        k, signs = worst_corner(rows)
        b = int(rows.block[k])
        names = self.decomposition.names(b)  # closed loops: the independent coordinates
        start = int(np.flatnonzero(rows.block == b)[0])
        every = list(self.decomposition.formulation.blocks[b].coordinates)
        q = [rows.q[b][(k - start) // len(names)][every.index(n)] for n in names]
        coords = ", ".join(f"{n} = {self.problem.coordinate[n].unit.from_si(float(v)):.4g} {self.problem.coordinate[n].unit.label}" for n, v in zip(names, q))
        return f"{corner_text(self.deviations, signs)} at {coords}"

    def _band(self, rows: Rows) -> dict[str, float]:
        self._torque = max(self._torque, float(np.max(rows.reference, initial=0.0)))
        zero = np.zeros(rows.A.shape[1])
        out = {"residual": float(np.max(np.abs(rows.r0) / rows.reference)), "all": float(np.max(worst(rows, zero, self._spec().shape)))}
        for kind in dict.fromkeys([d.tolerance.kind for d in self.deviations] + (["initial_tension"] if self.decomposition.tensions else [])):
            out[kind] = float(np.max(worst(rows, zero, self._spec().shape, [kind])))
        return out

    def _objective(self, z_ref: np.ndarray, free: list[int], p: np.ndarray) -> tuple[np.ndarray, float]:
        report = self.decomposition.formulation.report_function
        f0 = float(report(z_ref, p)[0])
        c = np.array([float(report(z_ref + np.eye(z_ref.size)[j], p)[0]) - f0 for j in free])
        return c, f0

    def _signs(self, z_ref: np.ndarray, free: list[int], p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        import casadi as ca

        f = self.decomposition.formulation
        if self._nonnegative is None:
            self._nonnegative = ca.Function("nonnegative", [f.z, f.p], [f.nonnegative])
        g0 = np.array(self._nonnegative(z_ref, p)).reshape(-1)
        if not g0.size:
            return np.zeros((0, len(free))), g0
        G = np.stack([np.array(self._nonnegative(z_ref + np.eye(z_ref.size)[j], p)).reshape(-1) - g0 for j in free], axis=1) if free else np.zeros((g0.size, 0))
        return G, g0

    def _infeasible_text(self, lp_status: str, cons: CornerConstraints | None = None) -> str:
        spec = self._spec()
        held = f" and the constraints {', '.join(cons.names)} at every tolerance corner" if cons is not None else ""
        if spec.mode == "limit":
            return (
                f"robust design infeasible ({lp_status}): no design within the bounds{held} keeps the worst-case residual ratio "
                f"at or below robust.limit = {spec.limit:g} over the tolerance box"
            )
        if cons is not None:
            return f"robust design infeasible ({lp_status}): no design within the bounds keeps the constraints {', '.join(cons.names)} at every tolerance corner"
        return f"robust design failed: cvxpy/Clarabel returned {lp_status}"

    def _tune(
        self,
        design: Solution,
        z: np.ndarray,
        p: np.ndarray,
        dense: list[np.ndarray],
        report: RobustReport,
        parameters: Mapping[str, float] | None,
        adjustments: Mapping[Slot, tuple[float, float]] | None = None,
    ) -> RobustReport:
        """Re-solve the tune variables at every corner of the box, the other variables held.

        One designer of the perturbed problem is built once, with every deviation at +h
        (so that no balance condition hides behind a deviation that is 0 at build time),
        and solved per corner with the corner's deviations as parameter values; each
        corner's design is verified densely (``TUNE_VERIFY_SAMPLES`` configurations)."""
        from ..designer.designer import Designer
        from ..verify.check import verify

        spec = self._spec()
        rows = self.decomposition.rows(dense, z, [], p)  # the untuned worst case at each corner
        # a deviation that changes no residual at this design (the z component of a point in a
        # planar mechanism) is left at 0: it would only double the corners
        scale = float(np.max(rows.reference)) * ZERO_EFFECT
        active = [i for i in range(len(self.deviations)) if float(np.max(np.abs(rows.S0[:, i]), initial=0.0)) > scale]
        corners = [(0,) * len(self.deviations)]
        for signs in itertools.product((-1, 1), repeat=len(active)):
            full = [0] * len(self.deviations)
            for i, sign in zip(active, signs):
                full[i] = sign
            corners.append(tuple(full))
        # the other variables held at the design's; a payload range's adjustments re-set per
        # payload (and corner) within their travel: ``adjustments``
        held: dict[Slot | str, tuple[float, float]] = {
            slot: (adjustments or {}).get(slot, (value, value)) for slot, value in design.values.items() if slot.variable not in spec.tune
        }
        self._held_values = {slot: value for slot, value in design.values.items() if slot.variable not in spec.tune and slot not in (adjustments or {})}
        if self._tuner is None:
            width = {d.parameter: d.half_width for d in self.deviations}
            built = replace(
                self.perturbed,
                parameters=tuple(replace(q, value=width[q.name]) if q.name in width else q for q in self.perturbed.parameters),
                settings=replace(self.perturbed.settings, verify_samples=min(self.perturbed.settings.verify_samples, TUNE_VERIFY_SAMPLES)),
            )
            self._tuner = Designer(built)
        base = dict(parameters or {})
        out = []
        tuned: list[tuple[tuple[int, ...], Solution]] = []
        for corner in corners:
            overrides = {**base, **{d.parameter: s * d.half_width for d, s in zip(self.deviations, corner)}}
            solution = self._tuner.solve(parameters=overrides, bounds=held, certify=False)
            tuned.append((corner, solution))
            before = float(np.max(np.abs(rows.at(corner)) / rows.reference))
            check = verify(solution)
            after = float(check.residual_ratio)
            values = solution.variable_values(self.perturbed.scenarios[0].name)
            settings = tuple((t, values[t]) for t in spec.tune)
            settings += tuple((f"{slot.variable}@{slot.scenario}", v) for slot, v in solution.values.items() if adjustments and slot in adjustments)
            worst = check.worst()
            where = worst.scenario if worst is not None and not after <= self.problem.settings.verify_tolerance else ""
            out.append(Corner(corner_name("", corner), corner, corner_text(self.deviations, corner), before, after, settings, where))
        tuning_range = {t: (min(c.settings[i][1] for c in out), max(c.settings[i][1] for c in out)) for i, t in enumerate(spec.tune)}
        tolerance = self.problem.settings.verify_tolerance
        failed = [c for c in out if not c.after <= tolerance]
        if failed:
            c = max(failed, key=lambda c: c.after)
            at = []
            for name, v in c.settings:
                variable, _, setting = name.partition("@")
                if adjustments and setting and c.scenario and self.perturbed.setting(c.scenario) != setting:
                    continue  # another payload's adjustment
                bounds = adjustments.get(Slot(variable, setting)) if adjustments and setting else None
                lo, hi = bounds if bounds is not None else (self.problem.variable[variable].lower, self.problem.variable[variable].upper)
                side = bound_side(v, lo, hi)
                if side:
                    u = self.problem.variable[variable].unit
                    at.append(f"{variable} at its {side} {'limit' if setting else 'bound'} {u.from_si(hi if side == 'upper' else lo):.6g} {u.label}")
            reason = (
                f"the bounds of {', '.join(spec.tune)} are too narrow ({', '.join(at)})"
                if at
                else f"{', '.join(spec.tune)} cannot re-balance this corner (the deviation changes the residual in a way the tuning does not reach)"
            )
            payload = self._payload_text(c.scenario)
            status = f"tuning infeasible: corner {c.name} ({c.deviation}){payload} keeps a residual ratio of {c.after:.3g} after tuning (> {tolerance:g}); {reason}"
        else:
            status = "balanced"
        report = replace(report, corners=tuple(out), tuning_range=tuning_range, tuning_status=status)
        if status != "balanced":
            return report
        report = self._hardware(design, tuned, report)  # the tuned corners' settings
        if report.tuning_status != "balanced" or not spec.tune:
            return report
        return self._law(design, z, p, report)

    def _law(self, design: Solution, z: np.ndarray, p: np.ndarray, report: RobustReport) -> RobustReport:
        """The tuning law (:mod:`.law`) of the design and its check at random as-built machines."""
        from . import law as tuning_law

        spec = self._spec()
        scenario = self._law_scenario()
        spans = {t: hi - lo for t, (lo, hi) in report.tuning_range.items()}
        law = tuning_law.build(self.decomposition, z, p, spec.tune, scenario, spans, steps=dict(spec.steps))
        if len(law.readings) < len(law.tune):
            return replace(report, law=law, tuning_status=f"no tuning law: the tune variables {', '.join(spec.tune)} move fewer readings than there are variables")
        pretension = {name: spring.initial_tension for name, spring in report.springs.items()}
        check = tuning_law.check(law, self.decomposition, z, p, LAW_SAMPLES, self.problem.settings.seed + 31, LAW_CONFIGURATIONS, pretension)
        return replace(report, law=law, law_check=check)

    def _law_scenario(self) -> str:
        """The scenario the technician tunes in: the nominal payload's (a payload range), else the first."""
        if self.problem.payloads:
            payload = self.problem.payloads[0]
            for sc in self.perturbed.scenarios:
                if sc.parameters.get(payload.name) == payload.nominal:
                    return sc.name
        return self.perturbed.scenarios[0].name

    def _spring_corners(self) -> list[tuple[tuple[int, ...], None]]:
        """The corners of the deviations that change a spring (its rate, its ends), at most
        MAX_HARDWARE_CORNERS (the rates alone beyond), each with no tuned design."""
        idx = [i for i, d in enumerate(self.deviations) if d.tolerance.kind in ("rate", "point")]
        if 2 ** len(idx) > MAX_HARDWARE_CORNERS:
            idx = [i for i in idx if self.deviations[i].tolerance.kind == "rate"][: int(np.log2(MAX_HARDWARE_CORNERS))]
        out: list[tuple[tuple[int, ...], None]] = []
        for signs in itertools.product((-1, 1), repeat=len(idx)):
            full = [0] * len(self.deviations)
            for i, sign in zip(idx, signs):
                full[i] = sign
            out.append((tuple(full), None))
        return out

    def _part_figures(self) -> dict[str, tuple[float, float, float, float]]:
        """Per pulley spring of a chosen catalogue part (:meth:`for_parts`): its part's initial
        tension, free length, allowable load and longest length (SI)."""
        out: dict[str, tuple[float, float, float, float]] = {}
        for slot in self.problem.slots:
            if slot.name not in self._parts:
                continue
            i, cat = self._parts[slot.name], slot.catalogue
            for name in slot.springs:
                if all(sp.direct is None for sp in self.problem.springs if sp.name == name):
                    out[name] = (cat.initial_tension[i], cat.free_length[i], cat.max_load[i], cat.max_length[i])
        return out

    def _hardware(self, design: Solution, corners: Sequence[tuple[tuple[int, ...], Solution | None]], report: RobustReport, *, tuned: bool = True) -> RobustReport:
        """Every tuned corner against the hardware limits of its springs (:mod:`.limits`): the
        distances of each free-stiffness pulley spring's ends at the tuned settings (the dense
        sample designed springs are checked on), its rate at the corner; the envelope over the
        corners, the spring designed for it (the cable as long as the longest distance), and
        each corner's margins. A limit broken at a corner makes the tuning infeasible, named."""
        from ..mechanics import Mechanics
        from ..springs import Envelope as Space
        from ..springs import Requirement, design as wind
        from ..springs.workspace import SEED_OFFSET, distances, free_springs, sample
        from .limits import Envelope as LimitEnvelope
        from .limits import Margin, PulleySpring, breaches, envelope, pulley_margins

        problem = self.perturbed
        springs = [sp for sp in free_springs(problem) if sp.direct is None]
        parts = self._part_figures()
        chosen = [sp for sp in problem.springs if sp.name in parts]
        if not springs and not chosen:
            return report
        scenario = self._law_scenario()
        gravity, base0 = design.scenario_parameters.get(scenario, next(iter(design.scenario_parameters.values())))
        q = sample(problem, {**base0, **{d.parameter: 0.0 for d in self.deviations}}, problem.settings.verify_samples, problem.settings.seed + SEED_OFFSET)
        names = [v.name for v in problem.variables]
        per_corner: dict[str, dict[str, tuple[float, float, float]]] = {}
        named: dict[str, str] = {}  # "corner_pm" -> "corner_pm (rate s +10 %, mass arm -5 %)", as the other messages
        for signs, solution in corners:
            named[corner_name("", signs)] = f"{corner_name('', signs)} ({corner_text(self.deviations, signs)})"
            values = (solution or design).variable_values(scenario)
            devs = self.decomposition.values_at(signs)
            variables = {n: np.array([[values[n]]]) for n in names}
            lengths = distances(problem, springs + chosen, q, variables, {**base0, **devs}, gravity)
            mech = Mechanics(problem, {**base0, **devs}, values, {c.name: c.home for c in problem.coordinates}, gravity)
            per_corner[corner_name("", signs)] = {sp.name: (float(mech.value(sp.stiffness)), float(lengths[sp.name].min()), float(lengths[sp.name].max())) for sp in springs + chosen}
        tension = {t.item: t.amount for t in self._spec().tolerances if t.kind == "initial_tension"}
        envelopes: dict[str, LimitEnvelope] = {}
        made_springs: dict[str, PulleySpring] = {}
        margins: dict[str, list[Margin]] = {}
        failures: list[str] = []
        for sp in springs:
            uses = [at[sp.name] for at in per_corner.values()]
            env = envelope(uses)
            if env.force_max * env.distance_max <= UNUSED_SPRING * self._torque:
                continue  # the balance does not use it (a rate at rounding level): nothing to build
            k = float(Mechanics(problem, {**base0, **self.decomposition.values_at([0] * len(self.deviations))}, design.variable_values(scenario), {c.name: c.home for c in problem.coordinates}, gravity).value(sp.stiffness))
            if not k > 0:
                continue
            need = Requirement(rate=k, force_min=max(env.force_min - tension.get(sp.name, 0.0), 0.0), force_max=env.force_max)
            o = sp.design
            made = wind(need, o.material, Space(o.max_outer_diameter, o.max_body_length), o.rate_tolerance, o.min_safety_factor)
            envelopes[sp.name] = replace(env, force_min=need.force_min)
            if not made.ok:
                worst = max(per_corner, key=lambda c: per_corner[c][sp.name][0] * per_corner[c][sp.name][2])
                failures.append(f"no spring {sp.name} can be wound for every tuned corner ({'; '.join(made.reasons)}); corner {named.get(worst, worst)} needs {env.force_max:.4g} N")
                continue
            made_springs[sp.name] = PulleySpring(k, made.initial_tension, made.free_length, env.distance_max, made.max_force, made.max_length)
            for name, at in per_corner.items():
                rate, d_min, d_max = at[sp.name]
                built = PulleySpring(rate, made.initial_tension + tension.get(sp.name, 0.0), made.free_length, env.distance_max, made.max_force, made.max_length)
                margins.setdefault(name, []).extend(pulley_margins(sp.name, built, d_min, d_max))
        for sp in chosen:  # a catalogue part: its own F0, L0, allowable load and length at every corner's rate
            f0, l0, f_max, l_max = parts[sp.name]
            for name, at in per_corner.items():
                rate, d_min, d_max = at[sp.name]
                built = PulleySpring(rate, f0 + tension.get(sp.name, 0.0), l0, math.nan, f_max, l_max)
                margins.setdefault(name, []).extend(pulley_margins(sp.name, built, d_min, d_max))
        broken = breaches(margins)
        if broken:
            where, m = min(broken, key=lambda cm: cm[1].margin)
            text = {"slack": "its cable goes slack", "cable": "its end reaches the pulley (the cable is too short)", "load": "it is loaded beyond its allowable load", "length": "it is stretched beyond its longest length"}[m.limit]
            failures.append(f"corner {named.get(where, where)}: spring {m.spring}: {text} by {m.margin * (-1 if m.limit == 'load' else -1e3):.4g} {'N' if m.limit == 'load' else 'mm'}")
        status = report.tuning_status
        if failures:
            what = "tuning infeasible: the tuned settings break the hardware" if tuned else "infeasible: the design as built breaks the hardware at a tolerance corner"
            status = f"{what}: " + "; ".join(failures)
        return replace(report, envelope=envelopes, springs=made_springs, margins={c: tuple(ms) for c, ms in margins.items()}, tuning_status=status)


def _reserved_text(v: Any, lo: float, hi: float) -> str:
    """'travel reserved for tuning: x 10.5 mm at its lower end and 0 mm at its upper end'."""
    a, b = v.adjusted_bounds()
    u = v.unit
    return f"travel reserved for tuning: {v.name} {u.from_si(lo - a):.4g} {u.label} at its lower end and {u.from_si(b - hi):.4g} {u.label} at its upper end"


def _without_deviations(
    values: Mapping[str, tuple[Gravity3, dict[str, float]]], deviations: tuple[Deviation, ...]
) -> dict[str, tuple[Gravity3, dict[str, float]]]:
    names = {d.parameter for d in deviations}
    return {s: (g, {k: v for k, v in base.items() if k not in names}) for s, (g, base) in values.items()}
