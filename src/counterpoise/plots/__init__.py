"""Plots (matplotlib, Agg backend, PNG files): energies of a design and study curves.

Import this subpackage only when a plot is wanted: matplotlib costs ~0.5 s to import, and
the CLI imports it inside the commands that plot.

- :func:`energy_plot`: potential energies (gravity, springs, total) of a solved design
  against each coordinate, with the residual torque and the unbalanced gravity torque.
- :func:`study_plots`: objective and design variables against each varied key, and a
  Pareto plot (added mass against added inertia) when an objective weight is varied.
"""

from __future__ import annotations

from .energy import energy_plot
from .study import study_plots

__all__ = ["energy_plot", "study_plots"]
