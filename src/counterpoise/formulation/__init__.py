"""The formulation layer: from a problem to symbols, and from "balanced everywhere" to a few
exact equalities.

- :mod:`.layout`: where each number lives in the design and parameter vectors;
- :mod:`.formulation`: objective, sign constraints and residual blocks as CasADi symbols;
- :mod:`.assumptions`: when exact conditions exist (trigonometric-polynomial energies);
- :mod:`.compression`: rank compression of sampled residuals;
- :mod:`.conditions`: the compressed balance equalities handed to a solver.
"""

from __future__ import annotations

from .layout import DesignLayout, ParameterLayout, Slot

__all__ = ["DesignLayout", "ParameterLayout", "Slot"]
