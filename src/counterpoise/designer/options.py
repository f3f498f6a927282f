"""The options of one solve, for every design method and designer: :class:`SolveOptions`."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from ..formulation.layout import Slot

#: base-parameter values (SI) in every scenario, by name
Parameters = Mapping[str, float]
#: variable bounds for one call (SI): a slot or a variable name -> (lower, upper)
BoundsOverride = Mapping["Slot | str", tuple[float, float]]
#: initial values (SI) of design-vector slots
Initial = Mapping[Slot, float]


@dataclass(frozen=True)
class SolveOptions:
    """What one solve of a design method is asked (all SI, all optional): base-parameter
    values in every scenario, variable bounds for this call (a slot or a variable name ->
    (lower, upper)), initial values of slots; ``certify=False`` skips the certificate gap
    and the minimax closest design (callers that solve many times and report one design
    certify that one). Every layer hands it on to its inner method, changed where the layer
    says (:func:`dataclasses.replace`): every option acts on every kind of problem."""

    parameters: Parameters | None = None
    bounds: BoundsOverride | None = None
    initial: Initial | None = None
    certify: bool = True
