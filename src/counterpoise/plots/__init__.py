"""Plots (matplotlib, Agg backend, PNG files): energies of a design and study curves.

Import this subpackage only when a plot is wanted: matplotlib costs ~0.5 s to import, and
the CLI imports it inside the commands that plot.

- :func:`energy_plot`: potential energies (gravity, springs, total) of a solved design
  against each coordinate, with the residual torque and the unbalanced gravity torque.
- :func:`study_plots`: objective and design variables against each varied key, and a
  Pareto plot (added mass against added inertia) when an objective weight is varied.

Each is imported from its module on first use (PEP 562): the study's plot helper
(:mod:`counterpoise.plotter`) imports :mod:`.study` alone, not :mod:`.energy`'s mechanics and
model (≈ 0.1 s of CPU).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .energy import energy_plot
    from .study import study_plots

__all__ = ["energy_plot", "study_plots"]


def __getattr__(name: str) -> Any:
    if name == "energy_plot":
        from .energy import energy_plot

        return energy_plot
    if name == "study_plots":
        from .study import study_plots

        return study_plots
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
