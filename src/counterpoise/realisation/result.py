"""What the realisation layer found of a design, as extras of its
:class:`~counterpoise.designer.solution.Solution`: the :class:`RealisationReport` (the
designed springs and every realisation limit, ``solution.extra(RealisationReport)``) and
the :class:`BuildCheck` (the build sheet and the balancer rebuilt from it,
``solution.extra(BuildCheck)``), both attached once, by the layer (:mod:`.method`) or when
the design is finished (:mod:`.layer`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .asbuilt import AsBuilt
    from .limits import Limit


@dataclass(frozen=True)
class RealisationReport:
    """What the realisation layer found of a design (an extra of its :class:`Solution`)."""

    limits: tuple[Limit, ...]
    #: the designed springs (:class:`~counterpoise.springs.workspace.DesignedSpring`)
    springs: tuple[Any, ...] = ()
    #: realisation constraints added to the problem before this design
    added: tuple[str, ...] = ()
    rounds: int = 0
    #: per designed spring whose stiffness was re-solved: (design rate, wound rate) in N/m
    wound: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    #: the springs are declared ideal: the limits are reported, not enforced
    ideal: bool = False
    notes: tuple[str, ...] = ()

    @property
    def violated(self) -> tuple[Limit, ...]:
        return tuple(lim for lim in self.limits if not lim.met)


@dataclass(frozen=True)
class BuildCheck:
    """The build sheet of a design (the rows ``build.csv`` holds, as written) and the
    balancer rebuilt from it with real springs (:mod:`.asbuilt`)."""

    sheet: tuple[dict[str, Any], ...]
    as_built: AsBuilt
