"""Energy plot of a solved design: one row per (subsystem, coordinate), one file per scenario.

Left: potential energy of gravity (given bodies and counter-masses), of the springs, and
their total against the coordinate, the other coordinates of its subsystem at home; a
balanced design has a flat total. Right: the residual generalized force ∂V/∂q of the
design (zero when balanced), with the unbalanced gravity torque (given bodies alone) for
scale.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..mechanics import NUMPY_FUNCTIONS, Mechanics
from ..mechanics.closure import closure
from ..verify.residuals import residuals
from ._mpl import pyplot, save

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from ..model.problem import Problem, Scenario
    from ..pipeline import DesignResult

SAMPLES = 181
#: one legend entry for the red dashed curves of both columns (energy left, torque right)
UNBALANCED = "given bodies alone (unbalanced): gravity energy, left; gravity torque, right"


def _energies(
    problem: Problem, subsystem: str, coords: Mapping[str, np.ndarray], variables: Mapping[str, float], base: Mapping[str, float], gravity: Sequence[float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(gravity energy of the bodies alone, of bodies and counter-masses, of the springs)."""
    mech = Mechanics(problem, base, variables, coords, gravity, NUMPY_FUNCTIONS)
    n = len(next(iter(coords.values())))
    grav = np.zeros(n)
    for b in problem.bodies:
        if b.subsystem == subsystem:
            grav = grav + np.broadcast_to(mech.gravity_energy(mech.value(b.mass), b.com), (n,))
    bodies = grav.astype(float)
    for c in problem.counter_masses:
        if c.subsystem == subsystem:
            grav = grav + np.broadcast_to(mech.gravity_energy(mech.value(c.mass), c.position), (n,))
    spring = np.zeros(n)
    for s in problem.springs:
        if s.subsystem == subsystem:
            end_a, end_b = mech.position(s.ends[0]), mech.position(s.ends[1])
            d2 = sum((np.asarray(x) - np.asarray(y)) ** 2 for x, y in zip(end_a, end_b))
            spring = spring + np.broadcast_to(0.5 * mech.value(s.stiffness) * d2, (n,))
    return bodies, grav.astype(float), spring.astype(float)


#: a residual below ROUNDING × the reference torque is rounding noise ("balanced to rounding")
ROUNDING = 1e-12


def _floor_axis(ax: Axes, curves: list[np.ndarray], floor: float) -> None:
    """Keep the y axis at least ±``floor`` wide around its data, so that rounding noise of a
    flat curve (1e-15) is not magnified into zig-zags that fill the panel."""
    data = np.concatenate([np.ravel(c) for c in curves])
    data = data[np.isfinite(data)]
    if data.size == 0 or not floor > 0:
        return
    lo, hi = float(data.min()), float(data.max())
    if hi - lo >= 2 * floor:
        return
    centre = 0.5 * (lo + hi)
    if abs(centre) < floor:  # a curve at zero stays centred on zero
        centre = 0.0
    ax.set_ylim(centre - 1.1 * floor, centre + 1.1 * floor)


def _balance_note(ax: Axes, residual: np.ndarray, reference: float, tolerance: float) -> None:
    """Say in the panel what a flat residual means."""
    worst = float(np.nanmax(np.abs(residual))) if residual.size else 0.0
    if not reference > 0 or not np.isfinite(worst):
        return
    if worst <= ROUNDING * reference:
        text = "balanced to rounding"
    elif worst <= tolerance * reference:
        text = f"balanced within the tolerance ({tolerance:.0e} of the largest unbalanced torque)"
    else:
        return
    ax.text(0.02, 0.04, text, transform=ax.transAxes, fontsize=8, va="bottom", color="tab:green", bbox={"facecolor": "white", "alpha": 0.85, "edgecolor": "none", "pad": 1.5})


