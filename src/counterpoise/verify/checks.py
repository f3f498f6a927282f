"""The verification's records and its definitions (residual ratio, reference, balanced):
they live in :mod:`counterpoise.designer.checks`, beside the :class:`~counterpoise.designer.solution.Solution`
that carries a :class:`Verification`; re-exported here, where the dense check and its
readers have always found them."""

from __future__ import annotations

from ..designer.checks import FORCE_NAME, NOISE_TOLERANCE, PRISMATIC, REVOLUTE, UNIT, CoordinateCheck, Verification

__all__ = ["FORCE_NAME", "NOISE_TOLERANCE", "PRISMATIC", "REVOLUTE", "UNIT", "CoordinateCheck", "Verification"]
