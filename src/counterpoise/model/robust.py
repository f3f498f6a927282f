"""What a ``[robust]`` table asks for: tolerances of the built balancer and what the design
must do about them (see docs/robust.md). Resolved by :mod:`counterpoise.io.resolve.robust`,
designed by :mod:`counterpoise.robust`."""

from __future__ import annotations

from dataclasses import dataclass

#: tolerance kinds and the element each applies to
KINDS = ("rate", "initial_tension", "mass", "com", "point")
#: the modes of ``[robust] mode``
MODES = ("minimise", "limit", "none")


@dataclass(frozen=True)
class Tolerance:
    """One toleranced item: ``kind`` of element ``item`` scatters by ± ``amount``.

    ``relative``: ``amount`` is a fraction of the nominal value (a rate, a mass); otherwise
    it is in SI (N/m, N, kg, m). ``com`` and ``point`` are absolute lengths, applied to each
    of the three components of the point in its frame independently."""

    kind: str
    item: str
    amount: float
    relative: bool
    key: str = ""  # the file key it was given at (for messages)


@dataclass(frozen=True)
class RobustSpec:
    """``[robust]``: the tolerances, the mode and the tuning variables."""

    tolerances: tuple[Tolerance, ...]
    mode: str = "none"
    #: minimise: kg of objective per unit of worst-case residual ratio
    weight: float = 0.0
    #: limit: the largest worst-case residual ratio
    limit: float = 0.0
    #: "box" (each deviation independently within ±, exact worst corner) or "ellipsoid"
    shape: str = "box"
    #: variables re-set on the built balancer (an anchor screw) to re-balance every corner
    tune: tuple[str, ...] = ()
    description: str = ""
    #: the tuning law's trial turn of each tune variable (SI; default a round quarter of its tuning range)
    steps: tuple[tuple[str, float], ...] = ()
    #: the screw pitch of each tune variable that is a length (m per turn; default PITCH)
    pitch: tuple[tuple[str, float], ...] = ()


#: the screw pitch the procedure states turns for when the file gives none (m per turn; M6 coarse)
PITCH = 1e-3