def plotted_scenarios(problem: Problem) -> tuple[Scenario, ...]:
    """The scenarios drawn: every one, except that on a tilting base each working mode is
    drawn once, at the middle of its tilt ranges (the other nodes differ only in the tilt)."""
    if not problem.tilts:
        return problem.scenarios
    from ..model.tilt import tilt_nodes

    middle = tuple(tilt_nodes(t)[len(tilt_nodes(t)) // 2] for t in problem.tilts)
    return tuple(s for s in problem.scenarios if s.tilt == middle) or problem.scenarios[:1]


def energy_plot(result: "DesignResult", folder: str | Path) -> list[Path]:
    """Write ``energy.png`` (``energy-<scenario>.png`` with several scenarios) into ``folder``."""
    plt = pyplot()
    problem, solution = result.problem, result.solution
    paths = []
    # closed loops: only the independent coordinates are swept; the dependent ones follow on the manifold
    rows = [(sub, name) for sub in problem.subsystems for name in sub.coordinates if not problem.coordinate[name].dependent]
    scenarios = plotted_scenarios(problem)
    verification = result.verification
    tolerance = problem.settings.verify_tolerance
    for scenario in scenarios:
        gravity, base = solution.scenario_parameters[scenario.name]
        variables = solution.variable_values(scenario.name)
        home = {c.name: c.home for c in problem.coordinates}
        fig, axes = plt.subplots(len(rows), 2, figsize=(11, 2.6 * len(rows) + 1.2), squeeze=False, layout="constrained")
        for r, (sub, name) in enumerate(rows):
            coord = problem.coordinate[name]
            q = np.linspace(coord.lower, coord.upper, SAMPLES)
            coords = {c: np.full(SAMPLES, home[c]) for c in sub.coordinates}
            coords[name] = q
            tangent = None
            if problem.subsystem_loops(sub.name):
                c = closure(problem, sub.name, base)
                qi = np.column_stack([coords[c.names[i]] for i in c.independent])
                points = c.solve(qi)
                coords = {n: points.q[:, i] for i, n in enumerate(c.names)}
                tangent = (c, points.tangent)
            bodies, grav, spring = _energies(problem, sub.name, coords, variables, base, gravity)
            x = np.asarray(q, dtype=float) / coord.unit.to_si  # the display unit's from_si, on an array
            xlabel = f"{name} [{coord.unit.label}]"
            ax = axes[r, 0]
            ax.plot(x, bodies, label=UNBALANCED, color="tab:red", linestyle="--", linewidth=1)
            ax.plot(x, grav, label="gravity (bodies + counter-masses)", color="tab:blue", linewidth=3.5, alpha=0.6)
            if problem.springs and any(s.subsystem == sub.name for s in problem.springs):
                ax.plot(x, spring, label="springs", color="tab:orange")
            ax.plot(x, grav + spring, label="total", color="black", linewidth=2)
            ax.set_xlabel(xlabel)
            ax.set_ylabel("potential energy [J]")
            reference = verification.reference("revolute" if coord.unit.dimension == "" else "prismatic") if verification.checks else 0.0
            # energy: at least ±tolerance × the reference torque over one unit of the coordinate
            _floor_axis(ax, [bodies, grav, grav + spring] + ([spring] if problem.springs else []), tolerance * reference)
            ax.set_title(f"{sub.name}: energy against {name}", fontsize=10)
            ax.grid(alpha=0.3)
            qmat = np.column_stack([coords[c] for c in sub.coordinates])
            res, torque = residuals(problem, sub.name, qmat, variables, base, gravity)
            if tangent is not None:  # the generalized force along the manifold (docs/loops.md)
                c, t = tangent
                res = np.column_stack([np.asarray(res)[:, c.independent] + np.einsum("kdi,kd->ki", t, np.asarray(res)[:, c.dependent])] + [np.asarray(res)[:, c.dependent]])
                torque = np.column_stack([np.asarray(torque)[:, c.independent] + np.einsum("kdi,kd->ki", t, np.asarray(torque)[:, c.dependent])] + [np.asarray(torque)[:, c.dependent]])
                order = list(c.independent) + list(c.dependent)
                res, torque = res[:, np.argsort(order)], torque[:, np.argsort(order)]
            j = sub.coordinates.index(name)
            unit = "N·m" if coord.unit.dimension == "" else "N"
            ax = axes[r, 1]
            ax.plot(x, torque[:, j], label=UNBALANCED, color="tab:red", linestyle="--", linewidth=1)
            ax.plot(x, res[:, j], label="residual ∂V/∂q of the design", color="black", linewidth=2)
            ax.set_xlabel(xlabel)
            ax.set_ylabel(f"∂V/∂{name} [{unit}]")
            _floor_axis(ax, [torque[:, j], res[:, j]], tolerance * reference)
            _balance_note(ax, np.asarray(res[:, j]), reference, tolerance)
            ax.set_title(f"{sub.name}: generalized force on {name}", fontsize=10)
            ax.grid(alpha=0.3)
        title = f"{problem.name}: {result.status.value}, added mass {solution.added_mass:.4g} kg"
        if len(scenarios) > 1:
            title += f", scenario {scenario.setting or scenario.name if problem.tilts else scenario.name}"
        if problem.tilts:
            title += " (base upright: middle of the tilt ranges)" if all(
                abs(a) < 1e-12 for a in scenario.tilt) else f" ({scenario.description})"
        note = "other coordinates of each subsystem at home" + ("; closed loops: dependent coordinates on the manifold" if problem.loops else "")
        fig.suptitle(title + f"\n({note})", fontsize=11)
        legend: dict[str, object] = {}
        for ax in axes.flat:
            for handle, label in zip(*ax.get_legend_handles_labels()):
                legend.setdefault(label, handle)
        fig.legend(list(legend.values()), list(legend.keys()), loc="outside lower center", ncols=3, fontsize=9)
        label = (scenario.setting or scenario.name) if problem.tilts else scenario.name
        path = Path(folder) / ("energy.png" if len(scenarios) == 1 else f"energy-{label}.png")
        save(fig, path)  # constrained layout once, then one draw into the PNG
        paths.append(path)
    return paths
